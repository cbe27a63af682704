"""
Kinematics of the passive-actuator measuring mode (the paper's section 4), any architecture.

With the measuring link attached the platform keeps 5 degrees of freedom: the link
(U joints at both ends, length L) holds the platform frame origin P on the sphere
|P - O| = L about the device's base joint O, which the core places at the base
origin (core/machine/device.py; the mount only says on which side of O the platform
hangs or stands).  Six position-controlled actuators over-constrain it, so one
actuator r is released (not powered, its encoder still reads) and the other five
are commanded.  The pose X = [x, y, z, theta, psi, phi] then solves six equations:

    lambda_c(X) - lambda_c^cmd = 0     for the five commanded chains c != r (IK),
    |P| - L = 0                        the link's sphere (O at the base origin),

6 equations for 6 unknowns.  Their Jacobian is the architecture's pose Jacobian
d lambda / d X with row r replaced by the sphere's gradient [P^T / |P|, 0, 0, 0];
it is regular wherever the five commanded legs and the link together constrain
the platform (`release_conditions` measures how well).  The released actuator
lambda_r(X) then follows by IK: it is where the link put it, and the encoder
reads it, which is why it is read and not commanded.

`solve_passive` is Newton's method on that system, batched over postures,
with the step halving and the branch check of forward kinematics (a solution
far from the start, or on the other side of O, is another assembly mode).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..architectures import KinematicParameters
from ..errors import ForwardKinematicsError, InvalidMeasurementError
from ..machine.device import DEFAULT_MOUNT, STANDING
from ..machine.kinematics import wrap_angle

MAX_HALVINGS = 10  # a Newton step is halved at most this often to reduce the residual
MAX_STALLS = 3  # Newton steps that no halving improves: no solution near the start


class PassiveSolveError(ForwardKinematicsError):
    """No platform pose near the start closes the five commanded chains and the link."""

    reason = 'passive-solve-failed'


@dataclass
class PassiveSolution:
    """Batched outcome of `solve_passive`: poses, full actuator readings, what failed and why."""

    poses: np.ndarray  # (N, 6); NaN rows where failed
    actuators: np.ndarray  # (N, 6) IK of the solved poses: the five commanded and the released
    released: np.ndarray  # (N,) 0-based chain index of the released actuator
    converged: np.ndarray  # (N,) bool
    iterations: np.ndarray  # (N,)
    failures: dict[int, str] = field(default_factory=dict)  # posture index -> reason

    @property
    def released_positions(self) -> np.ndarray:
        """Return the released actuators' positions (N,), m: what their encoders read."""
        return self.actuators[np.arange(len(self.released)), self.released]

    def raise_if_failed(self) -> None:
        """Raise PassiveSolveError naming the postures without a solution near their start."""
        if self.failures:
            first = sorted(self.failures.items())[:5]
            detail = '; '.join(f'#{i}: {why}' for i, why in first)
            raise PassiveSolveError(
                f'passive-actuator solve failed for {len(self.failures)} posture(s): {detail}',
                sorted(self.failures),
            )


def released_indices(released: np.ndarray | int, n: int) -> np.ndarray:
    """Return the released chain per posture (n,), 0-based; InvalidMeasurementError if not 0..5."""
    index = np.broadcast_to(np.asarray(released), (n,))
    if not np.issubdtype(index.dtype, np.integer) or np.any((index < 0) | (index > 5)):
        raise InvalidMeasurementError(
            f'released actuator must be a chain index 0..5 (0-based), got {np.unique(index)}'
        )
    return index.astype(int)


