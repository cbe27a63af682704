"""The driver's log lines in the units of the machine's actuators: sliders in m, cranks in rad."""

import math

from hexacal_driver.machine import SimulatedMachine
from hexacal_driver.parameters import PARAMETERS
from hexacal_driver.reports import (
    command_text,
    commanded_start_text,
    drives_start_text,
    MotionReport,
    noise_text,
)
from hexacal_driver.simulation import check_trajectory
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_msgs_py.models import LINEAR_ACTUATOR, MODELS, ROTARY_ACTUATOR
import numpy as np

TOPIC = '/joint_trajectory_controller/joint_trajectory'


def machine(**overrides) -> SimulatedMachine:
    """Return the commanded simulated machine of the node's defaults with `overrides`."""
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values['command_topic'] = TOPIC
    values.update(overrides)
    return SimulatedMachine(values)


def test_a_rotary_machine_logs_its_drives_in_rad_and_n_m():
    rotary = machine(model='rotary_hexapod')
    compliant = drives_start_text(rotary.follower)
    assert 'servos of 20000 N m/rad' in compliant and 'above 500 N m on a servo' in compliant
    assert 'or 500 N on the link' in compliant  # the link's force: N whatever the actuators
    stiff = drives_start_text(machine(model='rotary_hexapod', measuring_mode='lvdt').follower)
    assert '0.0005 rad following error' in stiff and 'LVDT link stroke +-0.005 m' in stiff
    start = commanded_start_text(rotary, TOPIC, 'the default', 100.0)
    assert 'rad/s' in start and '1.2] rad)' in start and 'crank_1' in start
    assert ' m/s' not in start and '] m)' not in start
    assert 'noise +-1e-05 rad / +-1e-05 rad' in start


def test_a_slider_machine_logs_as_before():
    slider = machine()
    assert (
        'compliant servos of 20000 N/m, fault above 500 N on a servo or 500 N on the link'
        in drives_start_text(slider.follower)
    )
    start = commanded_start_text(slider, TOPIC, 'Table 1', 100.0)
    assert ' m/s, stroke [' in start and '] m);' in start
    assert noise_text(NoiseModel(1e-5, 2e-5)) == '+-1e-05 m / +-2e-05 rad'


def test_commands_and_strain_are_shown_in_mm_for_sliders_and_deg_for_cranks():
    target = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    assert '[100.000, 200.000' in command_text(1, target, 1.0) and '] mm in' in command_text(
        1, target, 1.0
    )
    crank = command_text(2, np.full(6, math.pi / 2), 1.0, ROTARY_ACTUATOR)
    assert '[90.000, 90.000' in crank and '] deg in 1.00 s' in crank
    assert '20.0 mm from their setpoints' in MotionReport.strain_warning(0.02, LINEAR_ACTUATOR)
    assert '1.1 deg from their setpoints' in MotionReport.strain_warning(0.02, ROTARY_ACTUATOR)
    report = MotionReport()
    report.motion_line('moving', 0.0, 1, ROTARY_ACTUATOR)
    assert '3 urad from the setpoints' in report.motion_line('still', 3e-6, 1, ROTARY_ACTUATOR)


def test_a_crank_command_outside_its_stroke_is_refused_in_rad():
    names = MODELS['rotary_hexapod'].actuator_names
    points = [([2.0] + [0.0] * 5, 1.0)]
    _, problem = check_trajectory(list(names), points, names, (-1.2, 1.2), 'rad')
    assert 'stroke [-1.2, 1.2] rad' in problem and 'crank_1 2 rad' in problem
