"""
Calibration with a defective device: ignoring the defects, cancelling them, or identifying them.

Frames.  Section 2.3 defines the base X and Y axes by the inclinometer at zero
reading, and the platform's phi zero is the rotary sensor's zero.  A zero
offset beta0 of the inclinometer about Y is therefore the same thing as a
rotation of the base frame about Y (eq. 7 cannot tell them apart: the
identifiability analysis says so), and phi0 is a rotation of the platform frame
about z'.  Those two are frame definitions, not calibration results: joint
identification holds them at zero and identifies dL, alpha0 and gamma, and
every method here is judged against the true machine expressed in the frames
the device defines (``device_frame_truth``) - the frames the calibrated
controller works in.  All of it holds for any architecture: the frames are the
device's, and the architecture re-expresses its parameters in them (``in_frames``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..core.architectures import default_parameters, KinematicParameters
from ..core.assessment.validation import pose_errors, validation_poses
from ..core.errors import CalibrationError
from ..core.fit.identification import identify, SolverOptions
from ..core.machine.device import device_position, DeviceDefects, DeviceModel
from ..core.machine.measurements import (
    FIXED,
    Measurements,
    NoiseModel,
    simulate_measurements,
    SPHERE,
)
from ..core.machine.model import nominal_set
from ..core.machine.postures import sample_poses, Workspace

DEFAULT_DEFECTS = DeviceDefects(dL=5e-4, alpha0=2e-4, beta0=-1.5e-4, gamma=1e-4, phi0=1e-4)
FRAME_DEFINING = (
    'beta0',
    'phi0',
)  # imitated exactly by a base rotation about Y / platform rotation about z'
IDENTIFIED_WITH_EQ7 = ('dL', 'alpha0', 'gamma')


def _rotation_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def device_frame_truth(
    true_params: KinematicParameters, defects: DeviceDefects
) -> KinematicParameters:
    """
    Return the true machine in the device-defined frames.

    Base turned by -beta0 about Y, platform by phi0 about z'.

    A reading beta + beta0 puts the measured position at R_Y(-beta0) p (eq. 4), so
    the device's base frame is the true one turned by -beta0 about Y; a rotary
    reading phi + phi0 makes the platform frame R R_z(phi0), so B' = R_z(-phi0) B.
    The architecture turns every base-frame and platform-frame quantity of its parameters.
    """
    return true_params.architecture.in_frames(
        true_params, _rotation_y(-defects.beta0), _rotation_z(-defects.phi0)
    )


def calibrated_frames(defects: DeviceDefects, identified: tuple[str, ...]) -> DeviceDefects:
    """
    Return the frame-defining defects a calibration leaves in its frames.

    Beta0 and phi0 unless it identified them.
    """
    return DeviceDefects(
        beta0=0.0 if 'beta0' in identified else defects.beta0,
        phi0=0.0 if 'phi0' in identified else defects.phi0,
    )


def device_frame_poses(poses: np.ndarray, defects: DeviceDefects) -> np.ndarray:
    """
    Return poses in the device frames.

    R_Y(-beta0) P, and R_Y(-beta0) R R_z(phi0) = angles (theta - beta0, psi, phi + phi0).
    """
    converted = np.array(poses, dtype=float)
    converted[:, :3] = poses[:, :3] @ _rotation_y(-defects.beta0).T
    converted[:, 3] -= defects.beta0
    converted[:, 5] += defects.phi0
    return converted


def simulate_procedure(
    true_params: KinematicParameters,
    defects: DeviceDefects,
    sphere: int,
    fixed: int,
    noise_um: float,
    seed: int,
    lvdt: bool = False,
    device: DeviceModel = DeviceModel(),
    workspace: Workspace | None = None,
    device_turn: np.ndarray | None = None,
) -> Measurements:
    """
    Simulate the readings of the paper's two-step procedure with a defective device.

    Sphere postures lie on the true sphere of radius L + dL (with an LVDT the link
    is prismatic: radii vary by +-50 mm); fixed postures sit where the defective
    inclinometer reads zero.  Postures are drawn from ``workspace`` (default: the
    architecture's) with its link length replaced by the true one.  ``device_turn``
    (rad, one per sphere posture): the device turned about its link for them.
    """
    rng = np.random.default_rng([seed, 0xDEF])
    noise = NoiseModel.from_microns(noise_um)
    true_length = device.link_length + defects.dL
    base_workspace = (
        workspace if workspace is not None else true_params.architecture.default_workspace()
    )
    workspace = replace(base_workspace, link_length=true_length)
    parts = []
    if sphere:
        poses = sample_poses(true_params, sphere, rng, SPHERE, workspace)
        if lvdt:
            radius = rng.uniform(true_length - 0.05, true_length + 0.05, sphere)
            poses[:, :3] *= (radius / true_length)[:, None]
        parts.append(
            simulate_measurements(
                true_params, poses, SPHERE, device, noise, rng, defects, lvdt, device_turn
            )
        )
    if fixed:
        poses = sample_poses(true_params, fixed, rng, FIXED, workspace)
        poses[:, :3] = device_position(
            np.zeros(1), np.zeros(1), device.link_length, defects
        ).position[0]
        parts.append(
            simulate_measurements(true_params, poses, FIXED, device, noise, rng, defects, lvdt)
        )
    return Measurements.concatenate(parts)


@dataclass(frozen=True)
class Method:
    label: str
    cost: str
    free_device: tuple[str, ...] = ()
    defective: bool = True  # False: the same procedure with an ideal device (the reference)
    lvdt: bool = False
    weighted: bool = False  # residuals whitened by the (known) reading noise


METHODS = (
    Method('ideal device, eq. 7 (reference)', 'absolute', defective=False),
    Method('defects ignored, eq. 7', 'absolute'),
    Method('defects ignored, eqs. 8 + 10', 'sphere-fixed'),
    Method('relative, eqs. 12 + 13', 'relative'),
    Method('joint: eq. 7 + dL, alpha0, gamma', 'absolute', IDENTIFIED_WITH_EQ7),
    Method(
        'ideal device, eq. 7, noise-weighted (reference)',
        'absolute',
        defective=False,
        weighted=True,
    ),
    Method(
        'joint: eq. 7 + dL, alpha0, gamma, noise-weighted',
        'absolute',
        IDENTIFIED_WITH_EQ7,
        weighted=True,
    ),
    Method(
        'joint, LVDT link: eq. 7 + dL, alpha0, gamma, weighted',
        'absolute',
        IDENTIFIED_WITH_EQ7,
        lvdt=True,
        weighted=True,
    ),
)


@dataclass
class MethodOutcome:
    method: Method
    position_mean_m: list[float]
    orientation_mean_rad: list[float]
    aligned_position_mean_m: list[float]  # after removing the best base rotation about Y
    ranks: list[int]
    n_unknowns: int
    device: list[np.ndarray]
    failures: list[str]
    verdict: str = ''

    @staticmethod
    def mean(values: list[float]) -> float:
        return float(np.mean(values)) if values else float('nan')


def compare_methods(
    defects: DeviceDefects = DEFAULT_DEFECTS,
    noise_um: float = 10.0,
    seeds=range(3),
    sphere: int = 60,
    fixed: int = 20,
    nominal_set_number: int = 2,
    progress: Callable[[str], None] = lambda _: None,
    true_params: KinematicParameters | None = None,
    model: str | None = None,
) -> list[MethodOutcome]:
    """
    Compare every method of METHODS on the same machine, procedure and seeds.

    Every method of METHODS on the same machine, procedure and seeds; pose errors in the device
    frames.

    The machine is ``true_params``, else the default machine of ``model`` (default: the Table 1
    Hexa Slide).
    """
    if true_params is None:
        true_params = default_parameters(model)
    outcomes = []
    for method in METHODS:
        used_defects = defects if method.defective else DeviceDefects()
        truth = device_frame_truth(true_params, used_defects)
        outcome = MethodOutcome(method, [], [], [], [], 0, [], [])
        for seed in seeds:
            progress(f'{method.label}, seed {seed}')
            measurements = simulate_procedure(
                true_params, used_defects, sphere, fixed, noise_um, seed, method.lvdt
            )
            options = SolverOptions(
                cost=method.cost,
                free_device=method.free_device,
                noise=NoiseModel.from_microns(noise_um) if method.weighted else None,
                allow_rank_deficient=method.cost == 'relative',
            )
            try:
                result = identify(
                    nominal_set(nominal_set_number, seed=seed, exact=true_params),
                    measurements,
                    options,
                )
            except CalibrationError as error:
                outcome.failures.append(f'seed {seed}: {error.reason}')
                continue
            poses = device_frame_poses(validation_poses(true_params, 50, seed), used_defects)
            errors = pose_errors(truth, result.parameters, poses).summary()
            aligned = pose_errors(
                truth, result.parameters, poses, align_base_rotation_y=True
            ).summary()
            outcome.position_mean_m.append(errors['position_mean_m'])
            outcome.orientation_mean_rad.append(errors['orientation_mean_rad'])
            outcome.aligned_position_mean_m.append(aligned['position_mean_m'])
            outcome.ranks.append(result.rank)
            outcome.n_unknowns = result.identifiability.n_parameters
            outcome.device.append(result.device.vector)
            outcome.verdict = result.identifiability.verdict()
        outcomes.append(outcome)
    return outcomes


__all__ = [
    'DEFAULT_DEFECTS',
    'METHODS',
    'compare_methods',
    'device_frame_poses',
    'device_frame_truth',
    'simulate_procedure',
]
