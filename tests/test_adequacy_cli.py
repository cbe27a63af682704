"""
The fit's adequacy on the sample bags: `hexacal calibrate` (text, --json), status and report.

sphere50_noise10's postures are averages of readings with 10 um noise: with `--noise-um 10`
the residuals are within (below) what the noise predicts, a pass; with `--noise-um 1` (the noise
under-stated) they are far above it, a fail that names the postures and channels.
"""

from __future__ import annotations

import json
from pathlib import Path

from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
from hexacal_identify.calibration_steps.calibration_run import calibrate, status_fields
from hexacal_identify.calibration_steps.machine_files import load_machine
import pytest
from system_support import hexacal

REPO = Path(__file__).resolve().parents[1]
SAMPLE_BAG = REPO / 'bags' / 'sphere50_noise10'
KEYS = {
    'variance_factor',
    'expected_range',
    'dof',
    'verdict',
    'reason',
    'worst_postures',
    'worst_channels',
}


@pytest.fixture(scope='module')
def nominal(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('adequacy') / 'nominal.yaml'
    made = hexacal('params', 'nominal', '--set', 2, '--seed', 0, '--out', path)
    assert made.returncode == 0, made.stderr
    return path


def _calibrate(nominal: Path, tmp_path: Path, *options):
    return hexacal(
        'calibrate',
        SAMPLE_BAG,
        '--nominal',
        nominal,
        '--output',
        tmp_path / 'calibrated.yaml',
        '--store',
        tmp_path / 'store',
        *options,
    )


def test_the_true_noise_passes(nominal, tmp_path):
    run = _calibrate(nominal, tmp_path, '--noise-um', 10, '--json')
    assert run.returncode == 0, run.stderr
    adequacy = json.loads(run.stdout)['adequacy']
    assert set(adequacy) == KEYS
    assert adequacy['verdict'] == 'pass'
    assert adequacy['dof'] == 4 * 50 - 54
    low, high = adequacy['expected_range']
    assert adequacy['variance_factor'] <= high
    assert low < 1 < high


def test_understated_noise_fails_naming_postures_and_channels(nominal, tmp_path):
    run = _calibrate(nominal, tmp_path, '--noise-um', 1, '--json')
    assert run.returncode == 0, run.stderr  # the solver converged; the parameters are written
    adequacy = json.loads(run.stdout)['adequacy']
    assert adequacy['verdict'] == 'fail'
    assert adequacy['variance_factor'] > adequacy['expected_range'][1]
    postures = [p['index'] for p in adequacy['worst_postures']]
    assert len(postures) == 5 and all(0 <= p < 50 for p in postures)
    assert {c['channel'] for c in adequacy['worst_channels']} == {'x', 'y', 'z', 'phi'}
    text = _calibrate(nominal, tmp_path, '--noise-um', 1, '--report', tmp_path / 'report')
    assert text.returncode == 0, text.stderr
    lines = text.stdout.splitlines()
    assert lines[1].startswith('converged, but the fit is inadequate: ')
    assert not any(line.startswith('converged in') for line in lines)
    assert any(line.startswith('adequacy: fail: ') for line in lines)
    named = next(line for line in lines if 'largest contributions' in line)
    assert f'postures {postures[0]} (' in named
    page = (tmp_path / 'report' / 'index.html').read_text()
    assert "id='adequacy-verdict'>fail<" in page
    assert 'but the fit is inadequate' in page


def test_without_a_noise_model_unknown_and_the_text_is_unchanged(nominal, tmp_path):
    run = _calibrate(nominal, tmp_path, '--json')
    adequacy = json.loads(run.stdout)['adequacy']
    assert adequacy['verdict'] == 'unknown' and 'no noise model' in adequacy['reason']
    assert adequacy['variance_factor'] is None and adequacy['worst_postures'] == []
    text = _calibrate(nominal, tmp_path)
    assert not any(line.startswith('adequacy') for line in text.stdout.splitlines())
    assert text.stdout.splitlines()[1].startswith('converged in ')


def test_status_fields_carry_the_verdict(nominal):
    postures = postures_from_bag(SAMPLE_BAG).postures
    machine = load_machine(nominal)
    passed = status_fields(calibrate(machine, postures, noise=NoiseModel.from_microns(10)))
    failed = status_fields(calibrate(machine, postures, noise=NoiseModel.from_microns(1)))
    unweighted = status_fields(calibrate(machine, postures))
    assert passed['adequacy.verdict'] == 'pass' and passed['adequacy.dof'] == '146'
    assert failed['adequacy.verdict'] == 'fail'
    assert float(failed['adequacy.variance_factor']) > float(failed['adequacy.expected_high'])
    assert len(failed['adequacy.worst_postures'].split(',')) == 5
    assert unweighted['adequacy.verdict'] == 'unknown'
    assert 'adequacy.variance_factor' not in unweighted
