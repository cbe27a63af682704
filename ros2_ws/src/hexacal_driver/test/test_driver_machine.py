"""Unit tests of what the driver decides without ROS: parameter problems, the machine, reports."""

from __future__ import annotations

import math

from hexacal_driver.machine import DriverConfigurationError, SimulatedMachine, true_machine
from hexacal_driver.parameters import parameter_problem, PARAMETERS, RUNTIME_PARAMETERS
from hexacal_driver.plan import save_plan
from hexacal_driver.reports import (
    finish_lines,
    machine_source,
    MotionReport,
    plan_start_text,
    WalkReport,
)
from hexacal_driver.simulation import DONE, DWELLING, MOVING, SETTLING, STILL
from hexacal_identify.core.architectures import default_parameters
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np
import pytest

GS = 'gough_stewart'


def values(**changes) -> dict:
    value = {name: spec.default for name, spec in PARAMETERS.items()}
    value.update(changes)
    return value


# --------------------------------------------------------------------------- parameters


def test_only_noise_and_turn_change_at_run_time():
    assert RUNTIME_PARAMETERS == ('slider_noise_m', 'angle_noise_rad', 'device_turn')
    assert set(RUNTIME_PARAMETERS) <= set(PARAMETERS)


@pytest.mark.parametrize(
    'name, value, problem',
    [
        ('plan', '', "plan must be one of ['random', 'fixed', 'mixed'] or a plan file path"),
        ('plan', '/nonexistent/plan.yaml', 'is neither one of'),
        ('true_params', '/nonexistent/params.yaml', 'true_params: '),
        ('device_defects', 'dX=1', "device_defects 'dX=1': "),
        ('device_turn', 7.0, 'device_turn must be a finite angle within +-2 pi rad, got 7.0'),
        ('device_turn', math.nan, 'device_turn must be a finite angle'),
        (
            'model',
            'delta',
            "model must be '' or one of hexa_slide, gough_stewart, rotary_hexapod, got 'delta'",
        ),
        ('rate_hz', math.inf, 'rate_hz must be finite, got inf'),
        ('max_actuator_speed_m_s', math.nan, 'max_actuator_speed_m_s must be finite'),
    ],
)
def test_parameter_problems_are_named(name, value, problem):
    assert problem in parameter_problem(name, value)


@pytest.mark.parametrize(
    'name, value',
    [
        ('plan', 'mixed'),
        ('true_params', ''),
        ('device_defects', 'dL=1e-3'),
        ('model', ''),
        ('device_turn', -math.pi),
        ('rate_hz', 100.0),
        ('seed', 3),
    ],
)
def test_good_parameters_have_no_problem(name, value):
    assert parameter_problem(name, value) is None


def test_a_plan_file_is_checked_when_it_is_set(tmp_path):
    machine = SimulatedMachine(values(postures=4))
    path = tmp_path / 'plan.yaml'
    save_plan(path, machine.plan)
    assert parameter_problem('plan', str(path)) is None
    path.write_text(path.read_text().replace('kind: sphere', 'kind: flat', 1))
    assert "kind must be one of ['sphere', 'fixed']" in parameter_problem('plan', str(path))


# --------------------------------------------------------------------------- the machine


def test_the_default_machine_walks_a_generated_plan():
    machine = SimulatedMachine(values(postures=6, plan='mixed', seed=2))
    assert machine.model == 'hexa_slide' and machine.mount == 'hanging'
    assert machine.plan.name == 'mixed-6-seed2' and machine.follower is None
    assert machine.walker.settle_s == 1.0 and machine.walker.dwell_s == 1.5
    np.testing.assert_array_equal(machine.posture_turns(), np.zeros(6))
    readings, turn = machine.read(machine.walker.sample(0.0))
    assert turn == 0.0 and readings.actuators_m.shape == (6,)


def test_true_params_name_the_model_and_the_mount(tmp_path):
    path = tmp_path / 'gs.yaml'
    save_parameters(path, default_parameters(GS).vector, {'model': GS, 'device.mount': 'standing'})
    params, mount = true_machine(str(path), '')
    assert params.model == GS and mount == 'standing'
    with pytest.raises(DriverConfigurationError, match="model 'hexa_slide' contradicts"):
        true_machine(str(path), 'hexa_slide')
    path.write_text(path.read_text().replace('standing', 'sideways'))
    with pytest.raises(DriverConfigurationError, match='true_params: .*device mount must be'):
        true_machine(str(path), '')
    assert true_machine('', GS)[0].model == GS


def test_a_link_shortened_to_nothing_is_a_configuration_error():
    with pytest.raises(DriverConfigurationError, match='leaves no link'):
        SimulatedMachine(values(device_defects='dL=-0.8'))


