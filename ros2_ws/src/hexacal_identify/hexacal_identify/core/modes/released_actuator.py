"""
Choose the actuator released at each posture of a passive-actuator plan.

For each planned posture, among the six actuators, the released one is the one
that keeps the five commanded plus the link well conditioned all along the move
from the previous posture, on the nominal machine and on machines that depart
from it as a machine built to its drawing does (core/modes/release_rehearsal.py: the
move rehearsed by continuation as the drive walks it; core/modes/release_plan.py: which
candidates are rehearsed and which is taken), and that stays inside its stroke
less a margin there.  Where the plan's order is free within its groups (``groups``),
the order is chosen too: the next posture is the nearest whose move is safe on
every rehearsed machine (``release_plan.tour``).  The moves are the executor's
(core/modes/release_moves.py, ``paths.route_command``).  The released actuator follows
the five commanded ones wherever the link takes it, and on the true machine that
is up to millimetres from where the nominal model predicts (the model error a
first calibration removes), hence the margin (``DEFAULT_MARGIN_M``): a released
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

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .link_load import LinkLoad
from .passive_actuator import release_conditions
from .release_moves import inside_stroke, move
from .release_plan import (
    DEFAULT_MAX_MOVE_CONDITION,
    in_order,
    Leg,
    NoRelease,
    RehearsalSettings,
    Rehearser,
    Stuck,
    tour,
)
from ..architectures import KinematicParameters
from ..errors import CalibrationError
from ..machine.device import DEFAULT_MOUNT

DEFAULT_STEP_M = 0.01  # path samples at most this far apart (position; angles times L)
# Kept from both stroke ends by the released actuator along every move: the largest deviation
# of the true machine from a nominal model (the demo's strain: up to 4 mm) and more.  The
# default of linear actuators; each architecture states its own in its actuators' unit
# (Architecture.released_margin, rad for cranks), which a margin of None takes.
DEFAULT_MARGIN_M = 0.005


def released_margin(params: KinematicParameters, margin_m: float | None = None) -> float:
    """Return `margin_m`, or when None the architecture's (its actuators' unit: m or rad)."""
    return params.architecture.released_margin if margin_m is None else float(margin_m)


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
    the chosen release jams or leaves its stroke on that move (0: none); ``order`` (K,) the
    plan indices in the order chosen (None: as given), every other field in that order.
    """

    released: np.ndarray
    conditions: np.ndarray
    inside: np.ndarray
    travel: np.ndarray
    via_centre: np.ndarray
    move_conditions: np.ndarray | None = None
    jams: np.ndarray | None = None
    machines: int = 1
    order: np.ndarray | None = None

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
    both ends included, the way the executor goes (release_moves.py); IK rows are NaN out of
    reach.
    """
    moves = [
        move(params, start if i == 0 else poses[i - 1], pose, link_length, stroke_m, step_m,
             mount)
        for i, pose in enumerate(poses)
    ]
    return [(m.poses, m.actuators) for m in moves], np.array([m.via_centre for m in moves])


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


def choose_released_actuators(
    params: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    *,
    margin_m: float | None = None,
    step_m: float = DEFAULT_STEP_M,
    start: np.ndarray | None = None,
    mount: str = DEFAULT_MOUNT,
    rehearsal: RehearsalSettings = RehearsalSettings(),
    groups: np.ndarray | None = None,
    batched: bool = True,
    link_load: LinkLoad | None = None,
    progress: Callable[[str], None] | None = None,
) -> ReleaseChoice:
    """
    Choose each posture's released actuator (module doc); ReleaseError if one has none.

    `poses` (K, 6) in plan order, planned on `params` (the nominal machine) and the link sphere
    of radius `link_length`; `stroke_m` the actuator stroke (low, high), m; `margin_m` kept
    from both ends along every move by the released actuator (None: the architecture's
    ``released_margin``; m, or rad for cranks like the stroke); `mount` the device's (the centre
    a move may go by); `rehearsal` the machines the moves are rehearsed on; `groups` (K,) when
    the order within each group of postures is free (``ReleaseChoice.order`` then says it);
    `batched` False rehearses machine by machine (the reference; the same choice, slower);
    `link_load` the weights and the link's limit: a chain whose release loads the link beyond
    it along a move is not chosen where another will do (Rehearser.ranked); `progress` hears
    of each posture rehearsed.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    margin_m = released_margin(params, margin_m)
    rehearser = Rehearser(params, link_length, stroke_m, margin_m, step_m, mount, rehearsal,
                          batched=batched, link_load=link_load)
    order = None
    try:
        if groups is None or len(poses) < 3:
            legs = in_order(rehearser, poses, start, progress)
        else:
            order, legs = tour(rehearser, poses, np.asarray(groups), progress)
    except Stuck as stuck:
        raise _release_error(params, stroke_m, margin_m, stuck.posture) from None
    ordered = poses if order is None else poses[order]
    return _choice(params, ordered, link_length, stroke_m, margin_m, legs, rehearser, order)


