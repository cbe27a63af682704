"""
``replay BAG``: publish a bag's messages on their recorded topics, like ``ros2 bag play``.

Messages go out as the recorded CDR bytes (no decode/encode), in log-time order,
with the recorded spacing divided by ``--rate``, on publishers whose QoS is the
one each topic was recorded with (offered_qos_profiles).  Header stamps are the
recorded ones, so downstream nodes see the recorded timing.  Any recorded type
that is installed plays: the sensor streams as the user's drivers published them
(e.g. /joint_states, an Imu), the postures, and the platform pose and machine
markers the collector records (geometry_msgs/PoseStamped,
visualization_msgs/MarkerArray, transient local as recorded), so a bag replays
as a moving machine in RViz or Foxglove.  The tool exits when the bag is done
(or loops with ``--loop``); Ctrl-C stops it cleanly.
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path
import sys
import time

from hexacal_msgs_py.node_runtime import hold_termination_signals
import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..bag import BagError, open_bag
from ..bag.qos_yaml import first_offered_profile

_RELIABILITY = {
    'reliable': ReliabilityPolicy.RELIABLE,
    'best_effort': ReliabilityPolicy.BEST_EFFORT,
}
_DURABILITY = {
    'transient_local': DurabilityPolicy.TRANSIENT_LOCAL,
    'volatile': DurabilityPolicy.VOLATILE,
}


def qos_from_recorded(qos_profiles_yaml: str) -> QoSProfile:
    """Return a topic's recorded QoS (first offered); reliable, volatile, depth 10 if unknown."""
    profile = first_offered_profile(qos_profiles_yaml)
    depth = int(profile.get('depth') or 10)
    history = (
        HistoryPolicy.KEEP_ALL if profile.get('history') == 'keep_all' else HistoryPolicy.KEEP_LAST
    )
    return QoSProfile(
        history=history,
        depth=max(depth, 1),
        reliability=_RELIABILITY.get(profile.get('reliability', ''), ReliabilityPolicy.RELIABLE),
        durability=_DURABILITY.get(profile.get('durability', ''), DurabilityPolicy.VOLATILE),
    )


def message_class(type_name: str):
    """'sensor_msgs/msg/JointState' -> the Python message class."""
    package, _, name = type_name.replace('/msg/', '/').partition('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except (ImportError, AttributeError) as error:
        raise BagError(f'message type {type_name} is not installed: {error}') from error


class BagPlayer(Node):
    """Publishers for the chosen topics; the timing loop lives in ``play``."""

    def __init__(self, bag: Path, topics: list[str] | None):
        super().__init__('hexacal_replay')
        self.reader = open_bag(bag)
        available = self.reader.topics()
        wanted = (
            available
            if not topics
            else {
                t: available[t]
                for t in available
                if t.lstrip('/') in {x.lstrip('/') for x in topics}
            }
        )
        missing = sorted({x.lstrip('/') for x in topics or []} - {t.lstrip('/') for t in wanted})
        if missing:
            raise BagError(f'bag {bag} has no topic(s) {", ".join("/" + m for m in missing)}')
        self.publishers_by_topic = {
            topic: self.create_publisher(
                message_class(info.type_name),
                '/' + topic.lstrip('/'),
                qos_from_recorded(info.qos_profiles),
            )
            for topic, info in wanted.items()
        }

    def wait_for_subscribers(self, timeout_s: float) -> None:
        """Wait until every publisher has a subscriber or time is up (DDS discovery)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(p.get_subscription_count() > 0 for p in self.publishers_by_topic.values()):
                return
            rclpy.spin_once(self, timeout_sec=0.05)
        self.get_logger().warn('not every topic has a subscriber; replaying anyway')

    def play(self, rate: float) -> int:
        """Publish once through the bag; returns the number of messages sent."""
        messages = sorted(
            (m for m in self.reader.messages(list(self.publishers_by_topic))),
            key=lambda m: m.log_time_ns,
        )
        if not messages:
            return 0
        first = messages[0].log_time_ns
        started = time.monotonic()
        for count, message in enumerate(messages, 1):
            if not self.context.ok():  # SIGTERM: rclpy shut the context down
                return count - 1
            due = started + (message.log_time_ns - first) / 1e9 / rate
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)  # pacing the output, as ros2 bag play does
            try:
                self.publishers_by_topic[message.topic].publish(message.data_bytes)
            except Exception:
                # A signal between the check above and this publish shuts the context down under
                # it: rcl reports "publisher's context is invalid". That is a stop, not a crash.
                if self.context.ok():
                    raise
                return count - 1
            if count % 2000 == 0:
                self.get_logger().info(f'{count}/{len(messages)} messages replayed')
        for publisher in self.publishers_by_topic.values():
            # Reliable messages still in flight would die with the publisher: let them arrive.
            try:
                publisher.wait_for_all_acked(Duration(seconds=5.0))
            except Exception:
                if self.context.ok():  # as above: only a shut-down context makes this a stop
                    raise
                break
        return len(messages)


def parse_arguments(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='replay', description='Publish a rosbag2 MCAP bag on its recorded topics.'
    )
    parser.add_argument(
        'bag', type=Path, help='bag directory (metadata.yaml + .mcap) or .mcap file'
    )
    parser.add_argument(
        '--rate', type=float, default=1.0, help='playback speed factor (default 1.0)'
    )
    parser.add_argument('--topics', nargs='+', help='only these topics')
    parser.add_argument('--loop', action='store_true', help='start again at the end')
    parser.add_argument(
        '--wait-for-subscribers',
        type=float,
        default=0.0,
        metavar='SECONDS',
        help='wait up to this long for every topic to have a subscriber before starting',
    )
    args = parser.parse_args(argv)
    if not args.rate > 0:
        parser.error(f'--rate must be positive, got {args.rate}')
    return args


def main(argv: list[str] | None = None) -> int:
    ros_args = rclpy.utilities.remove_ros_args(sys.argv if argv is None else ['replay', *argv])
    args = parse_arguments(ros_args[1:])
    rclpy.init(args=sys.argv if argv is None else None)
    player = None
    try:
        player = BagPlayer(args.bag, args.topics)
        player.wait_for_subscribers(args.wait_for_subscribers)
        while True:
            sent = player.play(args.rate)
            if not player.context.ok():  # stopped by a signal
                return 0
            player.get_logger().info(f'replayed {sent} messages from {args.bag}')
            if not args.loop:
                break
        return 0
    except BagError as error:
        print(f'replay: error: {error}', file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except Exception:
        # A signal while the player is being built shuts the context down under it; the next rcl
        # call (creating a publisher) then fails: a stop, not a crash (node_runtime's rule).
        if rclpy.ok():
            raise
        return 0
    finally:
        hold_termination_signals()  # a second Ctrl-C must not interrupt the shutdown
        if player is not None:
            player.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
