"""Node `kinematics`: the calibrated model at work - live platform pose, compensated commands, machine markers.

The model is the calibrated one: the `parameters` file at start (a parameters
YAML of either model, e.g. the output of identify or ``hexacal calibrate``),
then every calibration published on the latched `hexacal/parameters`
(PARAMETERS_QOS; with `follow_calibrations`, the default), each logged and
reported on the status topic.  Without a file the first message on
`hexacal/parameters` decides the model; a later calibration of another model
is refused (`model-mismatch`) and the model in use is kept.

* Pose: the live actuator readings on `hexacal/sliders` (SENSOR_QOS;
  JointState with the model's actuator joints slider_1..6 or leg_1..6, other
  joints ignored) -> forward kinematics with the calibrated parameters ->
  `hexacal/platform_pose` (geometry_msgs/PoseStamped, POSE_QOS), header
  stamp = the reading's stamp, frame_id = `base_frame`.  Each solve starts
  from the previous pose; the first (and one after a failure) from the
  workspace centre (the device's fixed point [0, 0, -L], or [0, 0, +L] for a
  standing mount, platform level), following the readings from there
  (core/live.py) so the pose is the working mode's.  At most
  `max_pose_rate_hz` readings per second are solved (by their stamps).
* Command: a platform pose on `hexacal/target_pose` (PoseStamped, COMMAND_QOS,
  frame_id `base_frame` or empty) -> inverse kinematics with the calibrated
  parameters -> a trajectory_msgs/JointTrajectory on `command_topic`
  (COMMAND_QOS; ros2_control's joint_trajectory_controller interface): the
  model's actuator joint names, one point with the six targets (m) and
  time_from_start = the largest actuator travel from the current readings /
  `max_actuator_speed` (at least MIN_MOVE_TIME_S), header stamp zero (start
  now).  A target that no leg configuration reaches, that needs a reading
  outside `stroke_limits` (default: the architecture's workspace stroke), in
  another frame, not a pose (e.g. a zero quaternion), before any parameters or
  before any actuator reading is refused: a WARN status naming the reason, and
  nothing is published.
* Markers: `hexacal/machine_markers` (visualization_msgs/MarkerArray,
  MARKERS_QOS), the architecture's drawing of the machine at the latest pose
  (base joints, rails and sliders or legs, platform, device link O -> P), in
  `base_frame`, at most `markers_rate_hz` times a second and only when the
  pose changed.

Pose <-> PoseStamped: hexacal_msgs_py.poses (position m; orientation the
quaternion of R = R_Y(theta) R_X(psi) R_z(phi), eq. 2).  Status: DiagnosticArray
on `hexacal/calibration_status` (STATUS_QOS), status name 'hexacal
kinematics', with `outcome` (waiting, parameters, tracking, sent, refused with
its `reason`, pose-failed, invalid-reading, invalid-parameters,
model-mismatch) and the figures of the event; repeated reading problems are
logged and published at most every LOG_PERIOD_S.
"""

from __future__ import annotations

import math
import sys

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, PoseStamped
from hexacal_msgs_py.conversions import (
    diagnostic_status,
    joint_state_to_slider_reading,
    multiarray_model,
    multiarray_to_parameters,
    stamp_ns,
)
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY as MOUNT_PARAMETER
from hexacal_msgs_py.names import (
    CALIBRATION_STATUS_TOPIC,
    DEFAULT_COMMAND_TOPIC,
    KINEMATICS_STATUS_NAME,
    MACHINE_MARKERS_TOPIC,
    PARAMETERS_TOPIC,
    PLATFORM_POSE_TOPIC,
    SLIDERS_TOPIC,
    TARGET_POSE_TOPIC,
)
from hexacal_msgs_py.parameters_file import read_parameters_file
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
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from ..core.architectures import KinematicParameters, parameters_for
from ..core.device import check_mount, DEFAULT_MOUNT, DeviceMountError, MOUNTS
from ..core.errors import ForwardKinematicsError, UnreachablePoseError
from ..core.live import actuator_targets, default_stroke, home_pose, OutOfStrokeError, solve_pose
from .runtime import run_node

NODE_NAME = 'kinematics'
DEFAULT_BASE_FRAME = 'hexacal_base'
MIN_MOVE_TIME_S = 0.1  # a command's time_from_start is never shorter
LOG_PERIOD_S = 5.0  # repeated problems (bad readings, failed solves) are logged at most this often
NS_PER_S = 1_000_000_000

