"""
Node `kinematics`: the calibrated model at work - platform pose, compensated commands, markers.

Live actuator readings (hexacal/sliders) -> forward kinematics -> hexacal/platform_pose; a target
pose (hexacal/target_pose) -> inverse kinematics -> a JointTrajectory on `command_topic`, or a
refusal with its reason; the machine's drawing on hexacal/machine_markers; the parameters from
the calibration store's active calibration (else the `parameters` file; its compliance section
loaded by the weights of `physical_file`), then every deploy and rollback in the store (a timer
watches its active marker); a message on hexacal/parameters only when it is the deployed
calibration (any, with follow_calibrations). What it decides lives in
core/sessions/kinematics_session.py and session/deployment.py; this module is the ROS glue.
Full reference: docs/nodes.md.
"""

from __future__ import annotations

import sys

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from hexacal_msgs_py.conversions import (
    diagnostic_status,
    joint_state_to_actuator_reading,
    multiarray_model,
    multiarray_to_parameters,
    NS_PER_S,
    stamp_ns,
)
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.names import (
    CALIBRATION_STATUS_TOPIC,
    KINEMATICS_STATUS_NAME,
    MACHINE_MARKERS_TOPIC,
    PARAMETERS_TOPIC,
    PLATFORM_POSE_TOPIC,
    SLIDERS_TOPIC,
    TARGET_POSE_TOPIC,
)
from hexacal_msgs_py.node_parameters import parameter_descriptor
from hexacal_msgs_py.node_runtime import run_node
from hexacal_msgs_py.poses import fill_pose_message, pose_from_message
from hexacal_msgs_py.qos import (
    COMMAND_QOS,
    MARKERS_QOS,
    PARAMETERS_QOS,
    POSE_QOS,
    SENSOR_QOS,
    STATUS_QOS,
)
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import MarkerArray

from .kinematics_parameters import (
    actuator_parameter_defaults,
    ACTUATOR_PARAMETERS,
    PARAMETERS,
    RUNTIME_PARAMETERS,
    UNSET,
)
from .kinematics_parameters import DEFAULT_BASE_FRAME  # noqa: F401 - also imported from here
from .markers import machine_markers  # noqa: F401 - also imported from here
from ..calibration_steps.machine_files import load_machine_and_mount
from ..core.architectures import KinematicParameters, parameters_for
from ..core.machine.device import check_mount, DEFAULT_MOUNT, DeviceMountError
from ..core.sessions.kinematics_session import (
    check_parameter,
    KinematicsConfigurationError,
    Level,
    LiveSession,
    Outcome,
    Report,
)
from ..session.deployment import Deployed, DeployFollower, followed_model, NO_ACTIVE

NODE_NAME = 'kinematics'
STORE_POLL_PERIOD_S = 0.5  # how often the store's active marker is looked at (one stat)


def _duration(seconds: float) -> Duration:
    whole, fraction = divmod(int(round(seconds * NS_PER_S)), NS_PER_S)
    return Duration(sec=whole, nanosec=fraction)


def load_parameters_file(path: str) -> tuple[KinematicParameters, str]:
    """Return (parameters, device mount) of a parameters file; errors as configuration errors."""
    return load_calibration_file(path)[:2]


def load_calibration_file(path: str) -> tuple[KinematicParameters, str, dict[str, float]]:
    """
    Return (parameters, device mount, compliance section) of a parameters file.

    The compliance section in m/N ({}: rigid); errors as configuration errors.
    """
    from hexacal_msgs_py.parameters_file import compliances_from_extras, read_parameters_file

    try:
        params, mount = load_machine_and_mount(path)
        compliances = compliances_from_extras(read_parameters_file(path).extras)
    except (HexacalContractError, DeviceMountError, ValueError) as error:
        raise KinematicsConfigurationError(f'parameters: {error}') from error
    return params, mount, compliances


