"""
The paper-style identification, kept as the baseline to measure against (and for tests).

Section 3.3: "Effectiveness of the calibration procedure depends on the
Identification Jacobian that is computed numerically."  Here that is done the
way the paper describes it: forward kinematics solved posture by posture with
the Newton algorithm of section 2.2, and a finite-difference identification
Jacobian in which every column re-solves FK for every posture, handed to a
general least-squares solver (scipy's ``least_squares``).  It is correct but slow;
``identification.identify`` is the method.  Any architecture: FK is Newton on the
architecture's IK and its pose Jacobian d lambda / d X (``legs.pose_jacobian``).
"""

from __future__ import annotations

from dataclasses import dataclass
import time

import numpy as np
from scipy.optimize import least_squares

from ..architectures import KinematicParameters, parameters_for
from ..machine.device import DeviceModel, measured_position
from ..machine.measurements import Measurements


def forward_kinematics_one(
    params: KinematicParameters,
    actuators: np.ndarray,
    guess: np.ndarray,
    tolerance: float = 1e-12,
    max_iterations: int = 50,
) -> np.ndarray:
    """
    Solve the forward kinematics of one posture as section 2.2 does.

    Section 2.2 for a single posture: X <- X - J_inv^-1 (IK(X) - Q_d) until |IK(X) - Q_d| <
    tolerance.
    """
    arch = params.architecture
    chains = arch.chains(params)
    pose = np.array(guess, dtype=float)
    for _ in range(max_iterations):
        legs = arch.legs(chains, pose[None])
        if not legs.reachable()[0]:
            break
        residual = legs.actuators[0] - actuators
        if np.max(np.abs(residual)) < tolerance:
            return pose
        pose = pose - np.linalg.solve(legs.pose_jacobian()[0], residual)
    return np.full(6, np.nan)


def absolute_residuals(
    vector: np.ndarray,
    measurements: Measurements,
    device: DeviceModel = DeviceModel(),
    model: str | None = None,
) -> np.ndarray:
    """
    Eq. 7 residuals, FK posture by posture (what the paper's numerical Jacobian differentiates).

    ``vector`` holds the parameters of ``model`` (default: the Hexa Slide).
    """
    params = parameters_for(model, vector)
    alpha, beta = measurements.inclinometer.T
    measured = measured_position(alpha, beta, device.link_length)
    rows = np.empty((len(measurements), 4))
    for i in range(len(measurements)):
        guess = np.concatenate([measured[i], [0.0, 0.0, measurements.rotary[i]]])
        pose = forward_kinematics_one(params, measurements.actuator_positions[i], guess)
        rows[i, :3] = measured[i] - pose[:3]
        rows[i, 3] = measurements.rotary[i] - pose[5]
    return rows.reshape(-1)


def finite_difference_jacobian(
    residual_function, vector: np.ndarray, step: float = 1e-7
) -> np.ndarray:
    """Central differences, one column per parameter (each re-solving FK for every posture)."""
    columns = []
    for k in range(len(vector)):
        delta = np.zeros_like(vector)
        delta[k] = step
        columns.append(
            (residual_function(vector + delta) - residual_function(vector - delta)) / (2 * step)
        )
    return np.column_stack(columns)


@dataclass
class BaselineResult:
    parameters: KinematicParameters
    seconds: float
    evaluations: int
    status: str


def identify_baseline(
    nominal: KinematicParameters, measurements: Measurements, device: DeviceModel = DeviceModel()
) -> BaselineResult:
    """
    Identify the parameters the paper's way.

    Paper-style identification: per-posture FK, forward-difference Jacobian, scipy least_squares.
    """
    started = time.perf_counter()
    solution = least_squares(
        absolute_residuals,
        nominal.vector,
        jac='2-point',
        method='lm',
        args=(measurements, device, nominal.model),
        xtol=1e-12,
        ftol=1e-12,
    )
    return BaselineResult(
        nominal.with_vector(solution.x),
        time.perf_counter() - started,
        int(solution.nfev),
        solution.message,
    )
