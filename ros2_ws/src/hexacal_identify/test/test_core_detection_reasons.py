"""
The detector's reasons and states are enums whose values are the strings users see.

The collector publishes the counters in its status, logs them in its shutdown summary
(the dicts' repr) and writes them to JSON, so the values and the counters' keys must stay
exactly the strings they were before the enums.
"""

import json

from hexacal_identify.core.detection import vocabulary as detection
from hexacal_identify.core.detection.dwell_detector import DwellDetector
from hexacal_identify.core.detection.stream_synchronizer import StreamSynchronizer
from hexacal_identify.core.detection.vocabulary import (
    DetectorState,
    DroppedPeriod,
    DropReason,
    RejectReason,
    Stream,
    UnpairedReason,
)
from hexacal_msgs_py.readings import ActuatorReading, EncoderReading, InclinometerReading
import numpy as np

MS = 1_000_000  # ns

# The strings of the statuses, bags and JSON before the enums, by their old constant names.
STRINGS_BEFORE = {
    'SLIDERS_STREAM': 'sliders',
    'INCLINOMETER_STREAM': 'inclinometer',
    'ENCODER_STREAM': 'encoder',
    'DUPLICATE_STAMP': 'duplicate_stamp',
    'OUT_OF_ORDER': 'out_of_order',
    'NON_FINITE': 'non_finite',
    'NO_INCLINOMETER_WITHIN_SKEW': 'no_inclinometer_within_skew',
    'NO_ENCODER_WITHIN_SKEW': 'no_encoder_within_skew',
    'DROPPED_FOR_MOTION': 'motion',
    'DROPPED_FOR_GAP': 'gap',
    'DROPPED_AT_END': 'end_of_stream',
    'DROPPED_FOR_STREAM_STOP': 'stream_stopped',
}


def test_the_old_constant_names_are_enum_members_with_the_old_strings():
    for name, text in STRINGS_BEFORE.items():
        member = getattr(detection, name)
        assert member == text and f'{member}' == text and str(member) == text, name
        assert type(member) in (Stream, RejectReason, UnpairedReason, DropReason), name
    assert detection.STREAMS == ('sliders', 'inclinometer', 'encoder')
    assert [state.value for state in DetectorState] == ['armed', 'capturing', 'captured']


def test_every_enum_value_is_one_of_the_old_strings():
    enums = (Stream, RejectReason, UnpairedReason, DropReason)
    values = {member.value for enum in enums for member in enum}
    # The settled detector's reason (issue #19) is the one value added since.
    assert values == set(STRINGS_BEFORE.values()) | {'unsettled'}


def still(detector: DwellDetector, start_ns: int, count: int, value: float = 0.3) -> list:
    """Feed `count` readings 10 ms apart of every stream standing at `value`."""
    stamps = start_ns + 10 * MS * np.arange(count, dtype=np.int64)
    return detector.update(
        {
            stream: (stamps, np.full((count, width), value))
            for stream, width in (('sliders', 6), ('inclinometer', 2), ('encoder', 1))
        }
    )


def test_detector_counters_keep_plain_string_keys_and_the_same_repr_and_json():
    detector = DwellDetector()
    stamps = 10 * MS * np.arange(20, dtype=np.int64)
    values = np.full((20, 6), 0.3)
    values[3] = np.nan
    stamps = np.concatenate((stamps, stamps[-1:]))  # one duplicate stamp
    values = np.vstack((values, values[-1:]))
    assert detector.add('sliders', stamps, values) == []
    assert detector.state is DetectorState.ARMED
    assert detector.rejected == {'non_finite': 1, 'duplicate_stamp': 1}
    detector.dropped[DropReason.STREAM_STOPPED.value] = 1
    for counter in (detector.rejected, detector.dropped):
        assert all(type(key) is str for key in counter)
    assert repr(detector.dropped) == "{'stream_stopped': 1}"
    assert json.dumps(detector.rejected) == '{"non_finite": 1, "duplicate_stamp": 1}'
    assert detector.abort(DropReason.STREAM_STOPPED) is None  # nothing being captured


def test_abort_takes_the_plain_string_of_a_reason_and_refuses_an_unknown_one():
    detector = DwellDetector()
    assert still(detector, 0, 50) == []  # 0.5 s still: settled, not yet captured
    assert detector.state is DetectorState.CAPTURING
    dropped = detector.abort('end_of_stream')
    assert isinstance(dropped, DroppedPeriod) and dropped.reason is DropReason.END_OF_STREAM
    assert detector.dropped == {'end_of_stream': 1}
    still(detector, 500 * MS, 50, value=0.6)
    assert detector.state is DetectorState.CAPTURING
    try:
        detector.abort('tired')
    except ValueError:
        pass
    else:
        raise AssertionError('an unknown reason was taken')


def test_synchronizer_counters_and_statuses_keep_plain_string_keys():
    synchronizer = StreamSynchronizer(max_skew_ns=5 * MS)
    slider = ActuatorReading(100 * MS, (0.1,) * 6)
    synchronizer.add_actuators(slider)
    synchronizer.add_actuators(slider)  # the same stamp again
    synchronizer.add_encoder(EncoderReading(100 * MS, 0.0))
    synchronizer.add_inclinometer(InclinometerReading(200 * MS, 0.0, 0.0))
    assert synchronizer.flush() == []  # the inclinometer is 100 ms away
    assert synchronizer.rejected == {
        'sliders': {'duplicate_stamp': 1},
        'inclinometer': {},
        'encoder': {},
    }
    assert synchronizer.unpaired == {'no_inclinometer_within_skew': 1}
    assert repr(synchronizer.unpaired) == "{'no_inclinometer_within_skew': 1}"
    statuses = synchronizer.status(200 * MS)
    assert all(type(name) is str and type(statuses[name].name) is str for name in statuses)
    assert synchronizer.stale_streams(10**9) == ['sliders', 'inclinometer', 'encoder']
