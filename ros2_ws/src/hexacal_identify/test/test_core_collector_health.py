"""The collector's problem counters and status decisions (core.collector_health)."""

from hexacal_identify.core.detection.dwell_detector import DwellDetector
from hexacal_identify.core.detection.stream_synchronizer import StreamSynchronizer
from hexacal_identify.core.detection.vocabulary import DROPPED_FOR_STREAM_STOP
from hexacal_identify.core.sessions.collector_session import (
    decide_status,
    InputCounters,
    Level,
    Outcome,
    problems,
    silent_streams,
    summary,
)

S = 1_000_000_000
TOPICS = ('hexacal/sliders', 'hexacal/inclinometer', 'hexacal/encoder')
ONE_TOPIC = dict.fromkeys(TOPICS, '/joint_states')


def test_inputs_stop_by_receipt_time_and_one_topic_is_named_once():
    counters = InputCounters(TOPICS)
    assert counters.stopped(10 * S, 1.0, ONE_TOPIC) == ()  # never received: not stopped
    counters.count_received(TOPICS, 0)
    counters.count_received(TOPICS[:1], 2 * S)
    assert counters.received == {TOPICS[0]: 2, TOPICS[1]: 1, TOPICS[2]: 1}
    assert counters.stopped(int(2.5 * S), 1.0, ONE_TOPIC) == ('/joint_states',)
    names = {topic: '/' + topic for topic in TOPICS}
    stopped = counters.stopped(int(2.5 * S), 1.0, names)
    assert stopped == ('/hexacal/inclinometer', '/hexacal/encoder')
    assert counters.stopped(int(0.5 * S), 1.0, names) == ()


def test_problems_are_keyed_by_kind_stream_and_reason():
    counters = InputCounters(TOPICS)
    assert counters.count_invalid(TOPICS[1]) == 1
    assert counters.count_invalid(TOPICS[1]) == 2
    counters.lost.update({'hexacal/sliders': 0, 'hexacal/encoder': 3})
    synchronizer = StreamSynchronizer()
    synchronizer.add_values('sliders', 5, (0.0,) * 6)
    synchronizer.add_values('sliders', 5, (0.0,) * 6)  # a repeated stamp
    detector = DwellDetector()
    detector.dropped[DROPPED_FOR_STREAM_STOP] = 1
    found = problems(counters, synchronizer, detector, ('/joint_states',), 'disk full')
    assert found == {
        'invalid.hexacal/inclinometer': 2,
        'lost.hexacal/encoder': 3,
        'rejected.sliders.duplicate_stamp': 1,
        'dropped.stream_stopped': 1,
        'streams_stopped': '/joint_states',
        'recording_error': 'disk full',
    }


def test_a_status_is_published_when_the_problems_change():
    first = decide_status({}, None, None, recording=True)
    assert (first.level, first.outcome, first.message) == ('OK', 'recording', 'no new problems')
    assert decide_status({}, {}, None, recording=True) is None
    grown = decide_status(
        {'invalid.x': 2, 'unpaired.no_encoder_within_skew': 4},
        {'invalid.x': 1},
        None,
        recording=False,
    )
    assert grown.level is Level.WARN and grown.outcome is Outcome.NOT_RECORDING
    assert grown.message == 'invalid.x: 2; unpaired.no_encoder_within_skew: 4'
    # Invalid messages are logged where they happen; other counters in the status's log line.
    assert grown.to_log == ('unpaired.no_encoder_within_skew',)
    cleared = decide_status({}, {'invalid.x': 2}, None, recording=True)
    assert cleared.level == 'OK' and cleared.message == 'no new problems'
    failed = decide_status({'recording_error': 'e'}, {}, 'e', recording=False)
    assert (failed.level, failed.outcome) == (Level.ERROR, Outcome.RECORDING_STOPPED)
    assert failed.message == 'recording stopped: e' and failed.to_log == ()


def test_silent_streams_and_the_summary():
    synchronizer = StreamSynchronizer(stale_after_ns=S)
    synchronizer.add_values('sliders', 1 * S, (0.0,) * 6)
    synchronizer.add_values('encoder', 3 * S, (0.0,))
    names = {'sliders': '/a', 'inclinometer': '/b', 'encoder': '/a'}
    assert silent_streams(synchronizer, int(3.5 * S), names) == ['/a']
    counters = InputCounters(TOPICS)
    text = summary(2, counters, synchronizer, DwellDetector())
    assert text.startswith('2 postures published; messages received {')
    assert text.endswith(
        'invalid messages 0; lost 0; stamps rejected 0; periods dropped 0; unpaired samples 0'
    )


def test_stream_statistics_name_rate_gaps_offset_and_spikes_and_publish_on_change():
    from hexacal_identify.core.sessions.collector_session import stream_statistics
    from hexacal_identify.core.detection.dwell_detector import DwellDetector
    import numpy as np

    detector = DwellDetector(clock_offsets_s={'encoder': 0.03}, estimate_offsets=())
    stamps = S + np.arange(0, 200, dtype=np.int64) * 10_000_000
    stamps = np.delete(stamps, np.arange(50, 70))  # one 0.21 s gap
    detector.update(
        {
            'sliders': (stamps, np.zeros((len(stamps), 6))),
            'inclinometer': (stamps, np.zeros((len(stamps), 2))),
            'encoder': (stamps + 30_000_000, np.zeros((len(stamps), 1))),
        }
    )
    names = {'sliders': '/a', 'inclinometer': '/b', 'encoder': '/c'}
    values = stream_statistics(detector, names)
    assert values['stream.sliders.topic'] == '/a'
    assert abs(values['stream.sliders.rate_hz'] - 90.0) <= 0.1  # 180 readings over 1.99 s
    assert values['stream.encoder.gaps'] == 1
    assert values['stream.encoder.largest_gap_s'] == 0.21
    assert values['stream.encoder.clock_offset_s'] == 0.03
    assert values['stream.sliders.clock_offset_s'] == 0.0
    assert values['stream.inclinometer.spikes_rejected'] == 0
    # Statistics alone publish a status, level OK; unchanged problems and statistics do not.
    decision = decide_status({}, {}, None, recording=True, statistics_changed=True)
    assert decision is not None and decision.level is Level.OK and decision.to_log == ()
    assert decide_status({}, {}, None, recording=True, statistics_changed=False) is None