def passive_system(
    params: KinematicParameters,
    poses: np.ndarray,
    commanded: np.ndarray,
    released: np.ndarray | int,
    link_length: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the residuals (N, 6), their pose Jacobian (N, 6, 6) and the IK (N, 6) at `poses`.

    Row c: lambda_c(X) - commanded_c for the commanded chains; row r (the released one):
    |P| - L (module doc).  `commanded` (N, 6) may hold anything (NaN) in the released column.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    n = len(poses)
    rows, index = np.arange(n), released_indices(released, n)
    arch = params.architecture
    legs = arch.legs(arch.chains(params), poses)
    radius = np.linalg.norm(poses[:, :3], axis=1)
    with np.errstate(invalid='ignore'):
        residual = legs.actuators - np.atleast_2d(np.asarray(commanded, dtype=float))
    residual[rows, index] = radius - link_length
    jacobian = np.array(legs.pose_jacobian())
    sphere = np.zeros((n, 6))
    with np.errstate(divide='ignore', invalid='ignore'):
        sphere[:, :3] = poses[:, :3] / radius[:, None]
    jacobian[rows, index] = sphere
    reachable = legs.reachable() & (radius > 0)
    residual[~reachable] = np.inf
    return residual, jacobian, np.array(legs.actuators)


def release_conditions(
    params: KinematicParameters, poses: np.ndarray, link_length: float
) -> np.ndarray:
    """
    Return the condition number (N, 6) of the passive system with each chain released.

    Column r: cond of the Jacobian of [the five other actuator equations; the sphere] at the
    pose, angle columns scaled by 1 / L (angles as lengths, so the number is unit-free, as the
    workspace's ``max_condition``).  inf where the pose is out of reach.
    """
    systems, ok = _release_systems(params, poses, link_length)
    conditions = np.full(ok.shape + (6,), np.inf)
    if np.any(ok):
        conditions[ok] = np.linalg.cond(systems[ok].reshape(-1, 6, 6)).reshape(-1, 6)
    return conditions


def worst_release_conditions(
    params: KinematicParameters, poses: np.ndarray, link_length: float
) -> np.ndarray:
    """Return the largest of ``release_conditions`` over `poses`, each chain's (6,)."""
    systems, ok = _release_systems(params, poses, link_length)
    if not np.all(ok):
        return np.full(6, np.inf)
    groups = np.tile(np.arange(6), len(ok))
    return largest_conditions(systems.reshape(-1, 6, 6), groups, 6)


def _release_systems(
    params: KinematicParameters, poses: np.ndarray, link_length: float
) -> tuple[np.ndarray, np.ndarray]:
    """Return the systems of ``release_conditions`` (N, r, 6, 6) and where they hold (N,)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    n = len(poses)
    arch = params.architecture
    legs = arch.legs(arch.chains(params), poses)
    base = np.array(legs.pose_jacobian())
    base[:, :, 3:] /= link_length
    radius = np.linalg.norm(poses[:, :3], axis=1)
    sphere = np.zeros((n, 6))
    sphere[:, :3] = poses[:, :3] / np.where(radius > 0, radius, np.nan)[:, None]
    systems = np.repeat(base[:, None], 6, axis=1)  # (N, r, 6, 6)
    chains = np.arange(6)
    systems[:, chains, chains] = sphere[:, None, :]
    return systems, legs.reachable() & (radius > 0)


# Above this Frobenius bound a matrix is always taken to the SVD: its inverse may be too
# inaccurate to bound anything (relative error about eps x cond).
_UNTRUSTED_BOUND = 1e8


def largest_conditions(systems: np.ndarray, groups: np.ndarray, count: int) -> np.ndarray:
    """
    Return the largest np.linalg.cond of `systems` (M, n, n) in each of `count` groups (0: none).

    The same numbers as np.linalg.cond of all and a maximum per group, with the SVD taken only
    where the maximum can be: cond <= |A|_F |A^-1|_F <= n cond, so a matrix whose bound lies below
    a group's largest cond already found cannot raise it (a batched 6x6 inverse costs a quarter
    of the SVD: 43 against 167 ms for 68k matrices).
    """
    worst = np.zeros(count)
    if not len(systems):
        return worst
    try:
        inverse = np.linalg.inv(systems)
    except np.linalg.LinAlgError:  # an exactly singular matrix: every one to the SVD
        np.maximum.at(worst, groups, np.linalg.cond(systems))
        return worst
    with np.errstate(over='ignore', invalid='ignore'):
        bound = np.sqrt(np.sum(systems * systems, axis=(1, 2))
                        * np.sum(inverse * inverse, axis=(1, 2)))
    bound = np.where(np.isfinite(bound), bound, np.inf)
    top = np.full(count, -np.inf)
    np.maximum.at(top, groups, bound)
    seeds = np.flatnonzero(bound == top[groups])
    seeds = seeds[np.unique(groups[seeds], return_index=True)[1]]  # one per group, at its top
    np.maximum.at(worst, groups[seeds], np.linalg.cond(systems[seeds]))
    # Rounding of the bound (relative eps x cond) is covered by the factor.
    taken = (bound * (1.0 + 1e-6) >= worst[groups]) | (bound > _UNTRUSTED_BOUND)
    taken[seeds] = False
    if np.any(taken):
        np.maximum.at(worst, groups[taken], np.linalg.cond(systems[taken]))
    return worst


def _errors(params, poses, commanded, released, link_length) -> np.ndarray:
    residual = passive_system(params, poses, commanded, released, link_length)[0]
    return np.max(np.abs(residual), axis=1)


def _solve(jacobian: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve J step = residual per posture, batched; flag the singular ones."""
    try:
        step = np.linalg.solve(jacobian, residual[..., None])[..., 0]
        return step, np.asarray(np.isfinite(step).all(axis=1))
    except np.linalg.LinAlgError:  # rare: one at a time, so a singular one fails alone
        step = np.zeros_like(residual)
        solvable = np.zeros(len(jacobian), bool)
        for i in range(len(jacobian)):
            try:
                step[i] = np.linalg.solve(jacobian[i], residual[i])
                solvable[i] = bool(np.all(np.isfinite(step[i])))
            except np.linalg.LinAlgError:
                pass
        return step, solvable


