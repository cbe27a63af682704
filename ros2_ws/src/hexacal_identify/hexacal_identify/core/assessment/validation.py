"""
Pose accuracy of a parameter set, judged against the true machine.

Pose accuracy of a parameter set, judged against the true machine (simulation only), any
architecture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..architectures import KinematicParameters
from ..machine.kinematics import forward_kinematics, inverse_kinematics, rotation_matrices
from ..machine.postures import sample_poses, Workspace


@dataclass
class PoseErrors:
    """Per-posture position (m) and orientation (rad) errors; NaN where FK failed."""

    position_m: np.ndarray
    orientation_rad: np.ndarray

    def summary(self) -> dict[str, float]:
        return {
            'position_mean_m': float(np.nanmean(self.position_m)),
            'position_max_m': float(np.nanmax(self.position_m)),
            'orientation_mean_rad': float(np.nanmean(self.orientation_rad)),
            'orientation_max_rad': float(np.nanmax(self.orientation_rad)),
            'failed_postures': int(np.sum(np.isnan(self.position_m))),
        }


def validation_poses(
    true_params: KinematicParameters, n: int, seed: int, workspace: Workspace | None = None
) -> np.ndarray:
    """
    Fresh postures, drawn like the measurement postures but from their own seed.

    ``workspace`` defaults to the architecture's default workspace.
    """
    if workspace is None:
        workspace = true_params.architecture.default_workspace()
    return sample_poses(
        true_params, n, np.random.default_rng([seed, 0x7A11D]), 'sphere', workspace
    )


def pose_errors(
    true_params: KinematicParameters,
    model_params: KinematicParameters,
    poses: np.ndarray,
    align_base_rotation_y: bool = False,
    align_origin: bool = False,
) -> PoseErrors:
    """
    Return the pose errors of ``model_params`` on the true machine.

    Command the true machine's actuator readings for ``poses``; where does ``model_params`` put it?

    The controller's view: FK with the model parameters at the actuator readings
    the true machine has at each pose, compared with that pose (Table 3's errors).
    With ``align_base_rotation_y`` the model's poses are first turned about the
    base Y axis by the best-fitting angle: the error left is what remains once the
    one frame rotation that sphere-only and relative cost functions cannot see is
    set aside (it must then come from somewhere else, e.g. a fixed parameter).
    With ``align_origin`` the mean position error is removed first: what is left
    once the base frame's origin (the device's joint O) is re-referenced.
    """
    actuators = inverse_kinematics(true_params, poses)
    fk = forward_kinematics(
        model_params, actuators, poses, branch_tolerance_m=0.2, branch_tolerance_rad=0.5
    )
    if align_base_rotation_y:
        fk.poses[:] = _rotate_about_y(fk.poses, _best_angle_about_y(fk.poses[:, :3], poses[:, :3]))
    offsets = fk.poses[:, :3] - poses[:, :3]
    if align_origin:
        offsets = offsets - np.nanmean(offsets, axis=0)
    position = np.linalg.norm(offsets, axis=1)
    difference = rotation_matrices(fk.poses[:, 3:6]) - rotation_matrices(poses[:, 3:6])
    # |R1 - R2|_F = 2 sqrt(2) sin(angle / 2): accurate for micro-radian angles, unlike arccos of
    # the trace.
    chord = np.linalg.norm(difference, axis=(1, 2)) / (2.0 * np.sqrt(2.0))
    return PoseErrors(position, 2.0 * np.arcsin(np.clip(chord, 0.0, 1.0)))


def _best_angle_about_y(model_positions: np.ndarray, true_positions: np.ndarray) -> float:
    """Angle of R_Y that best maps model positions onto true ones (least squares, closed form)."""
    ok = np.all(np.isfinite(model_positions), axis=1)
    p, q = model_positions[ok], true_positions[ok]
    return float(
        np.arctan2(
            np.sum(p[:, 2] * q[:, 0] - p[:, 0] * q[:, 2]),
            np.sum(p[:, 0] * q[:, 0] + p[:, 2] * q[:, 2]),
        )
    )


def _rotate_about_y(poses: np.ndarray, angle: float) -> np.ndarray:
    """Apply R_Y(angle) to poses: positions turn, theta grows by angle (eq. 2 starts with R_Y)."""
    c, s = np.cos(angle), np.sin(angle)
    turned = poses.copy()
    turned[:, 0] = c * poses[:, 0] + s * poses[:, 2]
    turned[:, 2] = -s * poses[:, 0] + c * poses[:, 2]
    turned[:, 3] = poses[:, 3] + angle
    return turned
