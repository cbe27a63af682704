"""core/planning/plan_check.py, core/walk/: targets, strokes, moves, corrections, the walk."""

from __future__ import annotations

import math

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.device import (
    fixed_point,
    inclinometer_angles,
    measured_position,
)
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import (
    check_plan,
    check_stroke,
    default_stroke,
    plan_targets,
    PlanRefusedError,
)
from hexacal_identify.core.walk.execution import PlanExecution
from hexacal_identify.core.walk.messages import joint_positions
from hexacal_identify.core.walk.platform_paths import CommandPurpose as Purpose
from hexacal_identify.core.walk.platform_paths import (
    corrected_pose,
    fixed_position_correction,
    MIN_MOVE_S,
    move_duration,
)
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.settings import ExecutionState as State
import numpy as np
import pytest

L = 0.75
NOMINAL = nominal_set(2, seed=0)
GS = 'gough_stewart'


def _plan(params=NOMINAL, sphere=4, fixed=2, seed=0):
    rng = np.random.default_rng(seed)
    workspace = params.architecture.default_workspace()
    poses = np.concatenate(
        [
            sample_poses(params, n, rng, kind, workspace)
            for kind, n in (('sphere', sphere), ('fixed', fixed))
            if n
        ]
    )
    return poses, ['sphere'] * sphere + ['fixed'] * fixed


# ------------------------------------------------------------------------ targets and the stroke


@pytest.mark.parametrize('model', [None, GS])
def test_targets_are_the_nominal_inverse_kinematics(model):
    nominal = nominal_set(2, seed=0, model=model)
    poses, kinds = _plan(nominal)
    targets = check_plan(nominal, poses, kinds, default_stroke(nominal), L)
    np.testing.assert_array_equal(targets, inverse_kinematics(nominal, poses))
    assert default_stroke(nominal) == tuple(
        nominal.architecture.default_workspace().actuator_stroke_m
    )


def test_a_target_outside_the_stroke_refuses_the_whole_plan_naming_each_posture():
    poses, kinds = _plan()
    targets = inverse_kinematics(NOMINAL, poses)
    high = float(np.sort(targets.max(axis=1))[-3])  # the two highest postures go beyond it
    with pytest.raises(PlanRefusedError) as caught:
        check_plan(NOMINAL, poses, kinds, (0.0, high), L)
    outside = sorted(int(i) for i in np.flatnonzero(targets.max(axis=1) > high))
    assert len(outside) == 2 and sorted(caught.value.problems) == outside
    message = str(caught.value)
    assert caught.value.reason == 'plan-refused'
    assert 'plan refused before anything moved: 2 of 6 postures' in message
    assert f'postures {[i + 1 for i in outside]}' in message
    assert f'outside the stroke [0, {high:g}] m: slider_' in message


def test_unreachable_and_misplaced_postures_are_named():
    poses, kinds = _plan()
    poses = poses.copy()
    poses[0, :3] *= 1.01  # off the link sphere
    poses[4, :3] = [0.01, 0.0, -L]  # a fixed posture away from the fixed point
    poses[1, 2] = -5.0  # far below: no leg reaches
    _, problems = plan_targets(NOMINAL, poses, kinds, default_stroke(NOMINAL), L)
    assert 'must be on the link sphere' in problems[0]
    assert 'cannot reach it' in problems[1]
    assert 'a fixed-position posture must be at' in problems[4]
    assert set(problems) == {0, 1, 4}


@pytest.mark.parametrize('stroke', [(0.5, 0.1), (0.0,), (0.0, math.inf), ('a', 1.0)])
def test_stroke_limits_must_be_two_increasing_numbers(stroke):
    with pytest.raises(ValueError, match='stroke limits must be two finite numbers'):
        check_stroke(stroke)


def test_time_from_start_is_the_largest_move_at_the_maximum_speed():
    assert move_duration(np.zeros(6), np.array([0.0, 0.1, -0.3, 0, 0, 0]), 0.1) == pytest.approx(
        3.0
    )
    assert move_duration(np.zeros(6), np.full(6, 1e-6), 0.1) == MIN_MOVE_S


