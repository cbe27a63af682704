"""Units by the kind of actuator: a rotary hexapod's cranks in rad, N m, deg; sliders unchanged."""

import math

from hexacal_identify.calibration_steps.calibration_run import weight_choice
from hexacal_identify.cli.demo import actuator_limits, SLIDER_DRIVE_LIMITS, SLIDER_EXECUTOR_LIMITS
from hexacal_identify.cli.demo_summary import build_summary, summary_lines
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.weighting import choose_weights
from hexacal_identify.core.machine.measurements import NoiseModel, ScatterFloor
from hexacal_identify.core.modes.released_actuator import DEFAULT_MARGIN_M, released_margin
from hexacal_identify.core.planning.plan_check import plan_targets
from hexacal_msgs_py.measuring_modes import (
    COMPLIANT_SERVO_STIFFNESS_N_PER_M,
    GUARD_FORCE_FRACTION,
    LINK_FORCE_LIMIT_N,
)
import numpy as np
import pytest

ROTARY = architecture('rotary_hexapod')
SLIDERS = ('hexa_slide', 'gough_stewart')
POSES = {
    'position_mean_m': 1e-6,
    'position_max_m': 2e-6,
    'orientation_mean_rad': 1e-6,
    'orientation_max_rad': 2e-6,
    'failed_postures': 0,
}


@pytest.mark.parametrize('model', SLIDERS)
def test_slider_limits_come_back_unchanged(model):
    arch = architecture(model)
    assert arch.actuator_quantities.unit == 'm' and arch.actuator_lever_m == 1.0
    for dimension in ('length', 'force', 'stiffness'):
        assert arch.actuator_limit(0.123, dimension) == 0.123
    assert arch.released_margin == DEFAULT_MARGIN_M
    assert released_margin(arch.default_parameters()) == DEFAULT_MARGIN_M
    assert actuator_limits(arch, SLIDER_DRIVE_LIMITS) == {}  # the nodes' own defaults


def test_crank_limits_are_the_same_travel_at_the_crank_tip():
    lever = ROTARY.actuator_lever_m
    assert ROTARY.actuator_quantities.unit == 'rad' and 0.1 <= lever <= 0.2
    # 5 mm at the tip of the crank is 5 mm / lever rad; a force F at the tip is a torque F lever.
    assert ROTARY.released_margin == pytest.approx(0.005 / lever)
    assert ROTARY.actuator_limit(100.0, 'force') == pytest.approx(100.0 * lever)
    assert ROTARY.actuator_limit(2e6, 'stiffness') == pytest.approx(2e6 * lever**2)
    assert released_margin(ROTARY.default_parameters(), 0.01) == 0.01  # given: kept
    with pytest.raises(ValueError, match="'speed'"):
        ROTARY.actuator_limit(1.0, 'speed')
    drive = actuator_limits(ROTARY, SLIDER_DRIVE_LIMITS)
    assert drive['max_following_error_m'] == pytest.approx(5e-4 / lever)
    assert drive['max_force_n'] == pytest.approx(LINK_FORCE_LIMIT_N * lever)
    assert drive['servo_stiffness_n_per_m'] == pytest.approx(
        COMPLIANT_SERVO_STIFFNESS_N_PER_M * lever**2
    )
    assert 'max_link_force_n' not in drive  # on the link: N for every architecture
    executor = actuator_limits(ROTARY, SLIDER_EXECUTOR_LIMITS)
    assert executor['position_tolerance_m'] == pytest.approx(5e-3 / lever)
    # The executor's guard predicts the driver's servos: the same stiffness, and a torque limit
    # inside the drives' by the guard's margin.
    assert executor['servo_stiffness_n_per_m'] == drive['servo_stiffness_n_per_m']
    assert executor['max_force_n'] == pytest.approx(GUARD_FORCE_FRACTION * drive['max_force_n'])


def test_the_demo_prints_a_cranks_deviation_in_urad_and_its_torque_in_n_m():
    driver = {'max_actuator_deviation_m': '0.0012', 'max_force_n': '620.5'}
    summary = build_summary(
        model='rotary_hexapod',
        measuring_mode='compliant',
        postures=20,
        driver_values=driver,
        pose_errors=POSES,
        verification=None,
    )
    assert summary['actuator_unit'] == 'rad' and summary['max_force_n'] == 620.5
    text = '\n'.join(summary_lines(summary))
    assert '1200.0 urad' in text and 'largest actuator torque: 620.5 N m' in text
    assert ' um' not in text and ' N\n' not in text + '\n'
    slider = build_summary(
        model='hexa_slide',
        measuring_mode='compliant',
        postures=20,
        driver_values=driver,
        pose_errors=POSES,
        verification=None,
    )
    assert slider['actuator_unit'] == 'm'
    assert 'largest actuator force: 620.5 N' in '\n'.join(summary_lines(slider))


def test_weights_name_the_actuators_unit():
    noise = NoiseModel.from_microns(10.0)
    crank = choose_weights('noise-model', 0, 5, noise, ScatterFloor(), 'rad')
    assert '+-10 urad on the actuators' in crank.note
    assert '+-10 um on the actuators' in choose_weights('noise-model', 0, 5, noise).note
    assert '0.1 urad / 0.1 urad' in choose_weights('auto', 5, 5, None, ScatterFloor(), 'rad').note
    assert weight_choice([], 'none', None, ScatterFloor(), 'rad').note.startswith('unweighted')


def test_a_crank_target_outside_its_stroke_is_named_in_rad():
    nominal = ROTARY.default_parameters()
    workspace = ROTARY.default_workspace()
    pose = np.array([[0.05, 0.0, -math.sqrt(0.75**2 - 0.05**2), 0.0, 0.0, 0.0]])
    targets, problems = plan_targets(nominal, pose, ['sphere'], (-0.01, 0.01), 0.75)
    assert np.all(np.isfinite(targets)) and workspace.actuator_stroke_m == (-1.2, 1.2)
    assert 'outside the stroke [-0.01, 0.01] rad' in problems[0] and 'crank_' in problems[0]
    assert ' m:' not in problems[0]


def test_refinement_lines_show_a_cranks_deviation_in_urad_and_torque_in_n_m():
    from hexacal_identify.cli.demo_refinement import refinement_lines
    from hexacal_msgs_py.models import ROTARY_ACTUATOR

    phase = {
        'max_actuator_deviation_m': 2e-3,
        'max_force_n': 90.0,
        'max_move_force_n': 95.0,
        'max_link_extension_m': None,
        'max_move_link_extension_m': None,
    }
    refinement = {
        'postures_on_nominal': 20,
        'postures_on_refined': 6,
        'before': phase,
        'after': {**phase, 'max_actuator_deviation_m': 1e-6, 'max_force_n': 1.0},
    }
    lines = refinement_lines(refinement, ROTARY_ACTUATOR)
    assert 'deviation 2000.0 -> 1.0 urad' in lines[0]
    assert 'torque at rest 90.0 -> 1.0 N m' in lines[1]
    assert 'force at rest 90.0 -> 1.0 N,' in refinement_lines(refinement)[1]  # sliders
