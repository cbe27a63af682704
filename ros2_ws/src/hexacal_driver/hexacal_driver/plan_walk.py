"""
Walk a passive-actuator plan offline on the true machine: where the drives would jam (ROS-free).

A plan is made on the nominal model and rehearsed on machines drawn around it; the machine it is
walked on is none of them.  `walk_plan` follows, without ROS and without time passing, the moves
the executor commands and the simulated drives take:

* the executor's side (core/walk): at rest the released chain is swapped (the one released
  before locked where the link put it, its setpoint there), the move runs along the link sphere
  from where the machine stands (``route_command``: by way of the centre where the direct path
  leaves the stroke), blended from the drive's setpoints (``blend_from_setpoints``), on the
  executor's model (the nominal, or the refined model from a checkpoint on: ``refine_at``); the
  first release is rehearsed again from where the machine stands (``first_releases``), and
  with ``check_at_rest`` (the default, the executor's ``check_releases_at_rest``) each later
  one before its move (``release_checked_here``, as the executor does); each of these checks
  again from where the inclinometer puts the platform (``measured_standing``, the default: the
  true link's direction, the angles fitted on the executor's model);
* the drive's side (hexacal_driver.drives.DriveFollower on the true machine): the setpoints
  followed segment by segment, solved at most ``CONTINUATION_STEP`` apart (the driver's
  continuation) from the previous pose; a jam or a released actuator past its stroke faults.

Each move reports the worst condition number of the passive system with its released chain on
the true machine along the way (``release_conditions``: unit-free, angles as lengths; the fold
is where it is infinite) and the drive's fault, if any.  After a fault the drive is reset where
it stands and the walk goes on to the next posture (the executor would pause: every fold of the
plan is reported, not only the first); with ``recover`` (the default) it first does what the
executor does once the drive is reset and the walk resumed: another chain is released from where
the machine stands (``release_after_fault``) and the move is taken again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

from hexacal_driver.drives import CONTINUATION_STEP, DriveFollower, DriveSettings
from hexacal_driver.simulation import TrajectoryPoint
from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.machine.device import DEFAULT_MOUNT, fixed_point
from hexacal_identify.core.machine.kinematics import measured_pose
from hexacal_identify.core.modes.link_load import LinkLoad
from hexacal_identify.core.modes.passive_actuator import release_conditions
from hexacal_identify.core.walk.platform_paths import CommandPurpose, eased_command, PathError
from hexacal_identify.core.walk.platform_paths import route_command
from hexacal_identify.core.walk.release_choice import first_releases, release_after_fault
from hexacal_identify.core.walk.release_choice import release_checked_here
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.standing import blend_from_setpoints, estimate_pose
from hexacal_msgs_py.measuring_modes import MeasuringMode
import numpy as np

EXECUTOR_SPEED_M_S = 0.5  # the demo's executor
DRIVER_SPEED_M_S = 1.0  # the demo's driver
PATH_STEP_M = ExecutionSettings().path_step_m  # the executor's default


@dataclass(frozen=True)
class MoveWalk:
    """
    One move of a walked plan: to plan posture ``posture`` (0-based) with ``released`` free.

    ``worst_condition``: the passive system's worst condition number on the true machine along
    the move (inf: it met the fold); ``fault`` the drive's fault ('' none); ``refused`` why the
    executor could not command it ('' it did: a target outside the stroke, a path it cannot
    command).
    """

    posture: int
    released: int | None
    worst_condition: float
    fault: str = ''
    refused: str = ''
    recovered: bool = False  # faulted, then reached with another chain released

    @property
    def jammed(self) -> bool:
        """Return True when the drive faulted on the way."""
        return bool(self.fault)


@dataclass(frozen=True)
class PlanWalk:
    """A plan walked offline on the true machine: its moves and the releases walked."""

    moves: tuple[MoveWalk, ...]
    released: tuple[int | None, ...]

    @property
    def jams(self) -> int:
        """Return the moves on which the drive faulted."""
        return sum(move.jammed for move in self.moves)

    @property
    def recovered(self) -> int:
        """Return the moves that faulted and were then reached with another chain released."""
        return sum(move.recovered for move in self.moves)

    @property
    def refused(self) -> int:
        """Return the moves the executor could not command."""
        return sum(bool(move.refused) for move in self.moves)

    @property
    def worst_condition(self) -> float:
        """Return the worst condition met along any commanded move (inf: a fold reached)."""
        walked = [m.worst_condition for m in self.moves if not m.refused]
        return max(walked) if walked else 0.0


def _step_times(segments) -> list[float]:
    """Return the times at which the drive is solved: each segment in CONTINUATION_STEPs."""
    times: list[float] = []
    for start_s, end_s, begin, end in segments:
        steps = max(1, math.ceil(float(np.max(np.abs(end - begin))) / CONTINUATION_STEP))
        times.extend(start_s + (end_s - start_s) * (k + 1) / steps for k in range(steps))
    return times


def targets_outside(
    model: KinematicParameters, poses: np.ndarray, stroke: tuple[float, float]
) -> np.ndarray:
    """Return the mask of postures (K,) whose targets on `model` leave the stroke (or reach)."""
    arch = model.architecture
    legs = arch.legs(arch.chains(model), np.atleast_2d(poses))
    low, high = stroke
    with np.errstate(invalid='ignore'):
        inside = np.all((legs.actuators >= low) & (legs.actuators <= high), axis=1)
    return ~(inside & legs.reachable())


def walk_plan(
    truth: KinematicParameters,
    model: KinematicParameters,
    poses: np.ndarray,
    released: Sequence[int | None],
    link_length: float,
    stroke: tuple[float, float],
    *,
    true_link_length: float | None = None,
    mount: str = DEFAULT_MOUNT,
    refine_at: int | None = None,
    refined: KinematicParameters | None = None,
    rechoose_first: bool = True,
    check_at_rest: bool = True,
    recover: bool = True,
    path_step_m: float = PATH_STEP_M,
    measured_standing: bool = True,
    link_load: LinkLoad | None = None,
) -> PlanWalk:
    """
    Walk `poses` (K, 6, plan order) with `released` (0-based) on `truth` (module doc).

    `model` the executor's (its targets and paths), `link_length` the nominal link L (m),
    `true_link_length` the machine's (default L), `stroke` the actuators' (low, high);
    from posture `refine_at` (0-based) on the executor walks on `refined` instead.  The
    machine starts at the fixed-position point with zero angles, all six locked.  `recover`:
    after a fault the executor's recovery (another chain released from where it stands) is
    taken, else the walk goes on to the next posture from where the drive stopped.
    `measured_standing`: the checks at rest also rehearse from where the inclinometer puts the
    platform, as the executor does (False: from the model's estimate alone).  `link_load`: the
    executor's (its ``physical_file`` weights and the plan's limit; None: not weighed).
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    released = list(released)
    if len(released) != len(poses):
        raise ValueError(f'released names {len(released)} chains for {len(poses)} postures')
    true_link = float(link_length if true_link_length is None else true_link_length)
    names = truth.layout.actuator_names
    centre = np.concatenate([fixed_point(link_length, mount), np.zeros(3)])
    drive = DriveFollower(
        truth, np.concatenate([fixed_point(true_link, mount), np.zeros(3)]), DRIVER_SPEED_M_S,
        true_link, mount, settings=DriveSettings(mode=MeasuringMode.PASSIVE_ACTUATOR),
        joint_names=names, nominal_link_m=link_length, stroke_m=stroke,
    )
    now = 0.0
    here = _estimate(model, drive.actuators, [poses[0], centre], link_length, mount)
    if rechoose_first and here is not None and len(poses):
        chosen = first_releases(model, poses, released, None, here, drive.actuators.copy(),
                                link_length, stroke, mount,
                                _measured(model, drive, here, measured_standing), link_load)
        if chosen is not None:
            released = list(chosen[0])
    setpoints = drive.actuators.copy()
    where: np.ndarray | None = None
    moves: list[MoveWalk] = []
    for index, pose in enumerate(poses):
        if refine_at is not None and refined is not None and index == refine_at:
            model = refined
        if targets_outside(model, pose[None], stroke)[0]:
            moves.append(MoveWalk(index, released[index], 0.0,
                                  refused='a target outside the stroke'))
            continue
        if check_at_rest and index > 0:
            released[index] = _checked_release(model, drive, released[index], pose, poses,
                                               index, centre, link_length, stroke, mount,
                                               measured_standing, link_load, where)
        faulted: set[int] = set()
        first_fault = ''
        while True:
            wanted = released[index]
            if wanted != drive.released:
                if drive.released is not None:
                    locked = drive.released
                    drive.release(names[locked], False, now)
                    setpoints[locked] = drive.actuators[locked]
                if wanted is not None:
                    drive.release(names[wanted], True, now)
            start = where if where is not None else _estimate(
                model, drive.actuators, [poses[max(index - 1, 0)], pose, centre], link_length,
                mount,
            )
            outcome = _move(drive, truth, model, start, pose, setpoints, stroke, link_length,
                            true_link, path_step_m, mount, index, now)
            if isinstance(outcome, str):
                moves.append(MoveWalk(index, wanted, 0.0, fault=first_fault, refused=outcome))
                break
            now, worst, target = outcome
            if drive.fault is None:
                setpoints, where = target, pose
                moves.append(MoveWalk(index, wanted, worst, fault=first_fault,
                                      recovered=bool(first_fault)))
                break
            # The executor pauses; reset and resumed, it releases another chain from where the
            # machine stands (core/walk/release_choice.rechoose_release), if any may be.
            first_fault = first_fault or drive.fault.text
            drive.reset()
            setpoints, where = drive.actuators.copy(), None
            rechosen: int | None = None
            if recover and drive.released is not None:
                faulted.add(drive.released)
                here = _estimate(model, drive.actuators, [pose, centre], link_length, mount)
                if here is not None:
                    rechosen, _, _ = release_after_fault(
                        model, here, drive.actuators.copy(), drive.released, pose, faulted,
                        link_length, stroke, mount, f'posture {index + 1}',
                        _measured(model, drive, here, measured_standing), link_load,
                    )
            if rechosen is None:
                moves.append(MoveWalk(index, wanted, math.inf, fault=first_fault))
                break
            released[index] = rechosen
    return PlanWalk(tuple(moves), tuple(released))


