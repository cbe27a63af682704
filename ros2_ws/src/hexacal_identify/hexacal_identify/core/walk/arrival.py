"""
When a commanded posture is reached, and why it was not (ROS-free).

core/walk/execution.py asks these at each step of a posture:

* Arrive: the measured actuators are at the target (within ``position_tolerance_m``; the
  released chain is not judged, the link puts it where the constraint says) and still
  (peak-to-peak within ``still_tolerance_m``) over the last ``settle_s``, counted from when
  the command's own time has passed (`still_mean`).  The tolerance allows for the strain of
  the measuring link: where the nominal model is millimetres off, the actuators stop up to
  millimetres away from targets the true machine cannot reach on the link sphere.
* Fixed positions (eq. 10): the inclinometer reading judged once it has settled (two
  consecutive ``inclinometer_settle_s`` windows agree, core/walk_device/inclinometer.py), or with
  ``inclinometer_settle_s`` 0 the mean over ``settle_s`` as soon as the actuators are still
  (`judged_angles`).  A correction smaller than ``correction_nudge_m`` passes a nudge beyond
  its target first (`nudge`), so the collector sees a move.
* Measured: the collector's posture of this stop, its actuators within ``still_tolerance_m``
  of the still mean (`posture_matched`).
* Timeout: what was missing (`timeout_reason`).
* `correct_fixed_position`: what `PlanExecution` does with a fixed position not reached.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from hexacal_msgs_py.models import ActuatorQuantities, LINEAR_ACTUATOR
import numpy as np

from .messages import LogLevel, ReadingWindow
from .platform_paths import Command, CommandPurpose, corrected_pose, PathError
from .settings import ExecutionSettings, GuardStop
from ..machine.measurements import FIXED
from ..walk_device.inclinometer import InclinometerJudgement, InclinometerState, judge_inclinometer

if TYPE_CHECKING:
    from .execution import PlanExecution

MIN_WINDOW_READINGS = 3  # readings a still window needs


def commanded_away(actuators: np.ndarray, target: np.ndarray, released: int | None) -> float:
    """Return the largest distance of a commanded chain from its target (m, or rad)."""
    away = np.abs(actuators - target)
    if released is not None:  # the link puts the released chain where it goes
        away = np.delete(away, released)
    return float(np.max(away))


def still_mean(
    actuators: ReadingWindow,
    now: float,
    arrive_after: float,
    settings: ExecutionSettings,
    target: np.ndarray,
    released: int | None,
) -> np.ndarray | None:
    """Return the mean of the actuators once at the target and still; None: not yet."""
    settle = settings.settle_s
    if now < arrive_after + settle:
        return None
    window = actuators.between(now - settle, now)
    if len(window) < MIN_WINDOW_READINGS:
        return None
    if float(np.max(np.ptp(window, axis=0))) > settings.still_tolerance_m:
        return None
    mean = window.mean(axis=0)
    if commanded_away(mean, target, released) > settings.position_tolerance_m:
        return None
    return mean


def judged_angles(
    inclinometer: ReadingWindow, now: float, arrive_after: float, settings: ExecutionSettings
) -> tuple[tuple[float, float] | None, InclinometerJudgement | None]:
    """Return the inclinometer reading to judge the position on (None: not yet), its judgement."""
    window_s = settings.inclinometer_settle_s
    if window_s == 0:  # the mean over settle_s, as soon as the actuators are still
        start = max(now - settings.settle_s, arrive_after)
        window = inclinometer.between(start, now)
        if len(window) < MIN_WINDOW_READINGS:
            return None, None
        alpha, beta = window.mean(axis=0)
        return (float(alpha), float(beta)), None
    times, readings = inclinometer.timed(now - 2.0 * window_s, now)
    judgement = judge_inclinometer(
        times, readings, now, arrive_after, window_s, settings.fixed_tolerance_rad
    )
    return judgement.angles, judgement


def unsettled_reason(
    judgement: InclinometerJudgement | None, settings: ExecutionSettings
) -> str | None:
    """Return why a fixed position was not judged (the inclinometer), None if it was."""
    if judgement is None or judgement.settled:
        return None
    described = judgement.describe(settings.inclinometer_settle_s)
    if judgement.state == InclinometerState.NO_READINGS:
        return f'no inclinometer readings ({described})'
    return f'the inclinometer did not settle ({described})'


def posture_matched(
    mean: np.ndarray | None, postures: Sequence[tuple[float, np.ndarray]], tolerance: float
) -> bool:
    """Return whether a collector's (received, actuators) posture is of the still `mean`."""
    if mean is None:
        return False
    return any(float(np.max(np.abs(actuators - mean))) <= tolerance for _, actuators in postures)


