"""core/sessions/kinematics_session.py: what the kinematics node decides, without DDS."""

from hexacal_identify.core.architectures import architecture, ARCHITECTURES, parameters_for
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.live import home_pose
from hexacal_identify.core.sessions.kinematics_session import (
    check_parameter,
    KinematicsConfigurationError,
    Level,
    LiveSession,
    LOG_PERIOD_S,
    MIN_MOVE_TIME_S,
    Outcome,
    RefusalReason,
)
from hexacal_msgs_py.errors import InvalidReadingError
import numpy as np
import pytest

PERIOD_NS = 5_000_000  # max_pose_rate_hz 200
POSE = np.array([0.01, -0.02, -0.74, 0.02, -0.01, 0.05])


def session(model: str = 'hexa_slide', with_parameters: bool = True) -> LiveSession:
    params = architecture(model).default_parameters() if with_parameters else None
    return LiveSession.start(params, 'file.yaml' if params else '', 0.75, 'hanging', PERIOD_NS)


def test_the_enums_keep_todays_strings():
    assert [r.value for r in RefusalReason] == [
        'wrong-frame',
        'no-parameters',
        'invalid-target',
        'outside-stroke',
        'unreachable-pose',
        'no-actuator-readings',
    ]
    assert f'{Outcome.MODEL_MISMATCH}' == 'model-mismatch' and str(Level.WARN) == 'WARN'


@pytest.mark.parametrize(
    'name, value, problem',
    [
        ('stroke_limits', [0.5, 0.1], 'stroke_limits must be [low, high] (m) with low < high'),
        ('stroke_limits', [0.1, 0.5], None),
        ('mount', 'sideways', "mount must be '' or one of hanging, standing"),
        ('base_frame', '', 'base_frame must not be empty'),
        ('max_actuator_speed', float('nan'), 'max_actuator_speed must be finite'),
    ],
)
def test_parameter_checks(name, value, problem):
    found = check_parameter(name, value)
    assert found == problem or (problem and found.startswith(problem))


def test_a_parameters_file_that_does_not_load_is_refused():
    def load(path):
        raise KinematicsConfigurationError(f'parameters: {path}: no such file')

    assert check_parameter('parameters', 'x.yaml', load) == 'parameters: x.yaml: no such file'


def test_readings_are_solved_at_most_once_per_period_of_their_stamps():
    live = session()
    params = live.params
    readings = inverse_kinematics(params, POSE[None])[0]
    assert live.wants_reading(10**9)
    pose, report = live.solve(10**9, readings, 'stamp', 0.0)
    assert report is None and np.allclose(pose, POSE, atol=1e-9)
    assert not live.wants_reading(10**9 + PERIOD_NS - 1)
    assert live.wants_reading(10**9 + PERIOD_NS) and live.wants_reading(10**9 - 1)
    started = live.published(pose, '/hexacal/platform_pose')
    assert started.outcome == Outcome.TRACKING and live.published(pose, 'x') is None
    assert not session(with_parameters=False).wants_reading(0)


def test_failures_are_reported_once_per_log_period():
    live = session()
    first = live.solve(0, np.full(6, 5.0), None, 100.0)
    assert first[0] is None and first[1].outcome == Outcome.POSE_FAILED
    assert live.solve(PERIOD_NS, np.full(6, 5.0), None, 100.0 + LOG_PERIOD_S / 2)[1] is None
    later = live.solve(2 * PERIOD_NS, np.full(6, 5.0), None, 100.0 + LOG_PERIOD_S)[1]
    assert later.values == {'count': 3} and live.pose_failures == 3
    invalid = live.invalid_reading(InvalidReadingError('missing slider_3'), 0.0)
    assert invalid.level == Level.WARN and 'slider_1, slider_2' in invalid.message


@pytest.mark.parametrize('model', sorted(ARCHITECTURES))
def test_a_target_becomes_a_command_or_a_refusal_with_its_reason(model):
    live = session(model)
    params = live.params
    speed = 0.05

    def command(pose, frame='', limits=None):
        return live.command(frame, 'hexacal_base', lambda: pose, limits, speed)

    assert command(POSE, frame='world')[1].values['reason'] == RefusalReason.WRONG_FRAME
    # Beyond the stroke but reachable: cranks reach less far than sliders and legs (rad: their
    # rods reach -0.92 m with the cranks past -1.2 rad).
    far_z = -1.25 if params.layout.actuator_unit == 'm' else -0.915
    far = np.array([0.0, 0.0, far_z, 0.0, 0.0, 0.0])
    refused = command(far)[1]
    assert refused.values['reason'] == RefusalReason.OUTSIDE_STROKE
    assert refused.message.startswith('refused: outside-stroke: target [0.000000, 0.000000')
    assert command(POSE)[1].values['reason'] == RefusalReason.NO_ACTUATOR_READINGS

    def not_a_pose():
        raise InvalidReadingError('zero quaternion')

    invalid = live.command('', 'hexacal_base', not_a_pose, None, speed)[1]
    assert invalid.values['reason'] == RefusalReason.INVALID_TARGET
    readings = inverse_kinematics(params, POSE[None])[0]
    live.solve(0, readings, None, 0.0)
    target = POSE + np.array([0.004, 0.0, 0.0, 0.0, 0.0, 0.0])
    sent, report = command(target)
    expected = inverse_kinematics(params, target[None])[0]
    assert np.allclose(sent.targets, expected, atol=1e-12)
    assert sent.move_s == max(MIN_MOVE_TIME_S, np.abs(expected - readings).max() / speed)
    assert report.outcome == Outcome.SENT and report.values['commands_sent'] == 1
    assert live.status_values(report)['commands_refused'] == 4
    assert command(target, limits=[0.0, 0.01])[1].values['reason'] == 'outside-stroke'


def test_calibrations_are_taken_unless_of_another_model():
    live = session(with_parameters=False)
    assert live.start_report('/hexacal/parameters', '/cmd').outcome == Outcome.WAITING
    params = architecture('hexa_slide').default_parameters()
    first = live.take_calibration(params, 'hexacal/parameters', '/hexacal/parameters')
    assert first.message == 'calibrated hexa_slide parameters received on /hexacal/parameters'
    assert live.take_calibration(params, 'hexacal/parameters', '/hexacal/parameters') is None
    other = architecture('gough_stewart').default_parameters()
    mismatch = live.take_calibration(other, 'hexacal/parameters', '/hexacal/parameters')
    assert mismatch.outcome == Outcome.MODEL_MISMATCH and live.params is params
    moved = parameters_for('hexa_slide', params.vector + 1e-4)
    update = live.take_calibration(moved, 'hexacal/parameters', '/hexacal/parameters')
    assert update.values['largest_change_m'] == pytest.approx(1e-4)
    assert live.parameters_updates == 2 and live.params is moved


def test_the_markers_are_drawn_once_per_pose():
    live = session()
    assert live.drawing((0, 0), 'hexacal_base') is None  # no pose yet
    live.solve(0, inverse_kinematics(live.params, POSE[None])[0], None, 0.0)
    assert 'platform' in live.drawing((0, 0), 'hexacal_base')
    assert live.drawing((0, 0), 'hexacal_base') is None
    assert live.drawing((0, 0), 'other') is not None
    assert np.array_equal(live.home, home_pose())
