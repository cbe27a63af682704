"""
Test that JointState and Imu messages decoded in place equal the generic decoder's exactly.

hexacal_msgs_py.cdr_messages builds the messages of a learned layout from their bytes; the
bag reader uses it for JointState and Imu topics. Every field (its type and, for floats, its
bits) must be the generic decoder's, on the sample bags and on synthetic messages with odd
string lengths, empty or filled sequences, several layouts in one topic, and the device_turn
joint; what it cannot read (big endian, another encapsulation, another definition, bytes
that are no message) goes to the generic decoder. Re-detected postures are identical.
"""

from __future__ import annotations

import math
from pathlib import Path
import struct

from hexacal_identify.bag import BagReader, BagWriter, open_bag
from hexacal_identify.bag import reader as reader_module
from hexacal_msgs_py.cdr_messages import IMU_TYPE, JOINT_STATE_TYPE, MessageDecoder
from hexacal_msgs_py.names import DEVICE_TURN_JOINT, INCLINOMETER_NAMES
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
import pytest

BAGS = Path(__file__).resolve().parents[4] / 'bags'  # the repository's sample bags
SAMPLE_BAGS = sorted(p for p in BAGS.iterdir() if (p / 'metadata.yaml').is_file())


def _fields(value):
    """Return ``value`` as nested tuples naming every type, floats by their bits."""
    if isinstance(value, float):
        return ('float', struct.pack('<d', value))
    if isinstance(value, (list, tuple)):
        return (type(value).__name__, tuple(_fields(v) for v in value))
    if isinstance(value, (int, str)):
        return (type(value).__name__, value)
    slots = tuple(value.__slots__)
    return (type(value).__name__, tuple((s, _fields(getattr(value, s))) for s in slots))


def _decoders(bag: Path, topic: str) -> tuple[object, MessageDecoder]:
    """Return the generic decoder of ``topic``'s schema and an in-place decoder around it."""
    reader = open_bag(bag)
    type_name = reader.topics()[topic].type_name
    encoding, text = reader.schemas(topic)[0]
    schema = Schema(id=1, name=type_name, encoding=encoding, data=text.encode())
    generic = DecoderFactory().decoder_for('cdr', schema)
    return generic, MessageDecoder(type_name, generic)


def _assert_same(bag: Path, topic: str, extra: list[bytes] = ()) -> MessageDecoder:
    generic, fast = _decoders(bag, topic)
    datas = [m.data_bytes for m in open_bag(bag).messages([topic])] + list(extra)
    for data in datas:
        decoded, expected = fast(data), generic(data)
        assert type(decoded) is type(expected)  # the generic decoder's own class
        assert _fields(decoded) == _fields(expected)  # == is False for NaN fields
        assert repr(decoded) == repr(expected)
    return fast


