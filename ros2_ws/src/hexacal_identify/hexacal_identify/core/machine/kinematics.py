"""
Inverse and forward kinematics of any architecture, batched over postures.

A pose is ``X = [x, y, z, theta, psi, phi]`` (eq. 1): the position of the
platform frame origin P in the base frame and three Euler angles with
``R = R_Y(theta) R_X(psi) R_z(phi)`` (eq. 2): psi about the global X axis,
theta about the global Y axis, phi about the rotated local z axis.

Each architecture (``architectures/``) gives the actuator readings of a pose
(IK) with their derivatives d lambda / d X and d lambda / d u; forward
kinematics (Newton with the branch check of section 3.3) and the
identification Jacobian (implicit differentiation) are written once here.
The parameters object says which architecture it belongs to.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..architectures import KinematicParameters
from ..architectures.common import cross_last as _cross  # noqa: F401
from ..architectures.common import euler_rate_axes
from ..architectures.common import rotation_from_trig as _rotation_from_trig
# The Hexa Slide's posture-major reference path, under the names it has always had here.
from ..architectures.hexa_slide import (  # noqa: F401
    leg_geometry,
    LegGeometry,
    parameter_jacobian_blocks,
    pose_jacobian,
    rail_xy_slice,
)
from ..architectures.hexa_slide import subset_geometry as _subset  # noqa: F401
from ..errors import ForwardKinematicsError, InvalidMeasurementError, UnreachablePoseError

POSE_LABELS = ('x', 'y', 'z', 'theta', 'psi', 'phi')
MAX_HALVINGS = 10  # a Newton step is halved at most this often to reduce the slider error
# A posture whose Newton step fails to reduce the error at every step length this often has no
# solution near its start: stop there rather than spend every remaining iteration on it (Newton's
# direction is a descent direction wherever the pose Jacobian is regular, so a solvable one never
# stalls).
MAX_STALLS = 3
__all__ = [
    'POSE_LABELS',
    'ForwardKinematicsResult',
    'PoseSensitivity',
    'euler_rate_axes',
    'forward_kinematics',
    'inverse_kinematics',
    'measured_pose',
    'pose_sensitivities',
    'rotation_matrices',
]


def rotation_matrices(angles: np.ndarray) -> np.ndarray:
    """R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2) for angles (N, 3) = [theta, psi, phi]."""
    angles = np.asarray(angles, dtype=float)
    return _rotation_from_trig(np.cos(angles.T), np.sin(angles.T))


def _legs(params: KinematicParameters, poses: np.ndarray):
    arch = params.architecture
    return arch.legs(arch.chains(params), poses)


def inverse_kinematics(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """
    Actuator readings lambda (N, 6) for poses (N, 6) (Hexa Slide: eq. 3's slider positions).

    Raises UnreachablePoseError naming the postures whose legs cannot reach.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    if poses.shape[-1] != 6:
        raise InvalidMeasurementError(
            f'poses must have 6 columns [x y z theta psi phi], got {poses.shape}'
        )
    if not np.all(np.isfinite(poses)):
        bad = np.flatnonzero(~np.all(np.isfinite(poses), axis=1))
        raise InvalidMeasurementError(f'non-finite pose(s) at index {bad.tolist()}', bad)
    legs = _legs(params, poses)
    unreachable = ~legs.reachable()
    if np.any(unreachable):
        bad = np.flatnonzero(unreachable)
        raise UnreachablePoseError(
            f'{bad.size} pose(s) unreachable ({params.architecture.unreachable_reason}), '
            f'indices {bad[:10].tolist()}{" ..." if bad.size > 10 else ""}',
            bad,
        )
    return legs.actuators


@dataclass
class ForwardKinematicsResult:
    """Batched FK outcome: poses, which converged, and why the others did not."""

    poses: np.ndarray  # (N, 6); NaN rows where failed
    converged: np.ndarray  # (N,) bool
    iterations: np.ndarray  # (N,) Newton iterations used
    failures: dict[int, str] = field(default_factory=dict)  # index -> reason

    def raise_if_failed(self) -> None:
        if self.failures:
            first = sorted(self.failures.items())[:5]
            detail = '; '.join(f'#{i}: {why}' for i, why in first)
            raise ForwardKinematicsError(
                f'forward kinematics failed for {len(self.failures)} posture(s): {detail}',
                sorted(self.failures),
            )


def forward_kinematics(
    params: KinematicParameters,
    actuator_positions: np.ndarray,
    initial_poses: np.ndarray,
    *,
    tolerance: float = 1e-12,
    max_iterations: int = 30,
    branch_tolerance_m: float = 0.05,
    branch_tolerance_rad: float = 0.35,
    fit_tilt_first: bool = False,
) -> ForwardKinematicsResult:
    """
    Newton iteration X <- X - J_inv^-1 (IK(X) - lambda) (section 2.2), batched.

    Converged when every |IK(X) - lambda| < tolerance (m).  A step that leaves
    the reachable set or increases the residual is halved (up to 10 times).  The
    branch check of section 3.3 rejects a solution whose position moved more
    than ``branch_tolerance_m`` from the initial guess, or whose phi moved more
    than ``branch_tolerance_rad``: the initial guess is the expected posture.
    With ``fit_tilt_first`` the two unmeasured angles (theta, psi) are first
    fitted with position and phi held at the guess, which brings Newton's start
    close to the solution when only position and phi are known (the device's case).
    """
    targets = np.atleast_2d(np.asarray(actuator_positions, dtype=float))
    start = np.atleast_2d(np.asarray(initial_poses, dtype=float))
    arch = params.architecture
    chains = arch.chains(params)
    poses = _fit_tilt(arch, chains, targets, start) if fit_tilt_first else start.copy()
    n = len(targets)
    converged = np.zeros(n, bool)
    iterations = np.zeros(n, int)
    failures: dict[int, str] = {}
    finite = np.all(np.isfinite(targets), axis=1) & np.all(np.isfinite(start), axis=1)
    for i in np.flatnonzero(~finite):
        failures[int(i)] = 'non-finite slider positions or initial pose'
    active = np.flatnonzero(finite)
    target = targets[active]
    legs = arch.legs(chains, poses[active])
    error = _actuator_error(legs, target)
    stalls = np.zeros(len(active), int)  # Newton steps that no halving made better
    for iteration in range(max_iterations + 1):
        done = error < tolerance
        stuck = stalls >= MAX_STALLS
        for i in active[stuck & ~done]:
            failures[int(i)] = (
                f'no convergence: {MAX_STALLS} Newton steps did not reduce the slider error '
                'at any step length (no solution near the expected posture)'
            )
        if done.any() or stuck.any():
            converged[active[done]] = True
            keep = ~done & ~stuck
            active, error, target, stalls = active[keep], error[keep], target[keep], stalls[keep]
            if active.size:
                legs = legs.subset(keep)
        if active.size == 0 or iteration == max_iterations:
            break
        iterations[active] += 1
        step, solvable = _solve_batched(legs.pose_jacobian(), legs.actuators - target)
        if not solvable.all():
            for i in active[~solvable]:
                failures[int(i)] = 'singular pose Jacobian (the platform is at a singularity)'
            active, error, step, target = (
                active[solvable],
                error[solvable],
                step[solvable],
                target[solvable],
            )
            stalls = stalls[solvable]
        poses[active], legs, error, stalled = _damped_update(
            arch, chains, poses[active], step, target, error
        )
        stalls += stalled
    for i in active:
        failures.setdefault(int(i), f'no convergence in {max_iterations} Newton iterations')
    _check_branch(poses, start, converged, failures, branch_tolerance_m, branch_tolerance_rad)
    poses[~converged] = np.nan
    return ForwardKinematicsResult(poses, converged, iterations, failures)


def _fit_tilt(
    arch, chains, targets: np.ndarray, start: np.ndarray, iterations: int = 4
) -> np.ndarray:
    """Gauss-Newton on (theta, psi) alone: least squares over the 6 sliders, 2 unknowns."""
    poses = start.copy()
    finite = np.all(np.isfinite(targets), axis=1) & np.all(np.isfinite(start), axis=1)
    fitted, target = poses[finite], targets[finite]
    for _ in range(iterations):
        legs = arch.legs(chains, fitted)
        if not np.all(legs.reachable()):
            break
        jac = legs.pose_jacobian()[:, :, 3:5]
        residual = legs.actuators - target
        # 2 x 2 normal equations per posture, written out.
        a = np.sum(jac[:, :, 0] * jac[:, :, 0], axis=1)
        b = np.sum(jac[:, :, 0] * jac[:, :, 1], axis=1)
        c = np.sum(jac[:, :, 1] * jac[:, :, 1], axis=1)
        normal = np.stack([a, b, b, c], axis=1).reshape(-1, 2, 2)
        rhs = np.stack(
            [np.sum(jac[:, :, 0] * residual, axis=1), np.sum(jac[:, :, 1] * residual, axis=1)],
            axis=1,
        )
        try:
            step = np.linalg.solve(normal, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        fitted[:, 3:5] -= np.clip(step, -0.3, 0.3)
    poses[finite] = fitted
    return np.where(np.isfinite(poses), poses, start)


ANGLE_ITERATIONS = 8  # Gauss-Newton passes on the three angles: millimetres of error, 1e-12 rad


def measured_pose(
    params: KinematicParameters,
    actuators: np.ndarray,
    positions: np.ndarray,
    guesses: np.ndarray,
) -> np.ndarray:
    """
    Return poses (N, 6) at the measured `positions` (N, 3), angles fitted to `actuators` (N, 6).

    Where the device measured the platform (its position, eq. 4 of the inclinometer's angles)
    with the orientation that fits the six measured actuators best on `params` (Gauss-Newton
    on the three angles from those of `guesses` (N, 6)); a row whose legs leave the reach keeps
    its guess's angles.  On a Hexa Slide millimetres of model error put forward kinematics
    millimetres from where the platform is; the measured position does not depend on the model.
    """
    arch = params.architecture
    chains = arch.chains(params)
    poses = np.array(guesses, dtype=float, ndmin=2)
    poses[:, :3] = positions
    measured = np.atleast_2d(np.asarray(actuators, dtype=float))
    for _ in range(ANGLE_ITERATIONS):
        legs = arch.legs(chains, poses)
        reachable = legs.reachable()
        if not reachable.any():
            break
        jacobian = legs.pose_jacobian()[reachable][:, :, 3:]  # d actuators / d angles
        residual = (legs.actuators - measured)[reachable]
        poses[reachable, 3:] -= (np.linalg.pinv(jacobian) @ residual[..., None])[..., 0]
    return poses


def _actuator_error(legs, targets: np.ndarray) -> np.ndarray:
    error = np.max(np.abs(legs.actuators - targets), axis=1)
    return np.where(legs.reachable(), error, np.inf)


def _solve_batched(jac: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve J step = residual per posture; flag postures whose J is singular."""
    try:
        step = np.linalg.solve(jac, residual[..., None])[..., 0]
        solvable = np.all(np.isfinite(step), axis=1)
    except np.linalg.LinAlgError:  # rare: solve each posture on its own to find the singular ones
        step = np.zeros_like(residual)
        solvable = np.zeros(len(jac), bool)
        for i in range(len(jac)):
            try:
                step[i] = np.linalg.solve(jac[i], residual[i])
                solvable[i] = np.all(np.isfinite(step[i]))
            except np.linalg.LinAlgError:
                pass
    return step, solvable


def _damped_update(
    arch, chains, poses: np.ndarray, step: np.ndarray, targets: np.ndarray, error: np.ndarray
):
    """
    Take X - step, halving the step where it does not reduce the slider error.

    Also returns the mask of postures where even the smallest step did not reduce it (stalled).
    """
    trial = poses - step
    legs = arch.legs(chains, trial)
    trial_error = _actuator_error(legs, targets)
    scale = None
    worse = np.zeros(len(poses), bool)
    for _ in range(MAX_HALVINGS):
        worse = ~(trial_error < error) & (error > 0)
        if not np.any(worse):
            break
        if scale is None:
            scale = np.ones(len(poses))
        scale[worse] *= 0.5
        trial[worse] = poses[worse] - scale[worse, None] * step[worse]
        sub = arch.legs(chains, trial[worse])
        legs.replace_rows(worse, sub)
        trial_error[worse] = _actuator_error(sub, targets[worse])
    else:
        worse = ~(trial_error < error) & (error > 0)
    return trial, legs, trial_error, worse


def _check_branch(poses, start, converged, failures, tol_m, tol_rad) -> None:
    jump = np.linalg.norm(poses[:, :3] - start[:, :3], axis=1)
    phi_jump = np.abs(wrap_angle(poses[:, 5] - start[:, 5]))
    wrong = converged & ((jump > tol_m) | (phi_jump > tol_rad))
    for i in np.flatnonzero(wrong):
        failures[int(i)] = (
            f'converged to another branch: {jump[i] * 1e3:.1f} mm / {np.degrees(phi_jump[i]):.1f} '
            'deg from the expected posture'
        )
    converged &= ~wrong


def wrap_angle(angle: np.ndarray | float) -> np.ndarray:
    """Angles into [-pi, pi) (the rotary sensor's range)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


class PoseSensitivity:
    """
    Derivatives of forward-kinematics poses.

    Derivatives of FK poses: w.r.t. the parameters (54 for a Hexa Slide) and the 6 actuator
    readings.

    Kept factored: dX/du[n, k, F c + f] = -wrt_actuators[n, k, c] * actuator_blocks[n, c, f] (F
    fields per chain) (d lambda / d u is block diagonal), so a cost function can form just the rows
    it needs (``rows``, ``combined``) in one pass; ``wrt_parameters`` is the full (N, 6, 6 F)
    array, formed on first use.
    """

    def __init__(self, wrt_actuators: np.ndarray, actuator_blocks: np.ndarray):
        self.wrt_actuators = wrt_actuators  # dX/d lambda = J_inv^-1, (N, 6, 6)
        self.actuator_blocks = actuator_blocks  # d lambda_c / d u_c, (N, 6, F)
        self._wrt_parameters: np.ndarray | None = None

    @property
    def n_parameters(self) -> int:
        return self.actuator_blocks.shape[1] * self.actuator_blocks.shape[2]

    @property
    def wrt_parameters(self) -> np.ndarray:
        """dX/du, (N, 6, n)."""
        if self._wrt_parameters is None:
            full = -self.wrt_actuators[:, :, :, None] * self.actuator_blocks[:, None, :, :]
            self._wrt_parameters = full.reshape(len(full), 6, self.n_parameters)
        return self._wrt_parameters

    def _pick(self, index: np.ndarray | None):
        if index is None:
            return self.wrt_actuators, self.actuator_blocks
        return self.wrt_actuators[index], self.actuator_blocks[index]

    def rows(self, index: np.ndarray | None, coordinates: slice, factor: float) -> np.ndarray:
        """Factor * dX[coordinates]/du for postures ``index`` (None: all), (k, m, n)."""
        inverse, blocks = self._pick(index)
        # factor * (-M b) = (-factor M) b: the sign is exact, so with factor -1 this is M b bit for
        # bit.
        weights = inverse[:, coordinates, :] * -factor
        out = weights[:, :, :, None] * blocks[:, None, :, :]
        return out.reshape(len(out), out.shape[1], self.n_parameters)

    def combined(self, index: np.ndarray | None, weights: np.ndarray) -> np.ndarray:
        """
        Return sum_k weights[:, k] dX_k/du for postures ``index``.

        , k] dX_k/du for postures ``index`` (None: all); weights (k, 6) -> (k, n).
        """
        inverse, blocks = self._pick(index)
        mixed = -np.matmul(weights[:, None, :], inverse)  # (k, 1, 6)
        out = mixed[:, 0, :, None] * blocks
        return out.reshape(len(out), self.n_parameters)


def pose_sensitivities(params: KinematicParameters, poses: np.ndarray) -> PoseSensitivity:
    """
    dX/du and dX/d lambda at FK solutions, by implicit differentiation of IK(X, u) = lambda.

    J_inv dX = d lambda - (d lambda/d u) du, so dX/d lambda = J_inv^-1 and
    dX/du = -J_inv^-1 d lambda/d u.  d lambda/d u is block diagonal, so column
    block c of dX/du is the outer product of column c of J_inv^-1 with chain c's
    vector of derivatives.
    """
    arch = params.architecture
    chains = arch.chains(params)
    legs = arch.legs(chains, np.asarray(poses, dtype=float))
    unit = legs.unit_legs()
    return PoseSensitivity(
        np.linalg.inv(legs.pose_jacobian(unit)), legs.parameter_blocks(chains, unit)
    )


def pose_parameter_sensitivity(params: KinematicParameters, poses: np.ndarray):
    """
    Return dX/du (N, 6, n) at FK solutions and the legs there.

    dX/du (N, 6, n) at FK solutions (see ``pose_sensitivities``) and the legs (IK intermediates)
    there.
    """
    return pose_sensitivities(params, poses).wrt_parameters, _legs(
        params, np.asarray(poses, dtype=float)
    )
