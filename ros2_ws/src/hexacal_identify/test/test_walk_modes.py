"""core/walk/mode_driver.py and execution.py's released chain: the passive actuator at rest."""

from __future__ import annotations

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import default_stroke, plan_targets
from hexacal_identify.core.walk.execution import PlanExecution, ReleaseRequest
from hexacal_identify.core.walk.mode_driver import walk_mode
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.settings import ExecutionState as State
import numpy as np
import pytest

L = 0.75
GS = 'gough_stewart'
NOMINAL = default_parameters(GS)
STROKE = default_stroke(NOMINAL)
POSES = sample_poses(
    NOMINAL, 3, np.random.default_rng(1), 'sphere', NOMINAL.architecture.default_workspace()
)
NAMES = NOMINAL.layout.actuator_names


def _mode(parameter='', plan_mode=None, names=None):
    return walk_mode(parameter, plan_mode, names, NOMINAL, POSES, L, STROKE)


def test_the_mode_comes_from_the_parameter_else_the_plan_else_compliant():
    assert _mode().mode == 'compliant' and _mode().source == 'default'
    assert _mode().released == (None, None, None)
    plan = _mode('', 'passive_actuator', [NAMES[2], NAMES[0], NAMES[2]])
    assert (plan.source, plan.released, plan.chosen) == ('plan', (2, 0, 2), 0)
    forced = _mode('compliant', 'passive_actuator', [NAMES[2]] * 3)
    assert forced.released == (None, None, None) and forced.source == 'measuring_mode'
    assert _mode('lvdt').describe(NAMES).endswith('all six actuators commanded')


def test_releases_the_plan_does_not_name_are_chosen_as_the_planner_chooses():
    from hexacal_identify.core.modes.released_actuator import choose_released_actuators

    chosen = _mode('passive_actuator', 'compliant', None)
    expected = choose_released_actuators(NOMINAL, POSES, L, STROKE).released
    assert chosen.released == tuple(int(i) for i in expected) and chosen.chosen == 3
    assert '3 releases chosen here' in chosen.describe(NAMES)
    partly = _mode('', 'passive_actuator', [None, NAMES[5], None])
    assert partly.released[1] == 5 and partly.chosen == 2


def test_a_release_of_an_unknown_joint_is_named():
    with pytest.raises(ValueError, match='releases slider_9: not actuators of the model'):
        _mode('', 'passive_actuator', ['slider_9'] * 3)
    with pytest.raises(ValueError, match='must be one of'):
        _mode('rigid')


def _execution(released):
    targets, problems = plan_targets(NOMINAL, POSES, ['sphere'] * 3, STROKE, L)
    assert not problems
    settings = ExecutionSettings(settle_s=0.2, wait_for_posture=False, path_step_m=0.0)
    execution = PlanExecution(
        NOMINAL, POSES, ['sphere'] * 3, targets, settings, STROKE, L, released=released
    )
    execution.on_actuators(0.0, targets[0])
    return execution, targets


def _stand(execution, start, positions, seconds=1.5):
    """Feed still readings at `positions` from `start`; return the commands of each step."""
    commands = []
    for now in np.arange(start, start + seconds, 0.02):
        execution.on_actuators(now, positions)
        commands += execution.step(now)
    return commands


def test_each_posture_is_released_at_rest_and_judged_on_the_five_commanded():
    execution, targets = _execution([2, 2, 4])
    assert execution.start(0.0) == []  # nothing moves before the drive has released chain 3
    assert execution.release_request == ReleaseRequest(0, None, 2)
    assert execution.step(0.1) == []  # no timeout, no command while releasing
    commands = execution.on_release(0.1, 2, '')
    assert len(commands) == 1 and execution.released_now == 2
    np.testing.assert_allclose(commands[0].positions, targets[0])
    # The released chain stands 8 mm from its nominal target (the link puts it there): measured.
    standing = targets[0] + np.array([0, 0, 8e-3, 0, 0, 0])
    after = _stand(execution, 0.2, standing)
    assert execution.measured == 1 and len(after) == 1  # posture 2, same release: no swap
    assert execution.release_request is None
    after = _stand(execution, 2.0, targets[1] + np.array([0, 0, -6e-3, 0, 0, 0]), 20.0)
    assert execution.measured == 2 and after == []
    assert execution.release_request == ReleaseRequest(2, 2, 4)  # lock 3, release 5, at rest


