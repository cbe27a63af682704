"""Bag layer: rosbag2-compatible writing, reading (also by mcap, rosbags), recovery, errors."""

from __future__ import annotations

import errno
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time

import hexacal_identify.bag as bag_package
from hexacal_identify.bag import (
    BagCorruptError,
    BagDecodeError,
    BagEmptyError,
    BagError,
    BagFormatError,
    BagMetadataError,
    BagMissingFileError,
    BagNotFoundError,
    BagSchemaError,
    BagWriteError,
    BagWriter,
    message_definition,
    open_bag,
    reindex,
)
from hexacal_msgs_py.names import INCLINOMETER_NAMES, JOINT_STATE_TYPE, SLIDER_NAMES
from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import pytest
import yaml

SLIDERS = '/hexacal/sliders'
INCLINOMETER = '/hexacal/inclinometer'
RAW_TOPIC = '/hexacal/encoder'
T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 10_000_000  # 100 Hz


def slider_message(i: int) -> dict:
    stamp_ns = T0_NS + i * PERIOD_NS
    return {
        'header': {
            'stamp': {'sec': stamp_ns // 10**9, 'nanosec': stamp_ns % 10**9},
            'frame_id': 'base',
        },
        'name': list(SLIDER_NAMES),
        'position': [0.4 + 1e-3 * i + 1e-6 * k for k in range(6)],
        'velocity': [],
        'effort': [],
    }


def write_sample_bag(
    directory: Path, n_sliders: int = 120, n_inclinometer: int = 60, **writer_options
) -> Path:
    with BagWriter(directory, **writer_options) as writer:
        writer.add_topic(SLIDERS, JOINT_STATE_TYPE)
        writer.add_topic(INCLINOMETER, JOINT_STATE_TYPE)
        for i in range(n_sliders):
            writer.write(SLIDERS, slider_message(i), T0_NS + i * PERIOD_NS)
            if i < n_inclinometer:
                writer.write(
                    INCLINOMETER,
                    {'name': list(INCLINOMETER_NAMES), 'position': [1e-4 * i, -1e-4 * i]},
                    T0_NS + i * PERIOD_NS + 1,
                    publish_time_ns=T0_NS + i * PERIOD_NS,
                )
        writer.write_metadata('posture_plan', {'name': 'hemisphere', 'postures': '30'})
    return directory


# --------------------------------------------------------------------------- schema text


def test_message_definition_has_rosbag2_layout():
    text = message_definition('sensor_msgs/msg/JointState')
    share = Path(sys.prefix) / 'share'
    own = (share / 'sensor_msgs/msg/JointState.msg').read_text()
    assert text.startswith(own)
    separator = '\n' + '=' * 80 + '\n'
    assert text.count(separator) == 2
    assert separator + 'MSG: std_msgs/Header\n' in text
    assert separator + 'MSG: builtin_interfaces/Time\n' in text
    assert message_definition('sensor_msgs/JointState') == text  # short form accepted
    # An independent parser accepts the concatenated text.
    from rosbags.typesys import get_types_from_msg

    types = get_types_from_msg(text, 'sensor_msgs/msg/JointState')
    assert {'sensor_msgs/msg/JointState', 'std_msgs/msg/Header'} <= set(types)


def test_message_definition_unknown_type_is_named():
    with pytest.raises(BagSchemaError, match='no_such_msgs/msg/Nothing'):
        message_definition('no_such_msgs/msg/Nothing')
    with pytest.raises(BagSchemaError, match='not of the form'):
        message_definition('JointState')


# --------------------------------------------------------------------------- round trips


def test_roundtrip_with_our_reader(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1')
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml', 'run1_0.mcap']
    reader = open_bag(bag, expect_types={'hexacal/sliders': JOINT_STATE_TYPE})
    topics = reader.topics()
    assert {name: (t.type_name, t.count) for name, t in topics.items()} == {
        SLIDERS: (JOINT_STATE_TYPE, 120),
        INCLINOMETER: (JOINT_STATE_TYPE, 60),
    }
    assert yaml.safe_load(topics[SLIDERS].qos_profiles)[0]['reliability'] == 'reliable'

    sliders = list(reader.messages([SLIDERS]))
    assert [m.log_time_ns for m in sliders] == [T0_NS + i * PERIOD_NS for i in range(120)]
    for i, message in enumerate(sliders):
        assert message.topic == SLIDERS and message.type_name == JOINT_STATE_TYPE
        assert list(message.decoded.position) == slider_message(i)['position']
        assert list(message.decoded.name) == list(SLIDER_NAMES)
        assert message.decoded.header.stamp.sec == (T0_NS + i * PERIOD_NS) // 10**9
    inclinometer = list(reader.messages(['hexacal/inclinometer']))  # relative name matches
    assert [m.publish_time_ns for m in inclinometer] == [T0_NS + i * PERIOD_NS for i in range(60)]
    assert [m.log_time_ns for m in inclinometer] == [T0_NS + i * PERIOD_NS + 1 for i in range(60)]
    assert len(list(reader.messages())) == 180

    plan = [r for r in reader.metadata() if r.name == 'posture_plan']
    assert plan and plan[0].data == {'name': 'hemisphere', 'postures': '30'}

    info = reader.info()
    assert info.message_count == 180 and not info.truncated
    assert info.start_time_ns == T0_NS and info.end_time_ns == T0_NS + 119 * PERIOD_NS
    assert info.duration_ns == 119 * PERIOD_NS
    assert info.size_bytes == (bag / 'run1_0.mcap').stat().st_size
    text = info.format()
    assert 'Messages:          180' in text and f'Topic: {SLIDERS}' in text

    # The single .mcap file opens as well.
    assert open_bag(bag / 'run1_0.mcap').info().message_count == 180


def test_metadata_yaml_is_rosbag2_jazzy_version_9(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1')
    document = yaml.safe_load((bag / 'metadata.yaml').read_text())
    information = document['rosbag2_bagfile_information']
    assert information['version'] == 9
    assert information['storage_identifier'] == 'mcap'
    assert information['relative_file_paths'] == ['run1_0.mcap']
    assert information['message_count'] == 180
    assert information['starting_time'] == {'nanoseconds_since_epoch': T0_NS}
    assert information['duration'] == {'nanoseconds': 119 * PERIOD_NS}
    assert information['files'] == [
        {
            'path': 'run1_0.mcap',
            'starting_time': {'nanoseconds_since_epoch': T0_NS},
            'duration': {'nanoseconds': 119 * PERIOD_NS},
            'message_count': 180,
        }
    ]
    assert information['ros_distro'] == 'jazzy'
    assert information['compression_format'] == '' and information['compression_mode'] == ''
    topics = {t['topic_metadata']['name']: t for t in information['topics_with_message_count']}
    assert topics[SLIDERS]['message_count'] == 120
    metadata = topics[SLIDERS]['topic_metadata']
    assert metadata['type'] == JOINT_STATE_TYPE and metadata['serialization_format'] == 'cdr'
    profile = metadata['offered_qos_profiles'][0]  # v9: a list with named policies
    assert (profile['history'], profile['reliability'], profile['durability']) == (
        'keep_last',
        'reliable',
        'volatile',
    )


def test_read_with_mcap_and_mcap_ros2(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    bag = write_sample_bag(tmp_path / 'run1')
    with open(bag / 'run1_0.mcap', 'rb') as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert summary.statistics.message_count == 180
        assert {s.name: s.encoding for s in summary.schemas.values()} == {
            JOINT_STATE_TYPE: 'ros2msg'
        }
        channels = {c.topic: c for c in summary.channels.values()}
        assert channels[SLIDERS].message_encoding == 'cdr'
        assert 'offered_qos_profiles' in channels[SLIDERS].metadata
        decoded = [
            (c.topic, m.log_time, d)
            for _, c, m, d in reader.iter_decoded_messages(topics=[SLIDERS])
        ]
    assert [t for _, t, _ in decoded] == [T0_NS + i * PERIOD_NS for i in range(120)]
    assert list(decoded[7][2].position) == slider_message(7)['position']


def test_read_with_rosbags(tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_typestore, Stores

    bag = write_sample_bag(tmp_path / 'run1')
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        assert reader.message_count == 180
        counts = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert counts == {SLIDERS: (JOINT_STATE_TYPE, 120), INCLINOMETER: (JOINT_STATE_TYPE, 60)}
        qos = [c for c in reader.connections if c.topic == SLIDERS][0].ext.offered_qos_profiles
        assert qos[0].depth == 10 and qos[0].reliability.name == 'RELIABLE'
        connections = [c for c in reader.connections if c.topic == SLIDERS]
        rows = [
            (stamp, typestore.deserialize_cdr(raw, c.msgtype))
            for c, stamp, raw in reader.messages(connections=connections)
        ]
    assert [stamp for stamp, _ in rows] == [T0_NS + i * PERIOD_NS for i in range(120)]
    assert list(rows[42][1].position) == slider_message(42)['position']
    assert list(rows[42][1].name) == list(SLIDER_NAMES)


def test_raw_cdr_from_rclpy_roundtrip(tmp_path):
    pytest.importorskip('rclpy')
    from builtin_interfaces.msg import Time
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Header

    def rclpy_message(i: int) -> JointState:
        return JointState(
            header=Header(stamp=Time(sec=i, nanosec=7), frame_id='device'),
            name=['rotary'],
            position=[0.01 * i],
        )

    directory = tmp_path / 'raw'
    # Serialise once and compare with those bytes: Fast CDR leaves alignment padding uninitialised,
    # so two serialisations of one message may differ in their padding bytes.
    serialized = [serialize_message(rclpy_message(i)) for i in range(25)]
    with BagWriter(directory) as writer:
        writer.add_topic(RAW_TOPIC, JOINT_STATE_TYPE)
        for i in range(25):
            writer.write_raw(RAW_TOPIC, serialized[i], T0_NS + i)
        # A generated message object is encoded by mcap_ros2 and its topic added from its type.
        writer.write('/objects', rclpy_message(99), T0_NS + 100)

    reader = open_bag(directory)
    raw = list(reader.messages([RAW_TOPIC]))
    assert len(raw) == 25
    for i, message in enumerate(raw):
        assert message.data_bytes == serialized[i]  # bytes kept verbatim
        assert list(message.decoded.position) == [0.01 * i]
        assert message.decoded.header.stamp.nanosec == 7
    (obj,) = list(reader.messages(['/objects']))
    assert obj.type_name == JOINT_STATE_TYPE
    assert deserialize_message(obj.data_bytes, JointState).position[0] == pytest.approx(0.99)


def machine_messages(i: int):
    """What the collector records besides JointStates (#11): an Imu inclinometer, the kinematics
    node's platform pose and machine markers (rclpy message objects)."""
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import Point, PoseStamped
    from sensor_msgs.msg import Imu
    from std_msgs.msg import Header
    from visualization_msgs.msg import Marker, MarkerArray

    header = Header(stamp=Time(sec=1_700_000_000 + i, nanosec=5), frame_id='base_link')
    imu = Imu(header=header)
    imu.orientation.x, imu.orientation.w = 0.01 * i, 1.0
    imu.linear_acceleration_covariance[0] = -1.0
    pose = PoseStamped(header=header)
    pose.pose.position.x, pose.pose.position.z = 0.001 * i, -0.75
    pose.pose.orientation.w = 1.0
    rails = Marker(
        header=header,
        ns='rails',
        id=i,
        type=Marker.LINE_LIST,
        action=Marker.ADD,
        points=[Point(x=0.1 * k, y=0.0, z=-0.2) for k in range(12)],
        text='rails',
    )
    rails.scale.x = 0.005
    rails.color.r, rails.color.a = 0.8, 1.0
    rails.lifetime.sec = 2
    platform = Marker(header=header, ns='platform', id=0, type=Marker.CYLINDER)
    platform.pose = pose.pose
    return {
        '/imu': imu,
        '/hexacal/platform_pose': pose,
        '/hexacal/machine_markers': MarkerArray(markers=[rails, platform]),
    }


def test_imu_pose_and_markers_roundtrip_with_every_reader(tmp_path):
    """Raw CDR of sensor_msgs/Imu, geometry_msgs/PoseStamped and visualization_msgs/MarkerArray
    (nested Marker, Point, ColorRGBA, Duration, ...) is written with its schema and reads back with
    our reader, mcap_ros2 and rosbags."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_typestore, Stores

    types = {
        '/imu': 'sensor_msgs/msg/Imu',
        '/hexacal/platform_pose': 'geometry_msgs/msg/PoseStamped',
        '/hexacal/machine_markers': 'visualization_msgs/msg/MarkerArray',
    }
    directory = tmp_path / 'machine'
    serialized = {topic: [] for topic in types}
    with BagWriter(directory) as writer:
        for topic, type_name in types.items():
            writer.add_topic(topic, type_name)
        for i in range(5):
            for topic, message in machine_messages(i).items():
                serialized[topic].append(serialize_message(message))
                writer.write_raw(topic, serialized[topic][-1], T0_NS + i)
        writer.write(
            '/hexacal/machine_markers', machine_messages(9)['/hexacal/machine_markers'], T0_NS + 9
        )

    reader = open_bag(directory)
    assert {name: (info.type_name, info.count) for name, info in reader.topics().items()} == {
        '/imu': (types['/imu'], 5),
        '/hexacal/platform_pose': (types['/hexacal/platform_pose'], 5),
        '/hexacal/machine_markers': (types['/hexacal/machine_markers'], 6),
    }
    for topic in types:
        messages = list(reader.messages([topic]))
        assert [m.data_bytes for m in messages[:5]] == serialized[topic]
        decoded = messages[4].decoded
        if topic == '/imu':
            assert (
                decoded.orientation.x == 0.04 and decoded.linear_acceleration_covariance[0] == -1.0
            )
        elif topic == '/hexacal/platform_pose':
            assert decoded.pose.position.x == 0.004 and decoded.header.frame_id == 'base_link'
        else:
            rails, platform = decoded.markers
            assert len(rails.points) == 12 and rails.points[11].x == pytest.approx(1.1)
            assert (
                rails.lifetime.sec == 2
                and rails.text == 'rails'
                and platform.pose.position.z == -0.75
            )
        assert messages[-1].decoded is not None  # the encoded one decodes too
    counts = {}
    with open(next(directory.glob('*.mcap')), 'rb') as stream:
        for _, channel, _, message in make_reader(
            stream, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts == {'/imu': 5, '/hexacal/platform_pose': 5, '/hexacal/machine_markers': 6}
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(directory) as rosbags_reader:
        decoded = [
            typestore.deserialize_cdr(raw, c.msgtype) for c, _, raw in rosbags_reader.messages()
        ]
    assert len(decoded) == 16
    assert sum(len(getattr(m, 'markers', [])) for m in decoded) == 12


@pytest.mark.parametrize('preset', ['fastwrite', 'zstd_fast', 'zstd_small'])
def test_storage_presets_roundtrip(tmp_path, preset):
    from mcap.reader import make_reader

    bag = write_sample_bag(tmp_path / preset, storage_preset=preset)
    assert open_bag(bag).info().message_count == 180
    assert [m.decoded.position[0] for m in open_bag(bag).messages([SLIDERS])][:3] == [
        0.4,
        0.401,
        0.402,
    ]
    with open(bag / f'{preset}_0.mcap', 'rb') as handle:
        assert sum(1 for _ in make_reader(handle).iter_messages()) == 180


def test_reindex_rebuilds_missing_metadata(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1')
    original = yaml.safe_load((bag / 'metadata.yaml').read_text())
    (bag / 'metadata.yaml').unlink()
    assert open_bag(bag).info().message_count == 180  # readable without metadata.yaml
    info = reindex(bag)
    assert info.message_count == 180 and not info.truncated
    assert yaml.safe_load((bag / 'metadata.yaml').read_text()) == original


# --------------------------------------------------------------------------- writer errors


def test_writer_refuses_non_empty_directory(tmp_path):
    (tmp_path / 'taken').mkdir()
    (tmp_path / 'taken' / 'notes.txt').write_text('keep me')
    with pytest.raises(BagError, match='taken'):
        BagWriter(tmp_path / 'taken')
    assert (tmp_path / 'taken' / 'notes.txt').read_text() == 'keep me'


def test_writer_usage_errors_are_named(tmp_path):
    writer = BagWriter(tmp_path / 'bag')
    with pytest.raises(BagError, match='add_topic'):
        writer.write(SLIDERS, slider_message(0), T0_NS)
    writer.add_topic(SLIDERS, JOINT_STATE_TYPE)
    with pytest.raises(BagError, match='cannot add it again'):
        writer.add_topic(SLIDERS, 'std_msgs/msg/Float64MultiArray')
    with pytest.raises(BagError, match='log_time_ns'):
        writer.write(SLIDERS, slider_message(0), -1)
    with pytest.raises(BagError, match='QoS'):
        writer.add_topic('/other', JOINT_STATE_TYPE, qos_profiles_yaml='reliability: [')
    with pytest.raises(BagError, match='encode'):
        writer.write(SLIDERS, {'position': 'not numbers'}, T0_NS)
    with pytest.raises(BagError, match='positon'):  # a typo is not silently dropped
        writer.write(SLIDERS, {'positon': [1.0]}, T0_NS)
    writer.close()
    with pytest.raises(BagError, match='closed'):
        writer.write(SLIDERS, slider_message(0), T0_NS)


def test_flush_period_makes_writes_durable_without_explicit_flush(tmp_path):
    with BagWriter(tmp_path / 'periodic', flush_period_s=0.0) as writer:
        writer.add_topic(SLIDERS, JOINT_STATE_TYPE)
        for i in range(5):
            writer.write(SLIDERS, slider_message(i), T0_NS + i)
            assert writer.flushed_message_count == writer.message_count == i + 1


# --------------------------------------------------------------------------- reader errors


def test_random_bytes_empty_file_and_missing_paths_are_named(tmp_path):
    random_file = tmp_path / 'noise.mcap'
    random_file.write_bytes(os.urandom(4096))
    with pytest.raises(BagFormatError, match='not an MCAP file'):
        open_bag(random_file)
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    with pytest.raises(BagEmptyError, match='empty'):
        open_bag(empty)
    (tmp_path / 'no_mcap').mkdir()
    with pytest.raises(BagMissingFileError, match='no_mcap'):
        open_bag(tmp_path / 'no_mcap')
    with pytest.raises(BagNotFoundError):
        open_bag(tmp_path / 'nowhere')
    with pytest.raises(BagMissingFileError):
        reindex(tmp_path / 'no_mcap')


def test_metadata_yaml_problems_are_named(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1')
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed')
    with pytest.raises(BagMetadataError, match='reindex'):
        open_bag(bag)
    reindex(bag)
    assert open_bag(bag).info().message_count == 180
    (bag / 'run1_0.mcap').rename(bag / 'moved.mcap')
    with pytest.raises(BagMissingFileError, match='run1_0.mcap'):
        open_bag(bag)


def test_expected_type_mismatch_names_topic_expected_and_found(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1')
    with pytest.raises(BagSchemaError) as raised:
        open_bag(bag, expect_types={'hexacal/sliders': 'std_msgs/msg/Float64MultiArray'})
    error = raised.value
    assert (error.topic, error.expected, error.found) == (
        SLIDERS,
        'std_msgs/msg/Float64MultiArray',
        JOINT_STATE_TYPE,
    )
    assert SLIDERS in str(error) and 'Float64MultiArray' in str(error)
    open_bag(bag, expect_types={'hexacal/posture': JOINT_STATE_TYPE})  # absent topic: fine


def test_wrong_schema_encoding_is_named(tmp_path):
    from mcap.writer import Writer

    path = tmp_path / 'json.mcap'
    with open(path, 'wb') as handle:
        writer = Writer(handle)
        writer.start('', 'test')
        schema = writer.register_schema('Pose', 'jsonschema', b'{}')
        channel = writer.register_channel('/pose', 'json', schema)
        writer.add_message(channel, 1, b'{}', 1)
        writer.finish()
    with pytest.raises(BagSchemaError, match='/pose'):
        open_bag(path)


def test_undecodable_message_names_topic_and_log_time(tmp_path):
    directory = tmp_path / 'bad'
    with BagWriter(directory) as writer:
        writer.add_topic(SLIDERS, JOINT_STATE_TYPE)
        writer.write_raw(SLIDERS, b'\x00\x01\x00\x00\xff\xff\xff\x7f', 1234)
    (message,) = list(open_bag(directory).messages())
    with pytest.raises(BagDecodeError) as raised:
        message.decoded
    assert raised.value.topic == SLIDERS and raised.value.log_time_ns == 1234
    assert SLIDERS in str(raised.value) and '1234' in str(raised.value)


def test_damage_inside_a_complete_file_is_corrupt_error(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1', n_sliders=3000, n_inclinometer=0)
    path = bag / 'run1_0.mcap'
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF  # inside a chunk: its CRC no longer matches
    path.write_bytes(bytes(data))
    with pytest.raises(BagCorruptError, match='run1_0.mcap'):
        list(open_bag(bag).messages())


# --------------------------------------------------------------------------- truncation


def test_every_prefix_of_a_file_reads_as_a_prefix_of_its_messages(tmp_path):
    bag = write_sample_bag(tmp_path / 'run1', chunk_size_bytes=2048)
    full_bytes = (bag / 'run1_0.mcap').read_bytes()
    full = [(m.topic, m.log_time_ns, m.data_bytes) for m in open_bag(bag).messages()]
    previous = 0
    cut_file = tmp_path / 'cut.mcap'
    for cut in range(len(full_bytes) - 1, 7, -997):
        cut_file.write_bytes(full_bytes[:cut])
        reader = open_bag(cut_file)
        got = [(m.topic, m.log_time_ns, m.data_bytes) for m in reader.messages()]
        assert got == full[: len(got)]
        assert reader.info().truncated and reader.info().message_count == len(got)
        assert previous == 0 or len(got) <= previous  # shorter prefix, fewer messages
        previous = len(got)


_CHILD_WRITER = textwrap.dedent("""
    import sys
    from hexacal_identify.bag import BagWriter

    writer = BagWriter(sys.argv[1], chunk_size_bytes=2048)  # chunks also end between flushes
    writer.add_topic("/hexacal/sliders", "sensor_msgs/msg/JointState")
    i = 0
    while True:
        writer.write("/hexacal/sliders", {"name": ["s"], "position": [float(i)]},
                     1_000_000_000 + i * 10_000_000)
        i += 1
        if i % 40 == 0:
            writer.flush()
            print(i, flush=True)
""")


def _child_environment() -> dict[str, str]:
    package_root = Path(bag_package.__file__).resolve().parents[2]
    environment = dict(os.environ)
    environment['PYTHONPATH'] = os.pathsep.join(
        [str(package_root), *filter(None, [environment.get('PYTHONPATH')])]
    )
    return environment


def test_sigkilled_writer_keeps_everything_flushed(tmp_path):
    directory = tmp_path / 'killed'
    child = subprocess.Popen(
        [sys.executable, '-c', _CHILD_WRITER, str(directory)],
        stdout=subprocess.PIPE,
        text=True,
        env=_child_environment(),
    )
    flushed = 0
    try:
        deadline = time.monotonic() + 60
        while flushed < 400 and time.monotonic() < deadline:
            line = child.stdout.readline()
            if not line:
                break
            flushed = int(line)
        time.sleep(0.013)  # let it get into the middle of the next chunk
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=30)
        child.stdout.close()
    assert child.returncode == -signal.SIGKILL
    assert flushed >= 400, 'the writer subprocess did not report its flushes'
    assert not (directory / 'metadata.yaml').exists()

    copy = tmp_path / 'copy'
    shutil.copytree(directory, copy)
    (copy / 'killed_0.mcap').rename(copy / 'copy_0.mcap')
    info = reindex(copy)
    assert info.truncated and info.message_count >= flushed
    messages = list(open_bag(copy).messages())
    assert len(messages) == info.message_count
    for i, message in enumerate(messages):  # a gap-free prefix, every value intact
        assert message.log_time_ns == 1_000_000_000 + i * 10_000_000
        assert message.decoded.position == [float(i)]
    information = yaml.safe_load((copy / 'metadata.yaml').read_text())
    assert information['rosbag2_bagfile_information']['message_count'] == len(messages)


# --------------------------------------------------------------------------- disk full


@pytest.fixture
def tiny_tmpfs():
    mount_point = Path(tempfile.mkdtemp(prefix='hexacal-tmpfs-'))
    try:
        result = subprocess.run(
            ['mount', '-t', 'tmpfs', '-o', 'size=64k', 'tmpfs', str(mount_point)],
            capture_output=True,
            text=True,
        )
    except OSError as error:
        mount_point.rmdir()
        pytest.skip(f'cannot run mount: {error}')
    if result.returncode != 0:
        mount_point.rmdir()
        pytest.skip(f'cannot mount a 64 KiB tmpfs (needs root): {result.stderr.strip()}')
    try:
        yield mount_point
    finally:
        subprocess.run(['umount', str(mount_point)], check=False)
        mount_point.rmdir()


def test_disk_full_raises_write_error_and_keeps_flushed_data(tiny_tmpfs, tmp_path):
    directory = tiny_tmpfs / 'full'
    writer = BagWriter(directory, chunk_size_bytes=2048)
    writer.add_topic(SLIDERS, JOINT_STATE_TYPE)
    flushed = 0
    with pytest.raises(BagWriteError) as raised:
        for i in range(100_000):
            writer.write(SLIDERS, slider_message(i), T0_NS + i * PERIOD_NS)
            if i % 20 == 19:
                writer.flush()
                flushed = writer.flushed_message_count
    error = raised.value
    assert error.os_error is not None and error.os_error.errno == errno.ENOSPC
    assert 'full_0.mcap' in str(error) and error.path.endswith('full_0.mcap')
    assert flushed > 0
    with pytest.raises(BagWriteError):  # a failed writer stays failed
        writer.write(SLIDERS, slider_message(0), T0_NS)
    writer.close()  # cuts back to the last flush; does not raise again

    assert sorted(p.name for p in directory.iterdir()) in (
        ['full_0.mcap'],
        ['full_0.mcap', 'metadata.yaml'],
    )  # metadata.yaml only if it fit
    messages = list(open_bag(directory).messages())
    assert len(messages) == flushed
    assert [m.decoded.position[0] for m in messages] == [
        slider_message(i)['position'][0] for i in range(flushed)
    ]
    try:
        reindex(directory)
    except BagWriteError as reindex_error:  # still full: named, and nothing left behind
        assert reindex_error.os_error.errno == errno.ENOSPC
        assert not list(directory.glob('.metadata.yaml*.tmp'))
    moved = tmp_path / 'moved'
    shutil.copytree(directory, moved)
    (moved / 'full_0.mcap').rename(moved / 'moved_0.mcap')
    (moved / 'metadata.yaml').unlink(missing_ok=True)
    assert reindex(moved).message_count == flushed


# --------------------------------------------------------------------------- property


_SAMPLE_BYTES: dict[str, bytes] = {}


def _sample_file_bytes() -> bytes:
    if 'bytes' not in _SAMPLE_BYTES:
        with tempfile.TemporaryDirectory() as scratch:
            bag = write_sample_bag(
                Path(scratch) / 'sample',
                n_sliders=30,
                n_inclinometer=10,
                storage_preset='zstd_fast',
            )
            _SAMPLE_BYTES['bytes'] = (bag / 'sample_0.mcap').read_bytes()
    return _SAMPLE_BYTES['bytes']


def _read_everything(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as scratch:
        path = Path(scratch) / 'input.mcap'
        path.write_bytes(data)
        reader = open_bag(path, expect_types={SLIDERS: JOINT_STATE_TYPE})
        reader.info().format()
        reader.topics()
        reader.metadata()
        for message in reader.messages():
            message.decoded


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_malformed_or_truncated_input_raises_only_named_errors(data):
    original = _sample_file_bytes()
    kind = data.draw(st.sampled_from(['truncate', 'flip', 'splice', 'random']))
    if kind == 'truncate':
        mutated = original[: data.draw(st.integers(0, len(original)))]
    elif kind == 'flip':
        mutated = bytearray(original)
        for _ in range(data.draw(st.integers(1, 8))):
            position = data.draw(st.integers(0, len(original) - 1))
            mutated[position] = data.draw(st.integers(0, 255))
        mutated = bytes(mutated)
    elif kind == 'splice':
        start = data.draw(st.integers(0, len(original)))
        mutated = original[:start] + data.draw(st.binary(max_size=64)) + original[start:]
    else:
        mutated = data.draw(st.binary(max_size=512))
    try:
        _read_everything(mutated)
    except BagError:
        pass
