"""core/walk_refine/refined_targets.py: the walk's stop for an intermediate calibration, no DDS."""

from __future__ import annotations

import math

from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
from hexacal_identify.core.walk.execution import PlanExecution
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.settings import ExecutionState as State
from hexacal_identify.core.walk_refine.refined_targets import (
    NOMINAL_TARGETS,
    refine_checkpoints,
    RefineCall,
    RefineState,
    targets_model_label,
)
from hexacal_identify.core.walk_refine.refinement import full_rank_postures, refinement_checkpoints
import numpy as np

L = 0.75
NOMINAL = nominal_set(2, seed=0)
TRUTH = table1_parameters()
REST = np.array([[0, 0, -L, 0, 0, 0.0]])


def _execution(count: int, refine_at: tuple[int, ...]) -> PlanExecution:
    workspace = NOMINAL.architecture.default_workspace()
    poses = sample_poses(NOMINAL, count, np.random.default_rng(3), 'sphere', workspace)
    kinds = ['sphere'] * count
    stroke = default_stroke(NOMINAL)
    return PlanExecution(
        NOMINAL,
        poses,
        kinds,
        check_plan(NOMINAL, poses, kinds, stroke, L),
        ExecutionSettings(max_actuator_speed_m_s=0.5, settle_s=0.2, wait_for_posture=False),
        stroke,
        L,
        refine_at=refine_at,
    )


def _walk(execution: PlanExecution, until: float, dt: float = 0.05) -> list:
    """Reach each command at once (a machine without strain); return the commands sent."""
    t, sent = 0.0, []
    position = inverse_kinematics(NOMINAL, REST)[0]
    while t < until and execution.state == State.RUNNING or t == 0.0:
        execution.on_actuators(t, position)
        commands = execution.start(t) if execution.state == State.WAITING else execution.step(t)
        for command in commands:
            sent.append(command)
            position = command.positions
        if execution.refine_request is not None:
            return sent
        t += dt
    return sent


def test_the_schedule_is_the_refinement_modules():
    n = NOMINAL.layout.n_parameters
    assert full_rank_postures(n) == math.ceil(2 * n / 5)
    assert refine_checkpoints(True, n, 200) == refinement_checkpoints(200, full_rank_postures(n))
    assert refine_checkpoints(False, n, 200) == ()
    assert refine_checkpoints(True, n, full_rank_postures(n)) == ()  # nothing left to refine


def test_the_walk_stops_at_rest_at_the_checkpoint_and_retargets_on_the_model():
    execution = _execution(6, (2,))
    sent = _walk(execution, 60.0)
    assert execution.refine_request == 2 and execution.measured == 2
    assert execution.targets_model == NOMINAL_TARGETS == 'nominal'
    assert execution.step(1e3) == []  # at rest while the calibration runs: no timeout
    assert len(sent) == 2 and execution.index == 2
    commands = execution.on_refined(100.0, TRUTH, 'targets from the calibration')
    np.testing.assert_allclose(
        execution.targets[2:], inverse_kinematics(TRUTH, execution.poses[2:]), atol=1e-12
    )
    np.testing.assert_array_equal(
        execution.targets[:2], inverse_kinematics(NOMINAL, execution.poses[:2])
    )
    assert len(commands) == 1 and execution.nominal is TRUTH
    np.testing.assert_allclose(commands[0].positions, execution.targets[2], atol=1e-12)
    assert execution.targets_model == targets_model_label(2) == 'calibration after 2 postures'
    assert execution.refine_message == 'targets from the calibration'
    assert execution.refine_request is None and not execution.refine_at


def test_a_failed_calibration_leaves_the_targets():
    execution = _execution(4, (2,))
    _walk(execution, 60.0)
    before = execution.targets.copy()
    commands = execution.on_refined(100.0, None, 'intermediate calibration failed: rank')
    np.testing.assert_array_equal(execution.targets, before)
    assert execution.targets_model == 'nominal' and execution.nominal is NOMINAL
    np.testing.assert_allclose(commands[0].positions, before[2], atol=1e-12)