def test_a_refused_release_pauses_with_the_drives_answer_and_resume_asks_again():
    execution, targets = _execution([1, 1, 1])
    execution.start(0.0)
    hold = execution.on_release(0.5, None, 'the drive refused to release slider_2: moving')
    assert execution.state == State.PAUSED and hold == []  # nothing sent yet: nothing to hold
    assert 'the drive refused to release slider_2: moving' in execution.notice
    assert 'hexacal/executor/resume' in execution.notice
    assert _stand(execution, 0.6, targets[0], 1.0) == []  # paused: never moves on blindly
    success, _, commands = execution.resume(2.0)
    assert success and commands == [] and execution.notice == ''
    assert execution.release_request == ReleaseRequest(0, None, 1)
    assert len(execution.on_release(2.1, 1, '')) == 1


def test_a_move_the_guard_refuses_is_not_sent_and_the_plan_pauses():
    targets, _ = plan_targets(NOMINAL, POSES, ['sphere'] * 3, STROKE, L)
    asked = []

    def guard(current, start, points, released):
        asked.append((current.copy(), start.copy(), points.copy(), released))
        return 'the link would be stretched by 9 mm' if len(asked) == 2 else ''

    settings = ExecutionSettings(settle_s=0.2, wait_for_posture=False, path_step_m=0.0)
    execution = PlanExecution(
        NOMINAL, POSES, ['sphere'] * 3, targets, settings, STROKE, L, guard=guard
    )
    execution.on_actuators(0.0, targets[0])
    assert len(execution.start(0.0)) == 1 and len(asked) == 1
    np.testing.assert_allclose(asked[0][2][-1], targets[0])  # the points it was asked about
    after = _stand(execution, 0.1, targets[0])
    assert [c.purpose for c in after] == ['hold']  # where it stands: the move is not sent
    assert execution.state == State.PAUSED and execution.measured == 1
    assert execution.notice.startswith(
        'posture 2 of 3: the move was not sent: the link would be stretched by 9 mm'
    )
    success, _, commands = execution.resume(5.0)  # asks the guard again: now fine
    assert success and len(commands) == 1 and len(asked) == 3


def test_a_drive_fault_pauses_the_plan_without_a_command():
    execution, targets = _execution([None, None, None])
    assert len(execution.start(0.0)) == 1
    assert execution.on_drive_fault(0.5, 'following error 0.8 mm') == []
    assert execution.state == State.PAUSED
    assert execution.notice.startswith(
        'the drive faulted: following error 0.8 mm; reset the drive (hexacal/driver/reset) and '
        'resume'
    )
    assert execution.on_drive_fault(0.6, 'again') == []  # paused: said once
    assert 'again' not in execution.notice
    assert execution.on_link(0.7, 9e-3, 4e-3) == []  # paused: nothing more


def test_the_status_names_the_mode_the_released_joint_and_the_notice():
    from hexacal_identify.core.walk_device.turns import DeviceTurnSetter
    from hexacal_identify.core.sessions.executor_session import CalibrationCall, ExecutorStatus

    execution, _ = _execution([2, 2, 4])
    status = ExecutorStatus(
        execution, 'p', GS, [], CalibrationCall(False, '/hexacal/calibrate'), DeviceTurnSetter({})
    )
    assert 'measuring_mode' not in status.values(0.0)  # unset: as before the modes had names
    status.measuring_mode, status.joint_names = 'passive_actuator', tuple(NAMES)
    execution.start(0.0)
    assert status.values(0.1)['released_joint'] == ''
    execution.on_release(0.2, 2, '')
    values = status.values(0.3)
    assert values['released_joint'] == NAMES[2] and values['measuring_mode'] == 'passive_actuator'
    execution.on_drive_fault(0.4, 'jam')
    values = status.values(0.5)
    assert values['notice'].startswith('the drive faulted: jam') and status.level(values) == 'WARN'
    assert 'the drive faulted: jam' in status.text(values)
    compliant = _mode('', 'passive_actuator', [NAMES[1]] * 3).all_six('no release service')
    assert compliant.mode == 'compliant' and compliant.released == (None, None, None)