def solve_passive(
    params: KinematicParameters,
    commanded: np.ndarray,
    released: np.ndarray | int,
    start: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    *,
    tolerance: float = 1e-12,
    max_iterations: int = 30,
    branch_tolerance_m: float = 0.05,
    branch_tolerance_rad: float = 0.35,
) -> PassiveSolution:
    """
    Solve the platform pose and the released actuator from five commanded actuators (module doc).

    `commanded` (N, 6) actuator setpoints (m; the released column is ignored), `released` (N,)
    or one 0-based chain index, `start` (N, 6) the expected poses (the previous pose, or the
    planned one), `link_length` the true link length L (m), `mount` the side of O the platform
    is on.  Newton on `passive_system` until every |residual| < `tolerance` (m); a step that
    does not reduce the residual is halved.  A solution farther than `branch_tolerance_m` /
    `branch_tolerance_rad` from the start, or on the wrong side of O, is refused (another
    assembly mode).  Failed postures are NaN rows with a reason; ``raise_if_failed`` raises.
    """
    commanded = np.atleast_2d(np.asarray(commanded, dtype=float))
    start = np.atleast_2d(np.asarray(start, dtype=float))
    n = len(start)
    if commanded.shape != (n, 6) or start.shape != (n, 6):
        raise InvalidMeasurementError(
            f'commanded and start must be (N, 6), got {commanded.shape} and {start.shape}'
        )
    index = released_indices(released, n)
    rows = np.arange(n)
    used = commanded.copy()
    used[rows, index] = 0.0  # the released column is not an equation
    poses = start.copy()
    failures: dict[int, str] = {}
    finite = np.all(np.isfinite(used), axis=1) & np.all(np.isfinite(start), axis=1)
    for i in np.flatnonzero(~finite):
        failures[int(i)] = 'non-finite commanded actuators or start pose'
    error = np.full(n, np.inf)
    error[finite] = _errors(params, poses[finite], used[finite], index[finite], link_length)
    stalls = np.zeros(n, int)
    iterations = np.zeros(n, int)
    active = np.flatnonzero(finite)
    for _ in range(max_iterations):
        active = active[(error[active] >= tolerance) & (stalls[active] < MAX_STALLS)]
        if not active.size:
            break
        iterations[active] += 1
        residual, jacobian, _ = passive_system(
            params, poses[active], used[active], index[active], link_length
        )
        step, solvable = _solve(jacobian, residual)
        for i in active[~solvable]:
            failures[int(i)] = 'singular system (the five commanded legs and the link)'
        stalls[active[~solvable]] = MAX_STALLS
        active, step = active[solvable], step[solvable]
        _damped_update(params, poses, error, stalls, active, step, used, index, link_length)
    converged = finite & (error < tolerance)
    for i in np.flatnonzero(finite & ~converged):
        failures.setdefault(
            int(i),
            f'no convergence (residual {error[i]:.3g} m): no pose near the start closes the five '
            'commanded chains and the link',
        )
    _check_branch(poses, start, converged, failures, mount, branch_tolerance_m,
                  branch_tolerance_rad)
    poses[~converged] = np.nan
    actuators = np.full((n, 6), np.nan)
    if np.any(converged):
        arch = params.architecture
        actuators[converged] = arch.legs(arch.chains(params), poses[converged]).actuators
    return PassiveSolution(poses, actuators, index, converged, iterations, failures)


def _damped_update(params, poses, error, stalls, active, step, used, index, link_length) -> None:
    """Take X - step on the `active` rows, halving it where it does not reduce the residual."""
    if not active.size:
        return
    base, current = poses[active], error[active]
    scale = np.ones(len(active))
    trial, trial_error = base, current
    for _ in range(MAX_HALVINGS + 1):
        trial = base - scale[:, None] * step
        trial_error = _errors(params, trial, used[active], index[active], link_length)
        worse = ~(trial_error < current)
        if not np.any(worse):
            break
        scale[worse] *= 0.5
    better = trial_error < current
    poses[active[better]] = trial[better]
    error[active[better]] = trial_error[better]
    stalls[active[~better]] += 1


def _check_branch(poses, start, converged, failures, mount, tol_m, tol_rad) -> None:
    """Refuse solutions far from the start or on the other side of O (another assembly mode)."""
    jump = np.linalg.norm(poses[:, :3] - start[:, :3], axis=1)
    turn = np.max(np.abs(wrap_angle(poses[:, 3:] - start[:, 3:])), axis=1)
    side = poses[:, 2] > 0 if mount == STANDING else poses[:, 2] < 0
    wrong = converged & ((jump > tol_m) | (turn > tol_rad) | ~side)
    for i in np.flatnonzero(wrong):
        failures[int(i)] = (
            f'converged to another assembly mode: {jump[i] * 1e3:.1f} mm / '
            f'{np.degrees(turn[i]):.1f} deg from the start (no solution near it)'
        )
    converged &= ~wrong


__all__ = [
    'PassiveSolution',
    'PassiveSolveError',
    'passive_system',
    'largest_conditions',
    'release_conditions',
    'worst_release_conditions',
    'released_indices',
    'solve_passive',
]
