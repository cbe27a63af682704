"""core/sessions/executor_session.py: the executor node's set-up, status, calibration, checks."""

from __future__ import annotations

import math

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.planner import Plan
from hexacal_identify.core.sessions.executor_session import (
    CalibrationCall,
    CalibrationState,
    ExecutorStatus,
    model_defaults,
    parameter_problem,
    plan_mismatch,
    SERVICE_WAIT_S,
    setup_walk,
    STATUS_PERIOD_S,
    walk_link_load,
)
from hexacal_identify.core.walk.messages import LogLevel
from hexacal_identify.core.walk.settings import ExecutionState
from hexacal_identify.core.walk_device.turns import DeviceTurnSetter
from hexacal_identify.nodes.executor_parameters import MODEL_PARAMETERS, PARAMETERS
import numpy as np
import pytest

L = 0.75
NOMINAL = default_parameters()


def _plan(count: int = 4, turns=None) -> Plan:
    poses = sample_poses(NOMINAL, count, np.random.default_rng(0), 'sphere')
    return Plan('test-plan', L, poses, ['sphere'] * count, device_turns=turns)


def _values(plan: Plan, **changed) -> dict[str, object]:
    """Return the node's parameter values at their defaults (the model's too)."""
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    defaults, _ = model_defaults(plan.metadata, NOMINAL)
    values.update(defaults)
    values.update(changed)
    return values


def _setup(plan: Plan, **changed):
    defaults, source = model_defaults(plan.metadata, NOMINAL)
    return setup_walk(
        _values(plan, **changed), NOMINAL, plan, source, defaults['stroke_limits_m']
    )


def test_parameter_problems_beyond_type_and_range():
    assert parameter_problem('plan', '') == "parameter 'plan' is required (-p plan:=<path>)"
    assert parameter_problem('command_topic', '') == 'command_topic must name a topic'
    assert parameter_problem('settle_s', math.nan) == 'settle_s must be finite, got nan'
    assert parameter_problem('stroke_limits_m', [0.5, 0.1]).startswith('stroke_limits_m: ')
    assert parameter_problem('actuator_joints', ['a'] * 6) == (
        f"actuator_joints must be 6 distinct joint names, got {['a'] * 6!r}"
    )
    assert parameter_problem('inclinometer_joints', ['alpha', '']) is not None
    assert parameter_problem('device_turn_nodes', ['collector', '/ns/driver']) is None
    assert parameter_problem('device_turn_nodes', ['collector', 'collector']) is not None
    assert parameter_problem('device_turn_nodes', ['no spaces']) is not None
    assert parameter_problem('timeout_s', 10.0) is None
    assert set(MODEL_PARAMETERS) == {'stroke_limits_m', 'actuator_joints'}


def test_a_plan_for_another_model_or_mount_is_named():
    assert plan_mismatch('p.yaml', 'hexa_slide', 'hanging', 'hexa_slide', None) is None
    assert plan_mismatch('p.yaml', 'hexa_slide', 'standing', 'hexa_slide', None) is None
    assert 'is for a standing device' in plan_mismatch(
        'p.yaml', 'hexa_slide', 'standing', 'hexa_slide', 'hanging'
    )
    assert 'was made for a hexa_slide' in plan_mismatch(
        'p.yaml', 'hexa_slide', 'hanging', 'gough_stewart', None
    )


def test_setup_walks_a_plan_within_the_stroke_and_names_the_stroke_source():
    plan = _plan()
    setup = _setup(plan)
    assert setup.problems == {} and setup.refusal == ''
    assert setup.execution.state == ExecutionState.WAITING and setup.execution.total == 4
    assert setup.actuator_joints == tuple(NOMINAL.layout.actuator_names)
    assert setup.stroke_source == "the hexa_slide's default workspace"
    lines = setup.start_lines(plan, NOMINAL.model, '/cmd')
    assert lines[0].startswith("plan 'test-plan': 4 postures (4 sphere, 0 fixed) for a hexa_slide")
    assert len(lines) == 1  # no turning procedure
    narrow = _setup(plan, stroke_limits_m=[0.0, 0.01])
    assert narrow.stroke_source == 'stroke_limits_m'
    assert narrow.execution.state == ExecutionState.REFUSED
    assert sorted(narrow.problems) == [0, 1, 2, 3]
    assert narrow.execution.refusal == narrow.refusal
    assert narrow.refusal.startswith('plan refused before anything moved: 4 of 4 postures')


