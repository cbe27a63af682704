"""Walking a posture plan on a machine through its trajectory controller (ROS-free).

The executor node (nodes/executor.py) feeds this module what it hears and
publishes what it answers; everything that decides is here, unit-tested without ROS.

For each posture of a plan from ``hexacal plan``:

1. Targets: inverse kinematics of the planned pose with the *nominal*
   parameters (the only model a user has before calibrating). Every target of
   the plan is checked before anything moves (`plan_targets`): a pose the
   nominal machine cannot reach, an actuator outside the stroke limits, or a
   posture that is not where its kind says (a sphere posture off the link
   sphere, a fixed-position posture away from the fixed point) refuses the
   whole plan (`PlanRefusedError`, listing the postures). Chosen over skipping
   them: a plan that needs a target outside the stroke was made for another
   machine or other limits, and walking what remains of it would measure a
   different plan than the one asked for.
2. Move: one command, the targets with ``time_from_start`` from the largest
   actuator move at ``max_actuator_speed_m_s`` (`move_duration`). With the
   measuring link attached the platform must stay on the link sphere on the
   way too: a controller interpolates a one-point command in joint space, which
   between two postures leaves the sphere by centimetres and strains the
   machine against the link. So with ``path_step_m`` > 0 (the default) the
   command carries intermediate points, the nominal inverse kinematics of poses
   along the sphere (great circle about O, Euler angles linear; `sphere_path`),
   at most ``path_step_m`` apart, each timed at the same speed limit; its last
   point is the target. The paths between consecutive postures are checked
   with the plan; the first one, from where the machine stands, when it starts.
   ``path_step_m`` = 0 sends the single point.
3. Arrive: the measured actuators are at the target (within
   ``position_tolerance_m``) and still (peak-to-peak within
   ``still_tolerance_m``) over the last ``settle_s``, counted from when the
   command's own time has passed.  The tolerance allows for the strain of the
   measuring link: the link holds the platform on its sphere, so where the
   nominal model is millimetres off, the actuators stop up to millimetres away
   from targets the true machine cannot reach on that sphere.
4. Fixed-position postures (eq. 10) are reached in closed loop: with the
   machine still, the mean inclinometer reading (alpha, beta) over ``settle_s``
   gives the platform's position by eq. 4; the commanded pose's position is
   moved by ``-dp/d(alpha, beta) [alpha, beta]`` (eq. 4's derivative,
   `fixed_position_correction`) and new targets come from the nominal inverse
   kinematics, until both angles are within ``fixed_tolerance_rad``; after
   ``max_corrections`` the posture is skipped and reported.  Intermediate stops
   are valid sphere postures if the collector measures them.
5. Measured: the collector's posture of this stop (received after the last
   command, its actuators within ``still_tolerance_m`` of the still mean).
   Then the next posture.

A posture not done within ``timeout_s`` of its first command is skipped and
reported with what was missing. Pause holds the machine (a one-point command at
the measured actuator positions) and restarts the current posture on resume
(its timeout too); abort holds it and ends the plan.

Turning the device (a turning procedure: ``Plan.turns``, per posture, rad;
core/device.py "Turning the device about its link axis"; ``hexacal plan``
orders the postures by turn, one remount per turn).  The execution knows the
mounting the device is in (``mounted_turn``, from the start 0 = normal unless
told otherwise).  Before it begins a posture whose turn differs from that
mounting (compared modulo 2 pi, to within ``TURN_TOLERANCE_RAD``) it pauses
itself: state PAUSED, the hold command a pause sends, and a warning notice
(``turn_notice``) naming the posture, the turn it needs in deg and rad and
what to do ("turn the device to 180 deg about its link axis, then call
hexacal/executor/resume").  Nothing moves while the operator remounts the
device.  resume() then records the new mounting and begins that posture from
its planned pose (its timeout from the resume).  progress() reports the
current posture's ``device_turn_rad`` and, while waiting for a turn,
``device_turn_needed_rad``; the state stays one of STATES.  A posture skipped
after the turn (its path cannot be commanded, its timeout) does not undo the
turn: the next posture's turn is compared with the mounting the device is in.
The executor node tells the nodes that stamp or simulate the turn (collector,
driver) when the operator resumes.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

from hexacal_msgs_py.names import EXECUTOR_RESUME_SERVICE as RESUME_SERVICE
import numpy as np

from .architectures import KinematicParameters
from .device import DEFAULT_MOUNT, device_position, fixed_point
from .errors import CalibrationError
from .measurements import FIXED, POSTURE_KINDS, SPHERE

TURN_TOLERANCE_RAD = 1e-9  # mountings closer than this (modulo 2 pi) are the same

WAITING = 'waiting'  # for the machine (actuator readings, a controller on the command topic)
RUNNING = 'running'
PAUSED = 'paused'
ABORTED = 'aborted'
DONE = 'done'
REFUSED = 'refused'  # the plan was refused before anything moved
STATES = (WAITING, RUNNING, PAUSED, ABORTED, DONE, REFUSED)

MOVE, CORRECT, HOLD = 'move', 'correct', 'hold'  # why a command is sent

MIN_MOVE_S = 0.1  # shortest time_from_start of a command (a zero time asks a controller to jump)
MIN_SEGMENT_S = 0.01  # shortest time between two points of a path
SAME_SPHERE = 1e-3  # positions within this fraction of L of the link sphere move along it
HOLD_S = 0.2  # time_from_start of a hold command
POSITION_CHECK_M = 1e-6  # a plan posture's position must be where its kind says, to within this
MIN_WINDOW_READINGS = 3  # readings a still window needs
DEFAULT_OVERHEAD_S = (
    1.0  # ETA before any posture is done: per posture, besides moving and settle_s
)


class PlanRefusedError(CalibrationError, ValueError):
    """The plan has postures the executor will not command; `problems` maps posture index -> why."""

    reason = 'plan-refused'

    def __init__(self, message: str, problems: dict[int, str]):
        super().__init__(message)
        self.problems = dict(problems)


@dataclass(frozen=True)
class ExecutionSettings:
    """The executor's tolerances and limits (SI units)."""

    max_actuator_speed_m_s: float = 0.05
    position_tolerance_m: float = 5e-3
    still_tolerance_m: float = 1e-4
    settle_s: float = 0.5
    timeout_s: float = 60.0
    fixed_tolerance_rad: float = 2e-5
    max_corrections: int = 5
    wait_for_posture: bool = True
    path_step_m: float = 0.02  # 0: one-point commands

    def __post_init__(self) -> None:
        problems = []
        if (
            isinstance(self.path_step_m, bool)
            or not isinstance(self.path_step_m, (int, float))
            or not math.isfinite(self.path_step_m)
            or self.path_step_m < 0
        ):
            problems.append(f'path_step_m must be a finite number >= 0, got {self.path_step_m!r}')
        for name in (
            'max_actuator_speed_m_s',
            'position_tolerance_m',
            'still_tolerance_m',
            'settle_s',
            'timeout_s',
            'fixed_tolerance_rad',
        ):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not math.isfinite(value)
                or value <= 0
            ):
                problems.append(f'{name} must be a positive finite number, got {value!r}')
        if (
            isinstance(self.max_corrections, bool)
            or not isinstance(self.max_corrections, int)
            or self.max_corrections < 0
        ):
            problems.append(
                f'max_corrections must be an integer >= 0, got {self.max_corrections!r}'
            )
        if problems:
            raise ValueError('; '.join(problems))


