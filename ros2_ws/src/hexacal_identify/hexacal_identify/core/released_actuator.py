"""
Choose the actuator released at each posture of a passive-actuator plan (issue #18).

For each planned posture, among the six actuators, the released one is the one
that keeps the five commanded plus the link well conditioned all along the move
from the previous posture, on the nominal machine and on machines that depart
from it as a machine built to its drawing does (core/release_rehearsal.py: the
move rehearsed by continuation as the drive walks it), and that stays inside its
stroke less a margin there.  Candidates that leave the stroke on the nominal are
out; the others are rehearsed in the order of their worst condition number along
the nominal move (``passive_actuator.release_conditions``), the best two first:
the first to close on every machine with a worst condition within
``max_move_condition`` is taken, else all six are rehearsed and the one that
closes on most machines, then the best conditioned, is taken (the choice records
on how many it jams: ``jams``).  The move is the executor's
(``paths.route_command``): along the link sphere (``paths.sphere_path``: great
circle, Euler angles linear) if the nominal IK of all six stays inside the
stroke there, else by way of the centre (the fixed point, zero angles); it is
sampled at most ``step_m`` apart.  The released actuator follows the five
commanded ones wherever the link takes it, and on the true machine that is up to
millimetres from where the nominal model predicts (the model error a first
calibration removes), hence the margin (``DEFAULT_MARGIN_M``): a released
actuator must not run into its end stop.

The choice is per posture, and posture i's released actuator is the one released
during the move from posture i - 1 to posture i and during its measurement: the
executor swaps the released actuator after measuring posture i - 1, at rest
(locking the one released there at its measured position, which it has just
read, and releasing the next, which was standing at its setpoint).  So the
released actuator changes only at rest, by construction.  The first posture's
move starts where the machine is, unknown to the planner: each machine is
rehearsed from standing at the posture with its own actuators (or from ``start``
if given).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .architectures import KinematicParameters
from .device import DEFAULT_MOUNT, fixed_point
from .errors import CalibrationError
from .kinematics import inverse_kinematics
from .passive_actuator import release_conditions
from .paths import sphere_path
from .release_rehearsal import (
    DEFAULT_JOINT_STEP_M,
    DEFAULT_MODEL_SAMPLES,
    model_error_rms_m,
    Rehearsal,
    rehearse,
    sampled_machines,
    setpoint_samples,
    stand,
    Standings,
)

DEFAULT_STEP_M = 0.01  # path samples at most this far apart (position; angles times L)
# Kept from both stroke ends by the released actuator along every move: the largest deviation
# of the true machine from a nominal model (the demo's strain, issue #18: up to 4 mm) and more.
DEFAULT_MARGIN_M = 0.005
# A move whose worst condition number on the rehearsed machines stays below this is taken
# without rehearsing the other candidates; true-machine jams were met from a few hundred up
# (Hexa Slide, set 2 error), the released chain's condition is 30-100 at most postures.
DEFAULT_MAX_MOVE_CONDITION = 250.0
FIRST_REHEARSED = 2  # candidates rehearsed before the others are tried


class ReleaseError(CalibrationError, ValueError):
    """No actuator of a posture can be released: each leaves its stroke along the move."""

    reason = 'no-releasable-actuator'

    def __init__(self, message: str, posture: int):
        super().__init__(message)
        self.posture = posture


@dataclass(frozen=True)
class ReleaseChoice:
    """
    The released actuator per posture and why.

    ``released`` (K,) 0-based chain index; ``conditions`` (K, 6) the passive system's
    condition number with each chain released (angles scaled by L); ``inside`` (K, 6) whether
    that chain stays inside its stroke (less the margin) along the move to the posture;
    ``travel`` (K, 6) the range (max - min, m) each chain covers along that move;
    ``via_centre`` (K,) whether that move goes by way of the centre (the direct one leaves the
    stroke); ``move_conditions`` (K,) the chosen release's worst condition number along its
    move over the rehearsed machines; ``jams`` (K,) on how many of the ``machines`` rehearsed
    the chosen release jams or leaves its stroke on that move (0: none).
    """

    released: np.ndarray
    conditions: np.ndarray
    inside: np.ndarray
    travel: np.ndarray
    via_centre: np.ndarray
    move_conditions: np.ndarray | None = None
    jams: np.ndarray | None = None
    machines: int = 1

    @property
    def chosen_conditions(self) -> np.ndarray:
        """Return the condition number of the chosen release per posture (K,)."""
        return self.conditions[np.arange(len(self.released)), self.released]

    @property
    def worst_conditions(self) -> np.ndarray:
        """Return the worst release's condition number per posture (K,): what choosing avoids."""
        return np.max(self.conditions, axis=1)

    @property
    def released_travel(self) -> np.ndarray:
        """Return how far the released actuator moves on its way to each posture (K,), m."""
        return self.travel[np.arange(len(self.released)), self.released]

    def names(self, actuator_names: tuple[str, ...]) -> tuple[str, ...]:
        """Return the released actuators' joint names, one per posture."""
        return tuple(actuator_names[int(r)] for r in self.released)


