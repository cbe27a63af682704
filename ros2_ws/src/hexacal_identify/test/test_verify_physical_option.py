"""`hexacal verify --physical`: a calibration with compliances verified with its loads."""

import json

from hexacal_identify.bag import BagWriter
from hexacal_identify.bag.measuring import MEASURING_METADATA, MeasuringRecord
from hexacal_identify.cli import main
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.model import table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
from hexacal_msgs_py.names import JOINT_STATE_TYPE, POSTURE_NAMES, POSTURE_TOPIC
from hexacal_msgs_py.parameters_file import compliance_extras, save_parameters
import numpy as np
import pytest

TRUTH = {'chains': 2e-8, 'link': 1e-7}
MASSES = """gravity: [0.0, 0.0, -9.80665]
platform: {mass: 20.0, com: [0.0, 0.0, 0.0]}
legs: {mass: 2.0, com_fraction: 0.5}
link: {mass: 1.5, com_fraction: 0.5}
"""


def _joint_state(stamp_ns: int, positions) -> dict:
    return {
        'header': {'stamp': {'sec': stamp_ns // 10**9, 'nanosec': stamp_ns % 10**9},
                   'frame_id': ''},
        'name': list(POSTURE_NAMES),
        'position': [float(v) for v in positions],
        'velocity': [],
        'effort': [],
    }


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    directory = tmp_path_factory.mktemp('verify_physical')
    true = table1_parameters()
    poses = sample_poses(true, 12, np.random.default_rng(11))
    released = np.argmin(release_conditions(true, poses, 0.75), axis=1)
    physical = directory / 'masses.yaml'
    physical.write_text(MASSES)
    model = ComplianceModel('shared', MassModel.load(physical), 'passive_actuator', released)
    measurements, _ = simulate_loaded_measurements(
        true, poses, model, np.array([TRUTH['chains'], TRUTH['link']])
    )
    bag, record, names = directory / 'fresh', MeasuringRecord(), true.layout.actuator_names
    with BagWriter(bag) as writer:
        topic = '/' + POSTURE_TOPIC
        writer.add_topic(topic, JOINT_STATE_TYPE)
        for index in range(len(poses)):
            stamp = (index + 1) * 10**9
            record.note('passive_actuator', names[released[index]], stamp - 1)
            row = np.concatenate([
                measurements.actuator_positions[index],
                measurements.inclinometer[index],
                [measurements.rotary[index]],
            ])
            writer.write(topic, _joint_state(stamp, row), stamp)
        writer.write_metadata(MEASURING_METADATA, record.to_metadata())
    rigid, compliant = directory / 'rigid.yaml', directory / 'compliant.yaml'
    save_parameters(rigid, true.vector)
    save_parameters(compliant, true.vector, compliance_extras(TRUTH))
    return {'bag': bag, 'physical': physical, 'rigid': rigid, 'compliant': compliant}


def _verify(files, calibrated, *options, capsys):
    code = main([
        'verify', str(files['bag']), '--nominal', str(files['rigid']), '--calibrated',
        str(files[calibrated]), '--threshold-um', '0.5', *map(str, options),
    ])
    return code, capsys.readouterr().out


def test_compliances_verified_with_the_loads_of_the_physical_file(files, capsys):
    code, out = _verify(files, 'compliant', '--physical', files['physical'], '--json',
                        capsys=capsys)
    payload = json.loads(out)
    # The true geometry and compliances under the true weights: the readings to the nanometre.
    assert code == 0 and payload['verdict'] == 'pass', payload['verdict_reason']
    assert payload['calibrated']['position_rms_m'] < 1e-8
    # The same geometry read as rigid is the stretch of the loaded link and legs off.
    assert payload['nominal']['position_rms_m'] > 1e-6
    assert payload['compliance'] == {
        'values': TRUTH, 'mode': 'shared', 'physical': f'--physical {files["physical"]}'
    }
    code, out = _verify(files, 'compliant', '--physical', files['physical'], capsys=capsys)
    assert code == 0
    assert 'compliances (calibrated file): chains 2e-08, link 1e-07 m/N; weights of ' \
        f'--physical {files["physical"]}' in out


def test_without_physical_the_default_description_is_used_and_said(files, capsys):
    code, out = _verify(files, 'compliant', capsys=capsys)
    assert 'weights of the shipped hexa_slide physical description (no --physical given' in out
    code, out = _verify(files, 'compliant', '--json', capsys=capsys)
    payload = json.loads(out)
    # Its 3 kg sliders are weights this machine does not have: the verification sees them.
    assert payload['calibrated']['position_rms_m'] > 1e-8
    assert payload['compliance']['physical'].startswith('the shipped hexa_slide')


def test_a_rigid_calibration_says_the_physical_file_is_not_used(files, capsys):
    code, out = _verify(files, 'rigid', '--physical', files['physical'], '--json',
                        capsys=capsys)
    payload = json.loads(out)
    assert code == 1 and payload['compliance']['mode'] == 'none'
    assert payload['compliance']['physical'].startswith('not used')