@pytest.mark.parametrize('mount', ['hanging', 'standing'])
def test_the_fixed_position_correction_brings_the_inclinometer_to_zero(mount):
    alpha, beta = 4e-3, -7e-3
    position = measured_position(alpha, beta, L, mount)
    corrected = position + fixed_position_correction(alpha, beta, L, mount)
    # eq. 4's derivative: first order, so the error left is second order in the angles (~L * 1e-5).
    assert np.linalg.norm(corrected - fixed_point(L, mount)) < 5e-5
    left = np.abs(np.array(inclinometer_angles(corrected[None], mount)).ravel()).max()
    assert left < 1e-4 < max(abs(alpha), abs(beta))
    pose = np.array([*position, 0.1, -0.2, 0.3])
    moved = corrected_pose(pose, alpha, beta, L, mount)
    np.testing.assert_array_equal(moved[3:], pose[3:])  # the orientation is kept


def test_joint_positions_by_name_in_any_order():
    assert joint_positions(['b', 'x', 'a'], [2.0, 9.0, 1.0], ('a', 'b')).tolist() == [1.0, 2.0]
    assert joint_positions(['a'], [1.0], ('a', 'b')) is None
    assert joint_positions(['a', 'b'], [1.0, math.nan], ('a', 'b')) is None
    assert joint_positions(['a', 'a', 'b'], [1.0, 1.0, 2.0], ('a', 'b')) is None


def test_settings_name_every_bad_value():
    with pytest.raises(ValueError, match='settle_s must be a positive.*max_corrections must be'):
        ExecutionSettings(settle_s=0.0, max_corrections=-1)


# --------------------------------------------------------------------------- the state machine


class _Machine:
    """
    Reach every command exactly after its time_from_start (no link strain).

    A collector measures after 0.4 s of stillness; the inclinometer reads the
    true platform position.
    """

    def __init__(self, truth, execution: PlanExecution, speed_factor: float = 1.0):
        self.truth = truth
        self.execution = execution
        self.position = inverse_kinematics(truth, np.array([[0, 0, -L, 0, 0, 0.0]]))[0]
        self.start, self.goal, self.t0, self.t1 = self.position, self.position, 0.0, 0.0
        self.speed_factor = speed_factor
        self.commands = []
        self.measured_at = None
        self.t = 0.0
        self.inclinometer_scale = 1.0  # what the inclinometer reads per radian
        # Stiction: each actuator stops this far short of its goal, on the side its last
        # approach came from (its sign per actuator).
        self.stiction_m = 0.0
        self.approach = np.zeros(6)

    def command(self, commands):
        for command in commands:
            self.commands.append(command)
            path = np.vstack([self.at(self.t)[None], command.points])
            self.approach = np.sign(path[-1] - path[-2])
            self.start = self.at(self.t)
            self.goal = command.positions
            self.t0, self.t1 = self.t, self.t + command.duration_s / self.speed_factor

    def at(self, t):
        if t >= self.t1:
            return self.goal - self.stiction_m * self.approach
        s = (t - self.t0) / (self.t1 - self.t0)
        return self.start + s * (self.goal - self.start)

    def run(self, until, dt=0.01):
        from hexacal_identify.core.machine.kinematics import forward_kinematics

        execution = self.execution
        while self.t < until and execution.state not in (State.DONE, State.ABORTED):
            q = self.at(self.t)
            execution.on_actuators(self.t, q)
            if self.t >= self.t1:
                if self.measured_at is None:
                    pose = forward_kinematics(
                        self.truth, q[None], np.array([[0, 0, -L, 0, 0, 0.0]])
                    )
                    angles = inclinometer_angles(pose.poses[:, :3])
                    scale = self.inclinometer_scale
                    self.angles = (scale * float(angles[0][0]), scale * float(angles[1][0]))
                    self.measured_at = self.t + 0.4
                execution.on_inclinometer(self.t, *self.angles)
                if self.t >= self.measured_at:
                    execution.on_posture(self.t, q)
                    self.measured_at = math.inf
            else:
                self.measured_at = None
            self.command(
                execution.start(self.t)
                if execution.state == State.WAITING
                else execution.step(self.t)
            )
            self.t += dt


def _execution(nominal=NOMINAL, sphere=3, fixed=1, **settings):
    poses, kinds = _plan(nominal, sphere, fixed)
    stroke = default_stroke(nominal)
    settings = {'max_actuator_speed_m_s': 0.5, 'settle_s': 0.2, **settings}
    return PlanExecution(
        nominal,
        poses,
        kinds,
        check_plan(nominal, poses, kinds, stroke, L),
        ExecutionSettings(**settings),
        stroke,
        L,
    )