def _choice(params, poses, link_length, stroke, margin_m, legs: list[Leg], rehearser, order):
    """Return the ReleaseChoice of the rehearsed legs (in walking order)."""
    low, high = stroke
    actuators = [leg.move.actuators for leg in legs]
    return ReleaseChoice(
        released=np.array([leg.released for leg in legs]),
        conditions=release_conditions(params, poses, link_length),
        inside=np.array(
            [np.all(inside_stroke(a, low + margin_m, high - margin_m), axis=0) for a in actuators]
        ),
        travel=np.array([np.max(a, axis=0) - np.min(a, axis=0) for a in actuators]),
        via_centre=np.array([leg.move.via_centre for leg in legs]),
        move_conditions=np.array([leg.worst for leg in legs]),
        jams=np.array([leg.jams for leg in legs]),
        machines=len(rehearser.machines),
        order=order,
    )


def release_from_here(
    model: KinematicParameters,
    here: np.ndarray,
    actuators: np.ndarray,
    released: int,
    target: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    exclude: Sequence[int],
    *,
    margin_m: float | None = None,
    mount: str = DEFAULT_MOUNT,
    rehearsal: RehearsalSettings = RehearsalSettings(),
    prefer: int | None = None,
    batched: bool = True,
    measured_here: np.ndarray | None = None,
    link_load: LinkLoad | None = None,
    path_start: np.ndarray | None = None,
) -> int | None:
    """
    Return the chain to release for the rest of a move, none of `exclude`; None if none will do.

    `prefer` (the plan's choice) is kept if it closes on every rehearsed machine within the
    condition limit.  Also for a plan's first move, whose start the planner cannot know.

    After a drive fault with the chains `exclude` released (jams), at rest where the machine
    stands (`here`, a pose on the sphere, with the measured `actuators` and chain `released`
    free): the move to `target` rehearsed on `model` and machines like it (module doc), each
    standing with the five measured commanded actuators, as the planner would choose
    (`batched` as in ``choose_released_actuators``).

    `measured_here`: where the device measured the platform (kinematics.measured_pose), when
    known.  The move is then rehearsed again on the machines standing there, reading the
    measured `actuators` (``Rehearser.stand_measured``): `prefer` (else the chain chosen above)
    if it is safe on them, else the safest of the others: the one that closes on the most of
    them, then the best conditioned.  Where every release jams on all of them, the choice
    above stays: from a standing none of the machines walks out of, the rehearsal says nothing
    about which release the true machine can.

    `link_load` (the weights and the link's limit, as the planner's): a chain whose release
    loads the link beyond the limit along the move is neither kept nor chosen where another's
    does not (``Rehearser.ranked``); the chains `exclude` are not among those others.

    `path_start`: the pose the executor's path starts from, when not `here` (the pose it last
    commanded, where it believes the machine arrived); the move is rehearsed along that path,
    blended from where the machines stand, as the executor commands it (walk/standing.py).
    """
    margin_m = released_margin(model, margin_m)
    start = here if path_start is None else path_start
    rehearser = Rehearser(model, link_length, stroke_m, margin_m, DEFAULT_STEP_M, mount,
                          rehearsal, batched=batched, link_load=link_load, unavailable=exclude)
    rehearser.stand_at(actuators, released, here)
    chosen = _chosen_here(rehearser, start, target, exclude, prefer)
    if measured_here is None or chosen is None:
        return chosen
    measured = Rehearser(model, link_length, stroke_m, margin_m, DEFAULT_STEP_M, mount,
                         rehearsal, batched=batched, link_load=link_load, unavailable=exclude)
    if not measured.stand_measured(measured_here, actuators):
        return chosen
    wanted = prefer if prefer is not None and prefer not in exclude else chosen
    if _safe(measured, start, target, wanted):
        return wanted
    try:
        leg = measured.try_move(start, target, exclude)
    except NoRelease:
        return chosen
    # A release that walks out on some of the machines standing there tells more than the
    # estimate's choice; one that jams on all of them says nothing (make demo's posture 10).
    return leg.released if leg.jams < len(measured.machines) else chosen


def _safe(rehearser: Rehearser, here, target, chain: int) -> bool:
    """Return whether releasing `chain` on the move closes on every machine within the limit."""
    try:
        others = [c for c in range(6) if c != chain]
        return rehearser.safe(rehearser.try_move(here, target, others))
    except NoRelease:
        return False


def _chosen_here(rehearser: Rehearser, here, target, exclude, prefer) -> int | None:
    """Return `prefer` if safe on the rehearser's machines, else the best other; None: none."""
    if prefer is not None and prefer not in exclude and _safe(rehearser, here, target, prefer):
        return prefer
    try:
        leg = rehearser.try_move(here, target, exclude)
    except NoRelease:
        return None
    return leg.released


def _release_error(params, stroke, margin_m, posture: int) -> ReleaseError:
    """Return the error of a posture no actuator can be released for."""
    low, high = stroke
    names, unit = params.layout.actuator_names, params.layout.actuator_unit
    return ReleaseError(
        f'posture {posture}: no actuator can be released - every one of '
        f'{", ".join(names)} leaves the stroke [{low + margin_m:g}, {high - margin_m:g}] {unit} '
        f'(stroke less the {margin_m:g} {unit} margin) at the posture or on the move to it, or '
        'makes the five commanded plus the link singular',
        posture,
    )


__all__ = [
    'DEFAULT_MARGIN_M',
    'released_margin',
    'DEFAULT_MAX_MOVE_CONDITION',
    'DEFAULT_STEP_M',
    'RehearsalSettings',
    'ReleaseChoice',
    'ReleaseError',
    'choose_released_actuators',
    'move_paths',
    'move_samples',
    'release_from_here',
]
