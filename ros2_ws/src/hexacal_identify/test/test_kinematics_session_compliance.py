"""The kinematics session with a calibration's compliances, and the node's parameter table."""

from dataclasses import replace

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.statics import MassModel, static_loads
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.sessions.kinematics_session import (
    check_parameter,
    KinematicsConfigurationError,
    LiveSession,
    loaded_chains,
    Outcome,
)
from hexacal_identify.nodes.kinematics_parameters import PARAMETERS, RUNTIME_PARAMETERS, UNSET
from hexacal_msgs_py.node_parameters import parameter_descriptor
from hexacal_msgs_py.physical_file import default_physical, write_physical_file
import numpy as np
import pytest

PERIOD_NS = 5_000_000
POSE = np.array([0.01, -0.02, -0.74, 0.02, -0.01, 0.05])
SHARED = {'chains': 2e-8, 'link': 1e-7}


def session(compliances=None, physical_file=''):
    params = architecture('hexa_slide').default_parameters()
    return LiveSession.start(
        params, 'file.yaml', 0.75, 'hanging', PERIOD_NS, physical_file, compliances
    )


def command_targets(live: LiveSession) -> np.ndarray:
    live.readings = inverse_kinematics(live.params, POSE[None])[0]
    command, report = live.command('', 'base', lambda: POSE, None, 0.02)
    assert command is not None, report.message
    return command.targets


def test_compensated_command_is_the_rigid_one_plus_the_deflection_of_the_default_weights():
    rigid = command_targets(session())
    live = session(SHARED)
    assert live.loaded is not None and live.loaded.compliances == (2e-8,) * 6
    compensated = command_targets(live)
    shift = compensated - rigid
    # The six chains carry the weights; the link is off the machine in operation.
    masses = replace(MassModel.from_physical(default_physical('hexa_slide')), link_mass=0.0)
    expected = static_loads(live.params, POSE[None], masses, 'lvdt').reading_loads[0] * 2e-8
    np.testing.assert_allclose(shift, expected, rtol=1e-12, atol=1e-15)
    assert np.abs(shift).max() > 1e-6  # a 20 kg platform on 5e7 N/m legs: micrometres
    # The pose of the compensated readings is the target pose; read as rigid it is not.
    pose, _ = live.solve(1, compensated, None, 0.0)
    np.testing.assert_allclose(pose, POSE, atol=1e-10)
    assert 'chains 2e-08 m/N' in live.status_values(live.start_report('', 'cmd'))['compliance']
    assert 'shipped hexa_slide physical description' in live.compliance_text


def test_the_physical_file_sets_the_weights(tmp_path):
    heavy = replace(default_physical('hexa_slide'), payload_mass=50.0)
    path = write_physical_file(tmp_path / 'heavy.yaml', heavy)
    default = command_targets(session(SHARED)) - command_targets(session())
    loaded = command_targets(session(SHARED, str(path))) - command_targets(session())
    assert np.abs(loaded).max() > 1.5 * np.abs(default).max()  # 50 kg more on the legs
    assert str(path) in session(SHARED, str(path)).compliance_text


def test_rigid_without_a_compliance_section_and_wrong_physical_files(tmp_path):
    assert session().loaded is None and session({'link': 1e-7}).loaded is None
    assert session().status_values(session().start_report('', 'c'))['compliance'] == (
        'none (rigid)'
    )
    gough = write_physical_file(tmp_path / 'gs.yaml', default_physical('gough_stewart'))
    with pytest.raises(KinematicsConfigurationError, match='describes a gough_stewart'):
        loaded_chains('hexa_slide', SHARED, str(gough))
    bad = tmp_path / 'bad.yaml'
    bad.write_text('format: hexacal-physical/1\nmodel: hexa_slide\nplatform: {mass: -1}\n')
    assert 'physical_file' in check_parameter('physical_file', str(bad))
    assert check_parameter('physical_file', str(gough)) is None
    assert check_parameter('physical_file', '') is None


def test_take_calibration_carries_its_compliances():
    live = session()
    params = live.params
    # The same geometry with a compliance section is a new calibration; heard again, nothing.
    report = live.take_calibration(params, 'store', 'a.yaml', SHARED)
    assert report.outcome == Outcome.PARAMETERS and 'compliances chains' in report.message
    assert live.loaded is not None
    assert live.take_calibration(params, 'store', 'a.yaml', SHARED) is None
    # A parameters message (geometry only) of the same calibration keeps its compliances.
    assert live.take_calibration(params, 'topic', 'topic') is None and live.loaded is not None
    # A rigid calibration drops them, and says so.
    report = live.take_calibration(params, 'store', 'b.yaml', {})
    assert live.loaded is None and 'none (rigid)' in report.message
    # Compliances that cannot load the machine are refused; the calibration in use stays.
    report = live.take_calibration(params, 'store', 'c.yaml', {'chain_1': float('nan')})
    assert report.outcome == Outcome.INVALID_PARAMETERS and live.parameters_source == 'b.yaml'


def test_the_parameter_table_keeps_every_name_type_default_and_range():
    assert list(PARAMETERS) == [
        'parameters', 'follow_calibrations', 'calibration_store', 'model', 'physical_file',
        'base_frame', 'command_topic', 'max_actuator_speed', 'stroke_limits', 'link_length',
        'mount', 'max_pose_rate_hz', 'markers_rate_hz',
    ]
    defaults = {name: spec.default for name, spec in PARAMETERS.items()}
    assert defaults == {
        'parameters': '', 'follow_calibrations': False, 'calibration_store': '', 'model': '',
        'physical_file': '', 'base_frame': 'hexacal_base', 'command_topic': defaults[
            'command_topic'
        ], 'max_actuator_speed': 0.02, 'stroke_limits': None, 'link_length': 0.75, 'mount': '',
        'max_pose_rate_hz': 200.0, 'markers_rate_hz': 10.0,
    }
    assert defaults['command_topic']
    ranges = {
        name: (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value)
        for name, d in (
            (n, parameter_descriptor(n, s)) for n, s in PARAMETERS.items()
        )
        if d.floating_point_range
    }
    assert ranges == {
        'max_actuator_speed': (1e-6, 10.0),
        'link_length': (0.1, 5.0),
        'max_pose_rate_hz': (0.1, 10000.0),
        'markers_rate_hz': (0.0, 100.0),
    }
    assert RUNTIME_PARAMETERS == ('base_frame', 'max_actuator_speed', 'stroke_limits')
    assert UNSET == ('stroke_limits',)
    assert "'hanging'" in PARAMETERS['mount'].constraints
    assert "'gough_stewart'" in PARAMETERS['model'].constraints
