"""
Walking a posture plan on a machine through its trajectory controller (ROS-free).

The executor node (nodes/executor.py) feeds `PlanExecution` what it hears and
publishes what it answers; everything that decides is here, unit-tested
without ROS (its states and settings: core/walk/settings.py).  The plan was
checked before (core/planning/plan_check.py); the moves are core/walk/platform_paths.py's.  For
each posture:

1. Move: one command to the nominal targets, with intermediate points along
   the link sphere when ``path_step_m`` > 0 (core/walk/platform_paths.py), each timed at
   ``max_actuator_speed_m_s``; the first path, from where the machine stands
   (core/walk/standing.py), is checked when it starts (it cannot be commanded: the plan is
   refused).  It starts where the drive's setpoints are, their offset fading over the move.
2. Arrive: at the target and still over the last ``settle_s`` (core/walk/arrival.py).
3. Fixed-position postures (eq. 10) are reached in closed loop: once the inclinometer has
   settled after the move (core/walk/arrival.py, core/walk_device/inclinometer.py), the commanded
   pose's position is moved by ``-dp/d(alpha, beta) [alpha, beta]`` (`corrected_pose`; from
   the second correction on, the change asked for is scaled by how the machine answered the
   earlier ones: core/walk/correction_response.py) and
   new targets come from the nominal inverse kinematics, until both angles are within
   ``fixed_tolerance_rad``; after ``max_corrections`` the posture is skipped and reported.
   Intermediate stops are valid sphere postures if the collector measures them.
4. Measured: the collector's posture of this stop.  Then the next posture.

A posture not done within ``timeout_s`` of its first command is skipped and
reported with what was missing. Pause holds the machine (a move under way ends at
its target, else a one-point command at the drive's setpoints) and restarts the
current posture on resume (its timeout too); abort holds it and ends the plan.

Refined targets (core/walk_refine/refined_targets.py): when the postures measured reach a count of
``refine_at``, the walk stops at rest before the next posture (phase REFINING,
``refine_request``); `on_refined` with the intermediate model re-targets the remaining
postures (targets, paths, corrections and the guard on that model), without one the targets
stay; then the posture is commanded.

Turning the device (core/walk_device/turns.py): before a posture whose turn differs from the
mounting the device is in (``mounted_turn``, modulo 2 pi) the walk pauses itself, holding,
with a ``turn_notice`` naming the posture, the turn and what to do; resume() records the new
mounting and begins the posture from its planned pose.  A posture skipped after the turn does
not undo it.

Releasing an actuator (measuring_mode ``passive_actuator``): core/walk/release_choice.py.

The guard (core/walk/guard.py): with ``guard`` given, every move and correction
is predicted on the model before it is sent; one that would cross a limit is not
sent: the plan pauses (holding) with the prediction in ``notice``.  A drive
fault (`on_drive_fault`) or a measured LVDT length beyond its stroke less the
margin (`on_link`) pauses it too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
import math
from typing import TYPE_CHECKING

from hexacal_msgs_py.names import EXECUTOR_RESUME_SERVICE as RESUME_SERVICE
import numpy as np

from .arrival import correct_fixed_position, judged_angles, posture_matched, still_mean
from .arrival import timeout_reason
from .correction_response import CorrectionResponse
from .messages import LogLevel, Messages, ReadingWindow
from .platform_paths import Command, CommandPurpose, eased_command
from .platform_paths import path_command, PathError, route_command, setpoints_at
from .progress import eta_s, progress, summary, UNDER_WAY
from .release_choice import check_release_here, choose_first_release, hear_release
from .release_choice import rechoose_release
from .release_choice import ReleaseRequest
from .settings import ExecutionSettings, ExecutionState, GuardStop, Phase, PostureOutcome
from .standing import blend_from_setpoints, estimate_pose
from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT, device_position, fixed_point
from ..machine.kinematics import measured_pose
from ..machine.measurements import FIXED
from ..planning.plan_check import check_stroke
from ..walk_device.inclinometer import InclinometerJudgement
from ..walk_device.turns import check_turns, same_turn, turn_text
from ..walk_refine.refined_targets import refined_targets, targets_model_label

if TYPE_CHECKING:
    from ..modes.link_load import LinkLoad

# The guard: (current actuators, start pose, command points, released chain) -> problem ('': ok).
Guard = Callable[[np.ndarray, np.ndarray, np.ndarray, int | None], str]
HOLD_S = 0.2  # time_from_start of a hold command
# An inclinometer reading this much older than the actuators' is not where the platform is now.
STALE_READING_S = 1.0


class PlanExecution:
    """The executor's state machine: feed it readings, postures and time; send its commands."""

    def __init__(
        self,
        nominal: KinematicParameters,
        poses: np.ndarray,
        kinds: Iterable[str],
        targets: np.ndarray,
        settings: ExecutionSettings,
        stroke: tuple[float, float],
        link_length: float,
        mount: str = DEFAULT_MOUNT,
        start_paused: bool = False,
        device_turns: Iterable[float] | None = None,
        mounted_turn: float = 0.0,
        released: Sequence[int | None] | None = None,
        guard: Guard | None = None,
        refine_at: Sequence[int] = (),
        link_load: LinkLoad | None = None,
    ):
        """
        Walk `poses` (their nominal `targets` from core/planning/plan_check.py) on `nominal`.

        device_turns: the plan's turn of each posture (rad; None: every posture
        in the normal mounting); mounted_turn: the mounting the device is in at
        the start (rad); released: the chain released at each posture
        (None: all six commanded, the compliant and lvdt modes); refine_at: the measured-posture
        counts at which the walk stops at rest for an intermediate calibration
        (core/walk_refine/refined_targets.py; the node answers with `on_refined`); link_load:
        passive_actuator, the weights and the link's limit the releases chosen again at the
        machine keep within (release_choice.py; None: the link's load is not weighed).
        """
        self.nominal = nominal
        self.poses = np.atleast_2d(np.asarray(poses, dtype=float))
        self.kinds = [str(kind) for kind in kinds]
        self.targets = np.array(targets, dtype=float)  # the remaining ones may be refined
        self.settings = settings
        self.stroke = check_stroke(stroke)
        self.link_length = float(link_length)
        self.mount = mount
        self.link_load = link_load
        self.turns = check_turns(device_turns, len(self.poses))
        if isinstance(mounted_turn, bool) or not math.isfinite(float(mounted_turn)):
            raise ValueError(f'mounted_turn must be a finite angle (rad), got {mounted_turn!r}')
        self.mounted_turn = float(mounted_turn)  # the mounting the device is in (rad)
        self.turn_needed: float | None = None  # while paused for the operator to turn the device
        self.turn_notice = ''  # what the operator is asked to do (while turn_needed is set)
        self.state = ExecutionState.WAITING
        self.start_paused = bool(start_paused)
        self.index = 0  # current posture
        self.outcomes: list[PostureOutcome] = []
        keep = 4.0 * max(settings.settle_s, 2.0 * settings.inclinometer_settle_s) + 2.0
        self.actuators = ReadingWindow(keep)
        self.inclinometer = ReadingWindow(keep)
        self.messages: Messages = []  # for the node to log
        self.total_corrections = 0
        self.started_at: float | None = None
        self.finished_at: float | None = None
        self._paused_total = 0.0
        self._paused_at: float | None = None
        self._phase: Phase | None = None  # None: not commanding (waiting, paused, over)
        self._pose_cmd = np.zeros(6)
        self._target = np.zeros(6)
        self._new_corrections()
        self.posture_start = 0.0
        self._first_move_s = 0.0
        self._arrive_after = 0.0
        self._still_mean: np.ndarray | None = None
        self._posture_before = False  # see _command
        # The inclinometer since the last command (fixed positions; None: not judged yet).
        self.inclinometer_judgement: InclinometerJudgement | None = None
        # (received, actuators) since the last command
        self._postures: list[tuple[float, np.ndarray]] = []
        self._sent_any = False
        # The drive's setpoints as the executor knows them (None: unknown, the measured
        # actuators stand for them): the last command's end, a locked chain where it stood.
        self._setpoints: np.ndarray | None = None
        # The last command: (sent at, the setpoints it started from, it) for a hold mid-move.
        self._in_flight: tuple[float, np.ndarray, Command] | None = None
        self._where: np.ndarray | None = None  # the pose the last move went to
        self._at_where = False  # it stood still there since (so the next path starts there)
        self.refusal = ''  # why the plan was refused (state REFUSED)
        self.released: list[int | None] = (
            [None] * len(self.poses) if released is None else list(released)
        )
        if len(self.released) != len(self.poses):
            raise ValueError(
                f'released names {len(self.released)} chains for {len(self.poses)} postures'
            )
        self.released_now: int | None = None  # the chain the drive has released
        # Per posture, the chains released when the drive faulted on the way to it.
        self._faulted_releases: dict[int, set[int]] = {}
        self.release_request: ReleaseRequest | None = None  # for the node to carry out
        self.notice = ''  # why the plan paused itself (a drive's refusal); '' otherwise
        self.guard = guard
        self.refine_at = sorted(int(count) for count in refine_at)
        self.refine_request: int | None = None  # measured postures to calibrate (for the node)
        self.targets_model = targets_model_label(None)
        self.refine_message = ''  # what the last intermediate calibration did

    # ------------------------------------------------------------------ inputs

    def on_actuators(self, now: float, positions: np.ndarray) -> None:
        """Hear the measured actuator positions (model order, m) at `now` (s)."""
        self.actuators.add(now, positions)

    def on_inclinometer(self, now: float, alpha: float, beta: float) -> None:
        """Hear the inclinometer angles (rad) at `now` (s)."""
        self.inclinometer.add(now, np.array([alpha, beta]))

    def on_posture(self, now: float, actuators: np.ndarray) -> None:
        """Hear a posture the collector measured (its actuators, m) at `now` (s)."""
        if self.state in UNDER_WAY and self._phase is not None:
            self._postures.append((now, np.asarray(actuators, dtype=float)))

    def on_drive_released(self, released: int | None) -> None:
        """Hear which chain the drive has released (its status) before the plan starts."""
        if self.state == ExecutionState.WAITING and self.release_request is None:
            self.released_now = released

    def on_release(self, now: float, released: int | None, problem: str) -> list[Command]:
        """
        Hear the drive's answer to `release_request`: the chain released now, what went wrong.

        problem '': done, the posture is commanded; else the plan pauses (holding) with
        `problem` in ``notice`` until resumed (release_choice.py).
        """
        return hear_release(self, now, released, problem)

    def on_drive_fault(self, now: float, fault: str) -> list[Command]:
        """Hear the drive's fault: pause (the drive holds itself; resume once it is reset)."""
        if self.state != ExecutionState.RUNNING:
            return []
        self._setpoints = None  # the drive holds, and a reset re-enables it where it stands
        self._in_flight = None
        # Released then (a jam of the five commanded and the link): not for the rest of the move.
        if self.released_now is not None:
            self._faulted_releases.setdefault(self.index, set()).add(self.released_now)
        return self._stop(
            now,
            f'the drive faulted: {fault}; reset the drive (hexacal/driver/reset) and resume',
            hold=False,
        )

    def on_link(self, now: float, extension: float, limit: float) -> list[Command]:
        """Hear the LVDT link's extension (m): beyond `limit` the plan pauses, holding."""
        if self.state != ExecutionState.RUNNING or abs(extension) <= limit:
            return []
        return self._stop(
            now,
            f'posture {self.index + 1} of {self.total}: the LVDT link measures '
            f'{extension * 1e3:+.3f} mm, beyond +-{limit * 1e3:g} mm (its stroke less the margin)',
        )

    def _stop(self, now: float, text: str, hold: bool = True) -> list[Command]:
        """Pause the plan by itself with `text` in ``notice`` (holding unless told not to)."""
        self.state = ExecutionState.PAUSED
        self._paused_at = now
        self._phase = None
        self.notice = f'{text}; paused: call {RESUME_SERVICE} once safe'
        self._say(LogLevel.ERROR, self.notice)
        return self._hold(now) if hold else []

    def _ask_refinement(self) -> list[Command]:
        """Stop at rest before the current posture for an intermediate calibration."""
        while self.refine_at and self.measured >= self.refine_at[0]:
            self.refine_at.pop(0)
        self.refine_request = self.measured
        self._phase = Phase.REFINING
        return []

    def on_refined(
        self,
        now: float,
        model: KinematicParameters | None,
        message: str = '',
        guard: Guard | None = None,
    ) -> list[Command]:
        """
        Hear the intermediate calibration asked by `refine_request` (None: the targets stay).

        With a model, the remaining postures' targets, paths, corrections and (`guard`, built
        on the model) predictions come from it; then the current posture is commanded.
        """
        postures, self.refine_request = self.refine_request, None
        self.refine_message = message
        if model is not None and postures is not None:
            self.nominal = model
            self.targets[self.index:] = refined_targets(model, self.poses[self.index:])
            self.guard = guard if guard is not None else self.guard
            self.targets_model = targets_model_label(postures)
            self._say(
                LogLevel.INFO,
                f'targets of postures {self.index + 1}-{self.total} from the '
                f'{self.targets_model}',
            )
        if self._phase != Phase.REFINING or self.state != ExecutionState.RUNNING:
            return []  # paused or aborted meanwhile: resume begins the posture
        return self._begin(now, fresh=True)

    # ------------------------------------------------------------------ control

    @property
    def total(self) -> int:
        """Return the number of postures of the plan."""
        return len(self.poses)

    @property
    def measured(self) -> int:
        """Return the number of postures measured so far."""
        return sum(outcome.measured for outcome in self.outcomes)

    @property
    def skipped(self) -> list[PostureOutcome]:
        """Return the outcomes of the postures skipped so far."""
        return [outcome for outcome in self.outcomes if not outcome.measured]

    def start(self, now: float) -> list[Command]:
        """Begin now the machine is there (readings, a controller), or wait paused."""
        if self.state != ExecutionState.WAITING or self.actuators.latest is None:
            return []
        self.started_at = now
        if self.start_paused:
            self.state = ExecutionState.PAUSED
            self._paused_at = now
            self._say(LogLevel.INFO, f'ready to walk {self.total} postures; paused until resumed')
            return []
        self.state = ExecutionState.RUNNING
        choose_first_release(self)
        return self._begin(now, fresh=True)

    def pause(self, now: float) -> tuple[bool, str, list[Command]]:
        """Pause (hold the machine): (success, the service's answer, commands to send)."""
        if self.state == ExecutionState.WAITING:
            self.start_paused = True
            return True, 'paused: the plan will not start until resumed', []
        if self.state == ExecutionState.PAUSED:
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
        if self.state != ExecutionState.RUNNING:
            return False, f'cannot pause: the executor is {self.state}', []
        self.state = ExecutionState.PAUSED
        self._paused_at = now
        self._phase = None
        left = self._move_left_s(now)
        holding = f'the move under way ends at its target in {left:.2g} s, then ' if left else ''
        text = (
            f'paused at posture {self.index + 1} of {self.total}: {holding}holding; resume '
            'restarts this posture'
        )
        self._say(LogLevel.INFO, text)
        return True, text, [] if left else self._hold(now)

    def resume(self, now: float) -> tuple[bool, str, list[Command]]:
        """Resume (after a turn: in the new mounting): (success, answer, commands)."""
        if self.state == ExecutionState.WAITING:
            self.start_paused = False
            return True, 'resumed: the plan starts when the machine is ready', []
        if self.state != ExecutionState.PAUSED:
            return False, f'cannot resume: the executor is {self.state}', []
        if self._paused_at is not None:
            self._paused_total += now - self._paused_at
            self._paused_at = None
        self.state = ExecutionState.RUNNING
        self.notice = ''
        fresh = not self._sent_any
        text = f'resumed at posture {self.index + 1} of {self.total}'
        if self.turn_needed is not None:  # the operator turned the device: begin the posture
            previous, self.mounted_turn = self.mounted_turn, self.turn_needed
            self.turn_needed, self.turn_notice, fresh = None, '', True
            text += (
                f' with the device turned to {turn_text(self.mounted_turn)} about its link '
                f'axis (was {turn_text(previous)})'
            )
        self._say(LogLevel.INFO, text)
        if self._move_left_s(now) and self.turn_needed is None and not fresh:
            # Paused and resumed within a move: it went on meanwhile (_move_left_s), and goes on.
            self._phase, self.posture_start = Phase.MOVING, now
            return True, text, []
        rechoose_release(self)
        return True, text, self._begin(now, fresh=fresh)

    def abort(self, now: float) -> tuple[bool, str, list[Command]]:
        """End the plan (hold the machine): (success, answer, commands)."""
        if self.state in (ExecutionState.ABORTED, ExecutionState.DONE, ExecutionState.REFUSED):
            return False, f'cannot abort: the executor is already {self.state}', []
        was = self.state
        if self._paused_at is not None:
            self._paused_total += now - self._paused_at
            self._paused_at = None
        self.state = ExecutionState.ABORTED
        self.finished_at = now
        self._phase = None
        self.turn_needed, self.turn_notice = None, ''
        left = self._move_left_s(now)
        text = (
            f'aborted at posture {self.index + 1} of {self.total} ({self.measured} measured, '
            f'{len(self.skipped)} skipped)'
            + (f'; the move under way ends at its target in {left:.2g} s' if left else '')
        )
        self._say(LogLevel.WARN, text)
        if was != ExecutionState.RUNNING or left:
            return True, text, []
        return True, text, self._hold(now)

    def step(self, now: float) -> list[Command]:
        """Advance on the readings so far; return the commands to publish now."""
        if (
            self.state != ExecutionState.RUNNING
            or self._phase is None
            or self._phase in (Phase.RELEASING, Phase.REFINING)
        ):
            return []
        settings = self.settings
        if now - self.posture_start > settings.timeout_s:
            return self._skip(now, self._timeout_reason(now))
        if self._phase == Phase.MOVING:
            still = still_mean(
                self.actuators, now, self._arrive_after, settings, self._target, self.released_now
            )
            if still is None:
                return []
            if self.kinds[self.index] == FIXED:
                angles = self._judged_angles(now)
                if angles is None:
                    return []
                alpha, beta = angles
                if max(abs(alpha), abs(beta)) > settings.fixed_tolerance_rad:
                    return correct_fixed_position(self, now, alpha, beta)
            self._still_mean = still
            self._phase = Phase.POSTURE
        if self._phase == Phase.POSTURE:
            if not settings.wait_for_posture or posture_matched(
                self._still_mean, self._postures, settings.still_tolerance_m
            ):
                return self._complete(now)
        return []

    # ------------------------------------------------------------------ progress

    @property
    def commanding(self) -> bool:
        """Return whether a posture is being commanded (RUNNING: moving, at rest, measured)."""
        return self._phase is not None

    def paused_s(self, now: float) -> float:
        """Return the seconds paused so far (s)."""
        return self._paused_total + (now - self._paused_at if self._paused_at is not None else 0)

    def eta_s(self, now: float) -> float | None:
        """Return seconds until the plan is done at the pace so far (None when over)."""
        return eta_s(self, now)

    def progress(self, now: float) -> dict[str, object]:
        """Return the status fields: state, posture k of K, measured, skipped, ETA."""
        return progress(self, now)

    def summary(self) -> str:
        """Return one line: postures measured and skipped (which and why)."""
        return summary(self)

    # ------------------------------------------------------------------ internals

    def _say(self, level: LogLevel, text: str) -> None:
        self.messages.append((level, text))

    def _move_left_s(self, now: float) -> float:
        """
        Return how long the move under way has to go (s; 0 at rest).

        The operator's pause and abort do not cut a move short: the drive's setpoints when a
        hold arrived are unknown here (the hold is late by the network and a busy machine), and
        the drive would go from them to the hold in a straight line, off the path along the
        link sphere that the guard checked (a busy CI machine: 538 N on the 500 N link).  The
        move ends at its target, and the drive holds its last setpoints.
        """
        if self._in_flight is None:
            return 0.0
        sent_at, _, command = self._in_flight
        return max(sent_at + command.duration_s - now, 0.0)

    def _hold(self, now: float) -> list[Command]:
        """
        Hold where the drive's setpoints are at `now`: a move under way stops where it is.

        Not at the measured actuators: a compliant drive stands off its setpoints by the link's
        strain, and readings arrive late.  Cutting a move short is for the executor's own
        stops (an LVDT link near its end, a drive's answer); see _move_left_s.
        """
        latest = self.actuators.latest
        self._at_where = False
        if latest is None or not self._sent_any:
            return []
        hold = latest.copy() if self._setpoints is None else self._setpoints.copy()
        if self._setpoints is not None and self._in_flight is not None and self._move_left_s(now):
            sent_at, before, command = self._in_flight
            hold = setpoints_at(before, command, now - sent_at)
        if self.released_now is not None:
            hold[self.released_now] = latest[self.released_now]  # not commanded: follows
        self._setpoints, self._in_flight = hold.copy(), None
        return [Command(hold[None], np.array([HOLD_S]), CommandPurpose.HOLD, -1)]

    def _begin(self, now: float, fresh: bool) -> list[Command]:
        """Command the current posture (fresh: from its planned pose; else go on correcting)."""
        while True:
            if self.index >= self.total and self.released_now is not None:
                # Leave the machine as a machine: every actuator held by its drive.
                self.release_request = ReleaseRequest(self.total - 1, self.released_now, None)
                self._phase = Phase.RELEASING
                return []
            if self.index >= self.total:
                return self._finish(now)
            if fresh and not same_turn(self.turns[self.index], self.mounted_turn):
                return self._wait_for_turn(now)
            if fresh:
                self._pose_cmd = self.poses[self.index].copy()
                self._target = self.targets[self.index].copy()
                self._new_corrections()
                if self.refine_at and self.measured >= self.refine_at[0]:
                    return self._ask_refinement()
            self.posture_start = now
            if fresh and self.settings.check_releases_at_rest:
                check_release_here(self)
            wanted = self.released[self.index]
            if wanted != self.released_now:  # at rest: swap the released chain first
                self.release_request = ReleaseRequest(self.index, self.released_now, wanted)
                self._phase = Phase.RELEASING
                return []
            try:
                command = self._command(now, CommandPurpose.MOVE)
            except GuardStop as stop:
                return self._stop(now, str(stop))
            except PathError as error:
                if not self._sent_any:  # nothing has moved yet: the plan is refused
                    self.state = ExecutionState.REFUSED
                    self.finished_at = now
                    self._phase = None
                    self.refusal = (
                        f'plan refused before anything moved: the path from where the '
                        f'machine stands to posture {self.index + 1}: {error}'
                    )
                    self._say(LogLevel.ERROR, self.refusal)
                    return []
                self._record(now, False, f'its path cannot be commanded: {error}')
                self._say(
                    LogLevel.WARN,
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
        """Return whether it is paused before a posture for the operator to turn the device."""
        return self.state == ExecutionState.PAUSED and self.turn_needed is not None

    def _wait_for_turn(self, now: float) -> list[Command]:
        """Pause before the current posture until the operator has turned the device."""
        turn = float(self.turns[self.index])
        self.turn_needed = turn
        self.state = ExecutionState.PAUSED
        self._paused_at = now
        self._phase = None
        self.turn_notice = (
            f'posture {self.index + 1} of {self.total} needs the device turned to '
            f'{turn_text(turn)} about its link axis (it is at {turn_text(self.mounted_turn)}): '
            f'turn the device to {math.degrees(turn):.4g} deg about its link axis, then call '
            f'{RESUME_SERVICE}'
        )
        self._say(LogLevel.WARN, self.turn_notice)
        return self._hold(now)

    def _command(
        self, now: float, purpose: CommandPurpose, via: np.ndarray | None = None
    ) -> Command:
        """
        Return the command to the current commanded pose (PathError if it cannot be commanded).

        Along the link sphere from where the machine is (MOVE), or one point
        (CORRECT: a small correction from a standstill; through the pose `via` first
        when given).
        """
        current = self.actuators.latest if self.actuators.latest is not None else self._target
        step = self.settings.path_step_m
        start = None
        if purpose != CommandPurpose.CORRECT and step > 0:
            start = self._path_start()
        if start is None:
            command = path_command(
                self.nominal,
                current,
                self._pose_cmd[None] if via is None else np.stack([via, self._pose_cmd]),
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
        if self.guard is not None:
            # The guard sees the model's points, not the blend below: the offset is what the
            # model cannot explain (a chain locked where the true link put it, an earlier
            # model's targets), so on the model it would be a jump the machine does not make;
            # passive_actuator predicts from the model's own standing at the start pose. The
            # blend starts where the drive stands (measured, within the limits) and shrinks its
            # departure from the predicted path linearly to nothing.
            # Where the machine stands: the path's start, else nominal forward kinematics.
            guess = start if start is not None else self._estimate()
            problem = self.guard(
                current,
                self.poses[self.index] if guess is None else guess,
                command.points,
                self.released_now,
            )
            if problem:
                what = 'correction' if purpose == CommandPurpose.CORRECT else purpose
                raise GuardStop(
                    f'posture {self.index + 1} of {self.total}: the {what} was not sent: '
                    f'{problem}'
                )
        if start is not None and purpose == CommandPurpose.MOVE:
            command = self._blended(command, start)
        before = current if self._setpoints is None else self._setpoints
        command = eased_command(command, before, self.settings.max_actuator_speed_m_s)
        self._target = command.positions.copy()
        self._in_flight = (now, before.copy(), command)
        self._setpoints = command.positions.copy()
        # The collector's posture of this stop came before this correction: a correction below
        # its motion tolerances begins no new stationary period, so no posture may follow.
        self._posture_before = bool(self._postures) and purpose == CommandPurpose.CORRECT
        self._where, self._at_where = self._pose_cmd.copy(), False
        self._arrive_after = now + command.duration_s
        self._phase = Phase.MOVING
        self._postures = []
        self._still_mean = None
        self.inclinometer_judgement = None
        self._sent_any = True
        return command

    def _path_start(self) -> np.ndarray | None:
        """Return where a move's path starts: the pose commanded last if it stood still there."""
        return self._where if self._at_where else self._estimate()

    def _blended(self, command: Command, start: np.ndarray) -> Command:
        """Return the move `command` from the drive's setpoints (standing.py)."""
        setpoints = self._setpoints if self._setpoints is not None else self.actuators.latest
        if setpoints is None:
            return command
        return blend_from_setpoints(
            self.nominal, command, start, setpoints, self.released_now,
            self.settings.max_actuator_speed_m_s, self.stroke,
        )

    def _estimate(self) -> np.ndarray | None:
        """Return where the platform stands (standing.py); None (one-point command) if unknown."""
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
        pose, problem = estimate_pose(self.nominal, latest, guesses, self.link_length, self.mount)
        if problem:
            self._say(LogLevel.WARN, problem)
        return pose

    def _measured_standing(self, estimate: np.ndarray | None) -> np.ndarray | None:
        """
        Return where the device measures the platform standing (None: it cannot tell).

        The position from the newest inclinometer reading (eq. 4, in the mounting the device
        is in), the angles fitted on the model to the measured actuators from `estimate`'s;
        None while the inclinometer is silent or older than the actuators by STALE_READING_S.
        """
        latest, angles = self.actuators.latest, self.inclinometer.latest
        newest, actuated = self.inclinometer.newest_s, self.actuators.newest_s
        if estimate is None or latest is None or angles is None or newest is None:
            return None
        if actuated is not None and actuated - newest > STALE_READING_S:
            return None
        position = device_position(
            angles[:1], angles[1:], self.link_length, mount=self.mount,
            device_turn=self.mounted_turn,
        ).position
        return measured_pose(self.nominal, latest, position, estimate)[0]

    def _judged_angles(self, now: float) -> tuple[float, float] | None:
        """Return the inclinometer reading to judge the position on, None: not yet."""
        settings = self.settings
        angles, judgement = judged_angles(self.inclinometer, now, self._arrive_after, settings)
        if judgement is not None:
            self.inclinometer_judgement = judgement
        return angles

    def _timeout_reason(self, now: float) -> str:
        return timeout_reason(
            now, self.settings, self._phase == Phase.POSTURE, self._posture_before,
            self.actuators, self.kinds[self.index], self._target, self.released_now,
            self.inclinometer_judgement, self._corrections,
            self.nominal.layout.actuator_quantities,
        )

    def _skip(self, now: float, reason: str) -> list[Command]:
        self._record(now, False, reason)
        self._say(
            LogLevel.WARN,
            f'posture {self.index + 1} of {self.total} ({self.kinds[self.index]}) '
            f'skipped: {reason}',
        )
        return self._advance(now)

    def _complete(self, now: float) -> list[Command]:
        self._at_where = True  # it stood still at the commanded pose: the next path starts there
        self._record(now, True, '')
        corrections = f', {self._corrections} corrections' if self._corrections else ''
        self._say(
            LogLevel.INFO,
            f'posture {self.index + 1} of {self.total} ({self.kinds[self.index]}) '
            f'measured in {now - self.posture_start:.1f} s{corrections}',
        )
        return self._advance(now)

    def _record(self, now: float, measured: bool, reason: str) -> None:
        self.outcomes.append(
            PostureOutcome(
                self.index,
                self.kinds[self.index],
                measured,
                reason,
                now - self.posture_start,
                self._first_move_s,
                self._corrections,
            )
        )

    def _advance(self, now: float) -> list[Command]:
        self.index += 1
        self._phase = None
        self._new_corrections()
        return self._begin(now, fresh=True)

    def _new_corrections(self) -> None:
        """Start a posture's fixed-position corrections: none yet, the machine's answer unknown."""
        self._corrections = 0
        self.correction_response = CorrectionResponse()

    def _finish(self, now: float) -> list[Command]:
        self.state = ExecutionState.DONE
        self.finished_at = now
        self._phase = None
        self.index = self.total
        elapsed = now - (self.started_at or now)
        self._say(LogLevel.INFO, f'plan done in {elapsed:.1f} s: {self.summary()}')
        return []
