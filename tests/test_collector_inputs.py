"""The collector reads a user's own drivers (issue #11 section 1), with real nodes over Fast DDS.

A small publisher (this file run as a script: `publish_machine`) stands in for a ros2_control
machine: one /joint_states (joint_state_broadcaster-like: custom actuator names in another
order, the inclinometer and rotary joints, other joints besides - one of them NaN - with
changing velocity and effort), a sensor_msgs/Imu on /imu giving the same inclinometer angles
through a sensor mounted with alpha reversed and zero offsets, and the kinematics node's
/hexacal/platform_pose and /hexacal/machine_markers. It walks exact (noise-free) readings of
the simulated Table 1 machine, so every posture is known to rounding.

Two collectors listen at once: one with all three inputs remapped to /joint_states, one (in
namespace /imu_case) with the inclinometer from /imu (inclinometer_type imu, signs and
offsets). Both publish postures with the contract's names equal to the exact readings; the
Imu postures equal the JointState ones within rounding; each bag records the inputs as
received plus the mapping, calibrates offline with `hexacal calibrate`, and re-detected from
its raw inputs gives the live postures. Bad mapping parameters stop the node with exit 2.
"""

from __future__ import annotations

import json
from pathlib import Path
import sys

import numpy as np
import pytest
from system_support import (
    fast_collector_parameters,
    hexacal,
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)
import yaml

POSTURES = 30
SPEED = 2.5  # stamps advance 10 ms per sample, published 2.5 times faster (stamps drive detection)
ACTUATORS = [
    'arm_1_joint',
    'arm_2_joint',
    'arm_3_joint',
    'arm_4_joint',
    'arm_5_joint',
    'arm_6_joint',
]
INCLINOMETER = ['tilt_x', 'tilt_y']
ROTARY = 'platform_roll'
# The order /joint_states carries them in, with other joints of the machine besides.
BROADCAST = [
    'base_lift',
    'arm_3_joint',
    'tilt_y',
    'arm_1_joint',
    'gripper',
    'arm_2_joint',
    'platform_roll',
    'arm_6_joint',
    'arm_5_joint',
    'tilt_x',
    'arm_4_joint',
]
IMU_SIGNS = [-1, 1]
IMU_OFFSETS = [0.0125, -0.02]
IMU_NAMESPACE = '/imu_case'
REMAP_ALL = [
    'hexacal/sliders:=/joint_states',
    'hexacal/inclinometer:=/joint_states',
    'hexacal/encoder:=/joint_states',
]
JOINT_STATE = 'sensor_msgs/msg/JointState'


def exact_readings(count: int, seed: int = 5) -> np.ndarray:
    """(count, 9) exact posture readings of sphere postures on Table 1 (contract order)."""
    from hexacal_identify.core import sample_poses, simulate_measurements, table1_parameters

    truth = table1_parameters()
    data = simulate_measurements(truth, sample_poses(truth, count, np.random.default_rng(seed)))
    return np.column_stack([data.actuator_positions, data.inclinometer, data.rotary])


def imu_mapping():
    from hexacal_msgs_py.inputs import InputMapping

    return InputMapping(
        ACTUATORS,
        INCLINOMETER,
        ROTARY,
        'imu',
        IMU_SIGNS,
        IMU_OFFSETS,
        ('/joint_states', '/imu', '/joint_states'),
    )


def collector_argv(
    bags: Path, bag_name: str, mapping: dict[str, object], remaps: list[str], namespace: str = ''
) -> list[str]:
    """The collector's argv: fast detector settings, the mapping parameters, the remappings."""
    argv = node_argv('collector', fast_collector_parameters(bags, bag_name=bag_name), namespace)
    extra = [item for remap in remaps for item in ('-r', remap)]
    for name, value in mapping.items():
        # Lists spelled as YAML flow sequences (node_argv would quote them as one string).
        text = (
            f'[{", ".join(repr(v) if isinstance(v, float) else str(v) for v in value)}]'
            if isinstance(value, list)
            else str(value)
        )
        extra += ['-p', f'{name}:={text}']
    return argv + extra if '--ros-args' in argv else argv + ['--ros-args', *extra]


