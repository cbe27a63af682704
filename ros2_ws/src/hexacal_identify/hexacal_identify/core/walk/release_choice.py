"""
Which chain the walk releases, and when it asks the drive to swap (ROS-free).

Measuring mode ``passive_actuator``: with ``released`` given, each posture names the chain
released while it is moved to and measured (None: all six commanded).  Before a posture whose
released chain is not the one released now, at rest, core/walk/execution.py asks the node to
lock the one released now and release the posture's (a `ReleaseRequest`; the node calls the
drive's services, core/walk/drive_calls.py, and answers with ``on_release``); it moves on only
once the drive has done both.  A refusal or a missing service pauses the plan with the drive's
answer in ``notice``; resume asks again.  The released chain is never commanded and is not
judged against its target: the link puts it where the constraint says.  Once the plan is over
the released chain is locked: the machine is left a machine, every actuator held by its drive.

* `first_releases`: the planner cannot know where the first move starts; if the plan's first
  release is not safe from where the machine stands, the whole plan's releases are rehearsed
  again from there.
* `hear_release`, `choose_first_release`, `check_release_here`, `rechoose_release`: what
  `PlanExecution` does with the drive's answers and its releases (the walk is their first
  argument); before each later move, at rest, the posture's release is rehearsed again from
  where the machine stands and another chain released if it may jam.
* `release_after_fault`: after a drive fault with a chain released (most likely a jam of the
  five commanded and the link), another chain is released for the rest of the move.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from hexacal_msgs_py.names import EXECUTOR_RESUME_SERVICE as RESUME_SERVICE
import numpy as np

from .messages import LogLevel
from .platform_paths import Command
from .settings import ExecutionState, Phase
from ..architectures import KinematicParameters

if TYPE_CHECKING:
    from .execution import PlanExecution
    from ..modes.link_load import LinkLoad


@dataclass(frozen=True)
class ReleaseRequest:
    """Lock chain `lock` then release chain `release` (0-based; None: nothing) before `posture`."""

    posture: int
    lock: int | None
    release: int | None


def first_releases(
    nominal: KinematicParameters,
    poses: np.ndarray,
    released: Sequence[int | None],
    released_now: int | None,
    here: np.ndarray,
    actuators: np.ndarray,
    link_length: float,
    stroke: tuple[float, float],
    mount: str,
    measured_here: np.ndarray | None = None,
    link_load: LinkLoad | None = None,
) -> tuple[list[int | None], str] | None:
    """
    Return the releases rehearsed again from pose `here` and the line to log; None: keep them.

    Every later release assumes the standing the earlier ones leave, so they are rehearsed
    again in the plan's order (a plan whose releases cannot be rehearsed keeps its own: the
    guard still watches).  `measured_here`: where the device measured the platform
    (``release_from_here``); `link_load`: the link's limit the releases keep within, as the
    planner's did.
    """
    from ..modes.released_actuator import choose_released_actuators, release_from_here

    first = released[0]
    if first is None:
        return None  # nothing released at the first posture: nothing to rehearse
    standing_release = first if released_now is None else released_now
    kept = release_from_here(
        nominal, here, actuators, standing_release, poses[0], link_length, stroke, (),
        mount=mount, prefer=first, measured_here=measured_here, link_load=link_load,
    )
    if kept == first:
        return None
    try:
        choice = choose_released_actuators(
            nominal, poses, link_length, stroke, start=here, mount=mount, link_load=link_load
        )
    except ValueError:
        return None  # ReleaseError: the plan's releases stay; the guard still watches
    changed = int(np.sum(choice.released != np.array(released)))
    rehearsed: list[int | None] = [int(chain) for chain in choice.released]
    return rehearsed, (
        "the plan's first release is not safe from where the machine stands: its releases "
        f'were rehearsed again from here ({changed} of {len(poses)} changed)'
    )


def release_after_fault(
    nominal: KinematicParameters,
    here: np.ndarray,
    actuators: np.ndarray,
    released_now: int,
    pose: np.ndarray,
    faulted: set[int],
    link_length: float,
    stroke: tuple[float, float],
    mount: str,
    where: str,
    measured_here: np.ndarray | None = None,
    link_load: LinkLoad | None = None,
) -> tuple[int | None, LogLevel, str]:
    """
    Return the chain to release for the rest of the move to `pose` (None: the release stays).

    From where the machine stands, at rest, another chain than the `faulted` ones is
    released (``release_from_here``); the swap happens as any other, at rest, before the
    move goes on.  `where` names the posture for the line to log (returned with its level);
    `measured_here`: where the device measured the platform, `link_load` the link's limit
    (``release_from_here``).
    """
    from ..modes.released_actuator import release_from_here

    chosen = release_from_here(
        nominal, here, actuators, released_now, pose, link_length, stroke, sorted(faulted),
        mount=mount, measured_here=measured_here, link_load=link_load,
    )
    names = nominal.layout.actuator_names
    tried = ', '.join(names[c] for c in sorted(faulted))
    if chosen is None:
        return None, LogLevel.WARN, (
            f'{where}: the drive faulted with {tried} released and no other chain stays '
            'inside its stroke on the rest of the move: the release stays'
        )
    return chosen, LogLevel.WARN, (
        f'{where}: the drive faulted with {tried} released; {names[chosen]} is released for '
        'the rest of the move (rehearsed from where the machine stands, as the planner chooses)'
    )


def hear_release(
    walk: PlanExecution, now: float, released: int | None, problem: str
) -> list[Command]:
    """
    Hear the drive's answer to `release_request`: the chain released now, what went wrong.

    problem '': done, the posture is commanded; else the plan pauses (holding) with
    `problem` in ``notice`` until resumed.
    """
    request, walk.release_request = walk.release_request, None
    walk.released_now = released
    _lock_setpoint(walk, request)
    if request is None or walk._phase != Phase.RELEASING:
        return []  # paused or aborted meanwhile: resume asks again if need be
    if problem:
        walk.state = ExecutionState.PAUSED
        walk._paused_at = now
        walk._phase = None
        walk.notice = (
            f'posture {request.posture + 1} of {walk.total}: {problem}; paused: fix the '
            f'drive, then call {RESUME_SERVICE}'
        )
        walk._say(LogLevel.ERROR, walk.notice)
        return walk._hold(now)
    return walk._begin(now, fresh=False)


def _lock_setpoint(walk: PlanExecution, request: ReleaseRequest | None) -> None:
    """Take the chain the drive locked where it stands as its setpoint (drives.py)."""
    latest = walk.actuators.latest
    if request is None or request.lock is None or walk._setpoints is None:
        return
    if latest is None or walk.released_now == request.lock:
        return  # not locked (refused before): no setpoint changed
    walk._setpoints[request.lock] = latest[request.lock]


def choose_first_release(walk: PlanExecution) -> None:
    """
    Keep the walk's releases if its first move is safe from where the machine stands.

    The planner cannot know where the first move starts (it rehearses the first posture
    from standing at it), and every later release assumes the standing the earlier ones
    leave.  If the plan's first release is not safe from here (release_from_here), the
    releases of the whole plan are rehearsed again from here, in the plan's order.
    """
    first = walk.released[0] if walk.total else None
    here, latest = walk._estimate(), walk.actuators.latest
    if first is None or here is None or latest is None:
        return
    chosen = first_releases(
        walk.nominal, walk.poses, walk.released, walk.released_now, here, latest,
        walk.link_length, walk.stroke, walk.mount, walk._measured_standing(here), walk.link_load,
    )
    if chosen is not None:
        walk.released, text = chosen
        walk._say(LogLevel.INFO, text)


def release_checked_here(
    nominal: KinematicParameters,
    here: np.ndarray,
    actuators: np.ndarray,
    released_now: int,
    pose: np.ndarray,
    planned: int,
    link_length: float,
    stroke: tuple[float, float],
    mount: str,
    measured_here: np.ndarray | None = None,
    link_load: LinkLoad | None = None,
    path_start: np.ndarray | None = None,
) -> int:
    """
    Return the chain to release for the move from `here` (at rest) to `pose`.

    `planned` if the move closes with it on `nominal` and machines like it
    (``release_from_here``), else another chain that does; `planned` when none does (the guard
    still watches).  `measured_here`: where the device measured the platform; `link_load`: the
    link's limit a chain's release must keep within where another's does; `path_start`: where
    the executor's path starts when not `here` (the pose it last commanded).
    """
    from ..modes.released_actuator import release_from_here

    chosen = release_from_here(
        nominal, here, actuators, released_now, pose, link_length, stroke, (), mount=mount,
        prefer=planned, measured_here=measured_here, link_load=link_load,
        path_start=path_start,
    )
    return planned if chosen is None else chosen


def check_release_here(walk: PlanExecution) -> None:
    """
    At rest before a posture's move, keep its release only if the move is safe from here.

    The planner rehearsed each move from the posture before as the nominal stands there;
    the machine stands where the true machine put it.  The posture's release is rehearsed
    again from here on the walk's model and machines like it (``release_from_here``, as for
    the first move); if it may jam, another chain is released instead, before anything moves
    (a jam found by the drive faults it and pauses the plan).  The first posture is
    `choose_first_release`'s.
    """
    planned = walk.released[walk.index] if 0 < walk.index < walk.total else None
    here, latest = walk._estimate(), walk.actuators.latest
    if planned is None or walk.released_now is None or here is None or latest is None:
        return
    # Rehearsed along the path the move will take: from the pose commanded last, where the
    # machine stood still (PlanExecution._path_start), blended from where it stands.
    chosen = release_checked_here(
        walk.nominal, here, latest, walk.released_now, walk.poses[walk.index], planned,
        walk.link_length, walk.stroke, walk.mount, walk._measured_standing(here), walk.link_load,
        walk._path_start(),
    )
    if chosen == planned:
        return
    names = walk.nominal.layout.actuator_names
    walk.released[walk.index] = chosen
    walk._say(
        LogLevel.WARN,
        f'posture {walk.index + 1} of {walk.total}: from where the machine stands the move '
        f'may jam with {names[planned]} released (rehearsed on machines like the model); '
        f'{names[chosen]} is released instead',
    )


def rechoose_release(walk: PlanExecution) -> None:
    """
    After a drive fault with a chain released, release another for the rest of the move.

    The fault was most likely a jam of the five commanded and the link (a fold of the
    passive system the plan's release meets on this machine, not on the model): from where
    the machine stands, at rest, another chain is released (``release_from_here``) and the
    swap happens as any other, at rest, before the move goes on.
    """
    faulted = walk._faulted_releases.get(walk.index, set())
    if walk.index >= walk.total or walk.released[walk.index] not in faulted:
        return
    here, latest = walk._estimate(), walk.actuators.latest
    if here is None or latest is None or walk.released_now is None:
        return
    chosen, level, text = release_after_fault(
        walk.nominal, here, latest, walk.released_now, walk.poses[walk.index], faulted,
        walk.link_length, walk.stroke, walk.mount, f'posture {walk.index + 1} of {walk.total}',
        walk._measured_standing(here), walk.link_load,
    )
    if chosen is not None:
        walk.released[walk.index] = chosen
    walk._say(level, text)


__all__ = [
    'check_release_here',
    'choose_first_release',
    'first_releases',
    'hear_release',
    'rechoose_release',
    'release_after_fault',
    'release_checked_here',
    'ReleaseRequest',
]