# Marker style per drawing name: RGBA and size (m; sphere diameter or line width). Others: DEFAULT_STYLE.
MARKER_STYLES: dict[str, tuple[tuple[float, float, float, float], float]] = {
    'base_joints': ((0.35, 0.35, 0.35, 1.0), 0.04),
    'rails': ((0.55, 0.55, 0.55, 1.0), 0.012),
    'sliders': ((0.10, 0.40, 0.90, 1.0), 0.045),
    'cylinders': ((0.15, 0.25, 0.70, 1.0), 0.035),
    'legs': ((0.20, 0.60, 0.95, 1.0), 0.014),
    'platform_joints': ((0.95, 0.55, 0.10, 1.0), 0.03),
    'platform': ((0.95, 0.55, 0.10, 1.0), 0.016),
    'device_link': ((0.15, 0.80, 0.25, 1.0), 0.008),
}
DEFAULT_STYLE = ((0.8, 0.8, 0.8, 1.0), 0.01)


class KinematicsConfigurationError(Exception):
    """The node's parameters do not describe a machine it can work with."""


def _range(low: float, high: float) -> list[FloatingPointRange]:
    return [FloatingPointRange(from_value=low, to_value=high, step=0.0)]


def machine_markers(drawing: dict[str, np.ndarray], frame_id: str, stamp) -> MarkerArray:
    """MarkerArray of an Architecture.drawing: one marker per name (namespace = the name, id 0),
    points as a SPHERE_LIST, segments as a LINE_LIST."""
    header = Header(stamp=stamp, frame_id=frame_id)
    markers = []
    for name in sorted(drawing):
        array = np.asarray(drawing[name], dtype=float)
        (r, g, b, a), size = MARKER_STYLES.get(name, DEFAULT_STYLE)
        marker = Marker(
            header=header,
            ns=name,
            id=0,
            action=Marker.ADD,
            type=Marker.SPHERE_LIST if array.ndim == 2 else Marker.LINE_LIST,
            color=ColorRGBA(r=r, g=g, b=b, a=a),
        )
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = size
        marker.points = [
            Point(x=float(x), y=float(y), z=float(z)) for x, y, z in array.reshape(-1, 3)
        ]
        markers.append(marker)
    return MarkerArray(markers=markers)


def _duration(seconds: float) -> Duration:
    whole, fraction = divmod(int(round(seconds * NS_PER_S)), NS_PER_S)
    return Duration(sec=whole, nanosec=fraction)