def test_a_plan_is_walked_to_the_end_with_the_fixed_posture_in_closed_loop():
    execution = _execution(NOMINAL)
    machine = _Machine(table1_parameters(), execution)
    machine.run(60.0)
    assert execution.state == State.DONE and execution.measured == 4 and not execution.skipped
    purposes = [c.purpose for c in machine.commands]
    # The fixed one was corrected.
    assert purposes[:4] == [Purpose.MOVE] * 4 and Purpose.CORRECT in purposes
    assert max(map(abs, machine.angles)) <= execution.settings.fixed_tolerance_rad
    assert execution.outcomes[-1].corrections >= 1
    progress = execution.progress(machine.t)
    assert progress['state'] == 'done' and progress['posture'] == 4 and progress['skipped'] == 0
    assert 'eta_s' not in progress


def test_a_fixed_posture_whose_corrections_overshoot_is_reached_by_learning_the_answer():
    # An inclinometer reading 1.4x the angle: each correction the model asks for moves the
    # reading 1.4x as far, and the first-order corrections alone leave 40 % each time (from
    # 18 mrad, 8 to reach 20 urad). Learned from the first, the next one lands.
    execution = _execution(NOMINAL, sphere=1, fixed=1, max_corrections=4)
    machine = _Machine(table1_parameters(), execution)
    machine.inclinometer_scale = 1.4
    machine.run(60.0)
    assert execution.state == State.DONE and execution.measured == 2 and not execution.skipped
    assert 2 <= execution.outcomes[-1].corrections <= 4
    assert max(map(abs, machine.angles)) <= execution.settings.fixed_tolerance_rad


STICTION_M = 1e-5  # 10 um short: 36 to 56 urad of reading, flipping (5 um already did)


def test_small_corrections_approach_from_one_side_past_a_released_actuators_stiction():
    # Stiction leaves each actuator short of its goal on the side it came from: corrections
    # that approached from alternating sides (through their own nudge) made the reading flip
    # around the 20 urad tolerance until the posture was skipped (the MuJoCo Gough-Stewart).
    # From one side, the offset is the same each time and is corrected away.
    execution = _execution(NOMINAL, sphere=1, fixed=1, max_corrections=5)
    machine = _Machine(table1_parameters(), execution)
    machine.stiction_m = STICTION_M
    machine.run(60.0)
    assert execution.state == State.DONE and execution.measured == 2 and not execution.skipped
    assert max(map(abs, machine.angles)) <= execution.settings.fixed_tolerance_rad


def test_pause_holds_and_resume_restarts_the_posture_abort_ends_the_plan():
    execution = _execution(NOMINAL, sphere=4, fixed=0)
    machine = _Machine(default_parameters(), execution)
    machine.run(0.05)
    assert execution.state == State.RUNNING and len(machine.commands) == 1
    first = machine.commands[0]
    # Mid-move: nothing is sent, the move ends at its target (a hold's straight line from
    # wherever the drive is when it arrives would leave the path along the link sphere).
    ok, message, commands = execution.pause(machine.t)
    assert ok and execution.state == State.PAUSED and 'paused at posture 1 of 4' in message
    assert 'the move under way ends at its target' in message and commands == []
    machine.run(machine.t + 3.0)  # paused: nothing moves on
    assert execution.state == State.PAUSED and execution.measured == 0
    assert len(machine.commands) == 1 and np.array_equal(machine.at(machine.t), first.positions)
    assert execution.progress(machine.t)['state'] == 'paused'
    assert execution.progress(machine.t)['paused_s'] >= 2.9
    ok, message, commands = execution.resume(machine.t)
    assert ok and execution.state == State.RUNNING
    assert [c.purpose for c in commands] == [Purpose.MOVE]
    np.testing.assert_array_equal(commands[0].positions, execution.targets[0])
    machine.command(commands)
    while execution.measured < 2:
        machine.run(machine.t + 0.1)
    while execution._move_left_s(machine.t) > 0:  # at rest: the hold is one point, no jump
        machine.run(machine.t + 0.01)
    ok, message, commands = execution.abort(machine.t)
    assert ok and execution.state == State.ABORTED
    assert 'aborted at posture 3 of 4 (2 measured' in message
    assert [c.purpose for c in commands] == [Purpose.HOLD]
    np.testing.assert_array_equal(commands[0].positions, machine.commands[-1].positions)
    assert not execution.abort(machine.t)[0] and not execution.resume(machine.t)[0]
    assert execution.step(machine.t + 100.0) == []  # nothing more is ever commanded
    assert first.purpose == Purpose.MOVE