def _move(drive, truth, model, start, pose, setpoints, stroke, link_length, true_link,
          path_step_m, mount, index, now):
    """
    Command one move as the executor does and follow it on the drive (module doc).

    Return (the time at rest, the worst condition along, the command's target), or why the
    executor could not command it.
    """
    if start is None:
        return 'cannot tell where it stands'
    try:
        command = route_command(model, drive.actuators.copy(), start, pose, stroke,
                                EXECUTOR_SPEED_M_S, link_length, path_step_m, mount,
                                CommandPurpose.MOVE, index)
    except PathError as error:
        return f'its path: {error}'
    command = blend_from_setpoints(model, command, start, setpoints, drive.released,
                                   EXECUTOR_SPEED_M_S, stroke)
    command = eased_command(command, setpoints, EXECUTOR_SPEED_M_S)
    points = command.points.copy()
    if drive.released is not None:  # not commanded: the driver holds its column
        points[:, drive.released] = drive.actuators[drive.released]
    drive.command(now, [TrajectoryPoint(p, float(t)) for p, t in zip(points, command.times)])
    visited = [drive.pose.copy()]
    for time_s in _step_times(list(drive._segments)):
        drive.sample(time_s)
        if drive.fault is not None:
            break
        visited.append(drive.pose.copy())
    now = max(now, drive.end_time_s) + 1.0
    if drive.fault is not None:
        return now, math.inf, command.positions.copy()
    drive.sample(now)  # at rest
    worst = 0.0
    if drive.released is not None:
        conditions = release_conditions(truth, np.array(visited), true_link)
        worst = float(np.max(conditions[:, drive.released]))
    return now, worst, command.positions.copy()


