"""The demo's summary.json: the drives' figures per measuring mode, null where not applicable."""

import json

from hexacal_identify.cli.demo_summary import (
    build_summary,
    driver_figures,
    status_number,
    summary_lines,
    write_summary,
)

DRIVER = {
    'measuring_mode': 'compliant',
    'state': 'ok',
    'max_actuator_deviation_m': '0.003964',
    'max_force_n': '7928.0',
    'max_link_force_n': '15448.7',
    'max_link_extension_m': '',
}
POSES = {
    'position_mean_m': 1.1e-6,
    'position_max_m': 3.2e-6,
    'orientation_mean_rad': 2e-6,
    'orientation_max_rad': 5e-6,
    'failed_postures': 0,
}


def test_status_numbers_are_finite_or_none():
    assert status_number({'a': '1.5e-3'}, 'a') == 1.5e-3
    assert status_number({'a': ''}, 'a') is None
    assert status_number({}, 'a') is None
    assert status_number({'a': 'nan'}, 'a') is None
    assert status_number({'a': 'fault'}, 'a') is None


def test_only_the_figures_of_the_mode_are_given():
    compliant = driver_figures(DRIVER, 'compliant')
    assert compliant == {
        'max_actuator_deviation_m': 0.003964,
        'max_link_extension_m': None,
        'max_force_n': 7928.0,
        'max_link_force_n': 15448.7,
    }
    lvdt = driver_figures({**DRIVER, 'max_link_extension_m': '0.0012'}, 'lvdt')
    assert lvdt['max_link_extension_m'] == 0.0012 and lvdt['max_force_n'] is None
    # The kinematic drives model the link's force in the compliant mode only ('' otherwise).
    unloaded = {**DRIVER, 'max_link_force_n': ''}
    passive = driver_figures(unloaded, 'passive_actuator')
    assert passive['max_force_n'] is None and passive['max_link_extension_m'] is None
    assert passive['max_link_force_n'] is None
    assert driver_figures({**unloaded, 'max_link_extension_m': '0.0012'}, 'lvdt')[
        'max_link_force_n'] is None
    # The MuJoCo machine measures the link's force in every mode: a passive link bears load.
    mujoco = driver_figures({**DRIVER, 'max_link_force_n': '586.0'}, 'passive_actuator')
    assert mujoco['max_link_force_n'] == 586.0 and mujoco['max_force_n'] is None


def test_summary_is_written_as_json_with_the_keys_and_printed_in_um(tmp_path):
    verification = {'postures': 8, 'nominal': {'position_rms_m': 1e-3}, 'verdict': 'pass'}
    summary = build_summary(
        model='hexa_slide',
        measuring_mode='compliant',
        postures=20,
        driver_values=DRIVER,
        pose_errors=POSES,
        verification=verification,
    )
    path = write_summary(tmp_path / 'summary.json', summary)
    loaded = json.loads(path.read_text())
    assert loaded['measuring_mode'] == 'compliant' and loaded['postures'] == 20
    assert loaded['pose_error_mean_m'] == 1.1e-6 and loaded['pose_error_max_m'] == 3.2e-6
    assert loaded['max_link_extension_m'] is None and loaded['max_force_n'] == 7928.0
    assert loaded['verification'] == verification
    assert not list(tmp_path.glob('*.tmp*'))  # atomic: no temporary file left
    text = '\n'.join(summary_lines(summary))
    assert '3964.0 um' in text and '7928.0 N' in text and 'extension' not in text
    assert 'largest measuring-link force: 15448.7 N' in text
    assert 'beyond the 500 N a measuring link' in text  # and what to do instead
    within = build_summary(
        model='hexa_slide', measuring_mode='passive_actuator', postures=20,
        driver_values={**DRIVER, 'max_link_force_n': '420.0'}, pose_errors=POSES,
        verification=verification,
    )
    text = '\n'.join(summary_lines(within))
    assert 'largest measuring-link force: 420.0 N' in text and 'beyond' not in text


def test_a_summary_without_verification_or_driver_status_has_nulls():
    summary = build_summary(
        model='hexa_slide',
        measuring_mode='passive_actuator',
        postures=12,
        driver_values={},
        pose_errors=POSES,
        verification=None,
    )
    assert summary['verification'] is None and summary['max_actuator_deviation_m'] is None
    assert json.loads(json.dumps(summary, allow_nan=False)) == summary
    assert 'n/a' in '\n'.join(summary_lines(summary))


def test_summary_says_which_machine_and_the_fits_adequacy():
    fit = {'adequacy.verdict': 'fail', 'adequacy.variance_factor': '2.7e4', 'outcome': 'ok'}
    summary = build_summary(
        model='hexa_slide',
        measuring_mode='passive_actuator',
        postures=20,
        driver_values=DRIVER,
        pose_errors=POSES,
        verification=None,
        physics='mujoco',
        fit=fit,
    )
    assert summary['physics'] == 'mujoco'
    assert summary['adequacy'] == {'verdict': 'fail', 'variance_factor': 27000.0}
    plain = build_summary(
        model='hexa_slide',
        measuring_mode='passive_actuator',
        postures=20,
        driver_values=DRIVER,
        pose_errors=POSES,
        verification=None,
    )
    assert plain['physics'] == 'kinematic'
    assert plain['adequacy'] == {'verdict': 'unknown', 'variance_factor': None}