class KinematicsNode(Node):
    """FK of the live readings, IK of commanded poses, markers: with the calibrated parameters."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        for name, spec in PARAMETERS.items():
            if name not in ACTUATOR_PARAMETERS:
                self._declare(name, Parameter.Type.DOUBLE_ARRAY if name in UNSET else spec.default)
        value = {
            name: self.get_parameter(name).value
            for name in PARAMETERS
            if name not in UNSET and name not in ACTUATOR_PARAMETERS
        }
        params, file_mount, source = None, DEFAULT_MOUNT, ''
        compliances: dict[str, float] = {}
        if value['parameters']:
            params, file_mount, compliances = load_calibration_file(value['parameters'])
            source = value['parameters']
        try:
            model = followed_model(value['model'], params.model if params is not None else None)
        except ValueError as error:
            raise KinematicsConfigurationError(str(error)) from error
        self.deploys = DeployFollower.start(value['calibration_store'], model)
        if self.deploys.deployed is not None:  # the active calibration comes first
            deployed, mount_of, deployed_compliances = load_calibration_file(
                str(self.deploys.deployed.path)
            )
            if params is None or deployed.model == params.model:
                params, source = deployed, self._deployed_source(self.deploys.deployed)
                compliances = deployed_compliances
                file_mount = file_mount if value['parameters'] else mount_of
        # The actuator quantities' defaults are the model's in use (rad/s for cranks).
        in_use = params.model if params is not None else model
        for name, default in actuator_parameter_defaults(in_use).items():
            self._declare(name, default)
        try:
            mount = check_mount(value['mount'] or file_mount)
        except DeviceMountError as error:
            raise KinematicsConfigurationError(str(error)) from error
        self.session = LiveSession.start(
            params,
            source,
            value['link_length'],
            mount,
            int(NS_PER_S / value['max_pose_rate_hz']),
            value['physical_file'],
            compliances,
        )

        self._pose_pub = self.create_publisher(PoseStamped, PLATFORM_POSE_TOPIC, POSE_QOS)
        self._command_pub = self.create_publisher(
            JointTrajectory, value['command_topic'], COMMAND_QOS
        )
        self._status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self._markers_pub = None
        if value['markers_rate_hz'] > 0.0:
            self._markers_pub = self.create_publisher(
                MarkerArray, MACHINE_MARKERS_TOPIC, MARKERS_QOS
            )
            self.create_timer(1.0 / value['markers_rate_hz'], self._publish_markers)
        self.create_subscription(JointState, SLIDERS_TOPIC, self._on_readings, SENSOR_QOS)
        self.create_subscription(PoseStamped, TARGET_POSE_TOPIC, self._on_target, COMMAND_QOS)
        self.create_subscription(
            Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters, PARAMETERS_QOS
        )
        self._follow_any = bool(value['follow_calibrations'])
        taken = self.deploys.deployed is not None and source != value['parameters']
        self.session.deployment = self.deploys.values() if taken else dict(NO_ACTIVE)
        if self.deploys.watch.error:  # e.g. a directory that is not a store: said, not fatal
            self.get_logger().warning(f'calibration store: {self.deploys.watch.error}')
        self.create_timer(STORE_POLL_PERIOD_S, self._follow_store)
        # Where every calibration is taken from ('' = only the deployed ones).
        following = self.resolve_topic_name(PARAMETERS_TOPIC) if self._follow_any else ''
        self._report(
            self.session.start_report(
                following, self._command_pub.topic_name, self.deploys.where
            )
        )

    @property
    def params(self) -> KinematicParameters | None:
        """Return the parameters in use (None before any)."""
        return self.session.params

    def _declare(self, name: str, default: object) -> None:
        descriptor = parameter_descriptor(
            name, PARAMETERS[name], read_only=name not in RUNTIME_PARAMETERS
        )
        self.declare_parameter(name, default, descriptor)

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            problem = check_parameter(parameter.name, parameter.value, load_parameters_file)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _stroke_limits(self) -> list[float] | None:
        try:
            return self.get_parameter('stroke_limits').value
        except ParameterUninitializedException:
            return None

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds / NS_PER_S

    @staticmethod
    def _deployed_source(deployed: Deployed) -> str:
        return f'{deployed.path} ({deployed.active.describe()})'

    def _follow_store(self) -> None:
        """Take the store's active calibration when a deploy or rollback changed it."""
        deployed = self.deploys.poll()
        if deployed is None:
            return
        try:
            params, _, compliances = load_calibration_file(str(deployed.path))
        except KinematicsConfigurationError as error:
            self._report(self.session.invalid_calibration(str(self.deploys.root), error))
            return
        source = self._deployed_source(deployed)
        report = self.session.take_calibration(
            params, 'the calibration store', source, compliances
        )
        if report is None or report.outcome == Outcome.PARAMETERS:  # else the model in use stays
            self.session.deployment = self.deploys.values()
        self._report(report)

    def _on_parameters(self, message: Float64MultiArray) -> None:
        try:
            model = multiarray_model(message).name
            params = parameters_for(model, multiarray_to_parameters(message))
        except (HexacalContractError, ValueError) as error:
            self._report(self.session.invalid_calibration(PARAMETERS_TOPIC, error))
            return
        source = self.resolve_topic_name(PARAMETERS_TOPIC)
        self._follow_store()  # a deploy's message may arrive before the timer sees the store
        if self.deploys.deployed_match(model, params.vector) is not None:
            deployment = self.deploys.values()
        elif self._follow_any:
            deployment = dict(NO_ACTIVE)  # taken from the topic, not from the store
        else:
            self._report(self.session.not_deployed(PARAMETERS_TOPIC, self.deploys.where))
            return
        report = self.session.take_calibration(params, PARAMETERS_TOPIC, source)
        if report is not None and report.outcome == Outcome.PARAMETERS:
            self.session.deployment = deployment
        self._report(report)

    def _on_readings(self, message: JointState) -> None:
        stamp = stamp_ns(message.header.stamp)
        params = self.session.params
        if params is None or not self.session.wants_reading(stamp):  # no parameters: none
            return
        try:
            reading = joint_state_to_actuator_reading(message, params.model)
        except InvalidReadingError as error:
            self._report(self.session.invalid_reading(error, self._now_s()))
            return
        readings = np.array(reading.actuator_positions)
        pose, report = self.session.solve(stamp, readings, message.header.stamp, self._now_s())
        if pose is None:
            self._report(report)
            return
        frame = self.get_parameter('base_frame').value
        out = PoseStamped(header=Header(stamp=message.header.stamp, frame_id=frame))
        self._pose_pub.publish(fill_pose_message(out, pose.tolist()))
        self._report(self.session.published(pose, self._pose_pub.topic_name))

    def _publish_markers(self) -> None:
        stamp = self.session.pose_stamp
        frame = self.get_parameter('base_frame').value
        key = (stamp.sec, stamp.nanosec) if stamp is not None else ()
        drawing = self.session.drawing(key, frame)
        if drawing is not None and self._markers_pub is not None:
            self._markers_pub.publish(machine_markers(drawing, frame, stamp))

    def _on_target(self, message: PoseStamped) -> None:
        command, report = self.session.command(
            message.header.frame_id,
            self.get_parameter('base_frame').value,
            lambda: pose_from_message(message),
            self._stroke_limits(),
            self.get_parameter('max_actuator_speed').value,
        )
        if command is not None:
            point = JointTrajectoryPoint(
                positions=command.targets.tolist(), time_from_start=_duration(command.move_s)
            )
            names = list(command.names)
            self._command_pub.publish(JointTrajectory(joint_names=names, points=[point]))
        self._report(report)

    def _report(self, report: Report | None) -> None:
        """Log a session's report at its level's severity and publish its status."""
        if report is None:
            return
        # One call site per severity: rclpy refuses another severity from the same line.
        level, logger = report.log_level or report.level, self.get_logger()
        if level == Level.OK:
            logger.info(report.log_line)
        elif level == Level.WARN:
            logger.warning(report.log_line)
        else:
            logger.error(report.log_line)
        self._status_pub.publish(
            diagnostic_status(
                report.level,
                KINEMATICS_STATUS_NAME,
                report.message,
                self.session.status_values(report),
                stamp=self.get_clock().now().nanoseconds,
            )
        )

    def summary(self) -> str:
        """Return the counts logged at shutdown."""
        return self.session.summary()


def _finish(node: KinematicsNode) -> list[str]:
    return [node.summary()]


def main(args: list[str] | None = None) -> int:
    """Run the node until shutdown; the exit code (2: a configuration error at start)."""
    return run_node(
        NODE_NAME,
        KinematicsNode,
        args=args,
        finish=_finish,
        startup_errors=(
            KinematicsConfigurationError,
            InvalidParameterValueException,
            InvalidParameterTypeException,
        ),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