def _nominal_actuators(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """Return the nominal IK (M, 6), NaN rows where a pose is out of reach."""
    arch = params.architecture
    legs = arch.legs(arch.chains(params), poses)
    return np.where(legs.reachable()[:, None], legs.actuators, np.nan)


def _inside(actuators: np.ndarray, low: float, high: float) -> np.ndarray:
    """Return the mask of actuator values within [low, high] (NaN: outside)."""
    with np.errstate(invalid='ignore'):
        return (actuators >= low) & (actuators <= high)


def move_paths(
    params: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    step_m: float = DEFAULT_STEP_M,
    start: np.ndarray | None = None,
    mount: str = DEFAULT_MOUNT,
) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """
    Return every move's poses and nominal IK ((M, 6), (M, 6) each) and which go via the centre.

    Move i runs from posture i - 1 (``start`` for i = 0; none: posture 0 alone) to posture i,
    both ends included, the way the executor goes (module doc); IK rows are NaN out of reach.
    """
    low, high = stroke_m
    centre = np.concatenate([fixed_point(link_length, mount), np.zeros(3)])
    moves = []
    via = np.zeros(len(poses), bool)
    for i, pose in enumerate(poses):
        previous = start if i == 0 else poses[i - 1]
        if previous is None:
            path = pose[None]
        else:
            previous = np.asarray(previous, dtype=float)
            path = np.concatenate([previous[None], sphere_path(previous, pose, link_length,
                                                               step_m)])
            if not np.all(_inside(_nominal_actuators(params, path), low, high)):
                via[i] = True
                path = np.concatenate(
                    [
                        previous[None],
                        sphere_path(previous, centre, link_length, step_m),
                        sphere_path(centre, pose, link_length, step_m),
                    ]
                )
        moves.append((path, _nominal_actuators(params, path)))
    return moves, via


def move_samples(
    params: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    step_m: float = DEFAULT_STEP_M,
    start: np.ndarray | None = None,
    mount: str = DEFAULT_MOUNT,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the nominal IK along every move of the plan (M, 6), each sample's posture and via.

    The moves of `move_paths`, concatenated; ``via`` (K,) says which go by way of the centre.
    """
    moves, via = move_paths(params, poses, link_length, stroke_m, step_m, start, mount)
    samples = np.concatenate([actuators for _, actuators in moves])
    owners = np.concatenate([np.full(len(path), i) for i, (path, _) in enumerate(moves)])
    return samples, owners, via


@dataclass(frozen=True)
class RehearsalSettings:
    """How releases are rehearsed (release_rehearsal.py); model_error_m None: the default."""

    model_samples: int = DEFAULT_MODEL_SAMPLES
    model_error_m: float | None = None
    max_move_condition: float = DEFAULT_MAX_MOVE_CONDITION
    joint_step_m: float = DEFAULT_JOINT_STEP_M
    seed: int = 0


def choose_released_actuators(
    params: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    *,
    margin_m: float = DEFAULT_MARGIN_M,
    step_m: float = DEFAULT_STEP_M,
    start: np.ndarray | None = None,
    mount: str = DEFAULT_MOUNT,
    rehearsal: RehearsalSettings = RehearsalSettings(),
) -> ReleaseChoice:
    """
    Choose each posture's released actuator (module doc); ReleaseError if one has none.

    `poses` (K, 6) in plan order, planned on `params` (the nominal machine) and the link sphere
    of radius `link_length`; `stroke_m` the actuator stroke (low, high), m; `margin_m` kept
    from both ends along every move by the released actuator; `mount` the device's (the centre
    a move may go by); `rehearsal` the machines the moves are rehearsed on.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    conditions = release_conditions(params, poses, link_length)
    moves, via = move_paths(params, poses, link_length, stroke_m, step_m, start, mount)
    low, high = stroke_m
    count = len(poses)
    inside = np.ones((count, 6), bool)
    travel = np.zeros((count, 6))
    along = np.zeros((count, 6))  # worst nominal condition along each move
    for i, (path, actuators) in enumerate(moves):
        inside[i] = np.all(_inside(actuators, low + margin_m, high - margin_m), axis=0)
        travel[i] = np.max(actuators, axis=0) - np.min(actuators, axis=0)
        along[i] = np.max(release_conditions(params, path, link_length), axis=0)
    ranked = np.where(inside & np.isfinite(along), along, np.inf)
    stuck = ~np.any(np.isfinite(ranked), axis=1)
    if np.any(stuck):
        posture = int(np.flatnonzero(stuck)[0])
        names = params.layout.actuator_names
        raise ReleaseError(
            f'posture {posture}: no actuator can be released - every one of '
            f'{", ".join(names)} leaves the stroke [{low + margin_m:g}, {high - margin_m:g}] m '
            f'(stroke less the {margin_m:g} m margin) at the posture or on the move to it, or '
            'makes the five commanded plus the link singular',
            posture,
        )
    released, worst, jams, machines = _rehearse_plan(
        params, moves, ranked, link_length, stroke_m, margin_m, mount, rehearsal
    )
    return ReleaseChoice(
        released, conditions, inside, travel, via, worst, jams, len(machines)
    )


def _rehearse_plan(params, moves, ranked, link_length, stroke, margin_m, mount, settings):
    """Return the released chain, worst condition and jams per posture, and the machines."""
    error = (
        model_error_rms_m(params) if settings.model_error_m is None else settings.model_error_m
    )
    machines = sampled_machines(params, settings.model_samples, error, settings.seed)
    count = len(moves)
    released = np.zeros(count, int)
    worst = np.zeros(count)
    jams = np.zeros(count, int)
    first_path = moves[0][0]
    standing = Standings(
        np.repeat(first_path[:1], len(machines), axis=0),
        np.array([inverse_kinematics(m, first_path[:1])[0] for m in machines]),
    )
    for i, (path, actuators) in enumerate(moves):
        # Where each machine stands against the nominal setpoints: its own actuators at the
        # first posture, afterwards the released one where the link put it (the five commanded
        # stood at their setpoints); the drive locks it there and the move fades the offset.
        offsets = standing.actuators - actuators[0]
        setpoints = setpoint_samples(offsets, actuators, settings.joint_step_m)
        result = _rehearse_move(
            machines, standing, setpoints, ranked[i], link_length, stroke, margin_m, mount,
            settings.max_move_condition,
        )
        best = _best(result, len(machines), settings.max_move_condition)
        released[i] = result.candidates[best]
        worst[i] = result.worst[best]
        jams[i] = len(machines) - int(result.survived[best])
        standing = _restand(machines, result.ends[best], actuators[-1], int(released[i]),
                            path[-1], link_length, mount)
    return released, worst, jams, machines


def _rehearse_move(machines, standing, setpoints, ranked, link_length, stroke, margin_m, mount,
                   limit) -> Rehearsal:
    """Rehearse the best-ranked candidates first, the rest only if none of those will do."""
    order = [int(c) for c in np.argsort(ranked) if np.isfinite(ranked[c])]
    first = rehearse(machines, standing, setpoints, np.array(order[:FIRST_REHEARSED]),
                     link_length, stroke, margin_m, mount)
    if _acceptable(first, len(machines), limit).any() or len(order) <= FIRST_REHEARSED:
        return first
    rest = rehearse(machines, standing, setpoints, np.array(order[FIRST_REHEARSED:]),
                    link_length, stroke, margin_m, mount)
    return Rehearsal(
        np.concatenate([first.candidates, rest.candidates]),
        np.concatenate([first.survived, rest.survived]),
        np.concatenate([first.worst, rest.worst]),
        first.ends + rest.ends,
    )


def _acceptable(result: Rehearsal, machines: int, limit: float) -> np.ndarray:
    """Return which candidates close on every machine within the condition limit."""
    return (result.survived == machines) & (result.worst <= limit)


def _best(result: Rehearsal, machines: int, limit: float) -> int:
    """Return the index of the candidate to take (module doc)."""
    good = _acceptable(result, machines, limit)
    if good.any():
        return int(np.argmin(np.where(good, result.worst, np.inf)))
    # Closes on most machines, then the best conditioned there.
    return int(np.lexsort((result.worst, -result.survived))[0])


def _restand(machines, ends: Standings, setpoints, released, pose, link_length, mount):
    """Return the standings after a move; a machine that jammed stands afresh at the posture."""
    jammed = np.flatnonzero(~np.all(np.isfinite(ends.poses), axis=1))
    if not jammed.size:
        return ends
    fresh = stand(tuple(machines[k] for k in jammed), setpoints, released, pose, link_length,
                  mount)
    poses, actuators = ends.poses.copy(), ends.actuators.copy()
    poses[jammed], actuators[jammed] = fresh.poses, fresh.actuators
    return Standings(poses, actuators)


__all__ = [
    'DEFAULT_MARGIN_M',
    'DEFAULT_MAX_MOVE_CONDITION',
    'DEFAULT_STEP_M',
    'RehearsalSettings',
    'ReleaseChoice',
    'ReleaseError',
    'choose_released_actuators',
    'move_paths',
    'move_samples',
]
