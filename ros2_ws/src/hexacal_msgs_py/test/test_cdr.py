"""
In-place CDR reading (hexacal_msgs_py.cdr) gives exactly what rclpy decoding gives.

Messages laid out like the learned one are read from the bytes; anything else
(other names, lengths, frame_id, a non-finite value, a negative stamp) is left
to the full decoding, which reports the problem as before.
"""

from __future__ import annotations

import math
import struct

from hexacal_msgs_py.cdr import (
    header_stamp_ns,
    ImuReader,
    joint_state_positions_layout,
    JointStateReader,
)
from hexacal_msgs_py.conversions import joint_state_to_actuator_reading, to_stamp
from hexacal_msgs_py.names import SLIDER_NAMES
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState


def _message(
    stamp_ns: int = 1_700_000_000_123_456_789,
    names=tuple(SLIDER_NAMES),
    positions=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6),
    frame_id: str = '',
    velocity=(),
) -> bytes:
    message = JointState(
        name=list(names),
        position=[float(p) for p in positions],
        velocity=[float(v) for v in velocity],
    )
    message.header.stamp = to_stamp(stamp_ns) if stamp_ns >= 0 else message.header.stamp
    if stamp_ns < 0:
        message.header.stamp.sec = -1
    message.header.frame_id = frame_id
    return serialize_message(message)


def _learned(data: bytes) -> JointStateReader:
    return JointStateReader(data, deserialize_message(data, JointState), tuple(SLIDER_NAMES))


def test_fast_read_equals_rclpy_decoding_for_the_learned_layout():
    fast = _learned(_message())
    for stamp, positions in (
        (5, (1.5, -2.25, 3e-9, 0.0, -0.0, 1e300)),
        (2**31 * 10**9 - 1, (0.7,) * 6),
    ):
        data = _message(stamp, positions=positions)
        reading = joint_state_to_actuator_reading(deserialize_message(data, JointState))
        assert fast.read(data) == (reading.stamp_ns, reading.actuator_positions)
        assert header_stamp_ns(data) == reading.stamp_ns


def test_joint_order_follows_the_names_of_the_learned_message():
    names = tuple(reversed(SLIDER_NAMES))
    fast = _learned(_message(names=names, positions=(6, 5, 4, 3, 2, 1)))
    assert fast.read(_message(names=names, positions=(60, 50, 40, 30, 20, 10)))[1] == (
        10.0,
        20.0,
        30.0,
        40.0,
        50.0,
        60.0,
    )


@pytest.mark.parametrize(
    'other',
    [
        {'names': ('elbow', *SLIDER_NAMES[1:])},
        {'names': SLIDER_NAMES[:5], 'positions': (0.1,) * 5},
        {'positions': (0.1,) * 7, 'names': (*SLIDER_NAMES, 'extra')},
        {'frame_id': 'base'},
        {'velocity': (1.0,)},
        {'positions': (0.1, math.nan, 0.3, 0.4, 0.5, 0.6)},
        {'positions': (0.1, 0.2, math.inf, 0.4, 0.5, 0.6)},
        {'stamp_ns': -1},
    ],
)
def test_anything_else_goes_the_full_way(other):
    fast = _learned(_message())
    assert fast.read(_message(**other)) is None


def test_read_many_reads_what_read_reads_with_the_same_bits():
    """A recording's stream read at once: the messages `read` reads, in order, nothing else."""
    from hexacal_msgs_py.names import DEVICE_TURN_JOINT, MAX_DEVICE_TURN

    names = (*SLIDER_NAMES, DEVICE_TURN_JOINT)
    fast = JointStateReader(
        _message(names=names, positions=(0.1,) * 7),
        deserialize_message(_message(names=names, positions=(0.1,) * 7), JointState),
        tuple(SLIDER_NAMES),
    )
    messages = [
        _message(5 + k, names=names, positions=(0.1 * k, -0.2, 3e-9, -0.0, 1e300, 0.6, 0.01 * k))
        for k in range(6)
    ]
    messages[1] = _message(names=names, positions=(0.1, math.nan, 0.3, 0.4, 0.5, 0.6, 0.0))
    messages[2] = _message(-1, names=names, positions=(0.1,) * 7)
    messages[3] = _message(names=names, positions=(0.1,) * 6 + (MAX_DEVICE_TURN * 2,))
    messages.append(_message(7, names=names, positions=(0.2,) * 7, frame_id='base'))
    messages.append(_message()[:-8])
    block = fast.read_many(messages)
    read = [(i, fast.read(m)) for i, m in enumerate(messages) if fast.read(m) is not None]
    assert block.rows.tolist() == [i for i, _ in read] == [0, 4, 5]
    assert block.stamps_ns.tolist() == [stamp for _, (stamp, _) in read]
    assert [tuple(v) for v in block.values.tolist()] == [values for _, (_, values) in read]
    assert block.values.tobytes() == struct.pack('<18d', *(v for _, (_, r) in read for v in r))
    assert block.turns is not None and block.turns.tolist() == [0.0, 0.04, 0.05]
    assert fast.read_many([]).rows.size == 0


