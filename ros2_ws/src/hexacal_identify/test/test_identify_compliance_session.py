"""
The identify node's compliance parameters without DDS: validation and the session's calibration.

The session calibrates with axial compliances through the call `hexacal calibrate --compliance`
makes. Live lvdt postures show their mode by their measured link length; live postures without
one carry neither the mode nor the released actuator, and are refused by name.
"""

from __future__ import annotations

import logging
from pathlib import Path

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.session import CalibrationSession, parameter_problem, Reason, Settings
from hexacal_msgs_py.names import CALIBRATION_STATUS_NAME
from hexacal_msgs_py.parameters_file import (
    compliances_from_extras,
    read_parameters_file,
    save_parameters,
)
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest

PHYSICAL = """format: hexacal-physical/1
model: hexa_slide
gravity: [0.0, 0.0, -9.80665]
platform: {mass: 20.0, com: [0.0, 0.0, 0.0]}
legs: {mass: 2.0, com_fraction: 0.5}
link: {mass: 1.5, com_fraction: 0.5}
"""
CHAINS = 1e-7  # m/N: 1e7 N/m legs, deflections of a few um under the weights
NOISE = NoiseModel.from_microns(2.0)


class Recorder:
    """A StatusSink that keeps what was published."""

    def __init__(self) -> None:
        self.statuses: list[tuple] = []

    def status(self, name, level, message, values) -> None:
        self.statuses.append((name, level, message, dict(values)))

    def parameters(self, vector, model) -> None:
        pass


def _unchanged(name, fallback):
    return fallback


def test_bad_compliance_parameters_are_refused_by_name(tmp_path: Path):
    problem = parameter_problem('compliance', 'stiff', _unchanged)
    assert problem is not None and "'stiff'" in problem
    assert 'none, shared, per_chain' in problem
    for mode in ('none', 'shared', 'per_chain'):
        assert parameter_problem('compliance', mode, _unchanged) is None
    problem = parameter_problem('compliance_prior', 'link=1e-7', _unchanged)
    assert problem is not None and "'link=1e-7'" in problem and 'NAME=VALUE:STD' in problem
    assert parameter_problem('compliance_prior', 'link=1e-7:2e-8, chains=2e-8:1e-8',
                             _unchanged) is None
    assert parameter_problem('compliance_prior', '', _unchanged) is None
    missing = tmp_path / 'missing.yaml'
    problem = parameter_problem('physical_file', str(missing), _unchanged)
    assert problem is not None and str(missing) in problem
    physical = tmp_path / 'physical.yaml'
    physical.write_text(PHYSICAL)
    assert parameter_problem('physical_file', str(physical), _unchanged) is None
    assert parameter_problem('physical_file', '', _unchanged) is None


@pytest.fixture(scope='module')
def loaded(tmp_path_factory) -> dict:
    """Lvdt postures of the Table 1 machine loaded by its weights, a nominal file, the masses."""
    directory = tmp_path_factory.mktemp('loaded')
    true = architecture('hexa_slide').default_parameters()
    rng = np.random.default_rng(11)
    poses = sample_poses(true, 40, rng)
    nominal = directory / 'nominal.yaml'
    save_parameters(nominal, true.vector + rng.normal(0.0, 2e-4, true.vector.size))
    physical = directory / 'physical.yaml'
    physical.write_text(PHYSICAL)
    masses = MassModel.load(physical)  # the shipped description's defaults fill the rest
    model = ComplianceModel('shared', masses, 'lvdt')
    measurements, _ = simulate_loaded_measurements(
        true, poses, model, np.array([CHAINS]), noise=NOISE, rng=rng
    )
    postures = [
        PostureReading.from_values(
            (i + 1) * 10**9,
            [*measurements.actuator_positions[i], *measurements.inclinometer[i],
             measurements.rotary[i]],
            link_length=float(measurements.link_lengths[i]),
        )
        for i in range(len(poses))
    ]
    return {'postures': postures, 'nominal': nominal, 'physical': physical}


def _session(postures) -> tuple[CalibrationSession, Recorder]:
    recorder = Recorder()
    session = CalibrationSession(recorder, logging.getLogger('test'), lambda: None)
    for posture in postures:
        session.postures.add(posture, 'hexa_slide')
    return session, recorder


def _settings(loaded, tmp_path: Path, **changes) -> Settings:
    return Settings(
        nominal=str(loaded['nominal']),
        output_dir=str(tmp_path),
        report_dir='',
        calibration_store=str(tmp_path / 'store'),
        noise_slider_m=NOISE.actuator_m,
        noise_angle_rad=NOISE.angle_rad,
        weights='noise-model',
        **changes,
    )