def mapping_parameters(**overrides) -> dict[str, object]:
    parameters: dict[str, object] = {
        'actuator_joints': ACTUATORS,
        'inclinometer_joints': INCLINOMETER,
        'rotary_joint': ROTARY,
    }
    parameters.update(overrides)
    return parameters


# --------------------------------------------------------------------------- the test publisher


def publish_machine(argv: list[str]) -> int:
    """Publish the exact readings as a ros2_control machine with an IMU would (see the module doc)."""
    import argparse
    import math
    import time

    from geometry_msgs.msg import PoseStamped
    from hexacal_msgs_py.conversions import inclinometer_angles_to_imu, to_stamp
    from hexacal_msgs_py.names import MACHINE_MARKERS_TOPIC, PLATFORM_POSE_TOPIC
    from hexacal_msgs_py.qos import MARKERS_QOS, POSE_QOS, SENSOR_QOS
    from hexacal_msgs_py.readings import InclinometerReading
    import rclpy
    from sensor_msgs.msg import Imu, JointState
    from visualization_msgs.msg import Marker, MarkerArray

    parser = argparse.ArgumentParser()
    parser.add_argument('--postures', type=int, default=POSTURES)
    parser.add_argument('--joint-states-subscribers', type=int, default=2)
    parser.add_argument('--imu-subscribers', type=int, default=1)
    args = parser.parse_args(argv)
    readings = exact_readings(args.postures)
    mapping = imu_mapping()
    rclpy.init()
    node = rclpy.create_node('machine')
    joint_states = node.create_publisher(JointState, '/joint_states', SENSOR_QOS)
    imu = node.create_publisher(Imu, '/imu', SENSOR_QOS)
    pose = node.create_publisher(PoseStamped, PLATFORM_POSE_TOPIC, POSE_QOS)
    markers = node.create_publisher(MarkerArray, MACHINE_MARKERS_TOPIC, MARKERS_QOS)
    deadline = time.monotonic() + 60.0
    while (
        joint_states.get_subscription_count() < args.joint_states_subscribers
        or imu.get_subscription_count() < args.imu_subscribers
        or pose.get_subscription_count() < 1
        or markers.get_subscription_count() < 1
    ):
        if time.monotonic() > deadline:
            print('no subscribers', flush=True)
            return 3
        time.sleep(0.05)
    time.sleep(0.5)  # the matched readers' remote writers proxies settle (best effort: no retries)
    period_ns = 10_000_000
    stamp = time.time_ns() // period_ns * period_ns
    started = time.monotonic()
    index = {name: i for i, name in enumerate(BROADCAST)}
    previous = readings[0] + np.r_[[0.02] * 6, [0.01] * 3]
    sample = 0
    for target in readings:
        move = [previous + (target - previous) * (k + 1) / 30 for k in range(30)]  # 0.3 s
        for values in move + [target] * 70:  # then 0.7 s still
            sample += 1
            stamp += period_ns
            positions = [0.0] * len(BROADCAST)
            positions[index['base_lift']] = 0.1 * sample
            positions[index['gripper']] = math.nan  # a joint without a position: not ours
            for name, value in zip(ACTUATORS + INCLINOMETER + [ROTARY], values):
                positions[index[name]] = float(value)
            message = JointState(
                name=BROADCAST,
                position=positions,
                velocity=[0.01 * sample] * len(BROADCAST),
                effort=[-0.02 * sample] * len(BROADCAST),
            )
            message.header.stamp = to_stamp(stamp)
            message.header.frame_id = 'base_link'
            joint_states.publish(message)
            imu.publish(
                inclinometer_angles_to_imu(
                    InclinometerReading(stamp, float(values[6]), float(values[7])),
                    'imu_link',
                    mapping=mapping,
                    yaw=0.7,
                )
            )
            if sample % 10 == 0:
                pose_message = PoseStamped()
                pose_message.header.stamp = to_stamp(stamp)
                pose_message.header.frame_id = 'base_link'
                pose_message.pose.position.x = float(values[0])
                pose_message.pose.orientation.w = 1.0
                pose.publish(pose_message)
                marker = Marker(ns='platform', id=sample, type=Marker.SPHERE, action=Marker.ADD)
                marker.header = pose_message.header
                marker.pose = pose_message.pose
                marker.scale.x = marker.scale.y = marker.scale.z = 0.05
                marker.color.a = 1.0
                markers.publish(MarkerArray(markers=[marker]))
            delay = started + sample * period_ns / 1e9 / SPEED - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        previous = target
    time.sleep(0.5)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


