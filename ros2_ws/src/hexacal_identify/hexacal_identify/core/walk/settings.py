"""
The vocabulary of a plan's walk (ROS-free): its states, phases, settings and outcomes.

core/walk/execution.py walks the plan with them; the executor node reports them
(``state`` in its status is an `ExecutionState` value) and declares its
parameters from `ExecutionSettings`' defaults.
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import math


class ExecutionState(enum.StrEnum):
    """The state of a plan's walk (status field ``state``: the values)."""

    WAITING = 'waiting'  # for the machine (actuator readings, a controller on the command topic)
    RUNNING = 'running'
    PAUSED = 'paused'
    ABORTED = 'aborted'
    DONE = 'done'
    REFUSED = 'refused'  # the plan was refused before anything moved


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
    # 0: straight moves in joint space (no points on the sphere).  5 mm: chords 4 um off the
    # 0.75 m sphere (20 mm: 67 um), and on the MuJoCo Hexa Slide the path's corners shake the
    # passive system's softest mode less (a plan's replay: 5 moves beyond 500 N at 20 mm, 3).
    path_step_m: float = 0.005
    # Fixed-position loop: the two windows in which the inclinometer must have settled (s);
    # 0: judge the mean over settle_s once the actuators are still
    # (core/walk_device/inclinometer.py).
    inclinometer_settle_s: float = 0.25
    # A correction smaller than this goes this far beyond its target and back (m; 0: never),
    # so the collector sees a move (core/walk/arrival.py's nudge).
    correction_nudge_m: float = 1e-3
    # passive_actuator: before each later move, at rest, rehearse the posture's release again
    # from where the machine stands and release another chain if it may jam
    # (release_choice.check_release_here); False walks the plan's releases as planned (the
    # guard and the recovery after a drive fault still act).
    check_releases_at_rest: bool = True

    def __post_init__(self) -> None:
        problems = []
        for name in ('path_step_m', 'inclinometer_settle_s', 'correction_nudge_m'):
            value = getattr(self, name)
            if not _finite_number(value) or value < 0:
                problems.append(f'{name} must be a finite number >= 0, got {value!r}')
        for name in (
            'max_actuator_speed_m_s',
            'position_tolerance_m',
            'still_tolerance_m',
            'settle_s',
            'timeout_s',
            'fixed_tolerance_rad',
        ):
            value = getattr(self, name)
            if not _finite_number(value) or value <= 0:
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


def _finite_number(value: object) -> bool:
    return (
        not isinstance(value, bool)
        and isinstance(value, (int, float))
        and math.isfinite(value)
    )


@dataclass
class PostureOutcome:
    """What became of one posture of the plan."""

    index: int
    kind: str
    measured: bool
    reason: str  # why it was skipped ('' when measured)
    duration_s: float
    move_s: float  # the planned move time of its first command
    corrections: int


class Phase(enum.Enum):
    """Where the current posture stands while RUNNING."""

    MOVING = 'moving'  # commanded: arriving, settling, correcting
    POSTURE = 'posture'  # still at the target: waiting for the collector's posture
    RELEASING = 'releasing'  # at rest: waiting for the drive to lock/release a chain
    REFINING = 'refining'  # at rest: waiting for an intermediate calibration (refined_targets.py)


class GuardStop(Exception):
    """The guard refuses a command: it would cross a limit (the message says which)."""