def test_a_plan_for_another_link_is_a_configuration_error(tmp_path):
    machine = SimulatedMachine(values(postures=4))
    path = tmp_path / 'plan.yaml'
    save_plan(path, machine.plan)
    with pytest.raises(DriverConfigurationError, match="differs from the device's link length"):
        SimulatedMachine(values(plan=str(path), link_length=0.8))


def test_turns_and_noise_change_at_run_time():
    machine = SimulatedMachine(values(postures=4, device_defects='alpha0=1e-3'))
    walker = machine.walker
    assert machine.set_device_turn(0.0) is None  # unchanged
    assert machine.set_device_turn(math.pi) == 0.0
    assert machine.device_turn == math.pi and machine.posture_turn(2) == math.pi
    assert machine.walker is not walker  # a defective device re-places the fixed postures
    assert not machine.set_noise(None, None)
    assert machine.set_noise(2e-5, None)
    assert (machine.sensors.noise.actuator_m, machine.sensors.noise.angle_rad) == (2e-5, 1e-5)


def test_commanded_mode_stands_at_the_fixed_point_and_checks_commands():
    machine = SimulatedMachine(values(command_topic='/cmd'))
    assert machine.plan is None and machine.walker is None
    low, high = machine.stroke
    assert 0.0 <= low < high
    sample = machine.follower.sample(0.0)
    np.testing.assert_allclose(sample.pose, [0, 0, -0.75, 0, 0, 0], atol=1e-9)
    names = [f'slider_{i}' for i in range(1, 7)]
    target = [float(v) for v in sample.actuators]
    checked, problem = machine.check_command(names, [(target, 1.0)], 0, 10**9)
    assert problem is None and checked[-1].positions == pytest.approx(target)
    _, problem = machine.check_command(names, [(target, 1.0)], 1, 3 * 10**9)
    assert problem == 'it ends in the past (header.stamp + time_from_start)'
    _, problem = machine.check_command(names[:5], [(target[:5], 1.0)], 0, 0)
    assert problem is not None


# --------------------------------------------------------------------------- reports


def test_start_up_text_names_the_machine_and_the_plan():
    machine = SimulatedMachine(values(postures=4, device_turn=0.5, loop=True))
    source = machine_source('', machine)
    assert source == 'Table 1; device turned 0.5 rad about its link'
    text = plan_start_text(machine, source, 100.0)
    assert text.startswith("plan 'random-4-seed0': 4 postures (4 sphere, 0 fixed)")
    assert text.endswith('noise +-1e-05 m / +-1e-05 rad, looping')
    gs = SimulatedMachine(values(model=GS, command_topic='/cmd'))
    assert machine_source('', gs) == (
        'the default Gough-Stewart platform (6-UPS) (gough_stewart, joints leg_1, leg_2, leg_3, '
        'leg_4, leg_5, leg_6)'
    )


def test_walk_report_names_each_held_posture_once_and_the_end():
    machine = SimulatedMachine(values(postures=3, plan='fixed', loop=True))
    report = WalkReport(machine.plan, loop=True)
    assert report.lines(0, 0, SETTLING, 0.0, 0.0) == []
    first = report.lines(0, 0, DWELLING, 1.0, math.pi)
    assert len(first) == 1 and first[0].startswith('posture 1/3 (lap 1) (fixed): position [')
    assert first[0].endswith(', device turned 3.14159 rad')
    assert report.lines(0, 0, DWELLING, 1.1, math.pi) == []  # once per posture
    last = report.lines(2, 0, DWELLING, 5.0, 0.0)
    assert last[1] == "end of plan 'fixed-3-seed0' lap 1: looping"
    once = WalkReport(machine.plan, loop=False)
    assert once.lines(2, 0, DONE, 7.25, 0.0) == [
        "end of plan 'fixed-3-seed0': 3 postures in 7.2 s; standing at the last posture"
    ]


def test_motion_report_names_the_end_of_each_motion_and_the_strain():
    report = MotionReport()
    assert MotionReport.strain_warning(0.005) is None
    assert '20.0 mm from their setpoints' in MotionReport.strain_warning(0.02)
    assert report.motion_line(STILL, 0.0, 0) is None  # no command yet
    assert report.motion_line(MOVING, 0.0, 1) is None
    assert report.motion_line(STILL, 0.0, 1) == 'standing at the commanded position'
    assert report.motion_line(STILL, 0.0, 1) is None  # once per motion
    report.motion_line(MOVING, 0.0, 2)
    assert '3 um from the setpoints' in report.motion_line(STILL, 3e-6, 2)


def test_finish_lines_count_the_messages_and_the_commands():
    assert finish_lines(10, 4, 123, None) == [
        'published 10 messages on each sensor stream, 6 of them since the plan started '
        '(first stamp 123 ns)'
    ]
    assert finish_lines(1, 0, None, (2, 1))[1] == 'commands: 2 followed, 1 rejected'