class KinematicsNode(Node):
    """FK of the live readings, IK of commanded poses, markers: with the latest calibrated parameters."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.declare_parameter(
            'parameters',
            '',
            ParameterDescriptor(
                description="parameters YAML (either model) to start from; '' = wait for the first "
                'calibration on hexacal/parameters',
                read_only=True,
            ),
        )
        self.declare_parameter(
            'follow_calibrations',
            True,
            ParameterDescriptor(
                description='take every calibration published on hexacal/parameters (latched) over the '
                'parameters in use; false: keep the parameters file',
                read_only=True,
            ),
        )
        self.declare_parameter(
            'base_frame',
            DEFAULT_BASE_FRAME,
            ParameterDescriptor(
                description='frame_id of the platform pose and the markers (the base frame OXYZ); target '
                'poses must be in it (or have an empty frame_id)'
            ),
        )
        self.declare_parameter(
            'command_topic',
            DEFAULT_COMMAND_TOPIC,
            ParameterDescriptor(
                description='topic of the compensated actuator commands (trajectory_msgs/JointTrajectory; '
                "ros2_control's joint_trajectory_controller listens on <controller>/joint_trajectory)",
                read_only=True,
            ),
        )
        self.declare_parameter(
            'max_actuator_speed',
            0.02,
            ParameterDescriptor(
                description="actuator speed (m/s) that sets a command's time_from_start: the largest "
                f'travel from the current readings / this speed (at least {MIN_MOVE_TIME_S:g} s)',
                floating_point_range=_range(1e-6, 10.0),
            ),
        )
        self.declare_parameter(
            'stroke_limits',
            Parameter.Type.DOUBLE_ARRAY,
            ParameterDescriptor(
                description='[low, high] actuator readings (m) a command may ask for; unset = the '
                "architecture's workspace stroke (Hexa Slide 0-0.9 m, Gough-Stewart 0-0.5 m)"
            ),
        )
        self.declare_parameter(
            'link_length',
            0.75,
            ParameterDescriptor(
                description='measuring link length L (m): the first pose solve starts at the workspace '
                'centre, the fixed point [0, 0, -L] (standing: +L)',
                floating_point_range=_range(0.1, 5.0),
                read_only=True,
            ),
        )
        self.declare_parameter(
            'mount',
            '',
            ParameterDescriptor(
                description="device mount, which side of the base the workspace centre is: 'hanging' or "
                "'standing'; '' = the parameters file's device.mount, else hanging",
                read_only=True,
                additional_constraints="'', " + ', '.join(repr(m) for m in MOUNTS),
            ),
        )
        self.declare_parameter(
            'max_pose_rate_hz',
            200.0,
            ParameterDescriptor(
                description='actuator readings solved per second at most (by their stamps); the others '
                'are skipped',
                floating_point_range=_range(0.1, 10000.0),
                read_only=True,
            ),
        )
        self.declare_parameter(
            'markers_rate_hz',
            10.0,
            ParameterDescriptor(
                description='machine markers published per second at most (when the pose changed); '
                '0 = no markers',
                floating_point_range=_range(0.0, 100.0),
                read_only=True,
            ),
        )
        value = {
            name: self.get_parameter(name).value
            for name in (
                'parameters',
                'follow_calibrations',
                'link_length',
                'mount',
                'max_pose_rate_hz',
                'markers_rate_hz',
                'command_topic',
            )
        }

        self.params: KinematicParameters | None = None
        self.parameters_source = ''
        self.parameters_updates = 0
        file_mount = DEFAULT_MOUNT
        if value['parameters']:
            self.params, file_mount = self._load_file(value['parameters'])
            self.parameters_source = value['parameters']
        try:
            self.mount = check_mount(value['mount'] or file_mount)
        except DeviceMountError as error:
            raise KinematicsConfigurationError(str(error)) from error
        self.home = home_pose(value['link_length'], self.mount)
        self.min_period_ns = int(NS_PER_S / value['max_pose_rate_hz'])

        self.pose: np.ndarray | None = None  # latest solved pose and its readings
        self.readings: np.ndarray | None = None
        self.pose_stamp = None  # builtin_interfaces/Time of the reading
        self._last_solved_ns: int | None = None
        self._drawn = None  # the (pose stamp, parameters) last drawn
        self.poses_published = 0
        self.pose_failures = 0
        self.invalid_readings = 0
        self.commands_sent = 0
        self.commands_refused = 0
        self._tracking = False
        self._last_log: dict[str, float] = {}

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
        if value['follow_calibrations']:
            self.create_subscription(
                Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters, PARAMETERS_QOS
            )

        command_topic = self._command_pub.topic_name
        if self.params is not None:
            self.get_logger().info(
                f'{self.params.model} parameters from {self.parameters_source}; '
                f'{"following calibrations on " + self.resolve_topic_name(PARAMETERS_TOPIC) if value["follow_calibrations"] else "calibrations on hexacal/parameters ignored"}; '
                f'commands on {command_topic}'
            )
            self._status(
                'OK', 'parameters', f'{self.params.model} parameters from {self.parameters_source}'
            )
        else:
            self.get_logger().info(
                f'waiting for calibrated parameters on {self.resolve_topic_name(PARAMETERS_TOPIC)}; '
                f'commands on {command_topic}'
            )
            self._status(
                'WARN', 'waiting', 'waiting for calibrated parameters on hexacal/parameters'
            )

    # ------------------------------------------------------------------ parameters

    def _load_file(self, path: str) -> tuple[KinematicParameters, str]:
        try:
            contents = read_parameters_file(path)
            params = parameters_for(contents.model, contents.vector)
            mount = check_mount(contents.extras.get(MOUNT_PARAMETER, DEFAULT_MOUNT))
        except (HexacalContractError, DeviceMountError, ValueError) as error:
            raise KinematicsConfigurationError(f'parameters: {error}') from error
        return params, mount

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            name, value = parameter.name, parameter.value
            problem = None
            if name == 'stroke_limits' and value is not None:
                limits = list(value)
                if (
                    len(limits) != 2
                    or not all(math.isfinite(v) for v in limits)
                    or limits[0] >= limits[1]
                ):
                    problem = (
                        f'stroke_limits must be [low, high] (m) with low < high, got {limits}'
                    )
            elif name == 'mount' and value not in ('', *MOUNTS):
                problem = f"mount must be '' or one of {', '.join(MOUNTS)}, got {value!r}"
            elif name in ('base_frame', 'command_topic') and not value:
                problem = f'{name} must not be empty'
            elif name == 'parameters' and value:
                try:
                    self._load_file(value)
                except KinematicsConfigurationError as error:
                    problem = str(error)
            elif isinstance(value, float) and not math.isfinite(value):
                problem = f'{name} must be finite, got {value}'
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def stroke(self) -> tuple[float, float]:
        """The stroke limits commands must respect (m)."""
        try:
            limits = self.get_parameter('stroke_limits').value
        except ParameterUninitializedException:
            limits = None
        if limits is None:
            return default_stroke(self.params)
        return float(limits[0]), float(limits[1])

    def _on_parameters(self, message: Float64MultiArray) -> None:
        try:
            model = multiarray_model(message).name
            params = parameters_for(model, multiarray_to_parameters(message))
        except (HexacalContractError, ValueError) as error:
            self.get_logger().error(f'ignoring a message on {PARAMETERS_TOPIC}: {error}')
            self._status('ERROR', 'invalid-parameters', f'invalid parameters message: {error}')
            return
        previous = self.params
        if previous is not None and model != previous.model:
            text = (
                f'a {model} calibration on {PARAMETERS_TOPIC} does not fit this {previous.model} machine '
                f'({self.parameters_source}); keeping its parameters'
            )
            self.get_logger().error(text)
            self._status('ERROR', 'model-mismatch', text)
            return
        if previous is not None and np.array_equal(params.vector, previous.vector):
            return  # the same calibration again (e.g. republished at identify's start)
        self.params = params
        self.parameters_source = self.resolve_topic_name(PARAMETERS_TOPIC)
        self.parameters_updates += 1
        self._drawn = None
        if previous is None:
            text = f'calibrated {model} parameters received on {self.parameters_source}'
        else:
            change = np.abs(params.vector - previous.vector).max()
            text = (
                f'new calibration on {self.parameters_source}: {model} parameters updated '
                f'(largest change {change * 1e3:.4f} mm)'
            )
        self.get_logger().info(text)
        self._status(
            'OK',
            'parameters',
            text,
            largest_change_m=(
                float(np.abs(params.vector - previous.vector).max())
                if previous is not None
                else ''
            ),
        )

    # ------------------------------------------------------------------ pose

    def _on_readings(self, message: JointState) -> None:
        if self.params is None:
            return
        stamp = stamp_ns(message.header.stamp)
        if (
            self._last_solved_ns is not None
            and 0 <= stamp - self._last_solved_ns < self.min_period_ns
        ):
            return
        try:
            readings = np.array(
                joint_state_to_slider_reading(message, self.params.model).slider_positions
            )
        except InvalidReadingError as error:
            self.invalid_readings += 1
            self._throttled(
                'invalid',
                f'invalid actuator reading on {SLIDERS_TOPIC} ({self.params.model} '
                f'joints {", ".join(self.params.layout.actuator_names)}): {error}',
                'invalid-reading',
                count=self.invalid_readings,
            )
            return
        self._last_solved_ns = stamp
        pose = None
        problems = []
        for guess in (self.pose, self.home) if self.pose is not None else (self.home,):
            try:
                pose = solve_pose(self.params, readings, guess)
                break
            except ForwardKinematicsError as error:
                problems.append(str(error))
        if pose is None:
            self.pose_failures += 1
            self.pose = None
            self._tracking = False
            self._throttled(
                'pose',
                f'no platform pose for the readings {readings.tolist()}: {problems[-1]}',
                'pose-failed',
                count=self.pose_failures,
            )
            return
        self.pose, self.readings, self.pose_stamp = pose, readings, message.header.stamp
        out = PoseStamped(
            header=Header(
                stamp=message.header.stamp, frame_id=self.get_parameter('base_frame').value
            )
        )
        self._pose_pub.publish(fill_pose_message(out, pose))
        self.poses_published += 1
        if not self._tracking:
            self._tracking = True
            text = (
                f'tracking the platform: pose [{pose[0] * 1e3:.3f}, {pose[1] * 1e3:.3f}, '
                f'{pose[2] * 1e3:.3f}] mm, [{math.degrees(pose[3]):.3f}, {math.degrees(pose[4]):.3f}, '
                f'{math.degrees(pose[5]):.3f}] deg on {self._pose_pub.topic_name}'
            )
            self.get_logger().info(text)
            self._status('OK', 'tracking', text)

    def _publish_markers(self) -> None:
        if self.pose is None or self.params is None:
            return
        key = (
            self.pose_stamp.sec,
            self.pose_stamp.nanosec,
            id(self.params),
            self.get_parameter('base_frame').value,
        )
        if key == self._drawn:
            return
        self._drawn = key
        drawing = self.params.architecture.drawing(self.params, self.pose, self.readings)
        self._markers_pub.publish(machine_markers(drawing, key[3], self.pose_stamp))

    # ------------------------------------------------------------------ commands

    def _on_target(self, message: PoseStamped) -> None:
        base_frame = self.get_parameter('base_frame').value
        frame = message.header.frame_id
        if frame not in ('', base_frame):
            return self._refuse(
                'wrong-frame',
                f'target pose in frame {frame!r}; commands are poses in '
                f'{base_frame!r} (base_frame)',
            )
        if self.params is None:
            return self._refuse('no-parameters', 'no calibrated parameters yet')
        try:
            pose = np.array(pose_from_message(message))
        except InvalidReadingError as error:
            return self._refuse('invalid-target', f'target is not a pose: {error}')
        low, high = self.stroke()
        try:
            targets = actuator_targets(self.params, pose, (low, high))
        except OutOfStrokeError as error:
            return self._refuse(error.reason, f'target {self._pose_text(pose)} {error}', pose)
        except UnreachablePoseError:
            return self._refuse(
                'unreachable-pose',
                f'target {self._pose_text(pose)} is unreachable: '
                f'{self.params.architecture.unreachable_reason}',
                pose,
            )
        if self.readings is None:
            return self._refuse(
                'no-actuator-readings',
                f'no actuator reading on {SLIDERS_TOPIC} yet: the '
                'move time needs the current position',
                pose,
            )
        speed = self.get_parameter('max_actuator_speed').value
        travel = float(np.abs(targets - self.readings).max())
        move_s = max(MIN_MOVE_TIME_S, travel / speed)
        names = list(self.params.layout.actuator_names)
        command = JointTrajectory(
            joint_names=names,
            points=[
                JointTrajectoryPoint(positions=targets.tolist(), time_from_start=_duration(move_s))
            ],
        )
        self._command_pub.publish(command)
        self.commands_sent += 1
        text = (
            f'command {self.commands_sent}: target {self._pose_text(pose)} -> '
            f'{", ".join(f"{n} {t:.6f}" for n, t in zip(names, targets))} m in {move_s:.2f} s'
        )
        self.get_logger().info(text)
        self._status(
            'OK',
            'sent',
            text,
            commands_sent=self.commands_sent,
            move_time_s=move_s,
            **self._pose_values('target', pose),
            **{f'target.{n}': float(t) for n, t in zip(names, targets)},
        )

    def _refuse(self, reason: str, text: str, pose: np.ndarray | None = None) -> None:
        self.commands_refused += 1
        text = f'refused: {reason}: {text}; nothing sent'
        self.get_logger().warning(text)
        self._status(
            'WARN',
            'refused',
            text,
            reason=reason,
            commands_refused=self.commands_refused,
            **(self._pose_values('target', pose) if pose is not None else {}),
        )

    @staticmethod
    def _pose_text(pose: np.ndarray) -> str:
        return (
            f'[{pose[0]:.6f}, {pose[1]:.6f}, {pose[2]:.6f}] m, '
            f'[{pose[3]:.6f}, {pose[4]:.6f}, {pose[5]:.6f}] rad'
        )

    @staticmethod
    def _pose_values(prefix: str, pose: np.ndarray) -> dict[str, float]:
        return {
            f'{prefix}.{k}': float(v) for k, v in zip(('x', 'y', 'z', 'theta', 'psi', 'phi'), pose)
        }

    # ------------------------------------------------------------------ status

    def _throttled(self, key: str, text: str, outcome: str, **values: object) -> None:
        now = self.get_clock().now().nanoseconds / NS_PER_S
        if now - self._last_log.get(key, -math.inf) < LOG_PERIOD_S:
            return
        self._last_log[key] = now
        self.get_logger().warning(text)
        self._status('WARN', outcome, text, **values)

    def _status(self, level: str, outcome: str, message: str, **values: object) -> None:
        fields = {
            'outcome': outcome,
            'model': self.params.model if self.params is not None else '',
            'parameters_source': self.parameters_source,
            'parameters_updates': self.parameters_updates,
            'poses_published': self.poses_published,
            'commands_sent': self.commands_sent,
            'commands_refused': self.commands_refused,
            **values,
        }
        self._status_pub.publish(
            diagnostic_status(
                level,
                KINEMATICS_STATUS_NAME,
                message,
                fields,
                stamp=self.get_clock().now().nanoseconds,
            )
        )

    def summary(self) -> str:
        return (
            f'{self.poses_published} platform poses published ({self.pose_failures} readings without a '
            f'pose, {self.invalid_readings} invalid), {self.commands_sent} commands sent, '
            f'{self.commands_refused} refused, {self.parameters_updates} calibrations taken'
        )


def _finish(node: KinematicsNode) -> list[str]:
    return [node.summary()]


def main(args: list[str] | None = None) -> int:
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
