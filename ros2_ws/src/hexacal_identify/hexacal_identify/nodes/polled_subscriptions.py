"""
Subscriptions that a timer polls instead of the executor dispatching each message.

At 3 x 1 kHz, rclpy's executor costs more per message (wait set rebuild, task, callback)
than the collector's own work. A PolledSubscription is never in the executor's wait set:
its owner takes everything queued in one go from a timer (the reader queue must be deep
enough to hold the messages between two polls).

It relies on these rclpy behaviours and internals (ros-jazzy-rclpy 7.1.6), checked by
tests/test_polled_subscriptions.py:
- `Executor._wait_for_ready_callbacks` puts into the wait set only the subscriptions,
  timers and waitables whose `callback_group.can_execute(entity)` is True; a callback
  group whose `can_execute` is always False (PolledGroup) keeps them out, so the executor
  never wakes for, takes from or dispatches them.
- `Subscription.handle` (an `_rclpy.Subscription`) is a context manager (InvalidHandle
  once destroyed) whose `take_message(msg_type, raw)` returns `(message, info)` (bytes
  when raw; info a dict with 'source_timestamp' and 'received_timestamp', ns) or None.
- `Subscription.event_handlers` are the subscription's QoS `EventHandler` waitables, in
  the subscription's callback group (so out of the wait set too: in it, a subscription's
  events wake the executor on every message). Each has `event_type`, `callback` and
  `take_data()`, which takes the event status only when `_ready_to_take_data` is True (a
  ready wait set sets it in `is_ready`); `poll_lost` sets it itself.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import (
    EventHandler,
    QoSSubscriptionEventType,
    SubscriptionEventCallbacks,
)
from rclpy.exceptions import InvalidHandle
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile


def deep_reader_qos(offered: QoSProfile, depth: int) -> QoSProfile:
    """Return a reader QoS matching `offered` whose queue holds `depth` messages between polls."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=offered.reliability,
        durability=offered.durability,
    )


class PolledGroup(CallbackGroup):
    """Callback group the executor never waits on: its entities are polled by their owner."""

    def can_execute(self, entity: Any) -> bool:
        """Return False: the executor never waits on, takes from or runs these entities."""
        return False

    def beginning_execution(self, entity: Any) -> bool:
        """Return False: nothing of this group is ever executed by an executor."""
        return False

    def ending_execution(self, entity: Any) -> None:
        """Do nothing: nothing of this group is ever executed by an executor."""


class PolledSubscription:
    """A raw (CDR bytes) subscription whose messages are taken by `take`, never dispatched."""

    def __init__(
        self,
        node: Node,
        message_type: type,
        topic: str,
        qos: QoSProfile,
        group: PolledGroup,
        on_lost: Callable[[Any], None] | None = None,
    ) -> None:
        self.message_type = message_type
        callbacks = SubscriptionEventCallbacks(message_lost=on_lost) if on_lost else None
        self.subscription = node.create_subscription(
            message_type,
            topic,
            self._dispatched,
            qos,
            raw=True,
            callback_group=group,
            event_callbacks=callbacks,
        )
        # Only the loss reports are polled; the other QoS events are not used.
        # rclpy annotates event_handlers as one EventHandler; it is the list of them.
        handlers = cast(list[EventHandler], self.subscription.event_handlers)
        self._lost_handlers = [
            handler
            for handler in handlers
            if handler.event_type == QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST
        ]

    @staticmethod
    def _dispatched(data: bytes) -> None:
        raise RuntimeError('a polled subscription was dispatched by the executor')

    def take(self, limit: int) -> list[tuple[bytes, dict]]:
        """Take up to `limit` queued messages: [(CDR bytes, info)]; [] once destroyed."""
        taken: list[tuple[bytes, dict]] = []
        try:
            with self.subscription.handle:
                take = self.subscription.handle.take_message
                while len(taken) < limit:  # bounded under any flow
                    item = take(self.message_type, True)
                    if item is None:
                        break
                    taken.append(item)
        except InvalidHandle:
            pass  # shutting down
        return taken

    def poll_lost(self) -> None:
        """Read DDS's loss report; on a new loss call on_lost as the executor would."""
        for handler in self._lost_handlers:
            handler._ready_to_take_data = True  # what a ready wait set sets before take_data
            try:
                status = handler.take_data()
            except InvalidHandle:
                continue
            if status is not None and status.total_count_change:
                handler.callback(status)
