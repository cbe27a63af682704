"""``hexacal calibrate`` weighs a bag's postures by the scatter recorded with them."""

import json
from pathlib import Path

from hexacal_identify.core import sample_poses, simulate_measurements, table1_parameters
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.parameters_file import load_parameters, save_parameters
import numpy as np
import pytest
from synthetic_recording import write_recording
from system_support import hexacal

TRUE = table1_parameters()


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Return the same recording (same readings) with and without scatter on its postures."""
    exact = simulate_measurements(TRUE, sample_poses(TRUE, 40, np.random.default_rng(19)))
    root = tmp_path_factory.mktemp('bags')
    return {
        'scatter': write_recording(root / 'scatter', exact, seed=4, raw=False, scatter=True),
        'plain': write_recording(root / 'plain', exact, seed=4, raw=False),
    }


@pytest.fixture(scope='module')
def nominal_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('params') / 'nominal.yaml'
    save_parameters(path, nominal_set(2).vector)
    return path


def _calibrate(bag: Path, nominal: Path, output: Path, *options) -> dict:
    completed = hexacal('calibrate', bag, '--nominal', nominal, '--output', output, *options)
    assert completed.returncode == 0, completed.stderr
    return json.loads(completed.stdout) if '--json' in options else {'text': completed.stdout}


@pytest.mark.slow
def test_a_bag_with_scatter_is_weighed_by_it(bags, nominal_file, tmp_path):
    result = _calibrate(bags['scatter'], nominal_file, tmp_path / 'cal.yaml', '--json')
    assert result['weights'] == 'scatter'
    assert result['weighted_by_noise_model'] is False
    assert "each posture's measured scatter" in result['weights_note']
    # +-10 um uniform samples, 100 per dwell: standard errors of ~0.6 um, which the simulated
    # machine's residuals match (the model describes it exactly).
    adequacy = result['adequacy']
    assert adequacy['verdict'] == 'pass', adequacy['reason']
    low, high = adequacy['expected_range']
    assert low <= adequacy['variance_factor'] <= high
    identified = load_parameters(tmp_path / 'cal.yaml')
    assert np.max(np.abs(identified - TRUE.vector)) < 5e-4
    report = tmp_path / 'report'
    text = _calibrate(
        bags['scatter'], nominal_file, tmp_path / 'text.yaml', '--report', report
    )['text']
    assert [line for line in text.splitlines() if line.startswith('weights: ')] == [
        f'weights: {result["weights_note"]}'
    ]
    page = (report / 'index.html').read_text()
    assert "<th>Weights</th><td id='weights'>each posture&#x27;s measured scatter" in page


@pytest.mark.slow
def test_a_bag_without_scatter_calibrates_as_before(bags, nominal_file, tmp_path):
    plain = _calibrate(bags['plain'], nominal_file, tmp_path / 'plain.yaml', '--json')
    assert plain['weights'] == 'none' and plain['adequacy']['verdict'] == 'unknown'
    noise = _calibrate(
        bags['plain'], nominal_file, tmp_path / 'noise.yaml', '--json', '--noise-um', '10'
    )
    assert noise['weights'] == 'noise_model' and noise['weighted_by_noise_model'] is True
    # The scatter bag weighed by the noise model is the plain bag's fit: the same readings,
    # the same calibration to the bit.
    chosen = _calibrate(
        bags['scatter'],
        nominal_file,
        tmp_path / 'chosen.yaml',
        '--json',
        '--noise-um',
        '10',
        '--weights',
        'noise-model',
    )
    assert chosen['weights'] == 'noise_model'
    assert chosen['parameters'] == noise['parameters'] and chosen['std'] == noise['std']
    assert (tmp_path / 'chosen.yaml').read_text().split('\n', 1)[1] == (
        tmp_path / 'noise.yaml'
    ).read_text().split('\n', 1)[1]
    refused = hexacal(
        'calibrate',
        bags['plain'],
        '--nominal',
        nominal_file,
        '--output',
        tmp_path / 'refused.yaml',
        '--weights',
        'scatter',
    )
    assert refused.returncode != 0
    assert '40 of 40 postures carry no scatter' in refused.stderr
    assert not (tmp_path / 'refused.yaml').exists()
