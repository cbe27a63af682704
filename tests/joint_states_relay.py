"""Test stand-in for ros2_control's joint_state_broadcaster: one /joint_states of a machine.

    python joint_states_relay.py [--ros-args -r ...]

Merges the simulated driver's three sensor streams (remapped by the test to
machine/sliders, machine/inclinometer, machine/encoder) into one
sensor_msgs/JointState on /joint_states per sample, as a ros2_control machine
publishes it: the actuator joints in another order (reversed), the inclinometer
as `tilt_x`, `tilt_y` and the rotary sensor as `link_rotary`, plus joints
hexacal must ignore (`gripper` NaN, `spindle`), with velocity and effort
arrays. A sample is published once all three streams delivered its stamp (the
driver stamps the three alike), with that stamp.
Exits 0 on SIGINT/SIGTERM.
"""

from __future__ import annotations

import math
import signal
import sys

INCLINOMETER_JOINTS = ('tilt_x', 'tilt_y')
ROTARY_JOINT = 'link_rotary'
STREAMS = {
    'sliders': 'machine/sliders',
    'inclinometer': 'machine/inclinometer',
    'encoder': 'machine/encoder',
}
KEEP_SAMPLES = 200  # incomplete samples kept (a best-effort stream may lose one)


def main(argv: list[str]) -> int:
    from hexacal_msgs_py.qos import SENSOR_QOS
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from sensor_msgs.msg import JointState

    rclpy.init(args=argv)
    node = rclpy.create_node('joint_state_broadcaster')
    publisher = node.create_publisher(JointState, '/joint_states', SENSOR_QOS)
    pending: dict[tuple[int, int], dict[str, JointState]] = {}

    def receive(kind: str, message: JointState) -> None:
        key = (message.header.stamp.sec, message.header.stamp.nanosec)
        sample = pending.setdefault(key, {})
        sample[kind] = message
        if len(sample) == len(STREAMS):
            del pending[key]
            publisher.publish(merged(sample))
        while len(pending) > KEEP_SAMPLES:
            del pending[min(pending)]

    def merged(sample: dict[str, JointState]) -> JointState:
        sliders, inclinometer, encoder = (sample[k] for k in STREAMS)
        names = ['gripper', *reversed(sliders.name), *INCLINOMETER_JOINTS, ROTARY_JOINT, 'spindle']
        angles = dict(zip(inclinometer.name, inclinometer.position))
        rotary = dict(zip(encoder.name, encoder.position))
        positions = [
            math.nan,
            *reversed(sliders.position),
            angles['inclinometer_x'],
            angles['inclinometer_y'],
            rotary['rotary'],
            12.5,
        ]
        message = JointState(name=names, position=[float(v) for v in positions])
        message.header.stamp = sliders.header.stamp
        message.header.frame_id = ''
        message.velocity = [0.0] * len(names)
        message.effort = [0.0] * len(names)
        return message

    for kind, topic in STREAMS.items():
        node.create_subscription(JointState, topic, lambda m, k=kind: receive(k, m), SENSOR_QOS)
    signal.signal(signal.SIGTERM, lambda *_: rclpy.try_shutdown())
    node.get_logger().info('relaying machine/* to /joint_states')
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