@dataclass(frozen=True)
class Command:
    """One JointTrajectory: points (n, 6) of actuator positions (model order, m) at times (n,) s
    from its start; the last point is the target."""

    points: np.ndarray
    times: np.ndarray
    purpose: str  # MOVE, CORRECT or HOLD
    posture: int  # plan index (0-based) it serves; -1 for a hold

    @property
    def positions(self) -> np.ndarray:
        """The target: the last point."""
        return self.points[-1]

    @property
    def duration_s(self) -> float:
        return float(self.times[-1])


class PathError(ValueError):
    """A path along the link sphere leaves the nominal workspace or the stroke."""


@dataclass
class PostureOutcome:
    index: int
    kind: str
    measured: bool
    reason: str  # why it was skipped ('' when measured)
    duration_s: float
    move_s: float  # the planned move time of its first command
    corrections: int


def default_stroke(nominal: KinematicParameters) -> tuple[float, float]:
    """The actuator stroke of the nominal model's architecture (its default workspace), m."""
    low, high = nominal.architecture.default_workspace().slider_stroke_m
    return float(low), float(high)


def plan_stroke(metadata: dict, nominal: KinematicParameters) -> tuple[tuple[float, float], str]:
    """The stroke a plan was made within (``hexacal plan`` records its limits in the plan's
    metadata: ``limits.actuator_stroke_m``), else the nominal model's; and which one it is."""
    limits = metadata.get('limits') if isinstance(metadata, dict) else None
    if isinstance(limits, dict) and 'actuator_stroke_m' in limits:
        try:
            return check_stroke(list(limits['actuator_stroke_m'])), "the plan's limits"
        except (TypeError, ValueError):
            pass
    return default_stroke(nominal), f"the {nominal.model}'s default workspace"


def check_stroke(stroke: tuple[float, float] | list[float]) -> tuple[float, float]:
    """(low, high) with low < high, both finite; ValueError naming the problem."""
    values = list(stroke)
    if (
        len(values) != 2
        or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in values
        )
        or values[0] >= values[1]
    ):
        raise ValueError(
            f'stroke limits must be two finite numbers [low, high] with low < high (m), '
            f'got {values!r}'
        )
    return float(values[0]), float(values[1])


