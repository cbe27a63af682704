"""`hexacal study` labels actuator quantities in the machine's unit: urad, deg, N m for cranks."""

import argparse

from hexacal_identify.cli import study, study_modes
from hexacal_identify.core.architectures import architecture
from hexacal_identify.studies.accuracy import StudyRun
from hexacal_identify.studies.measuring_mode_accuracy import DEFAULT_SERVO_STIFFNESS_N_PER_M
from hexacal_msgs_py.models import LINEAR_ACTUATOR, ROTARY_ACTUATOR
import pytest

FIGURES = {
    'max_actuator_deviation_m': 2e-4,
    'max_force_n': 120.0,
    'max_link_extension_m': 3e-5,
    'max_released_offset_m': 4e-4,
}


def _payload(mode: str) -> dict:
    return {
        'measuring_mode': mode,
        'refine': True,
        'postures': 20,
        'before_refinement': FIGURES,
        'after_refinement': FIGURES,
        'pose_error_mean_m': 2e-6,
        'pose_error_max_m': 5e-6,
        'rms_residual': {'x': 1e-6, 'y': 1e-6, 'z': 1e-6},
        'rank': 66,
        'failed_postures': 0,
        'lvdt_inside_stroke': None,
        'released_travel_max_m': 0.05 if mode == 'passive_actuator' else None,
    }


def _table(units) -> str:
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        study_modes.print_table([_payload('passive_actuator'), _payload('compliant')], units)
    return out.getvalue()


def test_a_cranks_deviation_torque_and_travel_are_in_urad_n_m_and_deg():
    text = _table(ROTARY_ACTUATOR)
    header = text.splitlines()[0]
    assert 'deviation urad' in header and 'released urad' in header
    assert 'torque N m' in header and 'force N' not in header
    assert '200.0 -> 200.0' in text  # 2e-4 rad is 200 urad
    assert 'travel up to 2.9 deg along a move' in text  # 0.05 rad
    assert ' mm ' not in text


def test_a_sliders_table_is_as_before():
    text = _table(LINEAR_ACTUATOR)
    header = text.splitlines()[0]
    assert 'deviation um' in header and 'force N' in header and 'released um' in header
    assert 'travel up to 50.0 mm along a move' in text


@pytest.mark.parametrize('model', ['hexa_slide', 'rotary_hexapod'])
def test_the_servo_stiffness_of_the_mode_study_is_the_models(model):
    args = argparse.Namespace(
        model=model, true_params=None, nominal_params=None, nominal_set=2, postures=10,
        noise_um=10.0, lvdt_noise_m=1e-6, lvdt_stroke_m=0.005, servo_stiffness_n_per_m=None,
        seed=0, cost='absolute', validation_postures=10, first_calibration=None,
        measuring_mode='compliant', refine=True,
    )
    (run,) = study_modes.mode_runs(args, None)
    lever = architecture(model).actuator_lever_m
    assert run.servo_stiffness_n_per_m == pytest.approx(DEFAULT_SERVO_STIFFNESS_N_PER_M * lever**2)
    args.servo_stiffness_n_per_m = 5e5  # given: kept
    assert study_modes.mode_runs(args, None)[0].servo_stiffness_n_per_m == 5e5


@pytest.mark.slow
def test_the_configured_runs_noise_is_in_urad_on_a_rotary_hexapod(capsys):
    truth = architecture('rotary_hexapod').default_parameters()
    study._print_configured(
        StudyRun(true_params=truth, postures=25, noise_um=10.0, validation_postures=10)
    )
    first = capsys.readouterr().out.strip().splitlines()[0]
    assert 'Configured run: 25 postures, +-10 urad, seed 0' in first
