"""Pose accuracy of a parameter set, judged against the true machine (simulation only)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinematics import forward_kinematics, inverse_kinematics, rotation_matrices
from .model import HexaParameters
from .postures import Workspace, sample_poses


@dataclass
class PoseErrors:
    """Per-posture position (m) and orientation (rad) errors; NaN where FK failed."""

    position_m: np.ndarray
    orientation_rad: np.ndarray

    def summary(self) -> dict[str, float]:
        return {
            "position_mean_m": float(np.nanmean(self.position_m)),
            "position_max_m": float(np.nanmax(self.position_m)),
            "orientation_mean_rad": float(np.nanmean(self.orientation_rad)),
            "orientation_max_rad": float(np.nanmax(self.orientation_rad)),
            "failed_postures": int(np.sum(np.isnan(self.position_m))),
        }


def validation_poses(true_params: HexaParameters, n: int, seed: int, workspace: Workspace = Workspace()) -> np.ndarray:
    """Fresh postures, drawn like the measurement postures but from their own seed."""
    return sample_poses(true_params, n, np.random.default_rng([seed, 0x7A11D]), "sphere", workspace)


def pose_errors(true_params: HexaParameters, model_params: HexaParameters, poses: np.ndarray) -> PoseErrors:
    """Command the true machine's slider positions for ``poses``; where does ``model_params`` put it?

    The controller's view: FK with the model parameters at the slider positions
    the true machine has at each pose, compared with that pose (Table 3's errors).
    """
    sliders = inverse_kinematics(true_params, poses)
    fk = forward_kinematics(model_params, sliders, poses, branch_tolerance_m=0.2, branch_tolerance_rad=0.5)
    position = np.linalg.norm(fk.poses[:, :3] - poses[:, :3], axis=1)
    difference = rotation_matrices(fk.poses[:, 3:6]) - rotation_matrices(poses[:, 3:6])
    # |R1 - R2|_F = 2 sqrt(2) sin(angle / 2): accurate for micro-radian angles, unlike arccos of the trace.
    chord = np.linalg.norm(difference, axis=(1, 2)) / (2.0 * np.sqrt(2.0))
    return PoseErrors(position, 2.0 * np.arcsin(np.clip(chord, 0.0, 1.0)))
