"""Bag replay tests on the recorded sample bags of bags/ (see bags/README.md).

* Every sample bag reads with `rosbags` (an independent reader): topics, types and
  counts equal metadata.yaml.
* Each bag's raw streams replayed (`replay`) into a fresh collector + identify:
  the collector re-detects the bag's postures (same count, same values within
  the noise) and the calibration matches the truth the bag was made with.
* The posture topic of each cost and model replayed straight into identify: the published
  parameters equal `hexacal calibrate` of the same bag to 1e-9.

The Hexa Slide bags were made on Table 1, the Gough-Stewart bag on the default
Gough-Stewart machine; each is calibrated from nominal set 2 (seed 0) of its model.
"""

from __future__ import annotations

import json
from pathlib import Path

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
import numpy as np
import pytest
from rosproc import venv_executable
from system_support import (
    fast_collector_parameters,
    hexacal,
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)
import yaml

BAGS = Path(__file__).resolve().parent.parent / 'bags'
# name -> (cost, noise half-width m, postures): how each bag was made (bags/README.md).
SAMPLES = {
    'sphere50_noise10': ('absolute', 10e-6, 50),
    'sphere60_fixed20_noise10': ('sphere-fixed', 10e-6, 80),
    'sphere30_nonoise': ('absolute', 0.0, 30),
    'gs_sphere50_noise10': ('absolute', 10e-6, 50),
}
# Re-detected from their raw streams: fixed positions, exact data, the other model (the fourth,
# sphere50_noise10, is a Hexa Slide of the same kind as sphere60_fixed20_noise10).
RAW_SAMPLES = ('sphere60_fixed20_noise10', 'sphere30_nonoise', 'gs_sphere50_noise10')
# Replayed as postures into identify: each cost and model once (sphere30_nonoise's exact data
# are calibrated online from its raw streams above).
POSTURE_SAMPLES = ('sphere60_fixed20_noise10', 'sphere50_noise10', 'gs_sphere50_noise10')
# The machine model of each bag (default: the Hexa Slide).
MODELS = {'gs_sphere50_noise10': 'gough_stewart'}
RAW_TOPICS = ['/hexacal/sliders', '/hexacal/inclinometer', '/hexacal/encoder']
RAW_REPLAY_RATE = 3.0  # 50 Hz streams at 150 Hz: the collector keeps up on a busy 2-core machine (stamps drive detection)
POSTURE_REPLAY_RATE = 40.0  # postures are reliable, one per ~2 s recorded


def model_of(name: str) -> str:
    return MODELS.get(name, 'hexa_slide')


def recorded_posture_values(bag: Path) -> np.ndarray:
    return np.array([p.values() for p in postures_from_bag(bag).postures])


@pytest.mark.parametrize('name', sorted(SAMPLES))
def test_rosbags_reads_every_sample_bag_as_metadata_says(name):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import get_typestore, Stores

    bag = BAGS / name
    metadata = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    declared = {
        t['topic_metadata']['name']: (t['topic_metadata']['type'], t['message_count'])
        for t in metadata['topics_with_message_count']
    }
    typestore = get_typestore(Stores.ROS2_JAZZY)
    counts: dict[str, int] = {}
    with Reader(bag) as reader:
        found = {c.topic: c.msgtype for c in reader.connections}
        for connection, _, raw in reader.messages():
            message = typestore.deserialize_cdr(raw, connection.msgtype)
            assert np.all(np.isfinite(message.position))
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    assert {topic: (found[topic], counts[topic]) for topic in found} == declared
    assert declared['/hexacal/posture'][1] == SAMPLES[name][2]
    assert metadata['message_count'] == sum(counts.values())
    if name in MODELS:  # recorded by a collector that knew its model
        assert metadata['custom_data']['hexacal.model'] == MODELS[name]
    assert postures_from_bag(bag).model == model_of(name)


