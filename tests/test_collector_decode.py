"""The collector's in-place CDR reading (issue #12 item 4) gives exactly what rclpy decoding gives.

Messages laid out like the learned one are read from the bytes; anything else
(other names, lengths, frame_id, a non-finite value, a negative stamp) is left
to the full decoding, which reports the problem as before.
"""
from __future__ import annotations

import math

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from hexacal_identify.nodes.collector import _FastJointState, _positions_layout, _stamp_of
from hexacal_msgs_py.conversions import joint_state_to_slider_reading, to_stamp
from hexacal_msgs_py.names import SLIDER_NAMES


def _message(stamp_ns: int = 1_700_000_000_123_456_789, names=tuple(SLIDER_NAMES),
             positions=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6), frame_id: str = '',
             velocity=()) -> bytes:
    message = JointState(name=list(names), position=[float(p) for p in positions],
                         velocity=[float(v) for v in velocity])
    message.header.stamp = to_stamp(stamp_ns) if stamp_ns >= 0 else message.header.stamp
    if stamp_ns < 0:
        message.header.stamp.sec = -1
    message.header.frame_id = frame_id
    return serialize_message(message)


def _learned(data: bytes) -> _FastJointState:
    return _FastJointState(data, deserialize_message(data, JointState), tuple(SLIDER_NAMES))


def test_fast_read_equals_rclpy_decoding_for_the_learned_layout():
    fast = _learned(_message())
    for stamp, positions in ((5, (1.5, -2.25, 3e-9, 0.0, -0.0, 1e300)),
                             (2**31 * 10**9 - 1, (0.7,) * 6)):
        data = _message(stamp, positions=positions)
        reading = joint_state_to_slider_reading(deserialize_message(data, JointState))
        assert fast.read(data) == (reading.stamp_ns, reading.slider_positions)
        assert _stamp_of(data) == reading.stamp_ns


def test_joint_order_follows_the_names_of_the_learned_message():
    names = tuple(reversed(SLIDER_NAMES))
    fast = _learned(_message(names=names, positions=(6, 5, 4, 3, 2, 1)))
    assert fast.read(_message(names=names, positions=(60, 50, 40, 30, 20, 10)))[1] == (
        10.0, 20.0, 30.0, 40.0, 50.0, 60.0)


@pytest.mark.parametrize('other', [
    dict(names=('elbow', *SLIDER_NAMES[1:])),
    dict(names=SLIDER_NAMES[:5], positions=(0.1,) * 5),
    dict(positions=(0.1,) * 7, names=(*SLIDER_NAMES, 'extra')),
    dict(frame_id='base'),
    dict(velocity=(1.0,)),
    dict(positions=(0.1, math.nan, 0.3, 0.4, 0.5, 0.6)),
    dict(positions=(0.1, 0.2, math.inf, 0.4, 0.5, 0.6)),
    dict(stamp_ns=-1),
])
def test_anything_else_goes_the_full_way(other):
    fast = _learned(_message())
    assert fast.read(_message(**other)) is None


def test_malformed_bytes_have_no_layout():
    data = _message()
    assert _positions_layout(data[:20]) is None
    assert _positions_layout(b'\x00\x00\x00\x00' + data[4:]) is None  # big endian
    assert _learned(data).read(data[:-8]) is None
