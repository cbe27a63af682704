"""The calibrated parameters file carries the device defects identified with it, and verification uses them.

A joint calibration (machine + device defects) is only half useful if its file forgets the
device: `hexacal verify` of fresh postures measured with the same device would judge the
calibrated machine through an ideal device and see the device's own errors as the machine's.
`hexacal calibrate --identify-device ...` writes `device.defects.<name>` (SI) for each defect
identified; a calibration of the machine alone writes none (the file is as before);
`hexacal verify` takes them from the calibrated file (`--device-defects` overrides,
`none` = ideal device). Bags are real MCAP files; the CLI runs in this process.
"""

from __future__ import annotations

import json
from pathlib import Path

from hexacal_identify.cli import main as hexacal_main
from hexacal_identify.core.machine.device import DeviceDefects
from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses, Workspace
from hexacal_identify.calibration_steps.machine_files import load_device_defects
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
import numpy as np
import pytest
from system_support import posture_bag

DEFECTS = DeviceDefects(dL=5e-4, alpha0=2e-4, gamma=1e-4)
IDENTIFIED = ('dL', 'alpha0', 'gamma')
NOISE = NoiseModel.from_microns(10)


def measured_rows(count: int, seed: int) -> list[list[float]]:
    """Posture rows (six actuators, two inclinometer angles, rotary) of the Table 1 machine measured
    by the defective device: the platform on the sphere of the true link length."""
    truth = table1_parameters()
    rng = np.random.default_rng(seed)
    poses = sample_poses(truth, count, rng, 'sphere', Workspace(link_length=0.75 + DEFECTS.dL))
    data = simulate_measurements(truth, poses, 'sphere', noise=NOISE, rng=rng, defects=DEFECTS)
    return [
        [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]] for i in range(count)
    ]


@pytest.fixture(scope='module')
def files(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp('device_file')
    nominal = root / 'nominal.yaml'
    save_parameters(nominal, nominal_set(2, seed=3).vector)
    return {
        'nominal': nominal,
        'calibration': posture_bag(root / 'calibration', measured_rows(50, 11)),
        'verification': posture_bag(root / 'verification', measured_rows(30, 12)),
    }


def hexacal(capsys, *args) -> tuple[int, str, str]:
    code = hexacal_main([str(arg) for arg in args])
    out, err = capsys.readouterr()
    return code, out, err


def _calibrate_json(capsys, files, output: Path, *extra) -> dict:
    code, out, err = hexacal(
        capsys,
        'calibrate',
        files['calibration'],
        '--nominal',
        files['nominal'],
        '--output',
        output,
        '--noise-um',
        '10',
        '--json',
        *extra,
    )
    assert code == 0, err
    return json.loads(out)


def test_a_joint_calibration_writes_the_identified_defects(capsys, files, tmp_path):
    output = tmp_path / 'calibrated.yaml'
    result = _calibrate_json(capsys, files, output, '--identify-device', ','.join(IDENTIFIED))
    extras = read_parameters_file(output).extras
    written = {key: value for key, value in extras.items() if key.startswith('device.defects.')}
    # Exactly the identified ones, with the solve's values (repr: the same bits back).
    assert written == {f'device.defects.{name}': result['device'][name] for name in IDENTIFIED}
    defects, names = load_device_defects(output)
    assert names == IDENTIFIED
    assert [getattr(defects, n) for n in IDENTIFIED] == [result['device'][n] for n in IDENTIFIED]
    assert defects.beta0 == 0.0 and defects.phi0 == 0.0
    # Identified near the truth (dL is the weak one: tenths of its 0.5 mm).
    assert abs(defects.alpha0 - DEFECTS.alpha0) < 5 * result['device_std']['alpha0']
    assert abs(defects.dL - DEFECTS.dL) < 0.25e-3


def test_a_machine_only_calibration_writes_no_device_key(capsys, files, tmp_path):
    output = tmp_path / 'calibrated.yaml'
    _calibrate_json(capsys, files, output)
    assert 'device.defects' not in output.read_text()
    assert load_device_defects(output) == (DeviceDefects(), ())


def test_verify_measures_with_the_calibrated_device(capsys, files, tmp_path):
    calibrated = tmp_path / 'calibrated.yaml'
    result = _calibrate_json(capsys, files, calibrated, '--identify-device', ','.join(IDENTIFIED))
    common = (
        'verify',
        files['verification'],
        '--nominal',
        files['nominal'],
        '--calibrated',
        calibrated,
        '--noise-um',
        '10',
    )

    code, out, err = hexacal(capsys, *common, '--json')
    assert code in (0, 1), err
    with_device = json.loads(out)
    assert with_device['device_defects'] == {
        'source': 'calibrated file',
        'values': {name: result['device'][name] for name in IDENTIFIED},
    }

    code, out, err = hexacal(capsys, *common, '--json', '--device-defects', 'none')
    assert code in (0, 1), err
    ideal = json.loads(out)
    assert ideal['device_defects'] == {
        'source': '--device-defects none (ideal device)',
        'values': {},
    }
    # The same device measuring again: its identified defects remove its own share of the error.
    rms_with, rms_ideal = (p['calibrated']['position_rms_m'] for p in (with_device, ideal))
    assert rms_with < 0.5 * rms_ideal, (rms_with, rms_ideal)
    assert with_device['verdict'] == 'pass', with_device['verdict_reason']

    code, out, err = hexacal(capsys, *common, '--device-defects', 'dL=5e-4,alpha0=2e-4,gamma=1e-4')
    assert code in (0, 1), err
    assert (
        'measuring device (--device-defects): dL 500.00 um, alpha0 200.00 urad, gamma 100.00 urad'
        in out
    )

    code, out, err = hexacal(capsys, *common)
    assert 'measuring device (calibrated file): dL ' in out, out


def test_verify_names_a_bad_device_key_or_option(capsys, files, tmp_path):
    bad = tmp_path / 'bad.yaml'
    save_parameters(bad, table1_parameters().vector, extras={'device.defects.tilt': 1e-3})
    common = ('verify', files['verification'], '--nominal', files['nominal'])
    code, out, err = hexacal(capsys, *common, '--calibrated', bad)
    assert (
        code == 2 and 'device.defects.tilt' in err and str(bad) in err and 'Traceback' not in err
    ), err
    with pytest.raises(ParameterFileError, match='device.defects.tilt'):
        load_device_defects(bad)

    text = tmp_path / 'text.yaml'
    save_parameters(text, table1_parameters().vector, extras={'device.defects.dL': 'long'})
    code, out, err = hexacal(capsys, *common, '--calibrated', text)
    assert code == 2 and 'device.defects.dL' in err and 'number' in err, err

    good = tmp_path / 'good.yaml'
    save_parameters(good, table1_parameters().vector)
    code, out, err = hexacal(capsys, *common, '--calibrated', good, '--device-defects', 'tilt=1')
    assert code == 2 and '--device-defects' in err and 'tilt' in err, err