def _replay(bag: Path, topics: list[str], ros_processes, probe, rate: float) -> None:
    replay = ros_processes.start(
        [
            venv_executable('replay'),
            str(bag),
            '--rate',
            str(rate),
            '--topics',
            *topics,
            '--wait-for-subscribers',
            '20',
        ],
        name='replay',
    )
    # Spin the probe meanwhile: it listens to what the nodes publish while the bag plays.
    probe.spin_until(lambda: not replay.running(), 600.0, f'replay of {bag.name}', replay.describe)
    assert replay.popen.returncode == 0, replay.describe()


@pytest.mark.slow
@pytest.mark.parametrize('name', sorted(RAW_SAMPLES))
def test_raw_streams_replayed_into_collector_and_identify(name, ros_processes, tmp_path, probe):
    cost, noise, count = SAMPLES[name]
    model = model_of(name)
    bag = BAGS / name
    _, nominal = write_parameter_files(tmp_path, model)
    collector_model = {'model': model} if name in MODELS else {}
    collector = ros_processes.start(
        node_argv(
            'collector',
            fast_collector_parameters(
                tmp_path / 'bags',
                bag_name='rerecorded',
                window_s=0.3,
                capture_s=0.5,
                **collector_model,
            ),
        ),
        name='collector',
    )
    identify = ros_processes.start(
        node_argv(
            'identify',
            {'nominal': str(nominal), 'cost': cost, 'output_dir': str(tmp_path / 'out')},
        ),
        name='identify',
    )
    probe.subscribe_postures(model=model)
    probe.subscribe_status()
    probe.wait_for_node('collector', '/', collector)
    probe.wait_for_node('identify', '/', identify)
    _replay(bag, RAW_TOPICS, ros_processes, probe, RAW_REPLAY_RATE)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == count,
        60.0,
        f'identify to hold the {count} re-detected postures',
        identify.describe,
    )

    recorded = recorded_posture_values(bag)
    redetected = np.array([p.values() for p in probe.postures])
    assert redetected.shape == recorded.shape
    # Both are means over a dwell of the same samples, windows may differ by a few samples.
    tolerance = max(noise, 1e-9)
    assert np.max(np.abs(redetected - recorded)) < tolerance, np.max(np.abs(redetected - recorded))

    received = probe.subscribe_parameters()
    response = probe.call_trigger()
    assert response.success, response.message
    probe.spin_until(lambda: received, 30.0, 'the published parameters')
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0
    assert postures_from_bag(tmp_path / 'bags' / 'rerecorded').model == model
    truth = architecture(model).default_parameters()
    calibrated = truth.with_vector(received[-1])
    poses = validation_poses(truth, 30, 0, architecture(model).default_workspace())
    after = pose_errors(truth, calibrated, poses).summary()
    assert after['position_max_m'] < (1e-9 if noise == 0 else 60e-6), after


@pytest.mark.slow
@pytest.mark.parametrize('name', sorted(POSTURE_SAMPLES))
def test_posture_topic_replayed_into_identify_equals_offline_calibration(
    name, ros_processes, tmp_path, probe
):
    cost, _, count = SAMPLES[name]
    bag = BAGS / name
    _, nominal = write_parameter_files(tmp_path, model_of(name))
    identify = ros_processes.start(
        node_argv(
            'identify',
            {'nominal': str(nominal), 'cost': cost, 'output_dir': str(tmp_path / 'out')},
        ),
        name='identify',
    )
    probe.subscribe_status()
    probe.wait_for_node('identify', '/', identify)
    _replay(bag, ['/hexacal/posture'], ros_processes, probe, POSTURE_REPLAY_RATE)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == count,
        60.0,
        f"identify to hold the bag's {count} postures",
        identify.describe,
    )
    received = probe.subscribe_parameters()
    response = probe.call_trigger()
    assert response.success, response.message
    probe.spin_until(lambda: received, 30.0, 'the published parameters')

    offline = hexacal(
        'calibrate',
        str(bag),
        '--nominal',
        str(nominal),
        '--output',
        str(tmp_path / 'offline.yaml'),
        '--cost',
        cost,
        '--json',
    )
    assert offline.returncode == 0, offline.stderr
    from hexacal_msgs_py.parameters_file import chain_dict_to_parameters

    result = json.loads(offline.stdout)
    assert result['model'] == model_of(name) and result['bag']['model'] == model_of(name)
    np.testing.assert_allclose(
        received[-1],
        chain_dict_to_parameters(result['parameters'], model_of(name)),
        rtol=0,
        atol=1e-9,
    )