def _checked_release(model, drive, planned, pose, poses, index, centre, link_length, stroke,
                     mount, measured_standing, link_load, where):
    """
    Return the release the executor walks to `pose`: checked at rest from here.

    Rehearsed along the path the executor commands: from `where` (the pose it commanded last,
    where the machine stood still after it; None: from its estimate), blended from the setpoints.
    """
    if planned is None or drive.released is None:
        return planned
    here = _estimate(model, drive.actuators, [poses[index - 1], pose, centre], link_length, mount)
    if here is None:
        return planned
    return release_checked_here(model, here, drive.actuators.copy(), drive.released, pose,
                                planned, link_length, stroke, mount,
                                _measured(model, drive, here, measured_standing), link_load,
                                where)


def _measured(model, drive, estimate, measured_standing=True) -> np.ndarray | None:
    """
    Return where the executor measures the platform standing (PlanExecution._measured_standing).

    The inclinometer's position: the true link's direction at the nominal link length (eq. 4
    of an ideal inclinometer); the angles fitted on the executor's model to the actuators.
    """
    if not measured_standing:
        return None
    direction = drive.pose[:3] / np.linalg.norm(drive.pose[:3])
    return measured_pose(model, drive.actuators, drive.nominal_link_m * direction[None],
                         estimate)[0]


def _estimate(model, actuators, guesses, link_length, mount) -> np.ndarray | None:
    """Return where the executor believes the platform stands (standing.estimate_pose)."""
    pose, _ = estimate_pose(model, np.asarray(actuators, dtype=float), guesses, link_length,
                            mount)
    return pose


__all__ = ['MoveWalk', 'PlanWalk', 'targets_outside', 'walk_plan']
