"""
`hexacal calibrate --compliance` on a bag of a machine loaded by its weights (passive_actuator).

The bag holds postures of a Hexa Slide whose measuring link (1e7 N/m) and legs (5e7 N/m) stretch
under a 20 kg platform, 2 kg legs and a 1.5 kg link, readings with 2 um / 2 urad noise, and the
released actuator of each posture in its measuring record.  The rigid fit fails its adequacy;
the compliant one recovers the compliances within their standard deviations, passes, and the
parameters file carries them.
"""

from __future__ import annotations

import json
from pathlib import Path

from hexacal_identify.bag import BagWriter
from hexacal_identify.bag.measuring import MEASURING_METADATA, MeasuringRecord
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.model import table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
from hexacal_msgs_py.names import JOINT_STATE_TYPE, POSTURE_NAMES, POSTURE_TOPIC
from hexacal_msgs_py.parameters_file import compliances_from_extras, read_parameters_file
import numpy as np
import pytest
from system_support import hexacal, joint_state_dict

MASSES = MassModel(platform_mass=20.0, leg_mass=2.0, link_mass=1.5)
TRUTH = {'chains': 2e-8, 'link': 1e-7}
PHYSICAL = """format: hexacal-physical/1
gravity: [0.0, 0.0, -9.80665]
platform: {mass: 20.0, com: [0.0, 0.0, 0.0]}
legs: {mass: 2.0, com_fraction: 0.5}
link: {mass: 1.5, com_fraction: 0.5, axial_stiffness: 1.0e7}
"""


@pytest.fixture(scope='module')
def loaded(tmp_path_factory) -> dict[str, Path]:
    directory = tmp_path_factory.mktemp('weights')
    true = table1_parameters()
    rng = np.random.default_rng(7)
    poses = sample_poses(true, 50, rng)
    released = np.argmin(release_conditions(true, poses, 0.75), axis=1)
    model = ComplianceModel('shared', MASSES, 'passive_actuator', released)
    measurements, _ = simulate_loaded_measurements(
        true,
        poses,
        model,
        np.array([TRUTH['chains'], TRUTH['link']]),
        noise=NoiseModel.from_microns(2.0),
        rng=rng,
    )
    bag = directory / 'loaded'
    record = MeasuringRecord()
    names = true.layout.actuator_names
    with BagWriter(bag) as writer:
        topic = '/' + POSTURE_TOPIC
        writer.add_topic(topic, JOINT_STATE_TYPE)
        for index in range(len(poses)):
            stamp = (index + 1) * 10**9
            record.note('passive_actuator', names[released[index]], stamp - 1)
            row = np.concatenate(
                [
                    measurements.actuator_positions[index],
                    measurements.inclinometer[index],
                    [measurements.rotary[index]],
                ]
            )
            writer.write(topic, joint_state_dict(stamp, POSTURE_NAMES, row), stamp)
        writer.write_metadata(MEASURING_METADATA, record.to_metadata())
    nominal = directory / 'nominal.yaml'
    made = hexacal('params', 'nominal', '--set', 2, '--seed', 0, '--out', nominal)
    assert made.returncode == 0, made.stderr
    physical = directory / 'physical.yaml'
    physical.write_text(PHYSICAL)
    return {'bag': bag, 'nominal': nominal, 'physical': physical, 'dir': directory}


def _calibrate(loaded, output: Path, *options):
    return hexacal(
        'calibrate',
        loaded['bag'],
        '--nominal',
        loaded['nominal'],
        '--output',
        output,
        '--store',
        loaded['dir'] / 'store',
        '--noise-um',
        2,
        '--weights',
        'noise-model',
        *options,
    )


@pytest.mark.slow
def test_rigid_fails_and_compliant_recovers_and_writes_the_compliances(loaded):
    rigid_file = loaded['dir'] / 'rigid.yaml'
    rigid = _calibrate(loaded, rigid_file, '--json')
    assert rigid.returncode == 0, rigid.stderr
    payload = json.loads(rigid.stdout)
    assert payload['adequacy']['verdict'] == 'fail'
    assert 'compliance' not in payload
    assert compliances_from_extras(read_parameters_file(rigid_file).extras) == {}
    assert '    compliance.' not in rigid_file.read_text()

    output = loaded['dir'] / 'compliant.yaml'
    run = _calibrate(
        loaded, output, '--compliance', 'shared', '--physical', loaded['physical'], '--json'
    )
    assert run.returncode == 0, run.stderr
    payload = json.loads(run.stdout)
    assert payload['adequacy']['verdict'] == 'pass', payload['adequacy']
    compliance = payload['compliance']
    assert compliance['mode'] == 'shared' and compliance['unit'] == 'm/N'
    for name, true in TRUTH.items():
        assert abs(compliance['values'][name] - true) < 3.3 * compliance['std'][name], name
    written = compliances_from_extras(read_parameters_file(output).extras)
    assert written == pytest.approx(compliance['values'], rel=1e-12)

    text = _calibrate(
        loaded, output, '--compliance', 'shared', '--physical', loaded['physical']
    )
    assert text.returncode == 0, text.stderr
    assert 'axial compliances (shared; m/N, stiffness N/m):' in text.stdout
    assert any(line.strip().startswith('link: ') for line in text.stdout.splitlines())


def test_compliance_without_masses_is_refused_by_name(loaded, tmp_path):
    run = _calibrate(loaded, tmp_path / 'out.yaml', '--compliance', 'shared')
    assert run.returncode != 0
    assert '--physical' in run.stderr


def test_the_rigid_fit_with_a_physical_description_says_how_far_its_compliances_bias_it(
    loaded, tmp_path
):
    # The machine's description with its stiffnesses (the bag's truth: chains 5e7 N/m, link
    # 1e7 N/m): the rigid fit is checked against what they do to it.  A file of the masses
    # only cannot be checked: the calibration is written all the same, and the error says why.
    from hexacal_identify.calibration_steps.machine_files import load_machine_and_mount
    from hexacal_identify.core.assessment.validation import pose_errors

    described = tmp_path / 'described.yaml'
    described.write_text(PHYSICAL + 'model: hexa_slide\nstructure: {axial_stiffness: 5.0e7}\n')
    output = tmp_path / 'rigid.yaml'
    run = _calibrate(loaded, output, '--physical', described, '--json')
    assert run.returncode == 0, run.stderr
    check = json.loads(run.stdout)['deflection_check']
    assert check['source'] == str(described) and check['postures'] == 50
    assert check['significant'] is True
    true = table1_parameters()
    fresh = sample_poses(true, 200, np.random.default_rng(3))
    error = np.nanmean(pose_errors(true, load_machine_and_mount(output)[0], fresh).position_m)
    assert 0.5 * error < check['pose_bias_mean_m'] < 2.0 * error

    text = _calibrate(loaded, tmp_path / 'text.yaml', '--physical', described)
    assert 'deflection check' in text.stdout and 'identify the compliances' in text.stdout

    kept = tmp_path / 'kept.yaml'
    refused = _calibrate(loaded, kept, '--physical', loaded['physical'])  # the masses only
    assert refused.returncode != 0 and 'hexacal-physical/1' in refused.stderr
    assert kept.exists()  # the calibration was written before the check