# --------------------------------------------------------------------------- helpers


def subscribe_postures(probe, topic: str) -> list:
    from hexacal_msgs_py.conversions import joint_state_to_posture_reading
    from hexacal_msgs_py.names import POSTURE_NAMES
    from hexacal_msgs_py.qos import POSTURE_QOS
    from sensor_msgs.msg import JointState

    received: list = []

    def on_posture(message: JointState) -> None:
        assert tuple(message.name) == POSTURE_NAMES  # the contract's names, whatever the inputs
        received.append(joint_state_to_posture_reading(message))

    subscription = probe.node.create_subscription(JointState, topic, on_posture, POSTURE_QOS)
    _SUBSCRIPTIONS[id(received)] = subscription
    return received


_SUBSCRIPTIONS: dict = {}  # id(received list) -> its subscription (matched publishers)


def posture_array(postures) -> np.ndarray:
    return np.array([p.values() for p in postures])


def without_posture_topic(bag: Path, copy: Path) -> Path:
    """The bag as a recording of the raw inputs only (same bytes, metadata records kept)."""
    from hexacal_identify.bag import BagWriter, open_bag

    reader = open_bag(bag)
    with BagWriter(copy) as writer:
        for record in reader.metadata():
            if record.name != 'rosbag2':
                writer.write_metadata(record.name, record.data)
        for name, info in reader.topics().items():
            if not name.endswith('hexacal/posture'):
                writer.add_topic(name, info.type_name, info.qos_profiles)
        for message in reader.messages():
            if not message.topic.endswith('hexacal/posture'):
                writer.write_raw(
                    message.topic, message.data_bytes, message.log_time_ns, message.publish_time_ns
                )
    return copy


# --------------------------------------------------------------------------- tests