@pytest.mark.slow
def test_the_session_identifies_live_lvdt_compliances_and_verifies_with_them(loaded, tmp_path):
    session, recorder = _session(loaded['postures'][:30])
    settings = _settings(
        loaded, tmp_path, compliance='shared', physical_file=str(loaded['physical'])
    )
    outcome = session.calibrate(settings)
    assert outcome.success, outcome.message
    values = recorder.statuses[-1][3]
    assert recorder.statuses[-1][0] == CALIBRATION_STATUS_NAME
    assert values['compliance_mode'] == 'shared'
    assert values['compliance_physical'] == str(loaded['physical'])
    chains, std = float(values['compliance.chains']), float(values['std.compliance.chains'])
    assert 0 < std < 0.2 * CHAINS
    assert abs(chains - CHAINS) < 3.3 * std
    assert 'compliance.link' not in values  # the lvdt link carries no load
    written = compliances_from_extras(read_parameters_file(values['output']).extras)
    assert written == pytest.approx({'chains': chains}, rel=1e-5)
    # hexacal/verify on fresh live postures applies the compliances the calibration carries.
    for posture in loaded['postures'][30:]:
        session.postures.add(posture, 'hexa_slide')
    verified = session.verify(settings)
    assert verified.values['compliance_mode'] == 'shared', verified.message
    with_loads = verified.figures['calibrated']['position_rms_m']
    session.latest.compliance = {}  # the same geometry verified as a rigid machine
    rigid = session.verify(settings).figures['calibrated']['position_rms_m']
    assert 'compliance_mode' not in recorder.statuses[-1][3]
    assert with_loads < 0.5 * rigid, (with_loads, rigid)


def test_live_postures_without_their_mode_are_refused_with_compliance(loaded, tmp_path):
    bare = [
        PostureReading.from_values(p.stamp_ns, p.values()) for p in loaded['postures']
    ]
    session, recorder = _session(bare)
    outcome = session.calibrate(_settings(loaded, tmp_path, compliance='per_chain'))
    assert not outcome.success
    assert outcome.values['outcome'] == Reason.INVALID_OPTIONS
    assert 'released actuator' in outcome.message and 'parameter bag' in outcome.message
    assert not (tmp_path / 'hexacal_calibration.yaml').exists()


def test_the_session_checks_a_rigid_fit_for_deflections_it_absorbs(loaded, tmp_path):
    # Live lvdt postures of a machine whose 1e7 N/m legs deflect under its weights: the rigid
    # fit, checked with the shipped description's stiffnesses (5e7 N/m legs, as
    # `hexacal calibrate --physical` checks it).
    session, recorder = _session(loaded['postures'][:30])
    outcome = session.calibrate(_settings(loaded, tmp_path, deflection_check=True))
    assert outcome.success, outcome.message
    values = recorder.statuses[-1][3]
    assert values['deflection_check.source'] == 'the shipped hexa_slide physical description'
    assert values['deflection_check.postures'] == 30
    assert 0 < values['deflection_check.largest_deflection_m'] < 1e-4
    assert values['deflection_check.pose_bias_mean_m'] > 0
    assert values['deflection_check.visible_rms.x'] >= 0
    assert values['deflection_check.significant'] == (
        values['deflection_check.pose_bias_mean_m']
        > values['deflection_check.statistical_pose_error_mean_m']
    )
    # A mass-only file (no model: no stiffnesses) cannot be checked: named, the calibration
    # stands.
    masses = tmp_path / 'masses.yaml'
    masses.write_text('platform_mass: 20.0\nleg_mass: 2.0\n')
    outcome = session.calibrate(
        _settings(loaded, tmp_path, deflection_check=True, physical_file=str(masses))
    )
    assert outcome.success, outcome.message
    error = recorder.statuses[-1][3]['deflection_check.error']
    assert 'needs the stiffnesses' in error and str(masses) in error
    # With the compliances identified there is no rigid fit to check: refused by name.
    outcome = session.calibrate(
        _settings(loaded, tmp_path, deflection_check=True, compliance='shared')
    )
    assert not outcome.success and 'deflection_check judges a rigid fit' in outcome.message


def test_a_compliance_prior_without_compliance_is_refused(loaded, tmp_path):
    session, _ = _session(loaded['postures'])
    outcome = session.calibrate(_settings(loaded, tmp_path, compliance_prior='chains=1e-7:1e-8'))
    assert not outcome.success and 'compliance_prior' in outcome.message


