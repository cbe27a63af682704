"""
Rehearse a passive-actuator move on machines that differ from the nominal.

With one actuator released, the five commanded ones and the link decide where the platform
goes, and on the true machine that is not where the nominal model says: millimetres of model
error move the platform by centimetres on a Hexa Slide, and a move that is well conditioned on
the nominal can pass a singularity of the passive system on the true machine, where the five
commanded chains and the link jam (the drive faults).  A release is therefore judged on
machines whose geometry departs from the nominal as a machine built to its drawing does: the
nominal plus ``count`` draws of independent normal errors of ``error_m`` RMS on every parameter
(by default the architecture's Table 2 set 2 RMS, 1.45 mm on both shipped models; rail-direction
components 1.45e-3).  Each machine walks the move the way the drive does: from its standing at
the previous posture (the actuator released there locked where the link put it), the commanded
setpoints carry that offset to zero along the move (as the executor commands a move,
core/walk/platform_paths.py), sampled at most ``step_m`` apart in joint space, each sample solved
from the previous pose (``passive_actuator.solve_passive``: continuation on the machine's branch).
After a move's first sample, Newton starts from a predicted pose when that is closer: the
tangent step from the previous pose plus the previous sample's second-order correction (where
it closed less where its tangent step led; ``predicted_starts``), so that most samples close in
one Newton step instead of two.  The solution must then lie within the branch tolerance of both
the previous pose and the predicted one.
A candidate survives on a machine if every sample closes and its released actuator stays inside
the stroke less the margin; its score is the worst condition number of the passive system met
on the way, over all machines.

``rehearse`` walks one move's candidates machine by machine (the reference); ``rehearse_stacked``
walks many moves, all their candidates and all machines in one Newton iteration over a stacked
batch (``MachineStack``: each machine's per-chain constants computed once, the IK of every row
on its own machine in one call of the architecture's ``legs_stacked``), with the same
arithmetic row by row, so the same closures and decisions, in a fraction of the calls.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .passive_actuator import (
    _check_branch,
    _errors,
    _solve,
    largest_conditions,
    MAX_HALVINGS,
    MAX_STALLS,
    passive_system,
    release_conditions,
    solve_passive,
)
from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT, STANDING
from ..machine.kinematics import inverse_kinematics, wrap_angle

DEFAULT_MODEL_SAMPLES = 8  # machines besides the nominal a release is rehearsed on
DEFAULT_JOINT_STEP_M = 0.01  # a continuation step that follows the branch; the drive's is 5 mm
# Closing to 1 nm is plenty to follow a branch (the driver closes to 1e-12 m): fewer iterations.
REHEARSAL_TOLERANCE_M = 1e-9
# Samples on the way need only stay on the branch: Newton's next pass closes 0.1 mm to ~1e-8.
PATH_TOLERANCE_M = 1e-4
# The largest second-order correction (m or rad, any pose coordinate) a prediction carries:
# 99 % of the Hexa Slide's are below it, and it stays well inside the branch tolerance.
PREDICTION_LIMIT = 0.02
NOMINAL_ERROR_SET = 2  # Table 2's set of a machine built to its drawing


def _sample_tolerance(sample, count):
    """Return the closure a continuation sample needs: its move's last tight, others loose."""
    return np.where(sample >= count - 1, REHEARSAL_TOLERANCE_M, PATH_TOLERANCE_M)


def model_error_rms_m(nominal: KinematicParameters) -> float:
    """Return the default RMS parameter error (m) of the nominal's architecture (module doc)."""
    stats = nominal.architecture.nominal_error_stats_mm
    return float(stats[NOMINAL_ERROR_SET][2]) * 1e-3


def sampled_machines(
    nominal: KinematicParameters, count: int, error_m: float, seed: int = 0
) -> tuple[KinematicParameters, ...]:
    """Return the nominal and `count` machines with normal parameter errors of RMS `error_m`."""
    rng = np.random.default_rng([seed, 18])
    base = nominal.vector
    drawn = tuple(
        nominal.with_vector(base + rng.normal(0.0, error_m, len(base))) for _ in range(count)
    )
    return (nominal, *drawn)


@dataclass
class Standings:
    """Where each machine stands (K machines): poses (K, 6) and actuators (K, 6)."""

    poses: np.ndarray
    actuators: np.ndarray