@pytest.mark.slow
def test_one_joint_states_and_an_imu_give_the_contracts_postures(ros_processes, tmp_path, probe):
    from hexacal_identify.core import table1_parameters
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
    from hexacal_msgs_py.inputs import InputMapping
    from hexacal_msgs_py.parameters_file import load_parameters
    from rosproc import venv_executable  # noqa: F401 - the console scripts are installed

    _, nominal = write_parameter_files(tmp_path)
    bags = tmp_path / 'bags'
    joint_states_postures = subscribe_postures(probe, '/hexacal/posture')
    imu_postures = subscribe_postures(probe, f'{IMU_NAMESPACE}/hexacal/posture')
    collector = ros_processes.start(
        collector_argv(bags, 'joint_states', mapping_parameters(), REMAP_ALL), name='collector'
    )
    imu_collector = ros_processes.start(
        collector_argv(
            bags,
            'imu',
            mapping_parameters(
                inclinometer_type='imu',
                inclinometer_signs=IMU_SIGNS,
                inclinometer_offsets_rad=IMU_OFFSETS,
            ),
            [
                'hexacal/sliders:=/joint_states',
                'hexacal/inclinometer:=/imu',
                'hexacal/encoder:=/joint_states',
            ],
            IMU_NAMESPACE,
        ),
        name='imu_collector',
    )
    probe.wait_for_node('collector', '/', collector)
    probe.wait_for_node('collector', IMU_NAMESPACE, imu_collector)
    # Each collector's posture publisher matched with the probe before any reading is sent: on a
    # loaded machine discovery can take longer than the first posture.
    probe.spin_until(
        lambda: all(
            _SUBSCRIPTIONS[id(r)].get_publisher_count() >= 1
            for r in (joint_states_postures, imu_postures)
        ),
        60.0,
        'the collectors\' posture publishers to match the probe',
        lambda: '\n'.join(p.describe(15) for p in (collector, imu_collector)),
    )
    machine = ros_processes.start([sys.executable, __file__, '--publish'], name='machine')
    nodes = (collector, imu_collector, machine)

    def done() -> bool:
        for process in (collector, imu_collector):
            if not process.running():
                raise AssertionError(f'a collector exited early\n{process.describe()}')
        return len(joint_states_postures) >= POSTURES and len(imu_postures) >= POSTURES

    probe.spin_until(
        done,
        POSTURES / SPEED + 90.0,
        f'{POSTURES} postures from each collector',
        lambda: '\n'.join(p.describe(15) for p in nodes),
    )
    probe.spin_until(
        lambda: not machine.running(), 30.0, 'the publisher to finish', machine.describe
    )
    assert machine.popen.returncode == 0, machine.describe()
    for process in (collector, imu_collector):
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.describe()
        summary = process.log_path.read_text()
        assert (
            f'{POSTURES} postures published' in summary and 'invalid messages 0; lost 0' in summary
        )
        assert 'unpaired samples 0' in summary, summary[-2000:]
    assert 'inputs: sliders <- /joint_states [arm_1_joint' in collector.log_path.read_text()
    assert (
        'inclinometer <- /imu (sensor_msgs/Imu orientation) signs [-1.0, 1.0]'
        in imu_collector.log_path.read_text()
    )

    # Live: the contract's postures, paired from one message (JointState) or two topics (Imu).
    exact = exact_readings(POSTURES)
    live = posture_array(joint_states_postures)
    live_imu = posture_array(imu_postures)
    assert len(live) == len(live_imu) == POSTURES
    assert np.abs(live - exact).max() < 1e-12, np.abs(live - exact).max()
    assert np.abs(live_imu - live).max() < 1e-12, np.abs(live_imu - live).max()  # rounding only
    assert [p.stamp_ns for p in imu_postures] == [p.stamp_ns for p in joint_states_postures]

    # The bags: the inputs as received, under their real topics and types, plus the mapping.
    for name, expected_topics in (
        (
            'joint_states',
            {
                '/joint_states': JOINT_STATE,
                '/hexacal/posture': JOINT_STATE,
                '/hexacal/platform_pose': 'geometry_msgs/msg/PoseStamped',
                '/hexacal/machine_markers': 'visualization_msgs/msg/MarkerArray',
            },
        ),
        (
            'imu',
            {
                '/joint_states': JOINT_STATE,
                '/imu': 'sensor_msgs/msg/Imu',
                f'{IMU_NAMESPACE}/hexacal/posture': JOINT_STATE,
            },
        ),
    ):
        metadata = yaml.safe_load((bags / name / 'metadata.yaml').read_text())[
            'rosbag2_bagfile_information'
        ]
        topics = {
            t['topic_metadata']['name']: (t['topic_metadata']['type'], t['message_count'])
            for t in metadata['topics_with_message_count']
        }
        assert {topic: kind for topic, (kind, _) in topics.items()} == expected_topics
        assert topics['/joint_states'][1] == POSTURES * 100  # every message recorded once
        recorded = json.loads(metadata['custom_data']['hexacal.inputs'])
        assert (
            json.loads(recorded['actuator_joints']) == ACTUATORS
            and recorded['rotary_joint'] == ROTARY
        )
    assert _recorded_pose_and_markers(bags / 'joint_states') == (POSTURES * 10, POSTURES * 10)

    # Offline: the posture topic, and re-detection from the raw inputs with the recorded mapping.
    for name, postures in (('joint_states', joint_states_postures), ('imu', imu_postures)):
        from_topic = postures_from_bag(bags / name)
        assert from_topic.source == 'posture topic' and from_topic.postures == postures
        assert from_topic.ignored_topics == (
            ['/hexacal/machine_markers', '/hexacal/platform_pose']
            if name == 'joint_states'
            else []
        )
        redetected = postures_from_bag(bags / name, source='raw')
        assert (
            redetected.source == 'raw streams (re-detected)' and redetected.invalid_messages == 0
        )
        assert [p.stamp_ns for p in redetected.postures] == [p.stamp_ns for p in postures]
        difference = np.abs(posture_array(redetected.postures) - posture_array(postures)).max()
        assert difference < 1e-12, difference
    mapping = postures_from_bag(bags / 'imu').mapping
    assert mapping == imu_mapping() and not mapping.is_contract()
    assert postures_from_bag(bags / 'joint_states').mapping == InputMapping(
        ACTUATORS, INCLINOMETER, ROTARY, topics=('/joint_states',) * 3
    )

    # hexacal calibrate: from the posture topic, and from the raw inputs of a bag without one.
    truth = table1_parameters().vector
    results = {}
    for name, bag in (
        ('joint_states', bags / 'joint_states'),
        ('imu raw', without_posture_topic(bags / 'imu', tmp_path / 'imu_raw_only')),
    ):
        output = tmp_path / f'{name.replace(" ", "_")}.yaml'
        completed = hexacal('calibrate', bag, '--nominal', nominal, '--output', output, '--json')
        assert completed.returncode == 0, completed.stderr
        result = json.loads(completed.stdout)
        assert result['rank'] == 54 and result['bag']['postures'] == POSTURES
        assert result['bag']['source'] == (
            'posture topic' if name == 'joint_states' else 'raw streams (re-detected)'
        )
        results[name] = load_parameters(output)
        assert np.abs(results[name] - truth).max() < 1e-6  # exact readings
    assert np.abs(results['joint_states'] - results['imu raw']).max() < 1e-9