def test_ik_and_fk_apply_a_files_compliance_section(tmp_path, capsys):
    import json

    from hexacal_identify.cli.commands import main
    from hexacal_identify.core.machine.kinematics import inverse_kinematics
    from hexacal_identify.core.machine.live import LoadedChains
    from hexacal_msgs_py.parameters_file import compliance_extras

    true = architecture('hexa_slide').default_parameters()
    rigid, compliant = tmp_path / 'rigid.yaml', tmp_path / 'compliant.yaml'
    save_parameters(rigid, true.vector)
    save_parameters(compliant, true.vector, extras=compliance_extras({'chains': CHAINS}))
    physical = tmp_path / 'physical.yaml'
    physical.write_text(PHYSICAL)
    pose = [0.02, -0.01, -0.74, 0.01, 0.0, 0.02]
    pose_text = ','.join(str(v) for v in pose)

    def run(*argv):
        assert main(list(argv)) == 0
        return json.loads(capsys.readouterr().out)

    plain = run('ik', str(rigid), '--pose', pose_text, '--json')
    assert 'compliance' not in plain
    loaded = run('ik', str(compliant), '--pose', pose_text, '--json', '--physical', str(physical))
    assert str(physical) in loaded['compliance']
    names = true.layout.actuator_names
    rigid_targets = inverse_kinematics(true, [pose])[0]
    masses = MassModel.load(physical)
    shifts = LoadedChains((CHAINS,) * 6, masses).shifts(true, np.array([pose]))[0]
    assert np.abs(shifts).max() > 1e-6  # the weights shift the readings by microns
    assert [loaded['actuators'][n] for n in names] == pytest.approx(
        rigid_targets + shifts, abs=1e-12
    )
    assert [plain['actuators'][n] for n in names] == pytest.approx(rigid_targets, abs=1e-12)
    readings = ','.join(repr(loaded['actuators'][n]) for n in names)
    back = run('fk', str(compliant), '--actuators', readings, '--json', '--physical',
               str(physical))
    assert [back['pose'][f] for f in ('x', 'y', 'z', 'theta', 'psi', 'phi')] == pytest.approx(
        pose, abs=1e-9
    )
    shipped = run('fk', str(compliant), '--actuators', readings, '--json')
    assert 'shipped hexa_slide physical description' in shipped['compliance']


@pytest.mark.slow
def test_the_session_identifies_compliances_from_a_passive_actuator_bag(loaded, tmp_path):
    """The bag's measuring record gives the mode and each posture's released actuator."""
    from hexacal_identify.bag import BagWriter
    from hexacal_identify.bag.measuring import MEASURING_METADATA, MeasuringRecord
    from hexacal_identify.core.modes.passive_actuator import release_conditions
    from hexacal_msgs_py.names import JOINT_STATE_TYPE, POSTURE_NAMES, POSTURE_TOPIC

    true = architecture('hexa_slide').default_parameters()
    rng = np.random.default_rng(5)
    poses = sample_poses(true, 40, rng)
    released = np.argmin(release_conditions(true, poses, 0.75), axis=1)
    truth = {'chains': 2e-8, 'link': 1e-7}
    model = ComplianceModel(
        'shared', MassModel.load(loaded['physical']), 'passive_actuator', released
    )
    measurements, _ = simulate_loaded_measurements(
        true, poses, model, np.array([truth['chains'], truth['link']]), noise=NOISE, rng=rng
    )
    bag, record, names = tmp_path / 'passive', MeasuringRecord(), true.layout.actuator_names
    with BagWriter(bag) as writer:
        topic = '/' + POSTURE_TOPIC
        writer.add_topic(topic, JOINT_STATE_TYPE)
        for index in range(len(poses)):
            stamp = (index + 1) * 10**9
            record.note('passive_actuator', names[released[index]], stamp - 1)
            row = [*measurements.actuator_positions[index], *measurements.inclinometer[index],
                   measurements.rotary[index]]
            message = {
                'header': {'stamp': {'sec': stamp // 10**9, 'nanosec': 0}, 'frame_id': ''},
                'name': list(POSTURE_NAMES),
                'position': [float(v) for v in row],
                'velocity': [],
                'effort': [],
            }
            writer.write(topic, message, stamp)
        writer.write_metadata(MEASURING_METADATA, record.to_metadata())
    session, recorder = _session([])
    outcome = session.calibrate(_settings(
        loaded, tmp_path, bag=str(bag), compliance='shared', physical_file=str(loaded['physical'])
    ))
    assert outcome.success, outcome.message
    values = recorder.statuses[-1][3]
    for name, value in truth.items():
        std = float(values[f'std.compliance.{name}'])
        assert abs(float(values[f'compliance.{name}']) - value) < 3.3 * std, name
    rigid = _session([])[0].calibrate(_settings(loaded, tmp_path / 'rigid', bag=str(bag)))
    assert 'compliance_mode' not in rigid.values
    assert rigid.values['adequacy.verdict'] != 'pass'  # the weights the rigid model misses
