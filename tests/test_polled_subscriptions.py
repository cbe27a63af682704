"""
The rclpy behaviour the collector's polled subscriptions rely on (nodes/polled_subscriptions).

If an rclpy release changes it, these fail: the internals still exist with the expected
signatures, a polled subscription receives what is published without the executor ever
dispatching it, and its QoS loss report is read by polling.
"""

import inspect
import time

from hexacal_identify.nodes.polled_subscriptions import PolledGroup, PolledSubscription
import pytest
import rclpy
from rclpy.event_handler import EventHandler, QoSSubscriptionEventType
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from std_msgs.msg import String


def test_the_rclpy_internals_exist_with_the_expected_signatures():
    assert hasattr(Executor, '_wait_for_ready_callbacks')
    assert 'callback_group.can_execute(entity)' in inspect.getsource(Executor.can_execute)
    source = inspect.getsource(Executor._wait_for_ready_callbacks)
    assert 'filter(self.can_execute, node.subscriptions)' in source
    assert 'filter(self.can_execute, node.waitables)' in source
    assert isinstance(Subscription.handle, property)
    assert 'event_handlers' in inspect.getsource(Subscription.__init__)
    assert list(inspect.signature(EventHandler.take_data).parameters) == ['self']
    assert '_ready_to_take_data' in inspect.getsource(EventHandler.take_data)
    assert QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST


@pytest.fixture
def node():
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('polled_probe', context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_a_polled_subscription_receives_without_the_executor_dispatching(node):
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    lost = []
    group = PolledGroup()
    polled = PolledSubscription(node, String, 'polled_probe', qos, group, on_lost=lost.append)
    (subscription,) = node.subscriptions
    assert subscription.callback_group is group
    assert polled._lost_handlers and all(h.callback_group is group for h in polled._lost_handlers)
    publisher = node.create_publisher(String, 'polled_probe', qos)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    taken = []
    deadline = time.monotonic() + 10.0
    sent = 0
    while len(taken) < 5 and time.monotonic() < deadline:
        if sent < 5:
            publisher.publish(String(data=f'm{sent}'))
            sent += 1
        # The executor never takes nor dispatches it (the callback raises if it does).
        executor.spin_once(timeout_sec=0.02)
        taken += polled.take(limit=100)
    assert [data for data, _ in taken][:1] and len(taken) == 5, taken
    data, info = taken[0]
    assert isinstance(data, bytes) and {'source_timestamp', 'received_timestamp'} <= set(info)
    assert polled.take(limit=100) == []
    polled.poll_lost()  # reliable and drained: no loss reported
    assert lost == []
    executor.shutdown()