def test_a_pause_and_resume_within_a_move_let_it_go_on():
    execution = _execution(NOMINAL, sphere=2, fixed=0)
    machine = _Machine(default_parameters(), execution)
    machine.run(0.05)
    assert execution.pause(machine.t)[2] == []
    ok, message, commands = execution.resume(machine.t + 0.01)
    assert ok and commands == [] and execution.state == State.RUNNING
    while execution.state == State.RUNNING:
        machine.run(machine.t + 0.1)
    assert execution.state == State.DONE and execution.measured == 2
    assert len(machine.commands) == 2  # the first move was never sent again


def test_a_posture_not_reached_in_time_is_skipped_and_reported():
    execution = _execution(NOMINAL, sphere=2, fixed=0, timeout_s=0.5)
    machine = _Machine(default_parameters(), execution, speed_factor=0.01)  # 100x too slow
    machine.run(10.0)
    assert execution.state == State.DONE
    assert execution.measured == 0 and len(execution.skipped) == 2
    reason = execution.skipped[0].reason
    assert reason.startswith('not at the target and still within 0.5 s (actuators up to')
    progress = execution.progress(machine.t)
    assert progress['skipped'] == 2 and progress['skipped_postures'].startswith(
        '1: not at the target'
    )


def test_start_paused_waits_for_resume_and_eta_counts_down():
    execution = _execution(NOMINAL, sphere=3, fixed=0)
    execution.start_paused = True
    machine = _Machine(default_parameters(), execution)
    machine.run(1.0)
    assert execution.state == State.PAUSED and machine.commands == []
    eta_before = execution.eta_s(machine.t)
    assert eta_before > 0
    machine.command(execution.resume(machine.t)[2])
    while execution.measured < 1:
        machine.run(machine.t + 0.1)
    assert 0 < execution.eta_s(machine.t) < eta_before


def test_the_stroke_defaults_to_the_plans_limits_then_the_models():
    from hexacal_identify.core.planning.plan_check import plan_stroke

    assert plan_stroke({'limits': {'actuator_stroke_m': [0.05, 0.8]}}, NOMINAL) == (
        (0.05, 0.8),
        "the plan's limits",
    )
    assert plan_stroke({}, NOMINAL) == ((0.0, 0.9), "the hexa_slide's default workspace")
    assert plan_stroke({'limits': {'actuator_stroke_m': 'x'}}, nominal_set(2, model=GS))[0] == (
        0.0,
        0.5,
    )


# --------------------------------------------------------------------------- turning the device


def _turning_execution(turns, sphere=4, **kwargs):
    poses, kinds = _plan(NOMINAL, sphere, 0)
    stroke = default_stroke(NOMINAL)
    settings = ExecutionSettings(max_actuator_speed_m_s=0.5, settle_s=0.2)
    return PlanExecution(
        NOMINAL,
        poses,
        kinds,
        check_plan(NOMINAL, poses, kinds, stroke, L),
        settings,
        stroke,
        L,
        device_turns=turns,
        **kwargs,
    )