def test_malformed_bytes_have_no_layout():
    data = _message()
    assert joint_state_positions_layout(data[:20]) is None
    assert joint_state_positions_layout(b'\x00\x00\x00\x00' + data[4:]) is None  # big endian
    assert _learned(data).read(data[:-8]) is None


# ------------------------------------------------ a user's /joint_states and an Imu (issue #11)

BROADCASTER_NAMES = (
    'base_yaw',
    'act_c',
    'act_a',
    'incl_b',
    'act_b',
    'gripper',
    'act_d',
    'act_e',
    'act_f',
    'rot',
    'incl_a',
)
WANTED = ('act_a', 'act_b', 'act_c', 'act_d', 'act_e', 'act_f', 'incl_a', 'incl_b', 'rot')


def _broadcaster(
    stamp_ns: int,
    positions,
    velocity=None,
    effort=None,
    names=BROADCASTER_NAMES,
    frame_id: str = '',
) -> bytes:
    """Serialise a joint_state_broadcaster message: all joints, velocity, effort."""
    count = len(names)
    message = JointState(
        name=list(names),
        position=[float(p) for p in positions],
        velocity=[float(v) for v in (velocity if velocity is not None else [0.0] * count)],
        effort=[float(e) for e in (effort if effort is not None else [0.0] * count)],
    )
    message.header.stamp = to_stamp(stamp_ns)
    message.header.frame_id = frame_id
    return serialize_message(message)


def _positions(seed: float) -> list[float]:
    return [seed + 0.01 * i for i in range(len(BROADCASTER_NAMES))]


def test_a_broadcaster_message_is_read_in_place_whatever_its_velocity_and_effort():
    first = _broadcaster(7, _positions(0.1))
    fast = JointStateReader(first, deserialize_message(first, JointState), WANTED)
    for k in range(1, 5):
        positions = _positions(0.1 * k)
        positions[BROADCASTER_NAMES.index('gripper')] = math.nan  # an extra joint: not read
        data = _broadcaster(10 * k, positions, velocity=[k * 0.5] * 11, effort=[-k * 1.5] * 11)
        decoded = deserialize_message(data, JointState)
        expected = tuple(decoded.position[list(decoded.name).index(name)] for name in WANTED)
        assert fast.read(data) == (10 * k, expected)


@pytest.mark.parametrize(
    'other',
    [
        {'velocity': [0.0] * 10, 'effort': [0.0] * 12},  # same size, other sequence lengths
        {'velocity': [], 'effort': [0.0] * 11},
        {'names': (*BROADCASTER_NAMES[:-1], 'incl_z')},
        {'frame_id': 'x'},
    ],
)
def test_a_broadcaster_message_laid_out_otherwise_goes_the_full_way(other):
    first = _broadcaster(7, _positions(0.1))
    fast = JointStateReader(first, deserialize_message(first, JointState), WANTED)
    assert fast.read(_broadcaster(8, _positions(0.2), **other)) is None


def _imu(
    stamp_ns: int,
    alpha: float,
    beta: float,
    frame_id: str = 'imu_link',
    yaw: float = 0.4,
    covariance_0: float = 0.0,
) -> bytes:
    from hexacal_msgs_py.conversions import inclinometer_angles_to_imu
    from hexacal_msgs_py.readings import InclinometerReading

    message = inclinometer_angles_to_imu(
        InclinometerReading(stamp_ns, alpha, beta), frame_id, yaw=yaw
    )
    message.orientation_covariance[0] = covariance_0
    return serialize_message(message)


def test_an_imu_is_read_in_place_as_the_contract_converts_it():
    from hexacal_msgs_py.conversions import imu_to_inclinometer_reading
    from sensor_msgs.msg import Imu

    first = _imu(5, 0.01, -0.02)
    fast = ImuReader(first, deserialize_message(first, Imu))
    for k, (alpha, beta, yaw) in enumerate(
        [(0.1, 0.2, 0.0), (-0.25, 0.05, 2.5), (3e-6, -1e-7, -1.0)]
    ):
        data = _imu(1_000 + k, alpha, beta, yaw=yaw)
        reading = imu_to_inclinometer_reading(deserialize_message(data, Imu))
        assert fast.read(data) == (reading.stamp_ns, (reading.alpha, reading.beta))
        assert reading.alpha == pytest.approx(alpha, abs=1e-15)
        assert reading.beta == pytest.approx(beta, abs=1e-15)
    assert fast.read(_imu(9, 0.1, 0.1, frame_id='other')) is None
    assert fast.read(_imu(9, 0.1, 0.1, covariance_0=-1.0)) is None  # no orientation: full way
    assert fast.read(first[:-8]) is None
