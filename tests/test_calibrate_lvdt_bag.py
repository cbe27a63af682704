"""``hexacal calibrate`` on lvdt bags: the measured link lengths L_m replace L in eq. 4."""

import json
from pathlib import Path

from hexacal_identify.core import sample_poses, simulate_measurements, table1_parameters
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.parameters_file import load_parameters, save_parameters
import numpy as np
import pytest
from synthetic_recording import write_recording
from system_support import hexacal

TRUE = table1_parameters()
EXTENSION_M = 3e-3  # the true link lengths vary by up to +-3 mm about L
POSTURES = 40


def lvdt_measurements():
    """Return simulated readings at poses off the sphere by up to EXTENSION_M, with L_m."""
    poses = sample_poses(TRUE, POSTURES, np.random.default_rng(18))
    radius = np.linalg.norm(poses[:, :3], axis=1)
    extension = np.random.default_rng(7).uniform(-EXTENSION_M, EXTENSION_M, POSTURES)
    poses[:, :3] *= ((radius + extension) / radius)[:, None]
    exact = simulate_measurements(TRUE, poses, lvdt=True)
    assert np.ptp(exact.link_lengths) > 4e-3
    return exact


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Return the same readings: with the link (posture topic; raw only) and without it."""
    exact = lvdt_measurements()
    root = tmp_path_factory.mktemp('lvdt')
    measuring = {'measuring_mode': 'lvdt', 'released_actuators': '[]'}
    without = type(exact)(
        exact.actuator_positions, exact.inclinometer, exact.rotary, exact.kinds
    )
    return {
        'link': write_recording(
            root / 'link', exact, seed=4, raw=False, scatter=True, measuring=measuring
        ),
        'raw': write_recording(
            root / 'raw', exact, seed=4, postures=False, dwell_s=0.8, measuring=measuring
        ),
        'without': write_recording(root / 'without', without, seed=4, raw=False, scatter=True),
    }


@pytest.fixture(scope='module')
def nominal_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('params') / 'nominal.yaml'
    save_parameters(path, nominal_set(2).vector)
    return path


def _calibrate(bag: Path, nominal: Path, output: Path) -> tuple[dict, dict]:
    completed = hexacal('calibrate', bag, '--nominal', nominal, '--output', output, '--json')
    assert completed.returncode == 0, completed.stderr
    errors = pose_errors(
        TRUE, TRUE.with_vector(load_parameters(output)), validation_poses(TRUE, 50, seed=0)
    )
    return json.loads(completed.stdout), errors.summary()


@pytest.mark.slow
def test_calibrate_uses_the_measured_link_lengths(bags, nominal_file, tmp_path):
    result, errors = _calibrate(bags['link'], nominal_file, tmp_path / 'link.yaml')
    assert result['measuring_mode'] == 'lvdt'
    assert result['bag']['postures_with_link_length'] == POSTURES
    assert errors['position_mean_m'] < 20e-6, errors
    # hexacal verify measures with the same L_m: the calibration passes on the bag's postures.
    verified = hexacal(
        'verify', bags['link'], '--nominal', nominal_file, '--calibrated', tmp_path / 'link.yaml',
        '--json',
    )
    assert verified.returncode == 0, verified.stderr
    verification = json.loads(verified.stdout)
    assert verification['verdict'] == 'pass'
    assert verification['calibrated']['position_rms_m'] < 10e-6
    # The same readings with L in place of L_m: the millimetres of extension become model error.
    ignored, ignored_errors = _calibrate(bags['without'], nominal_file, tmp_path / 'no.yaml')
    assert ignored['measuring_mode'] is None
    assert ignored['bag']['postures_with_link_length'] == 0
    assert ignored_errors['position_mean_m'] > 10 * errors['position_mean_m'], ignored_errors
    assert ignored_errors['position_mean_m'] > 100e-6, ignored_errors


@pytest.mark.slow
def test_redetection_reads_the_recorded_link_stream(bags, nominal_file, tmp_path):
    result, errors = _calibrate(bags['raw'], nominal_file, tmp_path / 'raw.yaml')
    assert result['bag']['source'] == 'raw streams (re-detected)'
    assert result['bag']['postures'] == POSTURES
    assert result['bag']['postures_with_link_length'] == POSTURES
    assert '/hexacal/link' not in result['bag']['ignored_topics']
    assert errors['position_mean_m'] < 20e-6, errors
    # The removed window detector (it did not read the link) is refused, naming its successor.
    refused = hexacal(
        'calibrate', bags['raw'], '--nominal', nominal_file, '--output', tmp_path / 'w.yaml',
        '--detector', 'window',
    )
    assert refused.returncode == 2 and "use 'settled'" in refused.stderr
    assert not (tmp_path / 'w.yaml').exists()


def test_text_output_and_bag_info_name_the_mode(bags, nominal_file, tmp_path):
    completed = hexacal(
        'calibrate', bags['link'], '--nominal', nominal_file, '--output', tmp_path / 'c.yaml'
    )
    assert completed.returncode == 0, completed.stderr
    assert (
        f'measuring mode: lvdt, {POSTURES} of {POSTURES} postures with a measured link length'
        in completed.stdout
    )
    plain = hexacal(
        'calibrate', bags['without'], '--nominal', nominal_file, '--output', tmp_path / 'p.yaml'
    )
    assert 'measuring mode' not in plain.stdout  # a bag that says nothing of it: as before
    info = hexacal('bag-info', bags['link'])
    assert info.returncode == 0, info.stderr
    assert 'Measuring mode:    lvdt' in info.stdout
    assert 'released actuator none, link_length 0.7' in info.stdout
    assert 'Measuring mode' not in hexacal('bag-info', bags['without']).stdout


def test_bag_info_shows_each_postures_released_actuator(tmp_path):
    exact = simulate_measurements(TRUE, sample_poses(TRUE, 3, np.random.default_rng(2)))
    start = 1_700_000_000 * 1_000_000_000
    # slider_2 released from the start, slider_5 from after the first posture (1.6 s each).
    released = json.dumps([[start, 'slider_2'], [start + 2_000_000_000, 'slider_5']])
    bag = write_recording(
        tmp_path / 'passive',
        exact,
        raw=False,
        measuring={'measuring_mode': 'passive_actuator', 'released_actuators': released},
    )
    info = hexacal('bag-info', bag)
    assert info.returncode == 0, info.stderr
    assert 'Measuring mode:    passive_actuator' in info.stdout
    lines = [line for line in info.stdout.splitlines() if line.startswith('Posture ')]
    assert len(lines) == 3
    assert lines[0].endswith('released actuator slider_2')
    assert lines[1].endswith('released actuator slider_5')
