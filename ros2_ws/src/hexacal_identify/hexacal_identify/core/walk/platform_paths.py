"""
Platform paths and actuator commands along the measuring link's sphere (ROS-free).

With the measuring link attached the platform must stay on the link sphere
(|p| = L about O) on the way between postures too: a controller interpolates a
one-point command in joint space, which between two postures leaves the sphere
by centimetres and strains the machine against the link.  So a move carries
intermediate points, the nominal inverse kinematics of poses along the sphere
(great circle about O, Euler angles linear: `sphere_path`), at most ``step_m``
apart, each timed from its largest actuator move at the speed limit
(`path_command`); if that path leaves the stroke or the nominal workspace it
goes by way of the centre (`route_command`).  A controller interpolates from its current
setpoints to the first point: `blend_command` starts a move there when they are not the
model's start (a chain locked where the link put it, an earlier model's targets).

`interpolate_pose` is also the simulated driver's (hexacal_driver.simulation):
one interpolation for the commanded and the simulated machine.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import math

import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT, device_position, fixed_point

MIN_MOVE_S = 0.1  # shortest time_from_start of a command (a zero time asks a controller to jump)
# An eased move's points are at most this far apart in time: a controller interpolating linearly
# between them (a joint_trajectory_controller given positions only) changes its speed in steps
# a stiff drive follows without a jolt (on the MuJoCo Hexa Slide the released passive system's
# link peaks at its static load with 20 ms, at 10-15 kN when a move starts at full speed).
EASED_STEP_S = 0.02
# An eased move reaches its speed limit no faster than this: acceleration <= speed / RAMP_S.
RAMP_S = 0.25
CORNER_COS = 0.5  # a path turning by more than 60 deg between two segments stops there
_QUINTIC_PEAK_SPEED = 1.875  # the quintic law's largest speed over its mean
_QUINTIC_PEAK_ACCELERATION = 10.0 / math.sqrt(3.0)  # its largest acceleration, x distance / T^2
MIN_SEGMENT_S = 0.01  # shortest time between two points of a path
SAME_SPHERE = 1e-3  # positions within this fraction of L of the link sphere move along it
SAME_RADIUS_M = 1e-9  # without L: positions this close in |p| share a sphere
_MIN_ANGLE_RAD = 1e-12  # below: the same direction, a straight line
_ANTIPODES_RAD = 1e-6  # within this of pi the great circle is undefined (never in a workspace)


class CommandPurpose(enum.StrEnum):
    """Why a command is sent (the values are the log's words)."""

    MOVE = 'move'
    CORRECT = 'correct'  # a closed-loop fixed-position correction
    HOLD = 'hold'  # stand where the machine is (pause, abort, a turn)


@dataclass(frozen=True)
class Command:
    """
    One JointTrajectory: actuator positions at times from its start.

    ``points`` (n, 6) in model order (m), ``times`` (n,) s; the last point is
    the target.
    """

    points: np.ndarray
    times: np.ndarray
    purpose: CommandPurpose
    posture: int  # plan index (0-based) it serves; -1 for a hold

    @property
    def positions(self) -> np.ndarray:
        """Return the target: the last point."""
        return self.points[-1]

    @property
    def duration_s(self) -> float:
        """Return the command's time_from_start of its target (s)."""
        return float(self.times[-1])


class PathError(ValueError):
    """A path along the link sphere leaves the nominal workspace or the stroke."""


def move_duration(
    current: np.ndarray, target: np.ndarray, max_speed_m_s: float, minimum_s: float = MIN_MOVE_S
) -> float:
    """Return the time_from_start of a move: its largest actuator move at max_speed_m_s."""
    largest = float(
        np.max(np.abs(np.asarray(target, dtype=float) - np.asarray(current, dtype=float)))
    )
    return max(largest / max_speed_m_s, minimum_s)


def interpolate_pose(
    start: np.ndarray, end: np.ndarray, s: float, link_length: float | None = None
) -> np.ndarray:
    """
    Return the pose a fraction s in [0, 1] of the way from start to end.

    Positions on one sphere about O move along its great circle (slerp),
    others on a straight line; Euler angles move linearly.  Which positions
    share a sphere depends on who asks, hence ``link_length``:

    * the executor (``link_length`` = L, the nominal link): both positions
      within ``SAME_SPHERE`` L of the link sphere, and the radius goes linearly
      from |p0| to |p1| (plan postures, the standing estimate and the centre
      are each on it to within micrometres, not to the bit);
    * the simulated driver (None): it walks the true machine, whose link is
      L + dL and unknown to the walker, so positions share a sphere when their
      distances from O agree to within ``SAME_RADIUS_M``; the slerp keeps that
      radius as it is (no rescaling, so its samples stay bit for bit).
    """
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    p0, p1 = start[:3], end[:3]
    r0, r1 = float(np.linalg.norm(p0)), float(np.linalg.norm(p1))
    if link_length is None:
        same_sphere = r0 > 0 and abs(r0 - r1) <= SAME_RADIUS_M
    else:
        tolerance = SAME_SPHERE * link_length
        same_sphere = (
            r0 > 0 and r1 > 0 and max(abs(r0 - link_length), abs(r1 - link_length)) <= tolerance
        )
    angle = 0.0
    if same_sphere:
        angle = math.acos(min(max(float(np.dot(p0, p1)) / (r0 * r1), -1.0), 1.0))
    if angle > _MIN_ANGLE_RAD and math.pi - angle > _ANTIPODES_RAD:
        position = (math.sin((1 - s) * angle) * p0 + math.sin(s * angle) * p1) / math.sin(angle)
        if link_length is not None:
            position *= ((1 - s) * r0 + s * r1) / float(np.linalg.norm(position))
    else:
        position = p0 + s * (p1 - p0)
    return np.concatenate([position, start[3:] + s * (end[3:] - start[3:])])


def sphere_path(
    start: np.ndarray, end: np.ndarray, link_length: float, step_m: float
) -> np.ndarray:
    """
    Return poses (n, 6) from start (excluded) to end (included) along the link sphere.

    At most step_m apart in position and step_m / L in each angle; just [end]
    for step_m = 0.
    """
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    if step_m <= 0:
        return end[None].copy()
    p0, p1 = start[:3], end[:3]
    r0, r1 = float(np.linalg.norm(p0)), float(np.linalg.norm(p1))
    angle = (
        math.acos(min(max(float(p0 @ p1) / (r0 * r1), -1.0), 1.0)) if r0 > 0 and r1 > 0 else 0.0
    )
    length = max(angle * max(r0, r1), float(np.linalg.norm(p1 - p0)))
    turn = float(np.max(np.abs(end[3:] - start[3:]))) * link_length
    count = max(1, math.ceil(max(length, turn) / step_m - 1e-9))
    return np.array(
        [interpolate_pose(start, end, (k + 1) / count, link_length) for k in range(count)]
    )


def path_command(
    nominal: KinematicParameters,
    current: np.ndarray,
    poses: np.ndarray,
    stroke: tuple[float, float],
    max_speed_m_s: float,
    purpose: CommandPurpose = CommandPurpose.MOVE,
    posture: int = -1,
) -> Command:
    """
    Return the command through `poses` (nominal inverse kinematics) from actuators at `current`.

    Each point is timed from its largest actuator move at max_speed_m_s (the
    whole at least MIN_MOVE_S).  PathError if a pose is out of the nominal
    machine's reach or a point outside the stroke.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    arch = nominal.architecture
    legs = arch.legs(arch.chains(nominal), poses)
    reachable = legs.reachable()
    if not np.all(reachable):
        raise PathError(
            f'{int(np.sum(~reachable))} of its {len(poses)} points are out of the '
            f"nominal machine's reach ({arch.unreachable_reason})"
        )
    points = legs.actuators
    low, high = stroke
    outside = np.any((points < low) | (points > high), axis=1)
    if np.any(outside):
        names = nominal.layout.actuator_names
        worst = points[np.flatnonzero(outside)[0]]
        which = ', '.join(
            f'{names[c]} {worst[c]:.4f} m' for c in range(6) if not low <= worst[c] <= high
        )
        raise PathError(
            f'{int(np.sum(outside))} of its {len(poses)} points are outside the stroke '
            f'[{low:g}, {high:g}] m ({which})'
        )
    times = point_times(current, points, max_speed_m_s)
    return Command(points.copy(), times, CommandPurpose(purpose), posture)


def point_times(current: np.ndarray, points: np.ndarray, max_speed_m_s: float) -> np.ndarray:
    """
    Return the time_from_start (n,) of `points` (n, 6) from actuators at `current`.

    Each segment takes its largest actuator move at max_speed_m_s (at least MIN_SEGMENT_S),
    the whole at least MIN_MOVE_S.
    """
    previous = np.concatenate([np.asarray(current, dtype=float)[None], points[:-1]])
    segments = np.maximum(np.max(np.abs(points - previous), axis=1) / max_speed_m_s, MIN_SEGMENT_S)
    times = np.cumsum(segments)
    if times[-1] < MIN_MOVE_S:
        times *= MIN_MOVE_S / times[-1]
    return times


def smooth_step(fraction: float | np.ndarray) -> np.ndarray:
    """Return the quintic time law on [0, 1] (clipped): at rest, no acceleration, at both ends."""
    s = np.clip(fraction, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def eased_command(command: Command, start: np.ndarray, max_speed_m_s: float) -> Command:
    """
    Return `command` re-timed to start and stop at rest, from the drive's setpoints `start`.

    Timed at full speed from the first point on (`point_times`), a move's speed jumps from 0 to
    the limit: a stiff servo answers with the platform's inertia at its bandwidth, loads that no
    static model holds (on the MuJoCo Hexa Slide, 10-15 kN in a measuring link whose static
    load is a few hundred newtons).  Each leg of the path (split where it turns by more than
    60 deg: the centre of a route, a blend's start) follows the quintic law along its length
    (the largest actuator move), its peak speed at most `max_speed_m_s` and its acceleration at
    most max_speed_m_s / RAMP_S, sampled every EASED_STEP_S or less; the target is the
    command's, bit for bit.  A command that does not move is returned as it is.
    """
    start = np.asarray(start, dtype=float)
    path = np.vstack([start[None], command.points])
    steps = np.diff(path, axis=0)
    lengths = np.max(np.abs(steps), axis=1)
    if not np.any(lengths > 0):
        return command
    points: list[np.ndarray] = []
    times: list[np.ndarray] = []
    elapsed = 0.0
    for first, last in _legs(steps, lengths):
        leg_points, leg_times = _eased_leg(
            path[first:last + 1], lengths[first:last], max_speed_m_s
        )
        points.append(leg_points)
        times.append(elapsed + leg_times)
        elapsed += float(leg_times[-1])
    eased = np.vstack(points)
    eased[-1] = command.points[-1]
    return Command(eased, np.concatenate(times), command.purpose, command.posture)


def _legs(steps: np.ndarray, lengths: np.ndarray) -> list[tuple[int, int]]:
    """Return (first, last) vertex indices of the path's legs, split at sharp turns."""
    moving = np.flatnonzero(lengths > 0)
    directions = steps[moving] / np.linalg.norm(steps[moving], axis=1)[:, None]
    turns = np.sum(directions[1:] * directions[:-1], axis=1) < CORNER_COS
    ends = [int(moving[k + 1]) for k in np.flatnonzero(turns)]  # a leg ends where one turns
    bounds = [0, *ends, len(lengths)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if np.any(lengths[a:b] > 0)]


def _eased_leg(
    vertices: np.ndarray, lengths: np.ndarray, max_speed_m_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Return the points after the first vertex and their times along one leg (quintic)."""
    along = np.concatenate([[0.0], np.cumsum(lengths)])
    total = float(along[-1])
    duration = max(
        MIN_MOVE_S,
        _QUINTIC_PEAK_SPEED * total / max_speed_m_s,
        math.sqrt(_QUINTIC_PEAK_ACCELERATION * total * RAMP_S / max_speed_m_s),
    )
    count = max(1, math.ceil(duration / EASED_STEP_S - 1e-9))
    times = duration * np.arange(1, count + 1) / count
    travelled = smooth_step(times / duration) * total
    points = np.column_stack(
        [np.interp(travelled, along, vertices[:, j]) for j in range(vertices.shape[1])]
    )
    points[-1] = vertices[-1]
    return points, times


def setpoints_at(start: np.ndarray, command: Command, elapsed_s: float) -> np.ndarray:
    """
    Return the setpoints (6,) `elapsed_s` after `command` was sent to setpoints at `start`.

    As the drive follows it: linearly from `start` through each point at its time_from_start
    (a joint_trajectory_controller given positions only), at the target from its time on.
    """
    times = np.concatenate([[0.0], command.times])
    points = np.vstack([np.asarray(start, dtype=float)[None], command.points])
    return np.array([np.interp(elapsed_s, times, points[:, j]) for j in range(points.shape[1])])


def blend_command(
    command: Command,
    setpoints: np.ndarray,
    offset: np.ndarray,
    max_speed_m_s: float,
    stroke: tuple[float, float] = (-math.inf, math.inf),
) -> Command:
    """
    Return `command` starting from the drive's `setpoints` instead of the model's start.

    A controller interpolates from its current setpoints to the first point; where those are
    not the model's inverse kinematics of the path's start (a chain locked where the link put
    it, the targets of an earlier model) the first segment would be a jump of that `offset`
    (setpoints - model at the start, (6,) m) in a few milliseconds: a following error to a
    stiff drive, a push toward a jam to the passive system.  Each point carries ``offset x
    (1 - its fraction of the move's time from the first point)``: the first point is the
    setpoints, the offset goes to zero smoothly along the path and the last point is the
    model's target exactly, every point kept inside `stroke` (the setpoints and the model's
    points are; their blend near an end might not be).  The fraction is counted from the first
    point, not from the drive's setpoints: from those, the time to the model's start is the
    offset's own, and a chain locked centimetres from the model (the released one, where the
    link put it) would take that share of its offset in one straight segment, a path no
    rehearsal walked (core/modes/release_rehearsal.py fades it along the path).  Re-timed from
    `setpoints` at max_speed_m_s.
    """
    offset = np.asarray(offset, dtype=float)
    if not np.any(offset):
        return command
    elapsed = command.times - command.times[0]
    fraction = elapsed / elapsed[-1] if elapsed[-1] > 0 else np.ones(len(elapsed))
    points = np.clip(command.points + (1.0 - fraction)[:, None] * offset[None], *stroke)
    points[-1] = command.points[-1]  # the target stays the model's, bit for bit
    times = point_times(setpoints, points, max_speed_m_s)
    return Command(points, times, command.purpose, command.posture)


def route_command(
    nominal: KinematicParameters,
    current: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    stroke: tuple[float, float],
    max_speed_m_s: float,
    link_length: float,
    step_m: float,
    mount: str = DEFAULT_MOUNT,
    purpose: CommandPurpose = CommandPurpose.MOVE,
    posture: int = -1,
) -> Command:
    """
    Return the command along the link sphere from pose `start` to `end` (`sphere_path`).

    If that path leaves the stroke or the nominal workspace, it goes by way of
    the centre (the fixed-position point, zero angles: the middle of the
    workspace); PathError (the direct path's) if neither can be commanded.
    """
    try:
        return path_command(
            nominal,
            current,
            sphere_path(start, end, link_length, step_m),
            stroke,
            max_speed_m_s,
            purpose,
            posture,
        )
    except PathError as error:
        centre = np.concatenate([fixed_point(link_length, mount), np.zeros(3)])
        via = np.concatenate(
            [
                sphere_path(start, centre, link_length, step_m),
                sphere_path(centre, end, link_length, step_m),
            ]
        )
        try:
            return path_command(nominal, current, via, stroke, max_speed_m_s, purpose, posture)
        except PathError:
            raise error from None


def on_sphere(pose: np.ndarray, link_length: float, mount: str = DEFAULT_MOUNT) -> np.ndarray:
    """Return the pose with its position moved radially onto the link sphere (mount's side)."""
    pose = np.array(pose, dtype=float)
    radius = float(np.linalg.norm(pose[:3]))
    if radius > 0:
        pose[:3] *= link_length / radius
    else:
        pose[:3] = fixed_point(link_length, mount)
    return pose


def fixed_position_correction(
    alpha: float,
    beta: float,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    change: np.ndarray | None = None,
) -> np.ndarray:
    """
    Return the platform position change (3,) that brings the inclinometer from (alpha, beta) to 0.

    ``-dp/d(alpha, beta) [alpha, beta]`` with eq. 4's derivative at the
    reading (first order); `change` (2,), rad: the reading change to make instead
    (core/walk/correction_response.py: what the machine's answer so far asks for).
    """
    placed = device_position(np.array([alpha]), np.array([beta]), link_length, mount=mount)
    wanted = -np.array([alpha, beta]) if change is None else np.asarray(change, dtype=float)
    return placed.d_readings[0] @ wanted


def corrected_pose(
    commanded: np.ndarray,
    alpha: float,
    beta: float,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    change: np.ndarray | None = None,
) -> np.ndarray:
    """Return the commanded pose, its position corrected for the inclinometer reading."""
    pose = np.array(commanded, dtype=float)
    pose[:3] += fixed_position_correction(alpha, beta, link_length, mount, change)
    return pose
