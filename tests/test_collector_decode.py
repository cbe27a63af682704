"""
The collector reads one /joint_states for its three inputs, each reading once (issue #11).

The in-place CDR readers themselves (hexacal_msgs_py.cdr) are tested against rclpy's
decoding in the contract's tests (test_cdr.py).
"""

from __future__ import annotations

from hexacal_msgs_py.conversions import to_stamp
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

# ------------------------------------------------ a user's /joint_states (issue #11)

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
    """Serialise a joint_state_broadcaster message: every joint, with velocity and effort."""
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


def test_the_collector_reads_one_joint_states_for_its_three_inputs_once_each():
    """
    Read all three inputs remapped to one topic, each reading once per message.

    One subscription, the in-place reader learned from the first message, the detector taking
    each stream as it is.
    """
    from hexacal_identify.nodes.collector import CollectorNode
    from hexacal_msgs_py.names import ENCODER_TOPIC, INCLINOMETER_TOPIC, SLIDERS_TOPIC
    import rclpy

    rclpy.init(
        args=[
            '--ros-args',
            '-p',
            'record:=false',
            '-p',
            'detector:=settled',
            '-p',
            'window_s:=0.2',
            '-p',
            'capture_s:=0.3',
            '-p',
            'actuator_joints:=[act_a, act_b, act_c, act_d, act_e, act_f]',
            '-p',
            'inclinometer_joints:=[incl_a, incl_b]',
            '-p',
            'rotary_joint:=rot',
            '-p',
            'inclinometer_signs:=[1, -1]',
            '-p',
            'inclinometer_offsets_rad:=[0.0, 0.005]',
            *[
                item
                for topic in ('sliders', 'inclinometer', 'encoder')
                for item in ('-r', f'hexacal/{topic}:=/joint_states')
            ],
        ]
    )
    node = None
    try:
        node = CollectorNode()
        (source,) = node._sources
        assert source.name == '/joint_states' and source.inputs == (
            SLIDERS_TOPIC,
            INCLINOMETER_TOPIC,
            ENCODER_TOPIC,
        )
        published = []
        node._posture_pub.publish = published.append
        positions = _positions(0.1)
        for k in range(60):  # 0.6 s still at 100 Hz
            node._on_raw(
                source,
                _broadcaster(
                    1_000_000_000 + 10_000_000 * k,
                    positions,
                    velocity=[0.1 * k] * 11,
                    effort=[0.2 * k] * 11,
                ),
                {},
            )
            assert source.fast is not None  # learned from the first message
            node._detect()
        assert node.counters.received == {
            SLIDERS_TOPIC: 60,
            INCLINOMETER_TOPIC: 60,
            ENCODER_TOPIC: 60,
        }
        assert {name: status.accepted for name, status in node.synchronizer.status(0).items()} == {
            'sliders': 60,
            'inclinometer': 60,
            'encoder': 60,
        }
        assert node.counters.invalid == {} and node.synchronizer.unpaired == {}
        (posture,) = published
        # The detector sends the posture's scatter (noise-free: 0, 30 readings each).
        assert list(posture.velocity) == [0.0] * 9 and list(posture.effort) == [30.0] * 9
        value = dict(zip(BROADCASTER_NAMES, positions))
        assert list(posture.name) == [f'slider_{i}' for i in range(1, 7)] + [
            'inclinometer_x',
            'inclinometer_y',
            'rotary',
        ]
        assert list(posture.position) == pytest.approx(
            [value[f'act_{c}'] for c in 'abcdef']
            + [value['incl_a'], -(value['incl_b'] - 0.005), value['rot']],
            abs=1e-15,
        )
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.shutdown()


def test_the_collector_refuses_the_removed_window_detector_naming_settled():
    from hexacal_identify.nodes.collector import CollectorNode
    import rclpy
    from rclpy.exceptions import InvalidParameterValueException

    rclpy.init(args=['--ros-args', '-p', 'record:=false', '-p', 'detector:=window'])
    try:
        with pytest.raises(InvalidParameterValueException) as refused:
            CollectorNode().destroy_node()
        assert "detector 'window' was removed in hexacal 0.2.0: use 'settled'" in str(
            refused.value
        )
    finally:
        rclpy.shutdown()