def plan_targets(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds,
    stroke: tuple[float, float],
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> tuple[np.ndarray, dict[int, str]]:
    """Nominal actuator targets (N, 6) of every planned pose, and the problem of each posture that
    cannot be commanded (index -> reason; its row is NaN where it has no targets)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    kinds = [str(kind) for kind in kinds]
    low, high = check_stroke(stroke)
    arch = nominal.architecture
    names = nominal.layout.actuator_names
    problems: dict[int, str] = {}
    targets = np.full((len(poses), 6), np.nan)
    finite = np.all(np.isfinite(poses), axis=1)
    for index in np.flatnonzero(~finite):
        problems[int(index)] = 'the pose is not finite'
    if finite.any():
        legs = arch.legs(arch.chains(nominal), np.where(finite[:, None], poses, 0.0))
        reachable = legs.reachable() & finite
        targets[reachable] = legs.sliders[reachable]
        for index in np.flatnonzero(finite & ~reachable):
            problems[int(index)] = (
                f'the nominal machine cannot reach it ({arch.unreachable_reason})'
            )
    point = fixed_point(link_length, mount)
    for index, (pose, kind) in enumerate(zip(poses, kinds)):
        if index in problems:
            continue
        if kind not in POSTURE_KINDS:
            problems[index] = f'kind {kind!r} is not one of {list(POSTURE_KINDS)}'
        elif kind == FIXED and np.linalg.norm(pose[:3] - point) > POSITION_CHECK_M:
            problems[index] = (
                f'a fixed-position posture must be at {point.tolist()} m, got {pose[:3].tolist()}'
            )
        elif kind == SPHERE and abs(np.linalg.norm(pose[:3]) - link_length) > POSITION_CHECK_M:
            problems[index] = (
                f'a sphere posture must be on the link sphere |p| = {link_length:g} m, '
                f'got |p| = {np.linalg.norm(pose[:3]):.9g} m'
            )
        else:
            outside = [
                f'{names[c]} {targets[index, c]:.4f} m'
                for c in range(6)
                if not low <= targets[index, c] <= high
            ]
            if outside:
                problems[index] = f'target outside the stroke [{low:g}, {high:g}] m: ' + ', '.join(
                    outside
                )
    return targets, problems


def path_problems(
    nominal: KinematicParameters,
    poses: np.ndarray,
    stroke: tuple[float, float],
    link_length: float,
    step_m: float,
    skip: set[int] = frozenset(),
    mount: str = DEFAULT_MOUNT,
) -> dict[int, str]:
    """Postures whose path from the previous posture (along the link sphere, directly or by way of
    the centre: `route_command`) cannot be commanded."""
    problems: dict[int, str] = {}
    if step_m <= 0:
        return problems
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    for index in range(1, len(poses)):
        if index in skip or index - 1 in skip:
            continue
        try:
            route_command(
                nominal,
                np.zeros(6),
                poses[index - 1],
                poses[index],
                stroke,
                1.0,
                link_length,
                step_m,
                mount,
            )
        except PathError as error:
            problems[index] = f'the path from posture {index}: {error}'
    return problems


def refusal_message(problems: dict[int, str], total: int, shown: int = 10) -> str:
    """One line naming the refused postures (1-based, as progress counts them) and why."""
    items = sorted(problems.items())
    listed = '; '.join(f'posture {index + 1}: {why}' for index, why in items[:shown])
    more = f'; ... and {len(items) - shown} more' if len(items) > shown else ''
    return (
        f'plan refused before anything moved: {len(items)} of {total} postures cannot be '
        f'commanded (postures {[index + 1 for index, _ in items]}): {listed}{more}'
    )


def check_plan(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds,
    stroke: tuple[float, float],
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    path_step_m: float = 0.0,
) -> np.ndarray:
    """The targets of every posture, or PlanRefusedError listing each one that cannot be commanded
    (with path_step_m > 0, also each whose path from the previous posture cannot)."""
    targets, problems = plan_targets(nominal, poses, kinds, stroke, link_length, mount)
    problems.update(
        path_problems(nominal, poses, stroke, link_length, path_step_m, set(problems), mount)
    )
    if problems:
        raise PlanRefusedError(refusal_message(problems, len(targets)), problems)
    return targets


def move_duration(
    current: np.ndarray, target: np.ndarray, max_speed_m_s: float, minimum_s: float = MIN_MOVE_S
) -> float:
    """time_from_start of a move: the largest actuator move at max_speed_m_s, at least minimum_s."""
    largest = float(
        np.max(np.abs(np.asarray(target, dtype=float) - np.asarray(current, dtype=float)))
    )
    return max(largest / max_speed_m_s, minimum_s)


def interpolate_pose(
    start: np.ndarray, end: np.ndarray, s: float, link_length: float
) -> np.ndarray:
    """The pose a fraction s of the way from start to end: on the link sphere (great circle about
    O) when both positions are on it, else a straight line; Euler angles linear."""
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    p0, p1 = start[:3], end[:3]
    r0, r1 = float(np.linalg.norm(p0)), float(np.linalg.norm(p1))
    on_sphere = max(abs(r0 - link_length), abs(r1 - link_length)) <= SAME_SPHERE * link_length
    angle = (
        math.acos(min(max(float(p0 @ p1) / (r0 * r1), -1.0), 1.0)) if r0 > 0 and r1 > 0 else 0.0
    )
    if on_sphere and 1e-12 < angle < math.pi - 1e-6:
        position = (math.sin((1 - s) * angle) * p0 + math.sin(s * angle) * p1) / math.sin(angle)
        position *= ((1 - s) * r0 + s * r1) / float(np.linalg.norm(position))
    else:
        position = p0 + s * (p1 - p0)
    return np.concatenate([position, start[3:] + s * (end[3:] - start[3:])])


def sphere_path(
    start: np.ndarray, end: np.ndarray, link_length: float, step_m: float
) -> np.ndarray:
    """Poses (n, 6) from start (excluded) to end (included) along the link sphere, at most step_m
    apart in position and step_m / L in each angle; just [end] for step_m = 0."""
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
    purpose: str = 'move',
    posture: int = -1,
) -> Command:
    """The command through `poses` (nominal inverse kinematics) from the actuators at `current`:
    each point timed from its largest actuator move at max_speed_m_s (the whole at least
    MIN_MOVE_S); PathError if a pose is out of the nominal machine's reach or the stroke."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    arch = nominal.architecture
    legs = arch.legs(arch.chains(nominal), poses)
    reachable = legs.reachable()
    if not np.all(reachable):
        raise PathError(
            f'{int(np.sum(~reachable))} of its {len(poses)} points are out of the '
            f"nominal machine's reach ({arch.unreachable_reason})"
        )
    points = legs.sliders
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
    previous = np.concatenate([np.asarray(current, dtype=float)[None], points[:-1]])
    segments = np.maximum(np.max(np.abs(points - previous), axis=1) / max_speed_m_s, MIN_SEGMENT_S)
    times = np.cumsum(segments)
    if times[-1] < MIN_MOVE_S:
        times *= MIN_MOVE_S / times[-1]
    return Command(points.copy(), times, purpose, posture)


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
    purpose: str = 'move',
    posture: int = -1,
) -> Command:
    """The command along the link sphere from pose `start` to `end` (`sphere_path`); if that path
    leaves the stroke or the nominal workspace, by way of the centre (the fixed-position point,
    zero angles: the middle of the workspace); PathError (the direct path's) if neither can be
    commanded."""
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
    """The pose with its position moved radially onto the link sphere (on the mount's side of O)."""
    pose = np.array(pose, dtype=float)
    radius = float(np.linalg.norm(pose[:3]))
    if radius > 0:
        pose[:3] *= link_length / radius
    else:
        pose[:3] = fixed_point(link_length, mount)
    return pose