def _machine_bag(directory: Path, count: int) -> tuple[list, list]:
    """A bag of the kinematics node's topics as the collector records them (#11): the platform pose
    (POSE_QOS) and the machine markers (MARKERS_QOS, transient local), every 50 ms."""
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import PoseStamped
    from hexacal_identify.bag import BagWriter
    from hexacal_identify.bag.qos_yaml import qos_profiles_yaml
    from hexacal_msgs_py.qos import MARKERS_QOS, POSE_QOS
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Header
    from visualization_msgs.msg import Marker, MarkerArray

    poses, markers = [], []
    with BagWriter(directory) as writer:
        writer.add_topic(
            '/hexacal/platform_pose', 'geometry_msgs/msg/PoseStamped', qos_profiles_yaml(POSE_QOS)
        )
        writer.add_topic(
            '/hexacal/machine_markers',
            'visualization_msgs/msg/MarkerArray',
            qos_profiles_yaml(MARKERS_QOS),
        )
        for i in range(count):
            header = Header(stamp=Time(sec=100 + i, nanosec=0), frame_id='base_link')
            pose = PoseStamped(header=header)
            pose.pose.position.x, pose.pose.position.z, pose.pose.orientation.w = (
                0.001 * i,
                -0.75,
                1.0,
            )
            marker = Marker(
                header=header, ns='platform', id=i, type=Marker.CYLINDER, pose=pose.pose
            )
            log_time = 1_700_000_000_000_000_000 + i * 50_000_000
            poses.append(pose)
            markers.append(MarkerArray(markers=[marker]))
            writer.write_raw('/hexacal/platform_pose', serialize_message(pose), log_time)
            writer.write_raw('/hexacal/machine_markers', serialize_message(markers[-1]), log_time)
    return poses, markers


@pytest.mark.slow
def test_platform_pose_and_markers_replay_as_a_moving_machine(ros_processes, tmp_path, probe):
    from geometry_msgs.msg import PoseStamped
    from hexacal_msgs_py.qos import MARKERS_QOS, POSE_QOS
    from visualization_msgs.msg import MarkerArray

    count = 20
    poses, markers = _machine_bag(tmp_path / 'machine', count)
    received_poses, received_markers = [], []
    probe.node.create_subscription(
        PoseStamped, '/hexacal/platform_pose', received_poses.append, POSE_QOS
    )
    probe.node.create_subscription(
        MarkerArray, '/hexacal/machine_markers', received_markers.append, MARKERS_QOS
    )
    _replay(
        tmp_path / 'machine',
        ['/hexacal/platform_pose', '/hexacal/machine_markers'],
        ros_processes,
        probe,
        1.0,
    )
    probe.spin_until(
        lambda: received_markers and received_markers[-1] == markers[-1],
        30.0,
        'the last marker array (reliable, transient local)',
    )
    # Depth 1 (MARKERS_QOS): a sample not yet delivered may be replaced by the next, never reordered.
    assert len(received_markers) >= count - 3 and _ordered_subset(received_markers, markers)
    # Best effort, like the live pose stream: the first poses may go out before the probe's reader
    # has matched the replay's writer; everything after arrives, in order.
    assert (
        len(received_poses) >= count - 3 and received_poses == poses[count - len(received_poses) :]
    )


def _ordered_subset(found: list, recorded: list) -> bool:
    remaining = iter(recorded)
    return all(any(item == candidate for candidate in remaining) for item in found)
