"""
The executor node's ROS adapters: its service and parameter clients, trajectories, log lines.

The ROS-free walk (core/walk/) calls the drive's release services and the nodes' device_turn
parameters through small client protocols (core/walk/drive_calls.py `ReleaseClient`,
core/walk_device/turns.py `TurnClient`); these are their rclpy implementations. The walk's commands
become trajectory_msgs/JointTrajectory here, and what its parts ask to log goes to the node's
logger here.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from builtin_interfaces.msg import Duration
from hexacal_msgs_py.conversions import NS_PER_S
from hexacal_msgs_py.names import release_service
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..core.walk.messages import LogLevel, Messages
from ..core.walk_device.turns import TURN_PARAMETER


class ReleaseClient:
    """One chain's release service (core.walk.drive_calls.ReleaseClient)."""

    def __init__(self, node: Node, joint: str):
        """Create the client of `joint`'s release service on `node`."""
        self._client = node.create_client(SetBool, release_service(joint))
        self.srv_name = self._client.srv_name

    def service_is_ready(self) -> bool:
        """Return whether the drive offers the service."""
        return self._client.service_is_ready()

    def call(self, release: bool):
        """Call it (True releases, False locks) without blocking; return the future."""
        return self._client.call_async(SetBool.Request(data=release))


class TurnClient:
    """One node's device_turn through its parameter services (walk_device.turns.TurnClient)."""

    def __init__(self, node: Node, name: str):
        """Create the parameter client of node `name` on `node`."""
        # Created with the node, so the services are discovered long before the first turn.
        self._client = AsyncParameterClient(node, name)

    def ready(self) -> bool:
        """Return whether the node's parameter services are there."""
        return self._client.services_are_ready()

    def request(self, turn: float):
        """Set its device_turn (rad) without blocking; return the future."""
        # Never blocks: the executor's timer collects the answer (core.walk_device.turns).
        parameter = Parameter(TURN_PARAMETER, Parameter.Type.DOUBLE, turn)
        return self._client.set_parameters([parameter])


def duration(seconds: float) -> Duration:
    """Return `seconds` (negative: 0) as a builtin_interfaces Duration."""
    nanoseconds = int(round(max(seconds, 0.0) * NS_PER_S))
    return Duration(sec=nanoseconds // NS_PER_S, nanosec=nanoseconds % NS_PER_S)


def trajectory_message(
    joints: Sequence[str], points: Iterable[tuple[list[float], float]]
) -> JointTrajectory:
    """Return the trajectory of (positions, time from start) `points` for `joints`."""
    message = JointTrajectory()  # header.stamp zero: the controller starts it on receipt
    message.joint_names = list(joints)
    message.points = [
        JointTrajectoryPoint(positions=positions, time_from_start=duration(seconds))
        for positions, seconds in points
    ]
    return message


def trigger_answer(future: Any) -> tuple[bool, str]:
    """Return a done hexacal/calibrate call's (success, message); a call that raised fails."""
    try:
        answer = future.result()
    except Exception as error:  # noqa: B902 - the status must say what happened
        return False, f'{type(error).__name__}: {error}'
    return answer.success, answer.message


def log_lines(logger: Any, messages: Messages) -> None:
    """Log each (level, text) of `messages` at its level."""
    # One call site per severity: rclpy refuses another severity from the same line.
    for level, text in messages:
        if level == LogLevel.ERROR:
            logger.error(text)
        elif level == LogLevel.WARN:
            logger.warning(text)
        else:
            logger.info(text)


def log_messages(logger: Any, owners: Iterable[Any]) -> None:
    """Log and clear what each owner's ``messages`` (core.walk.messages.Messages) holds."""
    for owner in owners:
        messages: Messages = owner.messages
        owner.messages = []
        log_lines(logger, messages)


def now_s(node: Node) -> float:
    """Return the node's clock now (s)."""
    return node.get_clock().now().nanoseconds / NS_PER_S
