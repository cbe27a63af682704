"""A move starts and stops at rest (core/walk/platform_paths.eased_command)."""

from __future__ import annotations

from hexacal_identify.core.machine.device import fixed_point
from hexacal_identify.core.machine.model import table1_parameters
from hexacal_identify.core.walk.platform_paths import (
    Command,
    CommandPurpose,
    eased_command,
    EASED_STEP_S,
    RAMP_S,
    route_command,
)
import numpy as np

L = 0.75
SPEED = 0.5
TRUTH = table1_parameters()
CENTRE = np.concatenate([fixed_point(L), np.zeros(3)])
STROKE = (-np.inf, np.inf)


def _speeds(start, command):
    """Return each segment's largest actuator speed and the segments' durations."""
    points = np.vstack([start[None], command.points])
    durations = np.diff(np.concatenate([[0.0], command.times]))
    return np.max(np.abs(np.diff(points, axis=0)), axis=1) / durations, durations


def test_an_eased_move_ramps_its_speed_within_the_limits_and_keeps_its_target():
    end = CENTRE + np.array([0.12, -0.05, 0.0, 0.05, -0.03, 0.1])
    end[2] = -np.sqrt(L**2 - end[0] ** 2 - end[1] ** 2) if CENTRE[2] < 0 else end[2]
    start = route_command(TRUTH, np.zeros(6), CENTRE, CENTRE, STROKE, SPEED, L, 0.02).points[-1]
    command = route_command(TRUTH, start, CENTRE, end, STROKE, SPEED, L, 0.02)
    eased = eased_command(command, start, SPEED)
    speeds, durations = _speeds(start, eased)
    plain, _ = _speeds(start, command)
    assert plain[0] > 0.9 * SPEED  # timed at full speed from the first point
    # From rest to at most the limit and back, in steps a stiff drive follows.
    assert np.all(durations <= EASED_STEP_S + 1e-12) and np.all(durations > 0)
    assert speeds.max() <= SPEED * (1 + 1e-9)
    assert speeds[0] < 0.02 * SPEED and speeds[-1] < 0.02 * SPEED
    assert np.max(np.abs(np.diff(speeds))) <= SPEED / RAMP_S * EASED_STEP_S * 1.05
    # The same path, the same target bit for bit, more time.
    assert np.array_equal(eased.positions, command.positions)
    assert eased.purpose == command.purpose and eased.posture == command.posture
    assert command.duration_s < eased.duration_s < 2.0 * command.duration_s + RAMP_S
    vertices = np.vstack([start[None], command.points])
    gaps = [np.min(np.linalg.norm(vertices - point, axis=1)) for point in eased.points]
    assert max(gaps) < 0.02  # on the path (within a vertex spacing)


def test_a_path_that_turns_back_stops_at_the_turn_and_a_hold_is_left_as_it_is():
    start = np.zeros(6)
    out = np.full(6, 0.01)
    command = Command(np.vstack([out, np.zeros(6)]), np.array([0.02, 0.04]),
                      CommandPurpose.CORRECT, 2)
    eased = eased_command(command, start, SPEED)
    speeds, _ = _speeds(start, eased)
    turn = int(np.argmax(np.abs(eased.points - out).max(axis=1) == 0.0))
    assert np.array_equal(eased.points[turn], out)  # it reaches the far point ...
    assert speeds[turn] < 0.1 * speeds.max() and speeds[turn + 1] < 0.1 * speeds.max()
    assert eased.duration_s >= 0.2  # ... at rest: two legs of at least MIN_MOVE_S
    hold = Command(np.zeros((1, 6)), np.array([0.5]), CommandPurpose.HOLD, -1)
    assert eased_command(hold, start, SPEED) is hold
