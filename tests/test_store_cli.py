"""
The calibration store through the real ``hexacal`` command line, on the sample bags.

calibrate -> history (stored) -> deploy refused (unverified) -> verify on another bag attaches
a pass -> deploy (active) -> a second calibration deployed -> rollback restores the first ->
a calibration of another machine (a surprising jump) refused without --force, forced with it.
"""

from __future__ import annotations

import json
from pathlib import Path
import subprocess

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.machine.measurements import Measurements, simulate_measurements, SPHERE
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py import store_format as fmt
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np
import pytest
from synthetic_recording import write_recording
from system_support import hexacal

BAGS = Path(__file__).resolve().parents[1] / 'bags'
FIT_BAG, VERIFY_BAG = BAGS / 'sphere50_noise10', BAGS / 'sphere60_fixed20_noise10'


def _ok(*argv: object) -> subprocess.CompletedProcess:
    completed = hexacal(*argv)
    assert completed.returncode == 0, completed.stdout + completed.stderr
    return completed


def _history(store: Path) -> list[dict]:
    return json.loads(_ok('history', '--store', store, '--json').stdout)


def _states(store: Path) -> dict[str, str]:
    return {e['id']: e['state'] for e in _history(store)}


def _other_machine_bags(directory: Path) -> tuple[Path, Path]:
    """Two recordings (fit, verification) of a machine millimetres away from Table 1."""
    truth = nominal_set(3, seed=7)
    workspace = architecture().default_workspace()

    def measured(seed: int, count: int) -> Measurements:
        rng = np.random.default_rng(seed)
        poses = sample_poses(truth, count, rng, SPHERE, workspace)
        return simulate_measurements(truth, poses, SPHERE, rng=rng)

    fit = write_recording(directory / 'other_fit', measured(31, 40), seed=31, raw=False)
    verify = write_recording(directory / 'other_verify', measured(32, 20), seed=32, raw=False)
    return fit, verify


@pytest.fixture
def nominal(tmp_path) -> Path:
    path = tmp_path / 'nominal2.yaml'
    save_parameters(path, nominal_set(2, seed=0).vector)
    return path


def test_calibrate_verify_deploy_rollback_and_a_refused_jump(tmp_path, nominal):
    store = tmp_path / 'store'
    first_file, second_file = tmp_path / 'first.yaml', tmp_path / 'second.yaml'

    # calibrate -> stored, with its provenance
    completed = _ok(
        'calibrate', FIT_BAG, '--nominal', nominal, '--output', first_file, '--store', store
    )
    (first,) = _history(store)
    assert f'stored as {first["id"][:8]} (stored) in {store}' in completed.stdout
    assert first['state'] == 'stored' and first['verdict'] is None and first['time'].endswith('Z')
    record = first['record']
    assert record[fmt.RECORD_NOMINAL_DIGEST] == fmt.file_digest(nominal)
    assert record[fmt.RECORD_COST] == 'absolute' and record[fmt.RECORD_POSTURES_COUNT] == 50
    assert record[fmt.RECORD_FIT][fmt.FIT_RANK] == 54
    assert record[fmt.RECORD_BAG]['path'] == str(FIT_BAG)
    assert len(record[fmt.RECORD_POSTURES_DIGEST]) == 64 and record[fmt.RECORD_VERSION]
    assert first['digest'] == fmt.file_digest(first_file)
    table = _ok('history', '--store', store).stdout
    assert first['id'][:8] in table and 'stored' in table and 'sphere50_noise10' in table

    # deploy refused: unverified (exit 1, one line naming why and --force)
    refused = hexacal('deploy', first['id'][:8], '--store', store)
    assert refused.returncode == 1, refused.stderr
    assert refused.stderr.count('\n') == 1 and '--force' in refused.stderr
    assert '(unverified)' in refused.stderr

    # verified on its own bag: it does not count, said so, and not attached -> still refused
    completed = _ok(
        'verify', FIT_BAG, '--nominal', nominal, '--calibrated', first_file, '--store', store
    )
    assert 'does not count: these are the postures the calibration was fitted to' in (
        completed.stdout
    )
    assert 'not attached to the store' in completed.stdout and 'attached to ' not in (
        completed.stdout.replace('not attached to ', '')
    )
    assert _history(store)[0]['verdict'] is None
    refused = hexacal('deploy', first['id'], '--store', store)
    assert refused.returncode == 1 and '(unverified)' in refused.stderr
    # known from the file alone too (no store), in the JSON as well
    fitted = json.loads(
        _ok('verify', FIT_BAG, '--nominal', nominal, '--calibrated', first_file, '--json').stdout
    )
    assert fitted['fitted_postures'] and fitted['verdict'] == 'pass' and 'store' not in fitted

    # verified on another bag -> verified -> deploy -> active
    completed = _ok(
        'verify',
        VERIFY_BAG,
        '--nominal',
        nominal,
        '--calibrated',
        first_file,
        '--store',
        store,
        '--id',
        first['id'][:6],
        '--json',
    )
    payload = json.loads(completed.stdout)
    assert payload['verdict'] == 'pass' and payload['store']['id'] == first['id']
    assert _states(store) == {first['id']: 'verified'}
    _ok('deploy', first['id'][:8], '--store', store)
    assert _states(store) == {first['id']: 'active'}

    # a second calibration, verified on the first bag, deployed: a plausible change
    _ok('calibrate', VERIFY_BAG, '--nominal', nominal, '--output', second_file, '--store', store)
    second = _history(store)[1]
    _ok('verify', FIT_BAG, '--nominal', nominal, '--calibrated', second_file, '--store', store)
    _ok('deploy', second['id'], '--store', store)
    assert _states(store) == {first['id']: 'verified', second['id']: 'active'}

    # rollback restores the first
    completed = _ok('rollback', '--store', store)
    assert f'rolled back to {first["id"][:8]}' in completed.stdout
    assert _states(store) == {first['id']: 'active', second['id']: 'rolled-back'}
    entries = {e['id']: e for e in _history(store)}
    assert entries[first['id']]['active'] and entries[first['id']]['active_since']
    assert 'rolled-back' in _ok('history', '--store', store).stdout.splitlines()[-1]
    active = json.loads((store / fmt.ACTIVE_FILE).read_text())
    assert active[fmt.ACTIVE_ID] == first['id'] and active[fmt.ACTIVE_REASON] == 'rolled-back'

    # another machine, calibrated and verified on its own fresh recording: a surprising jump
    other_fit, other_verify = _other_machine_bags(tmp_path)
    other_file = tmp_path / 'other.yaml'
    _ok('calibrate', other_fit, '--nominal', nominal, '--output', other_file, '--store', store)
    other = _history(store)[2]
    _ok('verify', other_verify, '--nominal', nominal, '--calibrated', other_file, '--store', store)
    assert _states(store)[other['id']] == 'verified'
    refused = hexacal('deploy', other['id'], '--store', store)
    assert refused.returncode == 1, refused.stdout + refused.stderr
    assert '(parameter-jump)' in refused.stderr and '(pose-jump)' in refused.stderr
    assert _states(store)[first['id']] == 'active'
    completed = _ok('deploy', other['id'], '--store', store, '--force')
    assert '(forced)' in completed.stdout
    assert _states(store) == {
        first['id']: 'verified',
        second['id']: 'rolled-back',
        other['id']: 'forced',
    }
    assert _ok('rollback', '--store', store).stdout.startswith(f'rolled back to {first["id"][:8]}')


