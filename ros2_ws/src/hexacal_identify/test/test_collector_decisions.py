"""What the collector node decides besides its counters, without DDS (collector_session)."""

from hexacal_identify.bag import naming
from hexacal_identify.core.detection.dwell_detector import LINK_STREAM
from hexacal_identify.core.detection.turn_history import TurnHistory
from hexacal_identify.core.detection.vocabulary import DetectedPosture, Stream
from hexacal_identify.core.sessions.collector_session import (
    detector_settings,
    dwell_detector,
    end_of_data,
    InputCounters,
    Level,
    LinkReadings,
    plan_record,
    posture_line,
    start_lines,
    status_values,
    stopped_lines,
    turn_change_line,
    turned_reading,
)
from hexacal_identify.nodes.collector_parameters import DETECTOR_PARAMETERS, DWELL_PARAMETERS
from hexacal_identify.nodes.collector_parameters import PARAMETERS
from hexacal_msgs_py.models import ROTARY_ACTUATOR
from hexacal_msgs_py.names import DEVICE_TURN_JOINT, LINK_LENGTH_JOINT
from hexacal_msgs_py.readings import PostureReading

S = 1_000_000_000
TOPICS = ('hexacal/sliders', 'hexacal/inclinometer', 'hexacal/encoder')
DEFAULTS = {name: spec.default for name, (spec, _) in PARAMETERS.items()}


def test_the_detector_and_its_recorded_settings_come_from_the_parameters():
    recorded, settings = detector_settings(DEFAULTS, DETECTOR_PARAMETERS, DWELL_PARAMETERS)
    assert 'max_skew_s' in recorded and 'max_skew_s' not in settings  # the synchronizer's
    assert set(recorded) == set(DETECTOR_PARAMETERS) | set(DWELL_PARAMETERS)
    assert recorded['window_s'] == repr(DEFAULTS['window_s'])
    detector = dwell_detector({**DEFAULTS, 'inclinometer_clock_offset_s': 0.25}, settings)
    assert detector.offsets_s[Stream.INCLINOMETER] == 0.25


def test_link_lengths_are_kept_as_a_detector_stream_and_a_bad_one_is_named():
    link = LinkReadings()
    assert link.take() == {}
    assert link.add(['x', LINK_LENGTH_JOINT], [0.0, 0.75], 5) is None
    problem = link.add([LINK_LENGTH_JOINT], [-0.1], 6)
    assert problem == f'{LINK_LENGTH_JOINT} -0.1 m is not a length'
    assert link.add(['x'], [0.0], 7).startswith(f'no {LINK_LENGTH_JOINT} position')
    assert link.take() == {LINK_STREAM: ([5], [[0.75]])}
    assert link.take() == {}


def test_stopped_streams_are_said_once_and_the_end_of_data_waits_for_all_of_them():
    assert stopped_lines((), (), 1.0) == []
    assert stopped_lines((), ('/a',), 1.0) == [
        (Level.WARN, 'stream(s) stopped: no message on /a for 1 s')
    ]
    assert stopped_lines(('/a',), ('/a',), 1.0) == []
    assert stopped_lines(('/a',), (), 1.0) == [(Level.OK, 'stream(s) resumed: /a')]
    counters = InputCounters(TOPICS)
    counters.count_received(TOPICS, 0)
    _, settings = detector_settings(DEFAULTS, DETECTOR_PARAMETERS, DWELL_PARAMETERS)
    detector = dwell_detector(DEFAULTS, settings)
    assert end_of_data(counters, detector, int(0.5 * S), 1.0) == []  # not stopped yet
    assert end_of_data(counters, detector, 2 * S, 1.0) == []  # stopped, nothing captured


def _posture(stamp_ns: int) -> DetectedPosture:
    reading = PostureReading(stamp_ns, (0.1,) * 6, 0.0, 0.0, 0.0)
    return DetectedPosture(reading, stamp_ns - S, 40, (2e-6,) * 6 + (3e-6,) * 3)


def test_a_posture_carries_the_turn_of_its_inclinometer_messages_else_the_setting():
    _, settings = detector_settings(DEFAULTS, DETECTOR_PARAMETERS, DWELL_PARAMETERS)
    detector = dwell_detector(DEFAULTS, settings)
    reading, turn = turned_reading(_posture(10 * S), detector, TurnHistory(), S // 100, 0.0)
    assert turn == 0.0 and reading.device_turn == 0.0
    reading, turn = turned_reading(_posture(10 * S), detector, TurnHistory(), S // 100, 3.14)
    assert turn == 3.14 and reading.device_turn == 3.14
    line = posture_line(7, _posture(10 * S), turn)
    assert line == (
        'posture 7: 40 samples, std <= 2.0 um (actuators) / 3.0 urad (angles), device turn '
        '3.14 rad'
    )
    line = posture_line(7, _posture(10 * S), 0.0, ROTARY_ACTUATOR)
    assert line == 'posture 7: 40 samples, std <= 2.0 urad (actuators) / 3.0 urad (angles)'


def test_the_status_fields_the_log_lines_and_the_bag_records():
    counters = InputCounters(TOPICS)
    counters.count_received(TOPICS[:1], 0)
    values = status_values('recording', 3, '/bags/b', counters, {'invalid.x': 1}, {'s.rate': 2})
    assert values == {
        'outcome': 'recording',
        'postures_published': 3,
        'bag': '/bags/b',
        'received.hexacal/sliders': 1,
        'received.hexacal/inclinometer': 0,
        'received.hexacal/encoder': 0,
        'invalid.x': 1,
        's.rate': 2,
    }
    lines = start_lines('/p', DEFAULTS, 'hexa_slide', ['s1', 's6'], 'the inputs', 0.5)
    assert lines[0].startswith('collecting postures on /p (window ') and 's1..s6' in lines[0]
    assert lines[1] == 'inputs: the inputs' and DEVICE_TURN_JOINT in lines[2]
    assert len(start_lines('/p', DEFAULTS, 'hexa_slide', ['a', 'b'], '', 0.0)) == 2
    assert turn_change_line(0.0, 0.0) is None
    assert turn_change_line(0.0, 3.0).startswith('device_turn 0 -> 3 rad')
    assert plan_record(['plan', 'seed', 'postures'], ['p.yaml', None, 12]) == {
        'plan': 'p.yaml',
        'postures': '12',
    }
    custom, metadata = naming.collector_records('/collector', '/', 'hexa_slide', {'k': 1}, {})
    assert custom[naming.MODEL_CUSTOM_DATA] == 'hexa_slide'
    assert custom[naming.INPUTS_CUSTOM_DATA] == '{"k": 1}'
    assert metadata == {
        naming.COLLECTOR_METADATA: {'namespace': '/', 'model': 'hexa_slide', 'k': 1}
    }