def fixed_position_correction(
    alpha: float, beta: float, link_length: float, mount: str = DEFAULT_MOUNT
) -> np.ndarray:
    """Platform position change (3,) that brings the inclinometer from (alpha, beta) to zero:
    ``-dp/d(alpha, beta) [alpha, beta]`` with eq. 4's derivative at the reading (first order)."""
    placed = device_position(np.array([alpha]), np.array([beta]), link_length, mount=mount)
    return -placed.d_readings[0] @ np.array([alpha, beta])


def corrected_pose(
    commanded: np.ndarray,
    alpha: float,
    beta: float,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> np.ndarray:
    """The commanded pose with its position corrected for the inclinometer reading (orientation kept)."""
    pose = np.array(commanded, dtype=float)
    pose[:3] += fixed_position_correction(alpha, beta, link_length, mount)
    return pose


def same_turn(a: float, b: float) -> bool:
    """Whether two device turns (rad) are the same mounting (modulo 2 pi)."""
    difference = math.remainder(float(a) - float(b), 2.0 * math.pi)
    return abs(difference) <= TURN_TOLERANCE_RAD


def check_turns(turns, total: int) -> np.ndarray:
    """The plan's per-posture device turns as (total,) floats (None: all 0); ValueError if not one
    finite angle per posture."""
    if turns is None:
        return np.zeros(total)
    values = np.asarray(turns, dtype=float).reshape(-1)
    if values.shape != (total,) or not np.all(np.isfinite(values)):
        raise ValueError(
            f'device turns: one finite angle (rad) per posture ({total}), got {turns!r}'
        )
    return values


def turn_text(turn: float) -> str:
    """'180 deg (3.14159 rad)'."""
    return f'{math.degrees(turn):.4g} deg ({turn:.6g} rad)'


def joint_positions(names, positions, wanted) -> np.ndarray | None:
    """Positions of the `wanted` joints, in that order, from a JointState's names/positions
    (None if one is missing, repeated or not finite)."""
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in index and name in wanted:
            return None
        index[name] = i
    try:
        values = np.array([float(positions[index[name]]) for name in wanted])
    except (KeyError, IndexError, TypeError, ValueError):
        return None
    return values if np.all(np.isfinite(values)) else None


class ReadingWindow:
    """Recent (time s, values) readings, oldest first, kept for `keep_s`."""

    def __init__(self, keep_s: float):
        self.keep_s = float(keep_s)
        self._times: deque[float] = deque()
        self._values: deque[np.ndarray] = deque()

    def add(self, now: float, values: np.ndarray) -> None:
        self._times.append(float(now))
        self._values.append(np.asarray(values, dtype=float))
        while self._times and self._times[0] < now - self.keep_s:
            self._times.popleft()
            self._values.popleft()

    @property
    def latest(self) -> np.ndarray | None:
        return self._values[-1] if self._values else None

    def between(self, start: float, end: float) -> np.ndarray:
        """Readings received in [start, end], (n, channels)."""
        chosen = [v for t, v in zip(self._times, self._values) if start <= t <= end]
        return np.array(chosen) if chosen else np.empty((0, 0))


class PlanExecution:
    """The executor's state machine: feed it readings, postures and time; send its commands."""

    def __init__(
        self,
        nominal: KinematicParameters,
        poses: np.ndarray,
        kinds,
        targets: np.ndarray,
        settings: ExecutionSettings,
        stroke: tuple[float, float],
        link_length: float,
        mount: str = DEFAULT_MOUNT,
        start_paused: bool = False,
        device_turns=None,
        mounted_turn: float = 0.0,
    ):
        """device_turns: the plan's turn of each posture (rad; None: every posture in the normal
        mounting); mounted_turn: the mounting the device is in at the start (rad)."""
        self.nominal = nominal
        self.poses = np.atleast_2d(np.asarray(poses, dtype=float))
        self.kinds = [str(kind) for kind in kinds]
        self.targets = np.asarray(targets, dtype=float)
        self.settings = settings
        self.stroke = check_stroke(stroke)
        self.link_length = float(link_length)
        self.mount = mount
        self.turns = check_turns(device_turns, len(self.poses))
        if isinstance(mounted_turn, bool) or not math.isfinite(float(mounted_turn)):
            raise ValueError(f'mounted_turn must be a finite angle (rad), got {mounted_turn!r}')
        self.mounted_turn = float(mounted_turn)  # the mounting the device is in (rad)
        self.turn_needed: float | None = None  # while paused for the operator to turn the device
        self.turn_notice = ''  # what the operator is asked to do (while turn_needed is set)
        self.state = WAITING
        self.start_paused = bool(start_paused)
        self.index = 0  # current posture
        self.outcomes: list[PostureOutcome] = []
        keep = 4.0 * settings.settle_s + 2.0
        self.actuators = ReadingWindow(keep)
        self.inclinometer = ReadingWindow(keep)
        self.messages: list[tuple[str, str]] = []  # (level, text) for the node to log
        self.total_corrections = 0
        self.started_at: float | None = None
        self.finished_at: float | None = None
        self._paused_total = 0.0
        self._paused_at: float | None = None
        self._phase: str | None = (
            None  # 'moving' (arriving) or 'posture' (waiting for the collector)
        )
        self._pose_cmd = np.zeros(6)
        self._target = np.zeros(6)
        self._corrections = 0
        self._posture_start = 0.0
        self._first_move_s = 0.0
        self._command_time = 0.0
        self._arrive_after = 0.0
        self._still_mean: np.ndarray | None = None
        self._postures: list[
            tuple[float, np.ndarray]
        ] = []  # (received, actuators) since the last command
        self._sent_any = False
        self._where: np.ndarray | None = None  # the pose the last move went to
        self._at_where = (
            False  # the machine stood still there since (so the next path starts there)
        )
        self.refusal = ''  # why the plan was refused (state REFUSED)

    # ------------------------------------------------------------------ inputs

    def on_actuators(self, now: float, positions: np.ndarray) -> None:
        self.actuators.add(now, positions)

    def on_inclinometer(self, now: float, alpha: float, beta: float) -> None:
        self.inclinometer.add(now, np.array([alpha, beta]))

    def on_posture(self, now: float, actuators: np.ndarray) -> None:
        if self.state in (RUNNING, PAUSED) and self._phase is not None:
            self._postures.append((now, np.asarray(actuators, dtype=float)))

    # ------------------------------------------------------------------ control

    @property
    def total(self) -> int:
        return len(self.poses)

    @property
    def measured(self) -> int:
        return sum(outcome.measured for outcome in self.outcomes)

    @property
    def skipped(self) -> list[PostureOutcome]:
        return [outcome for outcome in self.outcomes if not outcome.measured]

    def start(self, now: float) -> list[Command]:
        """The machine is there (readings arrive, a controller listens): begin, or wait paused."""
        if self.state != WAITING or self.actuators.latest is None:
            return []
        self.started_at = now
        if self.start_paused:
            self.state = PAUSED
            self._paused_at = now
            self._say('info', f'ready to walk {self.total} postures; paused until resumed')
            return []
        self.state = RUNNING
        return self._begin(now, fresh=True)

    def pause(self, now: float) -> tuple[bool, str, list[Command]]:
        if self.state == WAITING:
            self.start_paused = True
            return True, 'paused: the plan will not start until resumed', []
        if self.state == PAUSED:
            if self.turn_needed is not None:
                return (
                    True,
                    (
                        f'already paused at posture {self.index + 1} of {self.total}: '
                        f'{self.turn_notice}'
                    ),
                    [],
                )
            return True, f'already paused at posture {self.index + 1} of {self.total}', []
        if self.state != RUNNING:
            return False, f'cannot pause: the executor is {self.state}', []
        self.state = PAUSED
        self._paused_at = now
        self._phase = None
        text = (
            f'paused at posture {self.index + 1} of {self.total}: holding; resume restarts '
            'this posture'
        )
        self._say('info', text)
        return True, text, self._hold()

    def resume(self, now: float) -> tuple[bool, str, list[Command]]:
        if self.state == WAITING:
            self.start_paused = False
            return True, 'resumed: the plan starts when the machine is ready', []
        if self.state != PAUSED:
            return False, f'cannot resume: the executor is {self.state}', []
        if self._paused_at is not None:
            self._paused_total += now - self._paused_at
            self._paused_at = None
        self.state = RUNNING
        fresh = not self._sent_any
        text = f'resumed at posture {self.index + 1} of {self.total}'
        if self.turn_needed is not None:  # the operator turned the device: begin the posture
            previous, self.mounted_turn = self.mounted_turn, self.turn_needed
            self.turn_needed, self.turn_notice, fresh = None, '', True
            text += (
                f' with the device turned to {turn_text(self.mounted_turn)} about its link '
                f'axis (was {turn_text(previous)})'
            )
        self._say('info', text)
        return True, text, self._begin(now, fresh=fresh)

    def abort(self, now: float) -> tuple[bool, str, list[Command]]:
        if self.state in (ABORTED, DONE, REFUSED):
            return False, f'cannot abort: the executor is already {self.state}', []
        was = self.state
        if self._paused_at is not None:
            self._paused_total += now - self._paused_at
            self._paused_at = None
        self.state = ABORTED
        self.finished_at = now
        self._phase = None
        self.turn_needed, self.turn_notice = None, ''
        text = (
            f'aborted at posture {self.index + 1} of {self.total} ({self.measured} measured, '
            f'{len(self.skipped)} skipped)'
        )
        self._say('warn', text)
        return True, text, self._hold() if was == RUNNING else []

    def step(self, now: float) -> list[Command]:
        """Advance on the readings so far; the commands to publish now."""
        if self.state != RUNNING or self._phase is None:
            return []
        settings = self.settings
        if now - self._posture_start > settings.timeout_s:
            return self._skip(now, self._timeout_reason(now))
        if self._phase == 'moving':
            still = self._still_mean_at(now)
            if still is None:
                return []
            if self.kinds[self.index] == FIXED:
                angles = self._mean_angles(now)
                if angles is None:
                    return []
                alpha, beta = angles
                if max(abs(alpha), abs(beta)) > settings.fixed_tolerance_rad:
                    return self._correct(now, alpha, beta)
            self._still_mean = still
            self._phase = 'posture'
        if self._phase == 'posture':
            if not settings.wait_for_posture or self._posture_matched():
                return self._complete(now)
        return []

    # ------------------------------------------------------------------ progress

    def eta_s(self, now: float) -> float | None:
        """Seconds until the plan is done at the pace so far (None when not running or paused)."""
        if self.state not in (RUNNING, PAUSED, WAITING):
            return None
        done = [o for o in self.outcomes if o.measured]
        overhead = (
            float(np.mean([o.duration_s - o.move_s for o in done]))
            if done
            else self.settings.settle_s + DEFAULT_OVERHEAD_S
        )
        remaining = 0.0
        previous = self.actuators.latest if self.actuators.latest is not None else self.targets[0]
        for index in range(self.index, self.total):
            remaining += move_duration(
                previous, self.targets[index], self.settings.max_actuator_speed_m_s
            ) + max(overhead, 0.0)
            previous = self.targets[index]
        if self.state == RUNNING and self._phase is not None:
            remaining -= min(now - self._posture_start, remaining)
        return max(remaining, 0.0)

    def progress(self, now: float) -> dict[str, object]:
        """The status fields: state, posture k of K, measured, skipped (which and why), ETA."""
        current = min(self.index + 1, self.total)
        values: dict[str, object] = {
            'state': self.state,
            'posture': current if self.state != DONE else self.total,
            'postures': self.total,
            'measured': self.measured,
            'skipped': len(self.skipped),
            'corrections': self.total_corrections,
        }
        if self.skipped:
            values['skipped_postures'] = '; '.join(
                f'{o.index + 1}: {o.reason}' for o in self.skipped
            )
        if self.state in (RUNNING, PAUSED) and self.index < self.total:
            values['kind'] = self.kinds[self.index]
        if self.total:
            values['device_turn_rad'] = float(self.turns[min(self.index, self.total - 1)])
        if self.turn_needed is not None:
            values['device_turn_needed_rad'] = self.turn_needed
        eta = self.eta_s(now)
        if eta is not None:
            values['eta_s'] = round(eta, 1)
        if self.started_at is not None:
            end = self.finished_at if self.finished_at is not None else now
            values['elapsed_s'] = round(end - self.started_at, 1)
            paused = self._paused_total + (
                now - self._paused_at if self._paused_at is not None else 0.0
            )
            if paused > 0:
                values['paused_s'] = round(paused, 1)
        return values

    def summary(self) -> str:
        return (
            f'{self.measured} of {self.total} postures measured, {len(self.skipped)} skipped'
            + (
                f' ({"; ".join(f"{o.index + 1}: {o.reason}" for o in self.skipped)})'
                if self.skipped
                else ''
            )
        )

    # ------------------------------------------------------------------ internals

    def _say(self, level: str, text: str) -> None:
        self.messages.append((level, text))

    def _hold(self) -> list[Command]:
        latest = self.actuators.latest
        self._at_where = False
        if latest is None or not self._sent_any:
            return []
        return [Command(latest.copy()[None], np.array([HOLD_S]), HOLD, -1)]

    def _begin(self, now: float, fresh: bool) -> list[Command]:
        """Command the current posture (fresh: from its planned pose; else resume its corrections)."""
        while True:
            if self.index >= self.total:
                return self._finish(now)
            if fresh and not same_turn(self.turns[self.index], self.mounted_turn):
                return self._wait_for_turn(now)
            if fresh:
                self._pose_cmd = self.poses[self.index].copy()
                self._target = self.targets[self.index].copy()
                self._corrections = 0
            self._posture_start = now
            try:
                command = self._command(now, MOVE)
            except PathError as error:
                if not self._sent_any:  # nothing has moved yet: the plan is refused
                    self.state = REFUSED
                    self.finished_at = now
                    self._phase = None
                    self.refusal = (
                        f'plan refused before anything moved: the path from where the '
                        f'machine stands to posture {self.index + 1}: {error}'
                    )
                    self._say('error', self.refusal)
                    return []
                self._record(now, False, f'its path cannot be commanded: {error}')
                self._say(
                    'warn',
                    f'posture {self.index + 1} of {self.total} skipped: its path '
                    f'cannot be commanded: {error}',
                )
                self.index += 1
                fresh = True
                continue
            self._first_move_s = command.duration_s
            return [command]

    @property
    def waiting_for_turn(self) -> bool:
        """Paused before a posture until the operator has turned the device (turn_needed)."""
        return self.state == PAUSED and self.turn_needed is not None

    def _wait_for_turn(self, now: float) -> list[Command]:
        """Pause before the current posture until the operator has turned the device."""
        turn = float(self.turns[self.index])
        self.turn_needed = turn
        self.state = PAUSED
        self._paused_at = now
        self._phase = None
        self.turn_notice = (
            f'posture {self.index + 1} of {self.total} needs the device turned to '
            f'{turn_text(turn)} about its link axis (it is at {turn_text(self.mounted_turn)}): '
            f'turn the device to {math.degrees(turn):.4g} deg about its link axis, then call '
            f'{RESUME_SERVICE}'
        )
        self._say('warn', self.turn_notice)
        return self._hold()

    def _command(self, now: float, purpose: str) -> Command:
        """The command to the current commanded pose: along the link sphere from where the machine
        is (MOVE), or one point (CORRECT: a small correction from a standstill); PathError."""
        current = self.actuators.latest if self.actuators.latest is not None else self._target
        step = self.settings.path_step_m
        start = None
        if purpose != CORRECT and step > 0:
            start = self._where if self._at_where else self._estimate()
        if start is None:
            command = path_command(
                self.nominal,
                current,
                self._pose_cmd[None],
                self.stroke,
                self.settings.max_actuator_speed_m_s,
                purpose,
                self.index,
            )
        else:
            command = route_command(
                self.nominal,
                current,
                start,
                self._pose_cmd,
                self.stroke,
                self.settings.max_actuator_speed_m_s,
                self.link_length,
                step,
                self.mount,
                purpose,
                self.index,
            )
        self._target = command.positions.copy()
        self._where, self._at_where = self._pose_cmd.copy(), False
        self._command_time = now
        self._arrive_after = now + command.duration_s
        self._phase = 'moving'
        self._postures = []
        self._still_mean = None
        self._sent_any = True
        return command

    def _estimate(self) -> np.ndarray | None:
        """Where the platform stands, by nominal forward kinematics of the measured actuators
        (moved onto the link sphere); None (one-point command) if that fails."""
        from .kinematics import forward_kinematics

        latest = self.actuators.latest
        if latest is None:
            return None
        guesses = [
            pose
            for pose in (
                self._where,
                self.poses[min(self.index, self.total - 1)],
                np.concatenate([fixed_point(self.link_length, self.mount), np.zeros(3)]),
            )
            if pose is not None
        ]
        found = forward_kinematics(
            self.nominal, np.tile(latest, (len(guesses), 1)), np.array(guesses)
        )
        for pose, converged in zip(found.poses, found.converged):
            if converged:
                return on_sphere(pose, self.link_length, self.mount)
        self._say(
            'warn',
            'cannot tell where the platform stands (nominal forward kinematics of '
            'the measured actuators failed): one-point command',
        )
        return None

    def _still_mean_at(self, now: float) -> np.ndarray | None:
        settle = self.settings.settle_s
        if now < self._arrive_after + settle:
            return None
        window = self.actuators.between(now - settle, now)
        if len(window) < MIN_WINDOW_READINGS:
            return None
        if float(np.max(np.ptp(window, axis=0))) > self.settings.still_tolerance_m:
            return None
        mean = window.mean(axis=0)
        if float(np.max(np.abs(mean - self._target))) > self.settings.position_tolerance_m:
            return None
        return mean

    def _mean_angles(self, now: float) -> tuple[float, float] | None:
        window = self.inclinometer.between(
            max(now - self.settings.settle_s, self._arrive_after), now
        )
        if len(window) < MIN_WINDOW_READINGS:
            return None
        alpha, beta = window.mean(axis=0)
        return float(alpha), float(beta)

    def _posture_matched(self) -> bool:
        if self._still_mean is None:
            return False
        tolerance = self.settings.still_tolerance_m
        return any(
            float(np.max(np.abs(actuators - self._still_mean))) <= tolerance
            for _, actuators in self._postures
        )

    def _correct(self, now: float, alpha: float, beta: float) -> list[Command]:
        index = self.index
        if self._corrections >= self.settings.max_corrections:
            return self._skip(
                now,
                (
                    f'fixed position not reached after {self._corrections} corrections (inclinometer '
                    f'{alpha:.3g}, {beta:.3g} rad; tolerance {self.settings.fixed_tolerance_rad:g} rad)'
                ),
            )
        previous = self._pose_cmd
        self._pose_cmd = corrected_pose(previous, alpha, beta, self.link_length, self.mount)
        try:
            command = self._command(now, CORRECT)
        except PathError as error:
            self._pose_cmd = previous
            return self._skip(now, f'the fixed-position correction cannot be commanded: {error}')
        self._corrections += 1
        self.total_corrections += 1
        moved = np.linalg.norm(self._pose_cmd[:3] - previous[:3])
        self._say(
            'info',
            f'posture {index + 1}: inclinometer {alpha:.3g}, {beta:.3g} rad; correction '
            f'{self._corrections} moves the platform by {moved * 1e6:.0f} um',
        )
        return [command]

    def _timeout_reason(self, now: float) -> str:
        timeout = self.settings.timeout_s
        if self._phase == 'posture':
            return f'no posture from the collector within {timeout:g} s'
        latest = self.actuators.latest
        if latest is None or self.actuators.between(now - self.settings.settle_s, now).size == 0:
            return f'no actuator readings (timeout {timeout:g} s)'
        away = float(np.max(np.abs(latest - self._target)))
        if (
            self.kinds[self.index] == FIXED
            and away <= self.settings.position_tolerance_m
            and self._corrections
        ):
            return (
                f'fixed position not reached within {timeout:g} s '
                f'({self._corrections} corrections)'
            )
        return (
            f'not at the target and still within {timeout:g} s (actuators up to '
            f'{away * 1e3:.3f} mm from it)'
        )

    def _skip(self, now: float, reason: str) -> list[Command]:
        self._record(now, False, reason)
        self._say(
            'warn',
            f'posture {self.index + 1} of {self.total} ({self.kinds[self.index]}) '
            f'skipped: {reason}',
        )
        return self._advance(now)

    def _complete(self, now: float) -> list[Command]:
        self._at_where = True  # it stood still at the commanded pose: the next path starts there
        self._record(now, True, '')
        corrections = f', {self._corrections} corrections' if self._corrections else ''
        self._say(
            'info',
            f'posture {self.index + 1} of {self.total} ({self.kinds[self.index]}) '
            f'measured in {now - self._posture_start:.1f} s{corrections}',
        )
        return self._advance(now)

    def _record(self, now: float, measured: bool, reason: str) -> None:
        self.outcomes.append(
            PostureOutcome(
                self.index,
                self.kinds[self.index],
                measured,
                reason,
                now - self._posture_start,
                self._first_move_s,
                self._corrections,
            )
        )

    def _advance(self, now: float) -> list[Command]:
        self.index += 1
        self._phase = None
        self._corrections = 0
        return self._begin(now, fresh=True)

    def _finish(self, now: float) -> list[Command]:
        self.state = DONE
        self.finished_at = now
        self._phase = None
        self.index = self.total
        elapsed = now - (self.started_at or now)
        self._say('info', f'plan done in {elapsed:.1f} s: {self.summary()}')
        return []