def test_a_failed_verification_is_attached_and_exits_1(tmp_path, nominal):
    store = tmp_path / 'store'
    calibrated = tmp_path / 'calibrated.yaml'
    _ok('calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated, '--store', store)
    # a threshold of 1 nm: no calibration passes it
    bad = hexacal(
        'verify',
        VERIFY_BAG,
        '--nominal',
        nominal,
        '--calibrated',
        calibrated,
        '--store',
        store,
        '--threshold-um',
        '0.001',
    )
    assert bad.returncode == 1, bad.stderr
    (entry,) = _history(store)
    assert entry['verdict'] == 'fail' and entry['state'] == 'stored'
    refused = hexacal('deploy', entry['id'], '--store', store)
    assert refused.returncode == 1 and '(verification-failed)' in refused.stderr


def test_bad_input_exits_2_with_one_line(tmp_path, nominal):
    store = tmp_path / 'store'
    calibrated = tmp_path / 'calibrated.yaml'
    _ok('calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated, '--store', store)
    cases = [
        (('deploy', 'abcdef12', '--store', store), "no entry 'abcdef12'"),
        (('rollback', '--store', store), 'nothing to roll back to'),
        (
            (
                'verify',
                VERIFY_BAG,
                '--nominal',
                nominal,
                '--calibrated',
                nominal,
                '--store',
                store,
            ),
            'no entry of calibration store',
        ),
        (
            (
                'verify',
                VERIFY_BAG,
                '--nominal',
                nominal,
                '--calibrated',
                nominal,
                '--store',
                store,
                '--id',
                _history(store)[0]['id'],
            ),
            'another parameters file',
        ),
        (('history', '--store', nominal), 'is not a directory'),
    ]
    for argv, message in cases:
        completed = hexacal(*argv)
        assert completed.returncode == 2, (argv, completed.stdout, completed.stderr)
        assert message in completed.stderr and completed.stderr.count('\n') == 1, completed.stderr
        assert completed.stderr.startswith(f'hexacal {argv[0]}: error: ')


def test_calibrate_stores_only_when_asked_and_says_where_or_that_it_did_not(
    tmp_path, nominal, monkeypatch
):
    monkeypatch.setenv(fmt.STORE_ENV, str(tmp_path / 'stores'))
    calibrated = tmp_path / 'calibrated.yaml'
    default = tmp_path / 'stores' / 'hexa_slide'
    # Offline, without --store: kept nowhere, and the output says so.
    completed = _ok('calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated, '--json')
    assert json.loads(completed.stdout)['store'] is None
    text = _ok('calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated).stdout
    assert 'not stored in a calibration store' in text and '--store' in text
    assert not default.exists()
    # --store alone: the machine model's store (the environment's here), said with its id.
    completed = _ok('calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated, '--store')
    (entry,) = json.loads(_ok('history', '--json').stdout)
    assert Path(entry['parameters']).is_relative_to(default)
    assert f'stored as {entry["short_id"]} (stored) in {default}' in completed.stdout
    completed = _ok(
        'calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated, '--store', '--json'
    )
    assert json.loads(completed.stdout)['store']['dir'] == str(default)
    _ok('calibrate', FIT_BAG, '--nominal', nominal, '--output', calibrated, '--no-store')
    assert len(json.loads(_ok('history', '--json').stdout)) == 2
    empty = _ok('history', '--model', 'gough_stewart').stdout
    assert empty.startswith('no calibrations in ')