def test_the_execution_pauses_for_the_operator_to_turn_the_device_then_walks_on():
    execution = _turning_execution([0.0, 0.0, math.pi, math.pi])
    machine = _Machine(default_parameters(), execution)
    assert execution.progress(0.0)['device_turn_rad'] == 0.0
    while execution.state != State.PAUSED:
        machine.run(machine.t + 0.1)
        assert machine.t < 60.0
    # Both postures of the normal mounting measured; paused before the third, holding.
    assert execution.measured == 2 and execution.index == 2 and execution.waiting_for_turn
    assert execution.turn_needed == math.pi and execution.mounted_turn == 0.0
    assert [c.purpose for c in machine.commands].count(Purpose.MOVE) == 2
    assert machine.commands[-1].purpose == Purpose.HOLD
    notice = execution.turn_notice
    assert notice.startswith('posture 3 of 4 needs the device turned to 180 deg (3.14159 rad)')
    assert (
        'turn the device to 180 deg about its link axis, then call hexacal/executor/resume'
        in notice
    )
    assert ('warn', notice) in execution.messages
    progress = execution.progress(machine.t)
    assert progress['state'] == State.PAUSED and progress['posture'] == 3
    assert progress['device_turn_rad'] == math.pi and progress['device_turn_needed_rad'] == math.pi
    commands = len(machine.commands)
    machine.run(machine.t + 3.0)  # nothing moves while the operator turns the device
    assert execution.state == State.PAUSED and len(machine.commands) == commands
    ok, message, _ = execution.pause(machine.t)
    assert ok and 'turn the device to 180 deg' in message  # a pause says what it waits for
    ok, message, commands = execution.resume(machine.t)
    assert ok and execution.state == State.RUNNING and execution.mounted_turn == math.pi
    assert 'resumed at posture 3 of 4 with the device turned to 180 deg' in message
    assert execution.turn_needed is None and execution.turn_notice == ''
    assert [c.purpose for c in commands] == [Purpose.MOVE] and commands[0].posture == 2
    np.testing.assert_array_equal(commands[0].positions, execution.targets[2])
    assert 'device_turn_needed_rad' not in execution.progress(machine.t)
    machine.command(commands)
    machine.run(machine.t + 60.0)
    assert execution.state == State.DONE and execution.measured == 4 and not execution.skipped
    assert sum(c.purpose == Purpose.HOLD for c in machine.commands) == 1  # one remount, one pause
    assert execution.progress(machine.t)['device_turn_rad'] == math.pi


def test_a_first_posture_in_another_mounting_pauses_before_anything_moves():
    execution = _turning_execution([math.pi / 2, math.pi, math.pi, 0.0])
    machine = _Machine(default_parameters(), execution)
    machine.run(1.0)
    assert execution.state == State.PAUSED and execution.index == 0 and machine.commands == []
    assert 'posture 1 of 4 needs the device turned to 90 deg' in execution.turn_notice
    machine.command(execution.resume(machine.t)[2])
    assert execution.mounted_turn == math.pi / 2
    while execution.state != State.PAUSED:
        machine.run(machine.t + 0.1)
    assert (
        execution.measured == 1 and execution.turn_needed == math.pi
    )  # quarter turn -> half turn
    machine.command(execution.resume(machine.t)[2])
    while execution.state != State.PAUSED:
        machine.run(machine.t + 0.1)
    assert execution.measured == 3 and execution.turn_needed == 0.0
    assert 'turned to 0 deg (0 rad)' in execution.turn_notice
    machine.command(execution.resume(machine.t)[2])
    machine.run(machine.t + 60.0)
    assert execution.state == State.DONE and execution.measured == 4


def test_no_pause_when_the_device_is_already_in_the_plans_mounting():
    for turns, mounted in (
        (None, 0.0),
        ([0.0] * 3, 0.0),
        ([math.pi] * 3, math.pi),
        ([0.0, 2 * math.pi, -2 * math.pi], 0.0),
    ):
        execution = _turning_execution(turns, sphere=3, mounted_turn=mounted)
        machine = _Machine(default_parameters(), execution)
        machine.run(60.0)
        assert execution.state == State.DONE and execution.measured == 3, turns
        assert not any(c.purpose == Purpose.HOLD for c in machine.commands)
        assert execution.turn_notice == '' and execution.mounted_turn == mounted


def test_abort_while_waiting_for_a_turn_and_bad_turns():
    execution = _turning_execution([math.pi] * 4)
    machine = _Machine(default_parameters(), execution)
    machine.run(0.5)
    assert execution.waiting_for_turn
    ok, message, commands = execution.abort(machine.t)
    assert ok and execution.state == State.ABORTED
    assert commands == [] and not execution.waiting_for_turn
    assert 'device_turn_needed_rad' not in execution.progress(machine.t)
    with pytest.raises(ValueError, match='one finite angle'):
        _turning_execution([0.0, 0.0])
    with pytest.raises(ValueError, match='one finite angle'):
        _turning_execution([0.0, math.nan, 0.0, 0.0])
    from hexacal_identify.core.walk_device.turns import same_turn

    assert same_turn(0.0, 2 * math.pi) and same_turn(-math.pi, math.pi)
    assert not same_turn(0.0, math.pi) and not same_turn(math.pi / 2, 3 * math.pi / 2)