def test_paused_while_refining_the_model_still_applies_and_resume_begins_the_posture():
    execution = _execution(4, (2,))
    _walk(execution, 60.0)
    assert execution.pause(50.0)[0] and execution.state == State.PAUSED
    assert execution.on_refined(51.0, TRUTH, 'ok') == []
    ok, _, commands = execution.resume(52.0)
    assert ok and len(commands) == 1
    np.testing.assert_allclose(
        commands[0].positions, inverse_kinematics(TRUTH, execution.poses[2:3])[0], atol=1e-12
    )


def test_the_call_needs_the_answer_and_the_parameters_in_either_order():
    call = RefineCall(NOMINAL, timeout_s=5.0)
    assert call.start(0.0, 17, service_ready=True) and call.state == RefineState.WAITING
    call.parameters(TRUTH.vector)
    call.poll(1.0)
    assert call.state == RefineState.WAITING
    call.answer(True, 'calibrated')
    call.poll(2.0)
    assert call.state == RefineState.DONE
    np.testing.assert_array_equal(call.model.vector, TRUTH.vector)
    assert call.message == 'targets from the calibration after 17 postures'


def test_a_refused_late_or_absent_calibration_gives_no_model():
    call = RefineCall(NOMINAL, timeout_s=5.0)
    call.start(0.0, 17, True)
    call.answer(False, 'rank deficient')
    assert call.state == RefineState.DONE and call.model is None
    assert 'rank deficient' in call.message
    call.start(10.0, 34, True)
    call.answer(True, 'calibrated')
    call.poll(16.0)
    assert call.model is None and 'the parameters did not come within 5 s' in call.message
    call.start(20.0, 40, True)
    call.parameters(np.ones(3))  # not this model's layout
    call.answer(True, 'calibrated')
    call.poll(21.0)
    assert call.model is None and 'do not fit' in call.message
    call.messages.clear()
    assert not call.start(30.0, 50, service_ready=False)
    assert not call.start(40.0, 60, service_ready=False)
    assert call.model is None and len(call.messages) == 1  # said once
    assert 'no calibration service' in call.messages[0][1]


def test_the_executor_setup_schedules_refinement_and_guards_on_the_intermediate_model():
    from hexacal_identify.core.architectures import default_parameters
    from hexacal_identify.core.planning.planner import Plan
    from hexacal_identify.core.walk_device.turns import DeviceTurnSetter
    from hexacal_identify.core.sessions.executor_session import (
        CalibrationCall,
        ExecutorStatus,
        model_defaults,
        refined_guard,
        setup_walk,
    )
    from hexacal_identify.nodes.executor_parameters import PARAMETERS

    nominal = default_parameters('gough_stewart')
    count = 24
    poses = sample_poses(nominal, count, np.random.default_rng(0), 'sphere')
    for mode, guarded in (('', False), ('compliant', True)):
        plan = Plan('refine', L, poses, ['sphere'] * count, measuring_mode=mode or None)
        defaults, source = model_defaults(plan.metadata, nominal)
        values = {name: spec.default for name, spec in PARAMETERS.items()} | defaults
        setup = setup_walk(values, nominal, plan, source, defaults['stroke_limits_m'])
        assert setup.execution.refine_at == [17]  # refine_targets is on by default
        assert (refined_guard(setup, nominal) is not None) == guarded
        status = ExecutorStatus(
            setup.execution, 'refine', nominal.model, [], CalibrationCall(False, 'c'),
            DeviceTurnSetter({}),
        )
        assert status.values(0.0)['targets_model'] == 'nominal'
        off = setup_walk(
            values | {'refine_targets': False}, nominal, plan, source, defaults['stroke_limits_m']
        )
        assert off.execution.refine_at == []