def _recorded_pose_and_markers(bag: Path) -> tuple[int, int]:
    """Counts of decodable platform poses and marker arrays in the bag (read with rosbags too)."""
    from hexacal_identify.bag import open_bag
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_typestore, Stores

    counts = {'/hexacal/platform_pose': 0, '/hexacal/machine_markers': 0}
    for message in open_bag(bag).messages(list(counts)):
        decoded = message.decoded
        if message.topic.endswith('platform_pose'):
            assert decoded.header.frame_id == 'base_link' and decoded.pose.orientation.w == 1.0
        else:
            assert decoded.markers[0].ns == 'platform' and decoded.markers[0].scale.x == 0.05
        counts[message.topic] += 1
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic in counts]
        for connection, _, raw in reader.messages(connections=connections):
            typestore.deserialize_cdr(raw, connection.msgtype)
    return counts['/hexacal/platform_pose'], counts['/hexacal/machine_markers']


@pytest.mark.parametrize(
    'parameters, text',
    [
        (
            mapping_parameters(actuator_joints=ACTUATORS[:5]),
            'actuator_joints: must name 6 joints, got 5',
        ),
        (
            mapping_parameters(inclinometer_type='gyroscope'),
            "inclinometer_type: must be 'joint_state' or 'imu', got 'gyroscope'",
        ),
        (
            mapping_parameters(inclinometer_signs=[1, 2]),
            'inclinometer_signs: each sign must be 1 or -1',
        ),
        (
            mapping_parameters(rotary_joint='arm_2_joint'),
            "rotary_joint: joint 'arm_2_joint' is also in actuator_joints",
        ),
    ],
)
def test_bad_mapping_parameters_are_named_and_exit_2(
    ros_processes, tmp_path, probe, parameters, text
):
    collector = ros_processes.start(
        collector_argv(tmp_path / 'bags', 'refused', parameters, REMAP_ALL), name='collector'
    )
    probe.spin_until(
        lambda: not collector.running(),
        60.0,
        'the collector to refuse its parameters',
        collector.describe,
    )
    assert collector.popen.returncode == 2, collector.describe()
    log = collector.log_text()
    assert f'cannot start: {text}' in log, log
    assert 'Traceback' not in log
    assert not (tmp_path / 'bags').exists() or not any((tmp_path / 'bags').iterdir())


if __name__ == '__main__' and sys.argv[1:2] == ['--publish']:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    sys.exit(publish_machine(sys.argv[2:]))
