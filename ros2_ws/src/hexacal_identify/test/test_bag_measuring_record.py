"""The bags' hexacal.measuring record and the postures' link lengths in Measurements."""

from hexacal_identify.bag.measuring import MeasuringRecord
from hexacal_identify.calibration_steps.posture_checks import (
    link_length_count,
    measurements_from_postures,
)
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest

VALUES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.01, -0.02, 0.03)


def test_released_actuator_at_a_stamp_is_the_last_change_before_it():
    record = MeasuringRecord()
    assert record.note('passive_actuator', 'slider_2', 100)
    assert not record.note('passive_actuator', 'slider_2', 150)  # a periodic status: no change
    assert record.note('passive_actuator', 'slider_5', 200)
    assert record.note(None, '', 300)  # locked again; the mode stays known
    assert record.mode == 'passive_actuator'
    assert [record.released_at(t) for t in (50, 100, 199, 200, 299, 300, 10**12)] == [
        '', 'slider_2', 'slider_2', 'slider_5', 'slider_5', '', ''
    ]


def test_record_round_trips_through_metadata_strings():
    record = MeasuringRecord()
    record.note('lvdt', '', 5)  # nothing released from the start: no entry needed
    assert record.released == []
    record.note('passive_actuator', 'leg_3', 7)
    data = record.to_metadata()
    assert all(isinstance(value, str) for value in data.values())
    assert MeasuringRecord.from_metadata(data) == record


def test_a_record_that_does_not_parse_reads_as_unknown():
    assert MeasuringRecord.from_metadata({}) == MeasuringRecord()
    broken = MeasuringRecord.from_metadata({'released_actuators': '[[1, '})
    assert broken.released == [] and broken.mode is None


def test_postures_link_lengths_become_the_measurements_link_lengths():
    plain = [PostureReading.from_values(k, VALUES) for k in range(3)]
    assert measurements_from_postures(plain).link_lengths is None
    measured = [
        PostureReading.from_values(k, VALUES, link_length=0.75 + k * 1e-3) for k in range(3)
    ]
    assert link_length_count(measured) == 3
    lengths = measurements_from_postures(measured).link_lengths
    np.testing.assert_array_equal(lengths, [0.75, 0.751, 0.752])
    mixed = measured[:2] + plain[:1]
    with pytest.raises(ValueError, match='nominal link length'):
        measurements_from_postures(mixed)
    lengths = measurements_from_postures(mixed, nominal_link_length=0.7).link_lengths
    np.testing.assert_array_equal(lengths, [0.75, 0.751, 0.7])