def _joint_state(stamp_ns: int, names, positions, velocity=(), effort=(), frame_id=''):
    return {
        'header': {
            'stamp': {'sec': stamp_ns // 1_000_000_000, 'nanosec': stamp_ns % 1_000_000_000},
            'frame_id': frame_id,
        },
        'name': list(names),
        'position': [float(v) for v in positions],
        'velocity': [float(v) for v in velocity],
        'effort': [float(v) for v in effort],
    }


def _imu(stamp_ns: int, quaternion, frame_id='imu'):
    vector = {'x': 0.25, 'y': -1.5, 'z': 9.81}
    return {
        'header': {
            'stamp': {'sec': stamp_ns // 1_000_000_000, 'nanosec': stamp_ns % 1_000_000_000},
            'frame_id': frame_id,
        },
        'orientation': dict(zip('xyzw', quaternion)),
        'orientation_covariance': [1e-6 * i for i in range(9)],
        'angular_velocity': vector,
        'angular_velocity_covariance': [-1.0] + [0.0] * 8,
        'linear_acceleration': vector,
        'linear_acceleration_covariance': [float(i) for i in range(9)],
    }


# --------------------------------------------------------------------------- sample bags


@pytest.mark.slow
@pytest.mark.parametrize('bag', SAMPLE_BAGS, ids=lambda p: p.name)
def test_every_message_of_the_sample_bags_decodes_as_the_generic_decoder(bag):
    for topic in open_bag(bag).topics():
        fast = _assert_same(bag, topic)
        assert fast.in_place >= open_bag(bag).topics()[topic].count - 3  # learned at once


@pytest.mark.slow
@pytest.mark.parametrize('bag', SAMPLE_BAGS[:1], ids=lambda p: p.name)
def test_the_reader_gives_the_generic_messages(bag, monkeypatch):
    fast = [_fields(m.decoded) for m in open_bag(bag).messages()]
    monkeypatch.setattr(BagReader, 'fast_decoding', False)
    assert fast == [_fields(m.decoded) for m in open_bag(bag).messages()]


# --------------------------------------------------------------------------- synthetic


def test_odd_names_frames_and_sequences_decode_as_the_generic_decoder(tmp_path):
    stamp = 1_700_000_000_123_456_789
    messages = [
        _joint_state(stamp, ['a'], [0.5]),
        _joint_state(stamp + 1, ['abc', 'de', ''], [1.0, -2.0, 3.5], frame_id='x'),
        _joint_state(stamp + 2, ['abc', 'de', ''], [1.0, -2.0, 3.5], [0.1, 0.2, 0.3], [1, 2, 3]),
        _joint_state(stamp + 3, ['abcdefg'], [7.0], [], [4.0], frame_id='frame_7'),
        _joint_state(stamp + 4, ['abcdefg'], [7.0], [5.0], [], frame_id='frame_7'),
        _joint_state(stamp + 5, [], []),
        _joint_state(stamp + 6, ['slider_1', 'slider_2'], [math.nan, math.inf]),
        _joint_state(stamp + 7, ['slider_1', 'slider_3'], [0.25, -0.0]),  # same size, other names
        _joint_state(-1_500_000_000, ['a'], [0.5]),  # a negative stamp (sec -2)
        _joint_state(stamp + 8, ['é'], [1.0], frame_id='ünï'),
    ]
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/joints', JOINT_STATE_TYPE)
        for index, message in enumerate(messages * 3):  # each layout learned, then read in place
            writer.write('/joints', message, 1_000 + index)
    fast = _assert_same(tmp_path / 'bag', '/joints')
    assert fast.in_place >= 2 * len(messages) - 2  # NaN breaks learning that layout only


def test_imu_decodes_as_the_generic_decoder(tmp_path):
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/imu', IMU_TYPE)
        for index in range(50):
            angle = 0.01 * index
            sign = -1.0 if index % 7 == 3 else 1.0  # -q is the same orientation
            quaternion = (sign * math.sin(angle), -0.0, 0.0, sign * math.cos(angle))
            frame = 'imu' if index % 10 else 'imu_link_odd'
            writer.write('/imu', _imu(1_700_000_000_000_000_000 + index, quaternion, frame), index)
    fast = _assert_same(tmp_path / 'bag', '/imu')
    assert fast.in_place >= 45


def _big_endian_joint_state(sec: int, nanosec: int, name: str, position: float) -> bytes:
    text = name.encode() + b'\x00'
    data = b'\x00\x00\x00\x00' + struct.pack('>iI', sec, nanosec) + struct.pack('>I', 1) + b'\x00'
    data += b'\x00' * 3 + struct.pack('>II', 1, len(text)) + text
    data += b'\x00' * (-len(data) % 4) + struct.pack('>I', 1)
    data += b'\x00' * (-(len(data) - 4) % 8) + struct.pack('>d', position)
    return data + struct.pack('>II', 0, 0)


def test_big_endian_and_other_encapsulations_take_the_generic_decoder(tmp_path):
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/joints', JOINT_STATE_TYPE)
        for index in range(3):
            writer.write('/joints', _joint_state(10**18 + index, ['ab'], [1.5]), index)
    little = next(iter(open_bag(tmp_path / 'bag').messages())).data_bytes
    options = little[:3] + b'\x01' + little[4:]  # encapsulation options set
    parameter_list = little[:1] + b'\x03' + little[2:]  # PL_CDR_LE
    big = _big_endian_joint_state(17, 42, 'ab', 1.5)
    generic, fast = _decoders(tmp_path / 'bag', '/joints')
    assert _fields(fast(little)) == _fields(generic(little))
    before = fast.in_place
    for data in (options, parameter_list, big, options, big):
        assert _fields(fast(data)) == _fields(generic(data))
    assert fast.in_place == before
    assert generic(big).header.stamp.sec == 17 and generic(big).position == [1.5]


def test_bytes_that_are_no_message_fail_as_in_the_generic_decoder(tmp_path):
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/joints', JOINT_STATE_TYPE)
        writer.write('/joints', _joint_state(10**18, ['ab', 'cd'], [1.5, 2.5]), 1)
    data = next(iter(open_bag(tmp_path / 'bag').messages())).data_bytes
    generic, fast = _decoders(tmp_path / 'bag', '/joints')
    fast(data)
    for broken in (data[:-9], data[:20], b'\x00\x01'):
        with pytest.raises(Exception) as expected:
            generic(broken)
        with pytest.raises(type(expected.value)) as found:
            fast(broken)
        assert str(found.value) == str(expected.value)


def test_only_the_known_definitions_are_read_in_place(tmp_path):
    with BagWriter(tmp_path / 'bag') as writer:
        writer.add_topic('/joints', JOINT_STATE_TYPE)
    _, text = open_bag(tmp_path / 'bag').schemas('/joints')[0]

    def generic(data: bytes) -> None:
        return None

    def schema(name: str, definition: str) -> Schema:
        return Schema(id=1, name=name, encoding='ros2msg', data=definition.encode())

    known = reader_module._in_place(schema(JOINT_STATE_TYPE, text), generic)
    assert isinstance(known, MessageDecoder)
    extra_field = text.replace('float64[] effort', 'float64[] effort\nuint8 more', 1)
    other_stamp = text.replace('int32 sec', 'int64 sec', 1)
    for name, definition in (
        (JOINT_STATE_TYPE, extra_field),
        (JOINT_STATE_TYPE, other_stamp),
        ('my_msgs/msg/JointState', text),
        ('std_msgs/msg/String', 'string data\n'),
    ):
        assert reader_module._in_place(schema(name, definition), generic) is generic


# --------------------------------------------------------------------------- re-detection


def _recording(directory: Path, imu: bool = False) -> Path:
    """
    Write raw streams of a few dwells.

    The inclinometer with device_turn on every other dwell, or (``imu``) as an Imu on /imu
    with the collector's input mapping saying so.
    """
    from hexacal_identify.core import sample_poses, simulate_measurements, table1_parameters
    from hexacal_msgs_py.inputs import inclinometer_angles_to_quaternion, InputMapping
    from hexacal_msgs_py.names import ENCODER_NAMES, SLIDER_NAMES
    import numpy as np

    true = table1_parameters()
    exact = simulate_measurements(true, sample_poses(true, 6, np.random.default_rng(3)))
    values = np.column_stack([exact.actuator_positions, exact.inclinometer, exact.rotary])
    rng = np.random.default_rng(4)
    topics = ['/hexacal/sliders', '/imu' if imu else '/hexacal/inclinometer', '/hexacal/encoder']
    stamp, previous = 1_700_000_000 * 1_000_000_000, values[0]
    with BagWriter(directory) as writer:
        if imu:
            mapping = InputMapping(
                SLIDER_NAMES, inclinometer_type='imu', topics=(topics[0], '/imu', topics[2])
            )
            writer.write_metadata('hexacal.collector', mapping.to_metadata())
        for topic in topics:
            writer.add_topic(topic, IMU_TYPE if topic == '/imu' else JOINT_STATE_TYPE)
        for index, target in enumerate(values):
            moving = [previous + (target - previous) * (k + 1) / 60 for k in range(60)]
            dwell = target + rng.uniform(-1e-5, 1e-5, (100, 9))
            turn = math.pi if index % 2 else 0.0
            for sample in moving + list(dwell):
                stamp += 10_000_000
                writer.write(topics[0], _joint_state(stamp, SLIDER_NAMES, sample[:6]), stamp)
                inclinometer = (
                    _imu(stamp, inclinometer_angles_to_quaternion(*sample[6:8]))
                    if imu
                    else _joint_state(
                        stamp, (*INCLINOMETER_NAMES, DEVICE_TURN_JOINT), [*sample[6:8], turn]
                    )
                )
                writer.write(topics[1], inclinometer, stamp)
                writer.write(topics[2], _joint_state(stamp, ENCODER_NAMES, sample[8:]), stamp)
            previous = target
    return directory


@pytest.mark.slow
@pytest.mark.parametrize('imu', (False, True), ids=('device_turn', 'imu'))
def test_recordings_decode_and_redetect_as_with_the_generic_decoder(tmp_path, monkeypatch, imu):
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    bag = _recording(tmp_path / 'raw', imu)
    inclinometer = '/imu' if imu else '/hexacal/inclinometer'
    fast = _assert_same(bag, inclinometer)
    assert fast.in_place >= open_bag(bag).topics()[inclinometer].count - 3
    in_place = postures_from_bag(bag)
    monkeypatch.setattr(BagReader, 'fast_decoding', False)
    generic = postures_from_bag(bag)
    assert in_place.source == 'raw streams (re-detected)' and len(in_place.postures) == 6
    assert in_place.postures == generic.postures
    assert {p.device_turn for p in in_place.postures} == ({0.0} if imu else {0.0, math.pi})


@pytest.mark.slow
def test_sample_bag_redetects_the_same_postures(monkeypatch):
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    bag = BAGS / 'sphere30_nonoise'
    in_place = postures_from_bag(bag, source='raw')
    monkeypatch.setattr(BagReader, 'fast_decoding', False)
    generic = postures_from_bag(bag, source='raw')
    assert len(in_place.postures) == 30 and in_place.postures == generic.postures
    assert in_place.invalid_messages == generic.invalid_messages
