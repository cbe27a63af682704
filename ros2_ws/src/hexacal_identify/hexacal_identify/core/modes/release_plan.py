"""
Walk a passive-actuator plan in rehearsal: the release per move and, if free, the order.

`Rehearser` keeps where each rehearsed machine stands (core/modes/release_rehearsal.py) and tries a
move to a posture: the candidates that stay inside the stroke less the margin on the nominal
move (core/modes/release_moves.py) are rehearsed in the order of their worst nominal condition
along it, the best ``FIRST_REHEARSED`` first; the first to close on every machine within
``max_move_condition`` is taken, else all are rehearsed and the one that closes on most
machines, then the best conditioned, is taken (its ``jams``: on how many it does not).

`in_order` walks the postures as given.  `tour` may also choose the order within each group of
postures (a kind and device turn: the plan's groups stay in their order): from the current
posture the ``tries`` nearest of the group (travel distance, angles weighted by L, as the
planner's travel order) are tried, nearest first, and the first whose move is safe (closes on
every machine within the limit) is walked next, else the least risky of them (fewest jams, then
the lowest worst condition).  The batched rehearser (the default) rehearses a move's
first candidates on all machines in one stacked batch (release_rehearsal.rehearse_stacked) and
the rest, where needed, in a second; after a move that needed them, all candidates in one batch
(the rows are independent, and a batch of more rows costs less than a second batch where the
rest is likely needed again: on the Hexa Slide; rarely on the Gough-Stewart) and decides
exactly as above, from the first ones' part where one of them will do;
``batched=False`` rehearses one machine at a time (the reference the tests compare it with).
Rehearsed on Table 1 with nominal set 2 (the demo), the order of the travel tour jams on the
true machine on 1-2 of 49 moves whatever is released, the rehearsed tour on none.  Tries are
rehearsed one after the other, not at once: the first is most often safe, and rows that jam
would run their Newton iterations in full.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .link_load import LinkLoad, released_link_forces
from .passive_actuator import worst_release_conditions
from .release_moves import inside_stroke, Move, move
from .release_rehearsal import (
    DEFAULT_JOINT_STEP_M,
    DEFAULT_MODEL_SAMPLES,
    MachineStack,
    model_error_rms_m,
    Rehearsal,
    RehearsalJob,
    rehearse,
    rehearse_stacked,
    sampled_machines,
    setpoint_samples,
    stand,
    stand_stacked,
    Standings,
)
from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT
from ..machine.kinematics import inverse_kinematics, measured_pose

# A move whose worst condition number on the rehearsed machines stays below this is taken
# without rehearsing the other candidates; true-machine jams were met from a few hundred up
# (Hexa Slide, set 2 error), the released chain's condition is 30-100 at most postures.
DEFAULT_MAX_MOVE_CONDITION = 250.0
FIRST_REHEARSED = 2  # candidates rehearsed before the others are tried
DEFAULT_TOUR_TRIES = 4  # nearest postures tried for the next move of a tour


@dataclass(frozen=True)
class RehearsalSettings:
    """How releases are rehearsed (release_rehearsal.py); model_error_m None: the default."""

    model_samples: int = DEFAULT_MODEL_SAMPLES
    model_error_m: float | None = None
    max_move_condition: float = DEFAULT_MAX_MOVE_CONDITION
    joint_step_m: float = DEFAULT_JOINT_STEP_M
    seed: int = 0
    tour_tries: int = DEFAULT_TOUR_TRIES


@dataclass(frozen=True)
class Leg:
    """A move tried in rehearsal: the chain to release, its worst condition, jams, and after."""

    move: Move
    released: int
    worst: float
    jams: int
    ends: Standings

    @property
    def risk(self) -> tuple[int, float]:
        """Return (machines it jams on, worst condition): lower is safer."""
        return self.jams, self.worst


class NoRelease(Exception):
    """No actuator stays inside its stroke (less the margin) on the nominal move."""


class Rehearser:
    """
    Where the rehearsed machines stand, and the moves tried from there (module doc).

    `link_load` (the weights and the link's limit): the chains whose release loads the link
    beyond it along a move are not tried where another will do (``ranked``); `unavailable`:
    chains never tried (they faulted), and not among those others.
    """

    def __init__(
        self,
        params: KinematicParameters,
        link_length: float,
        stroke: tuple[float, float],
        margin_m: float,
        step_m: float,
        mount: str = DEFAULT_MOUNT,
        settings: RehearsalSettings = RehearsalSettings(),
        *,
        batched: bool = True,
        link_load: LinkLoad | None = None,
        unavailable: Sequence[int] = (),
    ):
        error = (
            model_error_rms_m(params) if settings.model_error_m is None
            else settings.model_error_m
        )
        self.params = params
        self.machines = sampled_machines(params, settings.model_samples, error, settings.seed)
        self.link_length, self.stroke, self.margin_m = link_length, stroke, margin_m
        self.step_m, self.mount, self.settings = step_m, mount, settings
        self.standing: Standings | None = None
        self.batched = batched
        self.stack = MachineStack(self.machines) if batched else None
        self.link_load = link_load
        # Chains that may not be released at all (they faulted on this move): never candidates,
        # and not among those the link's limit keeps to (``_within_link_limit``).
        self.unavailable = tuple(unavailable)
        self._rest_was_needed = False  # whether the last move tried needed its rest candidates

    def ranked(self, nominal_move: Move) -> np.ndarray:
        """Return each chain's worst nominal condition along the move (inf: leaves the stroke)."""
        low, high = self.stroke
        inside = np.all(
            inside_stroke(nominal_move.actuators, low + self.margin_m, high - self.margin_m),
            axis=0,
        )
        along = worst_release_conditions(self.params, nominal_move.poses, self.link_length)
        ranked = np.where(inside & np.isfinite(along), along, np.inf)
        ranked[list(self.unavailable)] = np.inf
        if self.link_load is not None:
            ranked = self._within_link_limit(nominal_move, ranked)
        return ranked

    def _within_link_limit(self, nominal_move: Move, ranked: np.ndarray) -> np.ndarray:
        """
        Return `ranked` without the chains whose release loads the link beyond its limit.

        The link's static load along the nominal move with each chain released, from its start
        (where the executor swaps the releases) on; where every candidate passes the limit, all
        stay ranked as they were (the plan then reports the posture as overloaded).
        """
        assert self.link_load is not None
        forces = released_link_forces(self.params, nominal_move.poses, self.link_load.masses)
        largest = np.fmax.reduce(forces, axis=0)  # a pose out of reach (NaN) bears nothing
        light = largest <= self.link_load.max_force_n
        if not np.any(light & np.isfinite(ranked)):
            return ranked
        return np.where(light, ranked, np.inf)

    def try_move(
        self, previous: np.ndarray | None, pose: np.ndarray, exclude: Sequence[int] = ()
    ) -> Leg:
        """Return the move to `pose` rehearsed from where the machines stand; NoRelease."""
        if self.batched:
            leg = self.try_moves(previous, [pose], exclude)[0]
            if leg is None:
                raise NoRelease()
            return leg
        nominal_move, standing, setpoints, ranked = self._prepare(previous, pose, exclude)
        result = self._rehearse(standing, setpoints, ranked)
        best = _best(result, len(self.machines), self.settings.max_move_condition)
        chain = int(result.candidates[best])
        ends = self._restand(result.ends[best], nominal_move, chain)
        jams = len(self.machines) - int(result.survived[best])
        return Leg(nominal_move, chain, float(result.worst[best]), jams, ends)

    def try_moves(
        self, previous: np.ndarray | None, poses: Sequence[np.ndarray],
        exclude: Sequence[int] = (),
    ) -> list[Leg | None]:
        """Return ``try_move`` to each of `poses` (None: NoRelease), all rehearsed at once."""
        if not self.batched:
            return list(self.legs_to(previous, poses, exclude))
        prepared: list[tuple[Any, list[int]] | None] = []
        jobs: list[RehearsalJob] = []
        for pose in poses:
            try:
                nominal_move, standing, setpoints, ranked = self._prepare(previous, pose, exclude)
            except NoRelease:
                prepared.append(None)
                continue
            order = [int(c) for c in np.argsort(ranked) if np.isfinite(ranked[c])]
            prepared.append((nominal_move, order))
            jobs.append(RehearsalJob(standing, setpoints, np.array(order)))
        limit, count = self.settings.max_move_condition, len(self.machines)
        if self._rest_was_needed:
            # The last move needed the candidates after the first ones, and the next most often
            # does too: all in one batch, decided as _rehearse does (rows are independent).
            results = [_first_then_rest(result, count, limit) for result in self._stacked(jobs)]
        else:
            results = self._first_then_rest_batches(jobs, count, limit)
        self._rest_was_needed = any(len(r.candidates) > FIRST_REHEARSED for r in results)
        remaining = iter(results)
        chosen: list[tuple[Any, Rehearsal, int] | None] = []
        for item in prepared:
            if item is None:
                chosen.append(None)
                continue
            nominal_move, order = item
            result = next(remaining)
            best = _best(result, count, limit)
            chosen.append((nominal_move, result, best))
        return self._restand_all(chosen)

    def _first_then_rest_batches(self, jobs: list[RehearsalJob], count: int,
                                 limit: float) -> list[Rehearsal]:
        """Rehearse every job's first candidates in one batch, the rest where needed in another."""
        firsts = self._stacked([RehearsalJob(job.start, job.setpoints,
                                             job.candidates[:FIRST_REHEARSED]) for job in jobs])
        needed = [i for i, (job, first) in enumerate(zip(jobs, firsts))
                  if _rest_needed(first, len(job.candidates), count, limit)]
        rests = self._stacked([RehearsalJob(jobs[i].start, jobs[i].setpoints,
                                            jobs[i].candidates[FIRST_REHEARSED:])
                               for i in needed])
        results = list(firsts)
        for i, rest in zip(needed, rests):
            results[i] = _joined(firsts[i], rest)
        return results

    def _stacked(self, jobs: list[RehearsalJob]) -> list[Rehearsal]:
        """Return rehearse_stacked of `jobs` ([] for none)."""
        if not jobs:
            return []
        assert self.stack is not None  # batched
        return rehearse_stacked(self.stack, jobs, self.link_length, self.stroke, self.margin_m,
                                self.mount)

    def legs_to(
        self, previous: np.ndarray | None, poses: Sequence[np.ndarray],
        exclude: Sequence[int] = (),
    ) -> Iterator[Leg | None]:
        """
        Yield ``try_move`` to each of `poses` in turn (None: NoRelease), lazily.

        Lazily, not all at once: the first is most often safe, and the moves not taken are the
        ones whose machines jam, each sample's Newton iteration then running its full count.
        """
        for pose in poses:
            try:
                yield self.try_move(previous, pose, exclude)
            except NoRelease:
                yield None

    def _prepare(self, previous, pose, exclude):
        """Return the nominal move, the standings, the setpoints and the ranks; NoRelease."""
        nominal_move = move(self.params, previous, pose, self.link_length, self.stroke,
                            self.step_m, self.mount)
        ranked = self.ranked(nominal_move)
        ranked[list(exclude)] = np.inf
        if not np.any(np.isfinite(ranked)):
            raise NoRelease()
        standing = self.standing if previous is not None else None
        if standing is None:  # the first posture: each machine at it with its own actuators
            standing = Standings(
                np.repeat(nominal_move.poses[:1], len(self.machines), axis=0),
                np.array([inverse_kinematics(m, nominal_move.poses[:1])[0]
                          for m in self.machines]),
            )
        # Where each machine stands against the nominal setpoints: its own actuators at the
        # first posture, afterwards the released one where the link put it (the five commanded
        # stood at their setpoints); the drive locks it there and the move fades the offset.
        offsets = standing.actuators - nominal_move.actuators[0]
        setpoints = setpoint_samples(offsets, nominal_move.actuators, self.settings.joint_step_m)
        return nominal_move, standing, setpoints, ranked

    def _restand_all(self, chosen) -> list[Leg | None]:
        """Return the legs of the chosen candidates, the machines that jammed stood afresh."""
        machine, setpoints, released, poses, owners = [], [], [], [], []
        for i, item in enumerate(chosen):
            if item is None:
                continue
            nominal_move, result, best = item
            ends = result.ends[best]
            for k in np.flatnonzero(~np.all(np.isfinite(ends.poses), axis=1)):
                machine.append(k)
                setpoints.append(nominal_move.actuators[-1])
                released.append(int(result.candidates[best]))
                poses.append(nominal_move.poses[-1])
                owners.append((i, k))
        assert self.stack is not None  # batched
        fresh = (
            stand_stacked(self.stack, np.array(machine), np.array(setpoints), np.array(released),
                          np.array(poses), self.link_length, self.mount)
            if machine else None
        )
        legs: list[Leg | None] = []
        for i, item in enumerate(chosen):
            if item is None:
                legs.append(None)
                continue
            nominal_move, result, best = item
            ends = result.ends[best]
            rows = [r for r, (owner, _) in enumerate(owners) if owner == i]
            if rows:
                assert fresh is not None  # rows are owned only where machines were stood again
                ends = Standings(ends.poses.copy(), ends.actuators.copy())
                for r in rows:
                    k = owners[r][1]
                    ends.poses[k], ends.actuators[k] = fresh.poses[r], fresh.actuators[r]
            jams = len(self.machines) - int(result.survived[best])
            legs.append(Leg(nominal_move, int(result.candidates[best]), float(result.worst[best]),
                            jams, ends))
        return legs

    def stand_at(self, actuators: np.ndarray, released: int, pose: np.ndarray) -> None:
        """Stand every machine with `actuators` and `released` free, near `pose` (stand)."""
        actuators = np.asarray(actuators, dtype=float)
        pose = np.asarray(pose, dtype=float)
        if not self.batched:
            self.standing = stand(self.machines, actuators, released, pose, self.link_length,
                                  self.mount)
            return
        count = len(self.machines)
        assert self.stack is not None  # batched
        self.standing = stand_stacked(
            self.stack, np.arange(count), np.repeat(actuators[None], count, axis=0),
            np.full(count, released), np.repeat(pose[None], count, axis=0), self.link_length,
            self.mount,
        )

    def stand_measured(self, pose: np.ndarray, actuators: np.ndarray) -> bool:
        """
        Stand every machine where the device measured the platform, reading what was measured.

        `pose`: the measured position, the angles a guess.  Each rehearsed machine stands at the
        position with the angles that fit `actuators` best on it (``measured_pose``), made to
        agree with the measurement (``measured_machine``: its actuator zeros shifted by what
        its geometry still leaves, so that it reads `actuators` there); ``stand_at`` instead
        lets each machine's geometry put it where it would stand with those actuators,
        centimetres away on a Hexa Slide.  False (nothing changed) when a machine cannot reach
        there.
        """
        pose = np.asarray(pose, dtype=float)
        actuators = np.asarray(actuators, dtype=float)
        poses = np.array([measured_pose(machine, actuators, pose[None, :3], pose[None])[0]
                          for machine in self.machines])
        shifted = [measured_machine(machine, at, actuators)
                   for machine, at in zip(self.machines, poses)]
        if any(machine is None for machine in shifted):
            return False
        self.machines = tuple(m for m in shifted if m is not None)
        if self.stack is not None:
            self.stack = MachineStack(self.machines)
        self.standing = Standings(poses, np.repeat(actuators[None], len(poses), axis=0))
        return True

    def take(self, leg: Leg) -> None:
        """Walk `leg`: the machines stand where it ends."""
        self.standing = leg.ends

    def safe(self, leg: Leg) -> bool:
        """Return True when the leg closes on every machine within the condition limit."""
        return leg.jams == 0 and leg.worst <= self.settings.max_move_condition

    def _rehearse(self, standing: Standings, setpoints: np.ndarray, ranked) -> Rehearsal:
        """Rehearse the best-ranked candidates first, the rest only if none of those will do."""
        order = [int(c) for c in np.argsort(ranked) if np.isfinite(ranked[c])]

        def run(candidates: list[int]) -> Rehearsal:
            return rehearse(self.machines, standing, setpoints, np.array(candidates),
                            self.link_length, self.stroke, self.margin_m, self.mount)

        first = run(order[:FIRST_REHEARSED])
        if not _rest_needed(first, len(order), len(self.machines),
                            self.settings.max_move_condition):
            return first
        rest = run(order[FIRST_REHEARSED:])
        return _joined(first, rest)

    def _restand(self, ends: Standings, nominal_move: Move, chain: int) -> Standings:
        """Return the standings after a move; a machine that jammed stands afresh at the end."""
        jammed = np.flatnonzero(~np.all(np.isfinite(ends.poses), axis=1))
        if not jammed.size:
            return ends
        fresh = stand(
            tuple(self.machines[k] for k in jammed), nominal_move.actuators[-1], chain,
            nominal_move.poses[-1], self.link_length, self.mount,
        )
        poses, actuators = ends.poses.copy(), ends.actuators.copy()
        poses[jammed], actuators[jammed] = fresh.poses, fresh.actuators
        return Standings(poses, actuators)


ZERO_SHIFT_PASSES = 2  # an actuator zero moves its reading linearly: the second pass checks


def measured_machine(
    machine: KinematicParameters, pose: np.ndarray, actuators: np.ndarray
) -> KinematicParameters | None:
    """
    Return `machine` with its actuator zeros shifted so that at `pose` it reads `actuators`.

    Each chain's zero moves along the architecture's ``actuator_zero_shift`` (a slider's rail
    start, a leg's length offset, a crank's zero angle), which changes that chain's reading
    alone; None when the machine cannot reach `pose`.
    """
    arch = machine.architecture
    pose = np.asarray(pose, dtype=float)[None]
    shifts = np.array([arch.actuator_zero_shift(machine, c)[1] for c in range(6)])
    vector = machine.vector.copy()
    for _ in range(ZERO_SHIFT_PASSES):
        legs = arch.legs(arch.chains(machine.with_vector(vector)), pose)
        moved = arch.legs(arch.chains(machine.with_vector(vector + shifts.sum(axis=0))), pose)
        if not (bool(legs.reachable()[0]) and bool(moved.reachable()[0])):
            return None
        per_unit = moved.actuators[0] - legs.actuators[0]  # each chain's reading per unit shift
        vector = vector + ((actuators - legs.actuators[0]) / per_unit) @ shifts
    return machine.with_vector(vector)


def _first_then_rest(result: Rehearsal, machines: int, limit: float) -> Rehearsal:
    """Return the first FIRST_REHEARSED candidates' part where one will do, else all of it."""
    first = _part(result, slice(0, FIRST_REHEARSED))
    return result if _rest_needed(first, len(result.candidates), machines, limit) else first


def _rest_needed(first: Rehearsal, candidates: int, machines: int, limit: float) -> bool:
    """Return whether the candidates after the first ones are rehearsed: none of those will do."""
    return candidates > FIRST_REHEARSED and not _acceptable(first, machines, limit).any()


def _joined(first: Rehearsal, rest: Rehearsal) -> Rehearsal:
    """Return the rehearsal of the first candidates followed by the rest."""
    return Rehearsal(
        np.concatenate([first.candidates, rest.candidates]),
        np.concatenate([first.survived, rest.survived]),
        np.concatenate([first.worst, rest.worst]),
        first.ends + rest.ends,
    )


def _part(result: Rehearsal, which: slice) -> Rehearsal:
    """Return the rehearsal of a slice of the candidates."""
    return Rehearsal(result.candidates[which], result.survived[which], result.worst[which],
                     result.ends[which])


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


class Stuck(Exception):
    """No actuator can be released on the move to posture ``posture`` (plan index)."""

    def __init__(self, posture: int):
        super().__init__(posture)
        self.posture = posture


def in_order(
    rehearser: Rehearser, poses: np.ndarray, start: np.ndarray | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Leg]:
    """
    Return the legs of the postures walked in the given order (Stuck: one has no release).

    `progress` hears of each posture walked (``rehearsal k/K``).
    """
    legs = []
    previous = start
    for i, pose in enumerate(poses):
        try:
            leg = rehearser.try_move(previous, pose)
        except NoRelease:
            raise Stuck(i) from None
        rehearser.take(leg)
        legs.append(leg)
        previous = pose
        _walked(progress, len(legs), len(poses))
    return legs


def _walked(progress: Callable[[str], None] | None, done: int, total: int) -> None:
    if progress is not None:
        progress(f'rehearsal {done}/{total}')


def tour(
    rehearser: Rehearser, poses: np.ndarray, groups: np.ndarray,
    progress: Callable[[str], None] | None = None,
) -> tuple[np.ndarray, list[Leg]]:
    """
    Return the plan indices in walking order and their legs, rehearsed (module doc).

    `progress` hears of each posture walked (``rehearsal k/K``).
    """
    groups = np.asarray(groups)
    weighted = np.column_stack([poses[:, :3], poses[:, 3:6] * rehearser.link_length])
    try:
        first = rehearser.try_move(None, poses[0])
    except NoRelease:
        raise Stuck(0) from None
    rehearser.take(first)
    order, legs = [0], [first]
    _walked(progress, 1, len(poses))
    remaining = list(range(1, len(poses)))
    while remaining:
        current = order[-1]
        pool = [j for j in remaining if groups[j] == groups[current]]
        if not pool:  # the next group of the plan, in its order
            pool = [j for j in remaining if groups[j] == groups[remaining[0]]]
        distance = np.linalg.norm(weighted[pool] - weighted[current], axis=1)
        nearest = [pool[k] for k in np.argsort(distance, kind='stable')]
        chosen = _next(rehearser, poses, current, nearest[: max(1, rehearser.settings.tour_tries)])
        if chosen is None:
            raise Stuck(nearest[0])
        index, leg = chosen
        rehearser.take(leg)
        order.append(index)
        legs.append(leg)
        remaining.remove(index)
        _walked(progress, len(legs), len(poses))
    return np.array(order, dtype=int), legs


def _next(rehearser, poses, current, candidates) -> tuple[int, Leg] | None:
    """Return the first safe move among the candidates, else the least risky (None: none)."""
    best: tuple[int, Leg] | None = None
    tried = rehearser.legs_to(poses[current], [poses[index] for index in candidates])
    for index, leg in zip(candidates, tried):
        if leg is None:
            continue
        if rehearser.safe(leg):
            return index, leg
        if best is None or leg.risk < best[1].risk:
            best = (index, leg)
    return best


__all__ = [
    'DEFAULT_MAX_MOVE_CONDITION',
    'DEFAULT_TOUR_TRIES',
    'FIRST_REHEARSED',
    'Leg',
    'NoRelease',
    'Rehearser',
    'RehearsalSettings',
    'Stuck',
    'in_order',
    'tour',
]