@dataclass(frozen=True)
class Rehearsal:
    """
    A move rehearsed for candidate releases on K machines.

    ``survived`` (C,) on how many machines each candidate closes all along and stays inside
    its stroke; ``worst`` (C,) the worst condition number met on the machines it survived on
    (inf if none);
    ``ends`` the standings after the move per candidate (a machine that jammed: NaN rows).
    """

    candidates: np.ndarray
    survived: np.ndarray
    worst: np.ndarray
    ends: tuple[Standings, ...]


def stand(
    machines: tuple[KinematicParameters, ...],
    setpoints: np.ndarray,
    released: int,
    pose: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> Standings:
    """Return each machine standing with `setpoints` and `released` free, near `pose`."""
    poses, actuators = [], []
    for machine in machines:
        solved = solve_passive(machine, setpoints[None], released, pose[None], link_length, mount)
        if bool(solved.converged[0]):
            poses.append(solved.poses[0])
            actuators.append(solved.actuators[0])
        else:  # it cannot stand there: rehearse it from the posture as planned
            poses.append(np.asarray(pose, dtype=float))
            actuators.append(inverse_kinematics(machine, pose[None])[0])
    return Standings(np.array(poses), np.array(actuators))


def setpoint_samples(offsets: np.ndarray, model_path: np.ndarray, step_m: float) -> np.ndarray:
    """
    Return the setpoints (S, K, 6) of K machines along `model_path` (M, 6), offsets fading.

    Machine k starts at model_path[0] + offsets[k] and ends at model_path[-1]; samples at most
    `step_m` apart along the path (max-norm), the offset carried to zero with the path
    fraction.
    """
    lengths = np.max(np.abs(np.diff(model_path, axis=0)), axis=1)
    total = float(np.sum(lengths))
    count = max(1, math.ceil(max(total, float(np.max(np.abs(offsets)))) / step_m))
    fractions = np.arange(1, count + 1) / count
    if total > 0:
        along = np.concatenate([[0.0], np.cumsum(lengths)]) / total
        points = np.column_stack(
            [np.interp(fractions, along, model_path[:, c]) for c in range(6)]
        )
    else:
        points = np.repeat(model_path[-1:], count, axis=0)
    return points[:, None, :] + (1.0 - fractions)[:, None, None] * offsets[None]


def rehearse(
    machines: tuple[KinematicParameters, ...],
    start: Standings,
    setpoints: np.ndarray,
    candidates: np.ndarray,
    link_length: float,
    stroke: tuple[float, float],
    margin_m: float,
    mount: str = DEFAULT_MOUNT,
) -> Rehearsal:
    """Rehearse releasing each candidate along `setpoints` (S, K, 6) on every machine."""
    candidates = np.asarray(candidates, dtype=int)
    count, machine_count = len(candidates), len(machines)
    poses = np.repeat(start.poses[None], count, axis=0)  # (C, K, 6)
    actuators = np.repeat(start.actuators[None], count, axis=0)
    alive = np.ones((count, machine_count), bool)
    worst = np.zeros((count, machine_count))
    low, high = stroke[0] + margin_m, stroke[1] - margin_m
    tangent = np.full((count, machine_count, 6), np.nan)  # where each sample's tangent led
    for s, sample in enumerate(setpoints):
        tolerance = float(_sample_tolerance(s, len(setpoints)))
        for k, machine in enumerate(machines):
            rows = np.flatnonzero(alive[:, k])
            if not rows.size:
                continue
            released = candidates[rows]
            commanded = np.repeat(sample[k][None], len(rows), axis=0)
            here = poses[rows, k]
            starts, tangent[rows, k] = predicted_starts(
                machine, commanded, released, here, tangent[rows, k], link_length, tolerance,
                predict=s > 0,
            )
            solved = solve_passive(machine, commanded, released, starts, link_length, mount,
                                   tolerance=tolerance)
            ok = solved.converged
            _check_branch(solved.poses, here, ok, {}, mount, BRANCH_TOLERANCE_M,
                          BRANCH_TOLERANCE_RAD)
            alive[rows[~ok], k] = False
            rows, released = rows[ok], released[ok]
            poses[rows, k] = solved.poses[ok]
            actuators[rows, k] = solved.actuators[ok]
            position = actuators[rows, k, released]
            alive[rows, k] &= (position >= low) & (position <= high)
            conditions = release_conditions(machine, poses[rows, k], link_length)
            picked = conditions[np.arange(len(rows)), released]
            worst[rows, k] = np.maximum(worst[rows, k], picked)
    poses[~alive] = np.nan
    actuators[~alive] = np.nan
    return Rehearsal(
        candidates,
        np.sum(alive, axis=1),
        _worst_alive(worst, alive),
        tuple(Standings(poses[c], actuators[c]) for c in range(count)),
    )


def predicted_starts(
    machine: KinematicParameters,
    commanded: np.ndarray,
    released: np.ndarray,
    here: np.ndarray,
    last_tangent: np.ndarray,
    link_length: float,
    tolerance: float,
    *,
    predict: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return where Newton starts each row's next sample, and where its tangent step leads.

    The tangent step is Newton's first from `here` (the previous sample's pose; NaN for a row
    already closed there); the prediction adds the previous sample's second-order correction
    (`here` less `last_tangent`, where that sample's tangent step led), up to PREDICTION_LIMIT,
    and is the start where its residual is smaller than at `here` (else `here`).  The stacked
    continuation takes the same first step.
    """
    used = commanded.copy()
    used[np.arange(len(here)), released] = 0.0
    residual, jacobian, _ = passive_system(machine, here, used, released, link_length)
    error = np.max(np.abs(residual), axis=1)  # _errors at `here`, from the same evaluation
    step, solvable = _solve(jacobian, residual)
    with np.errstate(invalid='ignore'):
        moving = error >= tolerance
        tangent = np.where(moving[:, None], here - step, np.nan)
        correction = here - last_tangent
        usable = (predict & moving & solvable
                  & (np.abs(correction).max(axis=1) <= PREDICTION_LIMIT))
    if not usable.any():
        return here, tangent
    guess = np.where(usable[:, None], tangent + correction, here)
    closer = usable & (_errors(machine, guess, used, released, link_length) < error)
    return np.where(closer[:, None], guess, here), tangent


class MachineStack:
    """
    Machines of one architecture, their per-chain constants computed once, IK stacked.

    ``evaluate`` gives the IK of every row on its own machine in one call of the architecture's
    ``legs_stacked`` (vectorised on the shipped architectures; a loop over the machines present
    by default): the rehearsal's batches are small, and the per-call overhead is what costs.
    """

    def __init__(self, machines: tuple[KinematicParameters, ...]):
        self.machines = tuple(machines)
        self.architecture = self.machines[0].architecture
        self.stacked = self.architecture.stack_chains(
            [self.architecture.chains(machine) for machine in self.machines]
        )

    def evaluate(
        self, machine: np.ndarray, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return IK (N, 6), d lambda / d X (N, 6, 6) and reachable (N,) of row i on machine[i]."""
        legs = self.architecture.legs_stacked(self.stacked, machine, poses)
        return legs.actuators, legs.pose_jacobian, legs.reachable

    def rows(self, machine: np.ndarray) -> object:
        """Return rows on machine[i], their constants gathered once for ``evaluate_rows``."""
        return self.architecture.stacked_rows(self.stacked, machine)

    def evaluate_rows(
        self, rows: object, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``evaluate`` of the gathered ``rows`` (``rows``) at ``poses``."""
        legs = self.architecture.legs_of_rows(rows, poses)
        return legs.actuators, legs.pose_jacobian, legs.reachable


@dataclass
class StackedSolution:
    """``solve_stacked``'s closures: poses and IK (NaN where failed), converged, d lambda / d X."""

    poses: np.ndarray
    actuators: np.ndarray
    converged: np.ndarray
    jacobian: np.ndarray
    reachable: np.ndarray


def _radius(poses: np.ndarray) -> np.ndarray:
    """Return |P| per pose: np.linalg.norm's arithmetic without its per-call checks."""
    position = poses[:, :3]
    return np.sqrt(np.add.reduce(position * position, axis=1))


def _passive_residual(actuators, reachable, poses, used, released, link_length):
    """Return passive_system's residuals (N, 6) and |P| from IK already evaluated at `poses`."""
    rows = np.arange(len(poses))
    radius = _radius(poses)
    with np.errstate(invalid='ignore'):
        residual = actuators - used
    residual[rows, released] = radius - link_length
    residual[~(reachable & (radius > 0))] = np.inf
    return residual, radius


def _passive_jacobian(jacobian, poses, radius, released):
    """Return passive_system's Jacobian: row `released` replaced by the sphere's gradient."""
    n = len(poses)
    system = jacobian.copy()
    sphere = np.zeros((n, 6))
    with np.errstate(divide='ignore', invalid='ignore'):
        sphere[:, :3] = poses[:, :3] / radius[:, None]
    system[np.arange(n), released] = sphere
    return system


# solve_passive's defaults, as the reference rehearsal calls it.
MAX_ITERATIONS = 30
BRANCH_TOLERANCE_M = 0.05
BRANCH_TOLERANCE_RAD = 0.35
# The scales of solve_passive's step halvings after the full step: exact powers of two.
_HALVINGS = 0.5 ** np.arange(1, MAX_HALVINGS + 1)


def _damped_step(evaluate, active: np.ndarray, base: np.ndarray, step: np.ndarray,
                 current: np.ndarray) -> tuple[np.ndarray, tuple, np.ndarray]:
    """
    Return the Newton trial of each row, its evaluated values and error.

    A row whose full step does not reduce the residual takes the first halving that does, else
    the last (which the caller does not take): all rows' halvings are evaluated at once.
    """
    trial = base - step
    values, trial_error = evaluate(active, trial)
    worse = np.flatnonzero(~(trial_error < current))
    if not worse.size:
        return trial, values, trial_error
    count = len(_HALVINGS)
    halved = (base[worse][:, None, :]
              - _HALVINGS[None, :, None] * step[worse][:, None, :]).reshape(-1, 6)
    halved_values, halved_error = evaluate(np.repeat(active[worse], count), halved)
    halved_error = halved_error.reshape(-1, count)
    improves = halved_error < current[worse][:, None]
    first = np.where(np.any(improves, axis=1), np.argmax(improves, axis=1), count - 1)
    picked = np.arange(len(worse)) * count + first
    trial[worse] = halved[picked]
    trial_error[worse] = halved_error[np.arange(len(worse)), first]
    values = tuple(v.copy() for v in values)
    for value, halved_value in zip(values, halved_values):
        value[worse] = halved_value[picked]
    return trial, values, trial_error


def solve_stacked(
    stack: MachineStack,
    machine: np.ndarray,
    commanded: np.ndarray,
    released: np.ndarray,
    start: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    *,
    tolerance: float = 1e-12,
    max_iterations: int = 30,
    branch_tolerance_m: float = 0.05,
    branch_tolerance_rad: float = 0.35,
) -> StackedSolution:
    """
    Solve the passive system of row i on machine[i]: ``solve_passive`` over a stacked batch.

    The same Newton iteration, step halving and branch check as ``solve_passive``, row by row:
    the same poses.  The IK evaluated at a pose is kept for the next step (and the pose
    Jacobian of the solution returned, for its condition number); where the full step does not
    reduce the residual, every halving of it is evaluated at once and the first that does is
    taken (solve_passive evaluates them in turn until one does: the same one).
    """
    n = len(start)
    rows = np.arange(n)
    machine = np.asarray(machine, dtype=int)
    released = np.asarray(released, dtype=int)
    used = np.array(commanded, dtype=float)
    used[rows, released] = 0.0
    poses = np.array(start, dtype=float)
    finite = np.all(np.isfinite(used), axis=1) & np.all(np.isfinite(poses), axis=1)
    actuators = np.full((n, 6), np.nan)
    jacobian = np.full((n, 6, 6), np.nan)
    reachable = np.zeros(n, bool)
    residual = np.full((n, 6), np.nan)
    radius = np.full(n, np.nan)
    error = np.full(n, np.inf)

    def evaluate(where: np.ndarray, at: np.ndarray):
        """Return the IK, residuals, |P| and errors of rows `where` at poses `at`."""
        ik, pose_jacobian, ok = stack.evaluate(machine[where], at)
        res, rad = _passive_residual(ik, ok, at, used[where], released[where], link_length)
        return (ik, pose_jacobian, ok, res, rad), np.max(np.abs(res), axis=1)

    def keep(where: np.ndarray, values) -> None:
        actuators[where], jacobian[where], reachable[where], residual[where], radius[where] = (
            values
        )

    active = np.flatnonzero(finite)
    if active.size:
        values, error[active] = evaluate(active, poses[active])
        keep(active, values)
    stalls = np.zeros(n, int)
    for _ in range(max_iterations):
        active = active[(error[active] >= tolerance) & (stalls[active] < MAX_STALLS)]
        if not active.size:
            break
        system = _passive_jacobian(jacobian[active], poses[active], radius[active],
                                   released[active])
        step, solvable = _solve(system, residual[active])
        stalls[active[~solvable]] = MAX_STALLS
        active, step = active[solvable], step[solvable]
        if not active.size:
            continue
        base, current = poses[active], error[active]
        trial, values, trial_error = _damped_step(evaluate, active, base, step, current)
        better = trial_error < current
        taken = active[better]
        poses[taken] = trial[better]
        error[taken] = trial_error[better]
        keep(taken, tuple(v[better] for v in values))
        stalls[active[~better]] += 1
    converged = finite & (error < tolerance)
    _check_branch(poses, start, converged, {}, mount, branch_tolerance_m, branch_tolerance_rad)
    poses[~converged] = np.nan
    actuators[~converged] = np.nan
    return StackedSolution(poses, actuators, converged, jacobian, reachable)


def released_condition(
    jacobian: np.ndarray,
    reachable: np.ndarray,
    poses: np.ndarray,
    released: np.ndarray,
    link_length: float,
) -> np.ndarray:
    """Return ``release_conditions`` of the released chain only (N,), from d lambda / d X."""
    system, ok = _released_systems(jacobian, reachable, poses, released, link_length)
    conditions = np.full(len(poses), np.inf)
    if np.any(ok):
        conditions[ok] = np.linalg.cond(system[ok])
    return conditions


def worst_released_condition(
    jacobian: np.ndarray,
    reachable: np.ndarray,
    poses: np.ndarray,
    released: np.ndarray,
    link_length: float,
    rows: np.ndarray,
    count: int,
) -> np.ndarray:
    """Return the largest ``released_condition`` of each of `count` rows (`rows` (N,); 0: none)."""
    system, ok = _released_systems(jacobian, reachable, poses, released, link_length)
    worst = largest_conditions(system[ok], rows[ok], count)
    worst[np.unique(rows[~ok])] = np.inf
    return worst


def _released_systems(jacobian, reachable, poses, released, link_length):
    """Return the passive systems of ``released_condition`` (N, 6, 6) and where they hold."""
    n = len(poses)
    system = jacobian.copy()
    system[:, :, 3:] /= link_length
    radius = _radius(poses)
    sphere = np.zeros((n, 6))
    sphere[:, :3] = poses[:, :3] / np.where(radius > 0, radius, np.nan)[:, None]
    system[np.arange(n), released] = sphere
    return system, reachable & (radius > 0)


def stand_stacked(
    stack: MachineStack,
    machine: np.ndarray,
    setpoints: np.ndarray,
    released: np.ndarray,
    poses: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> Standings:
    """Return ``stand`` of row i: machine[i] with setpoints[i], released[i] free, near poses[i]."""
    machine = np.asarray(machine, dtype=int)
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    solved = solve_stacked(stack, machine, np.atleast_2d(setpoints), np.asarray(released, int),
                           poses, link_length, mount)
    out_poses, out_actuators = solved.poses.copy(), solved.actuators.copy()
    for i in np.flatnonzero(~solved.converged):  # it cannot stand there: from the posture
        out_poses[i] = poses[i]
        out_actuators[i] = inverse_kinematics(stack.machines[machine[i]], poses[i][None])[0]
    return Standings(out_poses, out_actuators)


@dataclass(frozen=True)
class RehearsalJob:
    """One move to rehearse: where the K machines stand, setpoints (S, K, 6), candidates (C,)."""

    start: Standings
    setpoints: np.ndarray
    candidates: np.ndarray


def rehearse_stacked(
    stack: MachineStack,
    jobs: list[RehearsalJob],
    link_length: float,
    stroke: tuple[float, float],
    margin_m: float,
    mount: str = DEFAULT_MOUNT,
) -> list[Rehearsal]:
    """Return ``rehearse`` of each job, every job, candidate and machine in one stacked batch."""
    machine_count = len(stack.machines)
    job_parts: list[np.ndarray] = []
    candidate_parts: list[np.ndarray] = []
    machine_parts: list[np.ndarray] = []
    count_parts: list[np.ndarray] = []
    start_parts: list[np.ndarray] = []
    start_act_parts: list[np.ndarray] = []
    for j, job in enumerate(jobs):
        candidates = np.asarray(job.candidates, dtype=int)
        c_index, k_index = np.meshgrid(np.arange(len(candidates)), np.arange(machine_count),
                                       indexing='ij')
        job_parts.append(np.full(c_index.size, j))
        candidate_parts.append(candidates[c_index.ravel()])
        machine_parts.append(k_index.ravel())
        count_parts.append(np.full(c_index.size, len(job.setpoints)))
        start_parts.append(job.start.poses[k_index.ravel()])
        start_act_parts.append(job.start.actuators[k_index.ravel()])
    job_of, released = np.concatenate(job_parts), np.concatenate(candidate_parts)
    machine, counts = np.concatenate(machine_parts), np.concatenate(count_parts)
    poses, actuators = np.concatenate(start_parts), np.concatenate(start_act_parts)
    total = len(job_of)
    setpoints = np.full((int(np.max(counts)), total, 6), np.nan)
    for j, job in enumerate(jobs):
        rows = np.flatnonzero(job_of == j)
        setpoints[: len(job.setpoints), rows] = job.setpoints[:, machine[rows]]
    low, high = stroke[0] + margin_m, stroke[1] - margin_m
    walk = _Continuation(stack, machine, released, setpoints, counts, poses, link_length, mount)
    alive, worst = walk.run(low, high)
    poses, actuators = walk.poses, walk.actuators
    poses[~alive] = np.nan
    actuators[~alive] = np.nan
    results = []
    for j, job in enumerate(jobs):
        rows = np.flatnonzero(job_of == j)
        count = len(job.candidates)
        shape = (count, machine_count)
        job_alive = alive[rows].reshape(shape)
        job_poses = poses[rows].reshape(shape + (6,))
        job_actuators = actuators[rows].reshape(shape + (6,))
        results.append(Rehearsal(
            np.asarray(job.candidates, dtype=int),
            np.sum(job_alive, axis=1),
            _worst_alive(worst[rows].reshape(shape), job_alive),
            tuple(Standings(job_poses[c], job_actuators[c]) for c in range(count)),
        ))
    return results


_IDENTITY = np.eye(6)


class _Continuation:
    """
    Rows (a candidate on a machine) each walking its own setpoint samples, asynchronously.

    Each row's arithmetic is solve_passive's on its samples in turn, as in ``rehearse``, but a
    row that has settled a sample goes on to its next while others still iterate: one batched
    Newton step per pass over every row still walking, so a row slow to close (near a fold, or
    jamming) delays no other.  The IK at a row's pose is kept: a new sample's first residual
    needs no evaluation.  As every row still walking steps in every pass (one that settles a
    sample begins its next in the same pass), a pass evaluates all rows, their per-chain
    constants gathered once, and keeps what the stepping rows took, with masks rather than
    index lists: the rows done or jammed cost less than gathering the others every pass.
    """

    def __init__(self, stack, machine, released, setpoints, counts, poses, link_length, mount):
        n = len(machine)
        self.stack, self.machine, self.released = stack, machine, released
        self.setpoints, self.counts, self.link_length, self.mount = (
            setpoints, counts, link_length, mount
        )
        self.poses = np.array(poses, dtype=float)
        self.actuators = np.full((n, 6), np.nan)
        self.sample = np.zeros(n, int)
        self.used = np.full((n, 6), np.nan)
        # The poses each row's solution must stay near: where its sample began, and where
        # Newton restarted (the prediction, when taken; else the same pose).
        self.anchors = np.repeat(self.poses[None], 2, axis=0)
        self.tolerance = np.full(n, PATH_TOLERANCE_M)  # the closure of each row's sample
        self.error = np.full(n, np.inf)
        self.stalls = np.zeros(n, int)
        self.iterations = np.zeros(n, int)
        self.ik = np.full((n, 6), np.nan)
        self.jacobian = np.full((n, 6, 6), np.nan)
        self.reachable = np.zeros(n, bool)
        self.residual = np.full((n, 6), np.nan)
        self.radius = np.full(n, np.nan)
        # The prediction (predicted_starts): each sample's tangent landing, the correction the
        # next sample's first step carries, and the pose Newton restarted from when it was taken.
        self.tangent = np.full((n, 6), np.nan)
        self.correction = np.zeros((n, 6))
        self.fresh = np.zeros(n, bool)  # the sample's first step is still to take
        self.predicting = np.zeros(n, bool)
        # Each settled sample's Jacobian, kept for the condition numbers computed at the end.
        self.settled: list[tuple[np.ndarray, ...]] = []

    def _evaluate(self, where: np.ndarray, at: np.ndarray):
        ik, pose_jacobian, ok = self.stack.evaluate(self.machine[where], at)
        res, rad = _passive_residual(ik, ok, at, self.used[where], self.released[where],
                                     self.link_length)
        return (ik, pose_jacobian, ok, res, rad), np.max(np.abs(res), axis=1)

    def _keep(self, where: np.ndarray, values) -> None:
        self.ik[where], self.jacobian[where], self.reachable[where] = values[:3]
        self.residual[where], self.radius[where] = values[3:]

    def _begin(self, which: np.ndarray) -> None:
        """Start each row's current sample from where it stands (solve_passive's start)."""
        used = self.setpoints[self.sample[which], which]
        used[np.arange(len(which)), self.released[which]] = 0.0
        self.used[which] = used
        finite = np.isfinite(used).all(axis=1) & np.isfinite(self.poses[which]).all(axis=1)
        residual, radius = _passive_residual(
            self.ik[which], self.reachable[which], self.poses[which], used,
            self.released[which], self.link_length,
        )
        self.residual[which], self.radius[which] = residual, radius
        self.error[which] = np.where(finite, np.max(np.abs(residual), axis=1), np.inf)
        self.stalls[which] = np.where(finite, 0, MAX_STALLS)
        self.iterations[which] = 0
        self.tolerance[which] = _sample_tolerance(self.sample[which], self.counts[which])
        self.anchors[:, which] = self.poses[which]
        correction = self.poses[which] - self.tangent[which]
        self.correction[which] = correction
        self.predicting[which] = (self.sample[which] > 0) & (
            np.abs(correction).max(axis=1) <= PREDICTION_LIMIT
        )
        self.tangent[which] = np.nan  # recorded by the sample's first step, if it takes one
        self.fresh[which] = True

    def _evaluate_all(self, at: np.ndarray):
        ik, pose_jacobian, ok = self.stack.evaluate_rows(self.bound, at)
        residual = ik - self.used
        radius = _radius(at)
        residual[self.rows, self.released] = radius - self.link_length
        residual[~(ok & (radius > 0))] = np.inf
        return (ik, pose_jacobian, ok, residual, radius), np.abs(residual).max(axis=1)

    def run(self, low: float, high: float) -> tuple[np.ndarray, np.ndarray]:
        """Walk every row through its samples; return alive (N,) and the worst condition."""
        n = len(self.machine)
        rows = self.rows = np.arange(n)
        self.bound = self.stack.rows(self.machine)
        alive, worst = np.ones(n, bool), np.zeros(n)
        finite = np.isfinite(self.poses).all(axis=1)
        if finite.any():
            values, _ = self._evaluate(rows[finite], self.poses[finite])
            self._keep(rows[finite], values)
        self._begin(rows)
        with np.errstate(all='ignore'):  # rows done or jammed compute NaN, never kept
            while True:
                walking = alive & (self.sample < self.counts)
                if not walking.any():
                    break
                open_ = ((self.error >= self.tolerance) & (self.stalls < MAX_STALLS)
                         & (self.iterations < MAX_ITERATIONS))
                settled = walking & ~open_
                if settled.any():
                    self._settle(settled, alive, low, high)
                    walking = alive & (self.sample < self.counts)
                    open_ = ((self.error >= self.tolerance) & (self.stalls < MAX_STALLS)
                             & (self.iterations < MAX_ITERATIONS))
                stepping = walking & open_
                if stepping.any():
                    self._step(stepping)
        if self.settled:  # the worst condition met on the way, all samples at once
            which, jacobian, reachable, poses = (np.concatenate(part)
                                                 for part in zip(*self.settled))
            kept = alive[which]  # a row that jammed has no score (_worst_alive)
            which = which[kept]
            worst = worst_released_condition(jacobian[kept], reachable[kept], poses[kept],
                                             self.released[which], self.link_length, which, n)
        self.poses[~alive] = np.nan
        self.actuators[~alive] = np.nan
        return alive, worst

    def _settle(self, settled, alive, low, high) -> None:
        """End each settled row's sample: closed on its branch and inside the stroke, or dead."""
        converged = settled & (self.error < self.tolerance)
        poses = self.poses
        away = poses - self.anchors  # (2, N, 6): from where the sample began and restarted
        moved = away[..., :3]
        jump = np.sqrt(np.add.reduce(moved * moved, axis=2)).max(axis=0)  # _radius of each
        turn = np.abs(wrap_angle(away[..., 3:])).max(axis=2).max(axis=0)
        side = poses[:, 2] > 0 if self.mount == STANDING else poses[:, 2] < 0
        converged &= ~((jump > BRANCH_TOLERANCE_M) | (turn > BRANCH_TOLERANCE_RAD) | ~side)
        alive &= ~settled | converged
        ok = np.flatnonzero(converged)
        self.actuators[ok] = self.ik[ok]
        position = self.ik[self.rows, self.released]
        alive &= ~converged | ((position >= low) & (position <= high))
        self.settled.append((ok, self.jacobian[ok], self.reachable[ok], poses[ok]))
        self.sample += converged
        going = np.flatnonzero(converged & alive & (self.sample < self.counts))
        if going.size:
            self._begin(going)

    def _step(self, stepping: np.ndarray) -> None:
        """
        One Newton step with solve_passive's halving on every stepping row.

        A predicting row instead tries its predicted start (predicted_starts): taken, Newton
        restarts there (no iteration counted); not closer, the row's next pass takes the plain
        step from where it stands.
        """
        predicting = stepping & self.predicting
        self.iterations += stepping & ~predicting
        system = _passive_jacobian(self.jacobian, self.poses, self.radius, self.released)
        idle = ~stepping
        system[idle] = _IDENTITY
        step, solvable = _solve(system, np.where(idle[:, None], 0.0, self.residual))
        fresh = stepping & self.fresh
        self.tangent[fresh] = self.poses[fresh] - step[fresh]
        self.fresh &= ~stepping
        self.predicting &= ~stepping
        predicting &= solvable
        step[predicting] -= self.correction[predicting]
        self.stalls[stepping & ~solvable] = MAX_STALLS
        ok = stepping & solvable
        trial = self.poses - step
        values, trial_error = self._evaluate_all(trial)
        worse = np.flatnonzero(ok & ~predicting & ~(trial_error < self.error))
        if worse.size:
            count = len(_HALVINGS)
            halved = (self.poses[worse][:, None, :]
                      - _HALVINGS[None, :, None] * step[worse][:, None, :]).reshape(-1, 6)
            halved_values, halved_error = self._evaluate(np.repeat(worse, count), halved)
            halved_error = halved_error.reshape(-1, count)
            improves = halved_error < self.error[worse][:, None]
            first = np.where(improves.any(axis=1), improves.argmax(axis=1), count - 1)
            picked = np.arange(len(worse)) * count + first
            trial[worse] = halved[picked]
            trial_error[worse] = halved_error[np.arange(len(worse)), first]
            for value, halved_value in zip(values, halved_values):
                value[worse] = halved_value[picked]
        better = ok & (trial_error < self.error)
        self.stalls += ok & ~better & ~predicting
        restarted = predicting & better
        self.anchors[1, restarted] = trial[restarted]
        taken = np.flatnonzero(better)
        self.poses[taken] = trial[taken]
        self.error[taken] = trial_error[taken]
        self._keep(taken, tuple(value[taken] for value in values))


def _worst_alive(worst: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """Return the worst condition over the machines each candidate survived on (inf: none)."""
    masked = np.where(alive, worst, -np.inf)
    best = np.max(masked, axis=1)
    return np.where(np.any(alive, axis=1), best, np.inf)


__all__ = [
    'DEFAULT_JOINT_STEP_M',
    'DEFAULT_MODEL_SAMPLES',
    'MachineStack',
    'Rehearsal',
    'RehearsalJob',
    'StackedSolution',
    'Standings',
    'model_error_rms_m',
    'rehearse',
    'rehearse_stacked',
    'released_condition',
    'worst_released_condition',
    'sampled_machines',
    'setpoint_samples',
    'solve_stacked',
    'stand',
    'stand_stacked',
]