def test_the_link_load_is_weighed_only_for_a_passive_plan_made_with_it(tmp_path):
    from dataclasses import replace

    from hexacal_msgs_py.measuring_modes import MeasuringMode
    from hexacal_msgs_py.physical_file import default_physical, write_physical_file

    passive, limit = MeasuringMode.PASSIVE_ACTUATOR, {'link_force_limit_n': 450.0}
    assert walk_link_load('', {}, 'hexa_slide', passive) == (None, '')  # planned without it
    assert walk_link_load('', limit, 'hexa_slide', MeasuringMode.LVDT) == (None, '')
    shipped, source = walk_link_load('', limit, 'hexa_slide', passive)
    assert shipped is not None and shipped.max_force_n == 450.0
    assert shipped.masses.platform_mass == default_physical('hexa_slide').platform_mass
    assert source == 'the shipped hexa_slide physical description'
    heavy = write_physical_file(tmp_path / 'heavy.yaml',
                                replace(default_physical('hexa_slide'), payload_mass=7.5))
    given, _ = walk_link_load(str(heavy), limit, 'hexa_slide', passive)
    assert given is not None and given.masses.payload_mass == 7.5
    with pytest.raises(ValueError, match='physical_file: cannot read'):
        walk_link_load(str(tmp_path / 'missing.yaml'), limit, 'hexa_slide', passive)
    plan = _plan()
    plan = replace(plan, metadata={**(plan.metadata or {}), **limit})
    setup = _setup(plan, measuring_mode='passive_actuator', physical_file=str(heavy))
    assert setup.execution.link_load is not None
    assert setup.execution.link_load.masses.payload_mass == 7.5
    assert setup.start_lines(plan, NOMINAL.model, '/cmd')[-1].endswith(
        f"within the plan's 450 N (weights: {heavy})"
    )
    assert _setup(_plan(), measuring_mode='passive_actuator').execution.link_load is None


def test_setup_refuses_parameters_that_describe_no_walk():
    plan = _plan()
    with pytest.raises(ValueError, match='actuator_joints must be 6 distinct'):
        _setup(plan, actuator_joints=['a'] * 6)
    with pytest.raises(ValueError, match='stroke_limits_m: stroke limits'):
        _setup(plan, stroke_limits_m=[1.0, 0.0])
    with pytest.raises(ValueError, match='device_turn_nodes must be'):
        _setup(plan, device_turn_nodes=['a b'])
    with pytest.raises(ValueError, match='settle_s must be a positive'):
        _setup(plan, settle_s=0.0)


def test_status_fields_level_text_and_when_they_are_due():
    plan = _plan(turns=[0.0, 0.0, math.pi, math.pi])
    setup = _setup(plan, device_turn_nodes=['collector'])
    calibration = CalibrationCall(True, '/hexacal/calibrate')
    status = ExecutorStatus(
        setup.execution, plan.name, NOMINAL.model, [], calibration, DeviceTurnSetter({})
    )
    assert 'turning procedure: device turns [0.0, 180.0] deg' in setup.start_lines(
        plan, NOMINAL.model, '/cmd'
    )[1]
    status.waiting_for = ('a controller on /cmd',)
    values = status.values(0.0)
    assert values['state'] == 'waiting' and values['waiting_for'] == 'a controller on /cmd'
    assert values['calibration'] == 'pending' and values['device_turn_rad'] == 0.0
    assert values['plan'] == 'test-plan' and values['commands_sent'] == 0
    assert 'device_turn_set' not in values and 'invalid_readings' not in values
    assert status.text(values) == 'waiting for a controller on /cmd'
    assert status.level(values) == 'OK'
    assert status.due(0.0, values) and not status.due(0.5, values)
    assert status.due(0.5, values, force=True)
    assert status.due(0.5 + STATUS_PERIOD_S, values)  # the ETA at least once a period
    status.invalid_readings = 2
    assert status.due(0.6 + STATUS_PERIOD_S, status.values(0.6))  # a change is due at once
    assert not status.finished()
    setup.execution.abort(1.0)
    assert status.level(status.values(1.0)) == 'WARN' and status.finished()


def test_a_refused_plan_is_an_error_status_and_finished():
    plan = _plan()
    setup = _setup(plan, stroke_limits_m=[0.0, 0.01])
    status = ExecutorStatus(
        setup.execution,
        plan.name,
        NOMINAL.model,
        sorted(setup.problems),
        CalibrationCall(False, '/hexacal/calibrate'),
        DeviceTurnSetter({}),
    )
    values = status.values(0.0)
    assert values['refused_postures'] == '1, 2, 3, 4' and values['reason'] == setup.refusal
    assert 'calibration' not in values
    assert status.level(values) == 'ERROR' and status.text(values) == setup.refusal
    assert status.finished()


def test_the_calibration_is_called_once_the_service_is_there_or_fails_after_waiting():
    call = CalibrationCall(True, '/hexacal/calibrate')
    assert not call.answered
    assert not call.due(0.0, service_ready=False)
    assert call.messages == [(LogLevel.INFO, 'plan done: calling /hexacal/calibrate')]
    assert call.due(1.0, service_ready=True) and call.state == CalibrationState.RUNNING
    assert not call.due(1.1, service_ready=True)  # called once
    call.answer(True, 'converged')
    assert call.state == 'success' and call.answered and call.message == 'converged'
    late = CalibrationCall(True, '/hexacal/calibrate')
    late.due(0.0, service_ready=False)
    assert not late.due(SERVICE_WAIT_S + 0.1, service_ready=False)
    assert late.state == CalibrationState.FAILED
    assert late.message == '/hexacal/calibrate did not appear within 30 s'
    assert late.messages[-1][0] == LogLevel.ERROR
    disabled = CalibrationCall(False, '/hexacal/calibrate')
    assert disabled.state == 'disabled' and disabled.answered
    assert not disabled.due(0.0, service_ready=True)