def nudge(
    pose: np.ndarray, previous: np.ndarray, nudge_m: float, side: np.ndarray | None = None
) -> np.ndarray | None:
    """
    Return the pose a correction from `previous` to `pose` passes through first; None: none.

    A correction smaller than `nudge_m` goes that far beyond its target and back, so the
    collector sees a move and measures the corrected position: a smaller move would continue
    its stationary period, of which it takes one posture (perhaps before the correction, or
    averaged across it).  Beyond it along its own direction (tangent to the link sphere), or
    along `side` (a unit vector): the side every nudged correction of the posture approaches
    from, so that a released actuator's stiction leaves the same offset each time instead of
    one of alternating sign (corrections that flip the reading around the tolerance).
    """
    step = pose[:3] - previous[:3]
    size = float(np.linalg.norm(step))
    if nudge_m == 0 or size == 0 or size >= nudge_m:
        return None
    via = pose.copy()
    via[:3] += (step / size if side is None else side) * nudge_m
    return via


def timeout_reason(
    now: float,
    settings: ExecutionSettings,
    waiting_for_posture: bool,
    posture_before: bool,
    actuators: ReadingWindow,
    kind: str,
    target: np.ndarray,
    released: int | None,
    judgement: InclinometerJudgement | None,
    corrections: int,
    quantities: ActuatorQuantities = LINEAR_ACTUATOR,
) -> str:
    """
    Return why a posture was not done within ``timeout_s``.

    waiting_for_posture: it stood still at the target and waited for the collector;
    posture_before: the collector's posture of this stop came before the last correction;
    quantities: the actuators' units (the distance from the target in mm, or deg for cranks).
    """
    timeout = settings.timeout_s
    if waiting_for_posture:
        if posture_before:
            return (
                f'no posture from the collector within {timeout:g} s (its posture of this '
                'stop came before the last correction, too small to be a move for it)'
            )
        return f'no posture from the collector within {timeout:g} s'
    latest = actuators.latest
    if latest is None or actuators.between(now - settings.settle_s, now).size == 0:
        return f'no actuator readings (timeout {timeout:g} s)'
    away = commanded_away(latest, target, released)
    there = kind == FIXED and away <= settings.position_tolerance_m
    unsettled = unsettled_reason(judgement, settings)
    if there and unsettled:
        counted = f', {corrections} corrections' if corrections else ''
        return f'{unsettled} within {timeout:g} s{counted}'
    if there and corrections:
        return f'fixed position not reached within {timeout:g} s ({corrections} corrections)'
    return (
        f'not at the target and still within {timeout:g} s (actuators up to '
        f'{quantities.shown(away)} from it)'
    )


def correct_fixed_position(
    walk: PlanExecution, now: float, alpha: float, beta: float
) -> list[Command]:
    """Correct the walk's fixed-position posture by the judged angles (rad), or skip it."""
    index = walk.index
    if walk._corrections >= walk.settings.max_corrections:
        return walk._skip(
            now,
            (
                f'fixed position not reached after {walk._corrections} corrections '
                f'(inclinometer {alpha:.3g}, {beta:.3g} rad; tolerance '
                f'{walk.settings.fixed_tolerance_rad:g} rad)'
            ),
        )
    judged = (
        f' (settled {now - walk._arrive_after:.1f} s after the move)'
        if walk.inclinometer_judgement is not None
        else ''
    )
    previous, response = walk._pose_cmd, walk.correction_response
    reading = np.array([alpha, beta])
    change = response.ask(reading)
    walk._pose_cmd = corrected_pose(previous, alpha, beta, walk.link_length, walk.mount, change)
    nudge_m = walk.settings.correction_nudge_m
    via = nudge(walk._pose_cmd, previous, nudge_m, response.side)
    done = walk._corrections
    try:
        commands = _send_correction(walk, now, previous, via, index, alpha, beta, judged)
    except GuardStop as stop:
        walk._pose_cmd = previous
        return walk._stop(now, str(stop))
    if walk._corrections > done:  # commanded (not skipped): learn from what it does
        response.sent(reading, change)
        if via is not None and response.side is None:  # the first nudge sets the side
            response.side = (via[:3] - walk._pose_cmd[:3]) / nudge_m
    return commands


def _send_correction(
    walk: PlanExecution, now, previous, via, index, alpha, beta, judged
) -> list[Command]:
    try:
        try:
            command = walk._command(now, CommandPurpose.CORRECT, via)
        except PathError:
            if via is None:
                raise
            via = None  # the nudge cannot be commanded (e.g. at the stroke's end)
            command = walk._command(now, CommandPurpose.CORRECT)
    except PathError as error:
        walk._pose_cmd = previous
        return walk._skip(now, f'the fixed-position correction cannot be commanded: {error}')
    walk._corrections += 1
    walk.total_corrections += 1
    moved = np.linalg.norm(walk._pose_cmd[:3] - previous[:3])
    walk._say(
        LogLevel.INFO,
        f'posture {index + 1}: inclinometer {alpha:.3g}, {beta:.3g} rad{judged}; correction '
        f'{walk._corrections} moves the platform by {moved * 1e6:.0f} um'
        + (
            f' (through a {walk.settings.correction_nudge_m * 1e6:.0f} um nudge beyond it, '
            'so the collector sees a move)'
            if via is not None
            else ''
        ),
    )
    return [command]


__all__ = [
    'correct_fixed_position',
    'commanded_away',
    'judged_angles',
    'MIN_WINDOW_READINGS',
    'nudge',
    'posture_matched',
    'still_mean',
    'timeout_reason',
    'unsettled_reason',
]
