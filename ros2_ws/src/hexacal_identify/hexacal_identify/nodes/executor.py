"""Node `executor`: walk a plan from `hexacal plan` on the machine through its trajectory controller.

    ros2 run hexacal_identify executor --ros-args -p plan:=plan.yaml -p nominal:=nominal.yaml \\
        -p command_topic:=/joint_trajectory_controller/joint_trajectory

For each planned posture: inverse kinematics with the nominal parameters gives
the actuator targets, published as a ``trajectory_msgs/JointTrajectory`` (the
actuator joints, ``time_from_start`` from the largest move at
``max_actuator_speed_m_s``) on ``command_topic`` (COMMAND_QOS: the topic
interface of ros2_control's joint_trajectory_controller). The trajectory's last
point is the target; with ``path_step_m`` > 0 (default 0.02 m) the points
before it keep the platform on the measuring link's sphere on the way (a
one-point command, ``path_step_m: 0``, is interpolated in joint space by the
controller and strains the machine against the link by centimetres between far
postures; core/execution.py). Then it waits until
the measured actuators (``hexacal/sliders``, SENSOR_QOS) are at the target and
still, and for the collector's posture on ``hexacal/posture``, and moves on.
Fixed-position postures are reached in closed loop on the inclinometer
(``hexacal/inclinometer``). What decides is ROS-free: ``core/execution.py``
(its docstring has the rules); this node hears, publishes and keeps time.

* The whole plan is checked before anything moves: a target outside the
  stroke (``stroke_limits_m``; default the stroke the plan was made within,
  ``hexacal plan``'s limits, else the model's), out of the nominal
  machine's reach or off its posture kind refuses the plan - nothing is ever
  published on the command topic; the ERROR status (state ``refused``) and the
  log list the postures. With ``shutdown_when_done`` the refusal is a start-up
  error instead (exit code 2).
* The plan starts once the machine is there: actuator readings arrive, a
  controller subscribes to the command topic and (with ``wait_for_posture``)
  a collector publishes postures.
* Services (std_srvs/Trigger) ``hexacal/executor/pause`` (hold where the
  machine is; the posture restarts on resume), ``resume`` and ``abort`` (hold
  and end the plan).
* Progress on ``hexacal/calibration_status`` (status name 'hexacal executor',
  latched): state (waiting, running, paused, aborted, done, refused), posture k
  of K, measured, skipped (which and why), ETA, elapsed; at every change and
  once a second.
* ``calibrate_when_done``: calls ``hexacal/calibrate`` when the plan is done
  and reports the answer (status fields ``calibration``,
  ``calibration_message``).

* Turning procedure (a plan whose postures carry ``device_turn``, rad: the
  device turned about its link axis; ``hexacal plan`` orders them one remount
  per turn): the plan starts with the device in the mounting ``mounted_turn``
  (default 0, normal; after a turned plan, the mounting it ended in), and
  with ``device_turn_nodes`` the executor first sets their ``device_turn`` to
  it (the first move waits for their answers), so they never carry the turn an
  earlier plan left them at.
  Before a posture in another mounting the executor pauses itself (state
  ``paused``, holding), logs a warning and publishes the notice (status field
  ``notice``, ``device_turn_needed_rad``): "posture 3 of 4 needs the device
  turned to 180 deg (3.14159 rad) about its link axis (...): turn the device to
  180 deg about its link axis, then call hexacal/executor/resume". Every status
  carries the current posture's ``device_turn_rad``. On that resume the
  executor sets the ``device_turn`` parameter (rcl_interfaces SetParameters,
  rclpy's AsyncParameterClient) of each node named in ``device_turn_nodes``
  (e.g. ``['collector', 'driver']``, resolved in the executor's namespace: the
  collector stamps its postures with it, the simulated driver turns its
  device) and begins the posture once they have all answered (or failed, or
  ``TURN_SET_TIMEOUT_S`` passed), so the postures recorded from then on carry
  the new turn. The requests never block the node; a node that refuses or does
  not answer is logged as an error and shown in the status
  (``device_turn_set``: pending, done or failed; ``device_turn_set_message``;
  level WARN) and the plan goes on. A pause while the requests are pending
  cancels the resume (the next resume sends them again).

The machine model is the nominal file's (``model:``; the plan must be for the
same model, and for the device mount of the nominal file's ``device.mount``
when it names one). ``actuator_joints`` are the names the controller and the
sliders input use (default: the model's ``slider_1..6`` / ``leg_1..6``), in
chain order; ``inclinometer_joints`` those of the inclinometer input.
"""

from __future__ import annotations

import math
import re
import sys
import time

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from hexacal_msgs_py.conversions import diagnostic_status
from hexacal_msgs_py.errors import HexacalContractError
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY as MOUNT_PARAMETER
from hexacal_msgs_py.models import MAX_DEVICE_TURN
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_TOPIC,
    DEFAULT_COMMAND_TOPIC,
    EXECUTOR_ABORT_SERVICE,
    EXECUTOR_PAUSE_SERVICE,
    EXECUTOR_RESUME_SERVICE,
    EXECUTOR_STATUS_NAME,
    INCLINOMETER_NAMES,
    INCLINOMETER_TOPIC,
    POSTURE_TOPIC,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.parameters_file import read_parameters_file
from hexacal_msgs_py.qos import COMMAND_QOS, POSTURE_QOS, SENSOR_QOS, STATUS_QOS
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidTopicNameException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from ..core.architectures import KinematicParameters, parameters_for
from ..core.device import check_mount, DEFAULT_MOUNT, DeviceMountError
from ..core.execution import (
    ABORTED,
    check_stroke,
    Command,
    DONE,
    ExecutionSettings,
    joint_positions,
    path_problems,
    PAUSED,
    plan_stroke,
    plan_targets,
    PlanExecution,
    PlanRefusedError,
    refusal_message,
    REFUSED,
    RUNNING,
    same_turn,
    WAITING,
)
from .parameters import parameter_descriptor
from .parameters import ParameterSpec as _Spec
from .runtime import run_node

NODE_NAME = 'executor'
CONTROL_PERIOD_S = 0.05  # the state machine steps this often
STATUS_PERIOD_S = 1.0  # progress (ETA) is republished at least this often
SERVICE_WAIT_S = 30.0  # calibrate_when_done: how long hexacal/calibrate may take to appear
INVALID_LOG_PERIOD_S = 5.0
TURN_SET_TIMEOUT_S = (
    10.0  # device_turn_nodes: how long their set_parameters may take (discovery too)
)
TURN_PARAMETER = 'device_turn'  # the parameter (rad) of the collector and the driver
_NODE_NAME_PATTERN = re.compile(r'^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$')
SHUTDOWN_LINGER_S = 0.3  # the last status (and hold command) reach their subscribers


SETTINGS = ExecutionSettings()
PARAMETERS: dict[str, _Spec] = {
    'plan': _Spec('', 'plan YAML written by `hexacal plan` (required)'),
    'nominal': _Spec(
        '',
        "nominal parameters YAML of the machine (required); its 'model' (none: "
        "hexa_slide) is the machine model and its 'device.mount' the device mount",
    ),
    'command_topic': _Spec(
        DEFAULT_COMMAND_TOPIC,
        'trajectory_msgs/JointTrajectory commands go '
        "here: the topic of ros2_control's joint_trajectory_controller",
    ),
    'max_actuator_speed_m_s': _Spec(
        SETTINGS.max_actuator_speed_m_s,
        'time_from_start of a move is its largest actuator move at this speed (m/s)',
        1e-6,
        10.0,
    ),
    'position_tolerance_m': _Spec(
        SETTINGS.position_tolerance_m,
        'the machine is at the target '
        'when every measured actuator is within this of it (m); it '
        'allows for the strain of the measuring link with a nominal '
        'model millimetres off',
        1e-7,
        0.1,
    ),
    'still_tolerance_m': _Spec(
        SETTINGS.still_tolerance_m,
        'the machine is still when no measured '
        'actuator moves more than this (peak to peak, m) over settle_s: '
        'above the reading noise',
        1e-7,
        0.01,
    ),
    'settle_s': _Spec(
        SETTINGS.settle_s, 'how long the machine must stand still at a target (s)', 0.01, 60.0
    ),
    'timeout_s': _Spec(
        SETTINGS.timeout_s,
        'a posture not reached, still and measured within this '
        'of its first command is skipped and reported (s)',
        0.1,
        3600.0,
    ),
    'fixed_tolerance_rad': _Spec(
        SETTINGS.fixed_tolerance_rad,
        'a fixed-position posture is '
        'reached when both inclinometer angles are within this (rad); '
        'keep it below the 5e-5 rad at which identify counts a posture '
        'as fixed',
        1e-7,
        0.01,
    ),
    'max_corrections': _Spec(
        SETTINGS.max_corrections,
        'closed-loop corrections of a fixed-position posture before it is skipped',
        0,
        100,
    ),
    'path_step_m': _Spec(
        SETTINGS.path_step_m,
        'a move goes along the link sphere through '
        'points at most this far apart (m; also this / L rad in each angle), so '
        'the platform stays where the measuring link lets it; 0: one-point '
        'commands (joint-space moves)',
        0.0,
        1.0,
    ),
    'inclinometer_joints': _Spec(
        list(INCLINOMETER_NAMES),
        'the inclinometer joints alpha (about X), beta (about Y) of the inclinometer input (rad)',
        constraints='two distinct names',
    ),
    'wait_for_posture': _Spec(
        True,
        "wait for the collector's posture at each stop (false: move on once the machine is still)",
    ),
    'calibrate_when_done': _Spec(
        False, 'call hexacal/calibrate when the plan is done and report the answer'
    ),
    'start_paused': _Spec(False, 'wait for hexacal/executor/resume before the first move'),
    'device_turn_nodes': _Spec(
        [],
        "nodes whose 'device_turn' parameter (rad) the executor sets "
        'when the operator resumes after turning the device for a plan '
        "posture (e.g. ['collector', 'driver']; names resolved in the "
        "executor's namespace); empty: none",
        constraints='distinct node names',
    ),
    'mounted_turn': _Spec(
        0.0,
        "the device's mounting at the start, rad about its link axis (0: "
        'normal; e.g. the last mounting of the plan walked before): a first '
        'posture in another mounting waits for the turn; with device_turn_nodes '
        'their device_turn is set to it before the first move',
        -MAX_DEVICE_TURN,
        MAX_DEVICE_TURN,
    ),
    'shutdown_when_done': _Spec(
        False,
        'stop the node once the plan is done or aborted (and the '
        'calibration answered); a refused plan is then a start-up error '
        '(exit code 2)',
    ),
}
# Declared once the nominal file is read: their defaults are the model's.
MODEL_PARAMETERS: dict[str, _Spec] = {
    'stroke_limits_m': _Spec(
        [0.0, 1.0],
        '[low, high] actuator stroke (m) every target must lie '
        "in; default: the plan's (hexacal plan's --stroke-m, recorded "
        "in the plan file), else the model's (its default workspace)",
        constraints='two finite numbers, low < high',
    ),
    'actuator_joints': _Spec(
        ['slider_1'],
        'the six actuator joints in chain order, as the '
        'controller and the sliders input name them; default: the '
        "model's (slider_1..6 or leg_1..6)",
        constraints='six distinct names',
    ),
}


class ExecutorConfigurationError(Exception):
    """The node's parameters do not describe a plan it can walk on this machine."""


def _names(name: str, value: object, count: int) -> tuple[str, ...]:
    if (
        not isinstance(value, (list, tuple))
        or len(value) != count
        or not all(isinstance(item, str) and item for item in value)
        or len(set(value)) != count
    ):
        raise ExecutorConfigurationError(
            f'{name} must be {count} distinct joint names, got {value!r}'
        )
    return tuple(value)


def _node_names(value: object) -> tuple[str, ...]:
    """device_turn_nodes: distinct node names (relative or absolute)."""
    if (
        not isinstance(value, (list, tuple))
        or not all(isinstance(item, str) and _NODE_NAME_PATTERN.match(item) for item in value)
        or len(set(value)) != len(value)
    ):
        raise ExecutorConfigurationError(
            f'device_turn_nodes must be distinct node names (e.g. [collector, driver]), got '
            f'{list(value) if isinstance(value, (list, tuple)) else value!r}'
        )
    return tuple(value)


def _parameter_problem(parameter: Parameter) -> str | None:
    """Checks beyond type and range (which the descriptors enforce)."""
    value = parameter.value
    name = parameter.name
    if name in ('plan', 'nominal') and not value:
        return f"parameter '{name}' is required (-p {name}:=<path>)"
    if name == 'command_topic' and not value:
        return 'command_topic must name a topic'
    if isinstance(value, float) and not math.isfinite(value):
        return f'{name} must be finite, got {value}'
    if name == 'stroke_limits_m':
        try:
            check_stroke(list(value))
        except ValueError as error:
            return f'stroke_limits_m: {error}'
    if name == 'actuator_joints':
        try:
            _names(name, list(value), 6)
        except ExecutorConfigurationError as error:
            return str(error)
    if name == 'inclinometer_joints':
        try:
            _names(name, list(value), 2)
        except ExecutorConfigurationError as error:
            return str(error)
    if name == 'device_turn_nodes':
        try:
            _node_names(list(value))
        except (ExecutorConfigurationError, TypeError) as error:
            return str(error)
    return None


def _duration(seconds: float) -> Duration:
    nanoseconds = int(round(max(seconds, 0.0) * 1e9))
    return Duration(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def _now_s(node: Node) -> float:
    return node.get_clock().now().nanoseconds * 1e-9


class ExecutorNode(Node):
    """Plan walker: commands on command_topic, readings in, services, progress out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        for name, spec in PARAMETERS.items():
            self.declare_parameter(name, spec.default, parameter_descriptor(name, spec))
        value = {name: self.get_parameter(name).value for name in PARAMETERS}

        self.nominal, nominal_mount = self._load_nominal(value['nominal'])
        self.model = self.nominal.model
        self.plan = self._load_plan(value['plan'], nominal_mount)
        # As the driver's: a collector with driver_node:=executor records the plan in its bag.
        self.declare_parameter(
            'plan_name',
            self.plan.name,
            ParameterDescriptor(
                description='name of the plan being walked (set by the node)', read_only=True
            ),
            ignore_override=True,
        )
        stroke, self.stroke_source = plan_stroke(self.plan.metadata, self.nominal)
        defaults = {
            'stroke_limits_m': list(stroke),
            'actuator_joints': list(self.nominal.layout.actuator_names),
        }
        for name, spec in MODEL_PARAMETERS.items():
            value[name] = self.declare_parameter(
                name, defaults[name], parameter_descriptor(name, spec)
            ).value
        self.actuator_joints = _names('actuator_joints', list(value['actuator_joints']), 6)
        self.posture_joints = (
            self.nominal.layout.actuator_names
        )  # the collector's (contract) names
        self.inclinometer_joints = _names(
            'inclinometer_joints', list(value['inclinometer_joints']), 2
        )
        if list(value['stroke_limits_m']) != list(stroke):
            self.stroke_source = 'stroke_limits_m'
        try:
            self.stroke = check_stroke(list(value['stroke_limits_m']))
        except ValueError as error:
            raise ExecutorConfigurationError(f'stroke_limits_m: {error}') from error
        try:
            self.settings = ExecutionSettings(
                max_actuator_speed_m_s=value['max_actuator_speed_m_s'],
                position_tolerance_m=value['position_tolerance_m'],
                still_tolerance_m=value['still_tolerance_m'],
                settle_s=value['settle_s'],
                timeout_s=value['timeout_s'],
                fixed_tolerance_rad=value['fixed_tolerance_rad'],
                max_corrections=value['max_corrections'],
                wait_for_posture=value['wait_for_posture'],
                path_step_m=value['path_step_m'],
            )
        except ValueError as error:
            raise ExecutorConfigurationError(str(error)) from error
        self.device_turn_nodes = _node_names(list(value['device_turn_nodes']))
        self.calibrate_when_done = bool(value['calibrate_when_done'])
        self.shutdown_when_done = bool(value['shutdown_when_done'])

        targets, problems = plan_targets(
            self.nominal,
            self.plan.poses,
            self.plan.kinds,
            self.stroke,
            self.plan.link_length,
            self.plan.mount,
        )
        problems.update(
            path_problems(
                self.nominal,
                self.plan.poses,
                self.stroke,
                self.plan.link_length,
                self.settings.path_step_m,
                set(problems),
                self.plan.mount,
            )
        )
        refusal = refusal_message(problems, len(targets)) if problems else ''
        if problems and self.shutdown_when_done:
            raise PlanRefusedError(refusal, problems)
        self.execution = PlanExecution(
            self.nominal,
            self.plan.poses,
            self.plan.kinds,
            targets,
            self.settings,
            self.stroke,
            self.plan.link_length,
            self.plan.mount,
            start_paused=bool(value['start_paused']),
            device_turns=self.plan.turns,
            mounted_turn=float(value['mounted_turn']),
        )
        if problems:
            self.execution.state = REFUSED
            self.execution.refusal = refusal
        self.refused_postures = sorted(problems)

        try:
            self._command_pub = self.create_publisher(
                JointTrajectory, value['command_topic'], COMMAND_QOS
            )
        except InvalidTopicNameException as error:
            raise ExecutorConfigurationError(f'command_topic: {error}') from error
        self._status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self.create_subscription(JointState, SLIDERS_TOPIC, self._on_sliders, SENSOR_QOS)
        self.create_subscription(JointState, INCLINOMETER_TOPIC, self._on_inclinometer, SENSOR_QOS)
        self.create_subscription(JointState, POSTURE_TOPIC, self._on_posture, POSTURE_QOS)
        self.create_service(Trigger, EXECUTOR_PAUSE_SERVICE, self._on_pause)
        self.create_service(Trigger, EXECUTOR_RESUME_SERVICE, self._on_resume)
        self.create_service(Trigger, EXECUTOR_ABORT_SERVICE, self._on_abort)
        self._calibrate_client = self.create_client(Trigger, CALIBRATE_SERVICE)
        # Created now, so their services are discovered long before the first turn.
        self._turn_clients = {
            name: AsyncParameterClient(self, name) for name in self.device_turn_nodes
        }
        self._turn_setting: dict | None = (
            None  # the requests of a resume after a turn (or of the start)
        )
        # The nodes start from the mounting the device is in, not from what an earlier plan left them at.
        self._start_turn_set = not self._turn_clients
        self._turn_set_state = ''  # '', pending, done, failed
        self._turn_set_message = ''

        self.commands_sent = 0
        self.invalid_readings = 0
        self._last_status = 0.0
        self._last_published: tuple | None = None
        self._waiting_for: tuple[str, ...] = ()
        self._calibration = 'disabled' if not self.calibrate_when_done else 'pending'
        self._calibration_message = ''
        self._calibration_requested_at: float | None = None
        self._calibration_future = None
        self._stopping = False

        counts = self.plan_counts()
        self.get_logger().info(
            f"plan '{self.plan.name}': {len(self.plan.poses)} postures ({counts['sphere']} sphere, "
            f'{counts["fixed"]} fixed) for a {self.model}; commands on '
            f'{self._command_pub.topic_name} (joints {", ".join(self.actuator_joints)}), at most '
            f'{self.settings.max_actuator_speed_m_s:g} m/s, stroke [{self.stroke[0]:g}, '
            f'{self.stroke[1]:g}] m ({self.stroke_source})'
        )
        turns = sorted({float(turn) for turn in self.plan.turns})
        if any(turns):
            self.get_logger().info(
                f'turning procedure: device turns {[round(math.degrees(t), 3) for t in turns]} deg; '
                + (
                    f'device_turn set on {", ".join(self.device_turn_nodes)} at each remount'
                    if self.device_turn_nodes
                    else 'device_turn_nodes is empty: no node is told the turn'
                )
            )
        if problems:
            self.get_logger().error(refusal)
        self._publish_status(force=True)
        self._timer = self.create_timer(CONTROL_PERIOD_S, self._tick)

    # ------------------------------------------------------------------ configuration

    def _load_nominal(self, path: str) -> tuple[KinematicParameters, str | None]:
        """The nominal machine and the device mount its file names (None: it names none)."""
        try:
            loaded = read_parameters_file(path)
            mount = loaded.extras.get(MOUNT_PARAMETER)
            if mount is not None:
                check_mount(mount)
            return parameters_for(loaded.model, loaded.vector), mount
        except (HexacalContractError, DeviceMountError, ValueError) as error:
            raise ExecutorConfigurationError(f'nominal: {error}') from error

    def _load_plan(self, path: str, nominal_mount: str | None):
        from ..core.planning import Plan

        try:
            plan = Plan.load(path)
        except (OSError, ValueError) as error:
            raise ExecutorConfigurationError(f'plan: {error}') from error
        if plan.model != self.model:
            raise ExecutorConfigurationError(
                f'plan {path} was made for a {plan.model} (plan.model; absent: hexa_slide) but the '
                f'nominal machine is a {self.model}'
            )
        if nominal_mount is not None and plan.mount != nominal_mount:
            raise ExecutorConfigurationError(
                f'plan {path} is for a {plan.mount} device (plan.mount; absent: {DEFAULT_MOUNT}) but '
                f'the nominal file says {MOUNT_PARAMETER}: {nominal_mount}'
            )
        return plan

    def plan_counts(self) -> dict[str, int]:
        kinds = [str(kind) for kind in self.plan.kinds]
        return {'sphere': kinds.count('sphere'), 'fixed': kinds.count('fixed')}

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            problem = _parameter_problem(parameter)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ inputs

    def _invalid(self, what: str) -> None:
        self.invalid_readings += 1
        self.get_logger().warning(
            f'ignored an invalid {what} message ({self.invalid_readings} so far)',
            throttle_duration_sec=INVALID_LOG_PERIOD_S,
        )

    def _on_sliders(self, message: JointState) -> None:
        positions = joint_positions(message.name, message.position, self.actuator_joints)
        if positions is None:
            self._invalid(
                f'sliders (joints {list(message.name)}, expected {list(self.actuator_joints)})'
            )
            return
        self.execution.on_actuators(_now_s(self), positions)

    def _on_inclinometer(self, message: JointState) -> None:
        angles = joint_positions(message.name, message.position, self.inclinometer_joints)
        if angles is None:
            self._invalid(f'inclinometer (joints {list(message.name)})')
            return
        self.execution.on_inclinometer(_now_s(self), float(angles[0]), float(angles[1]))

    def _on_posture(self, message: JointState) -> None:
        positions = joint_positions(message.name, message.position, self.posture_joints)
        if positions is not None:
            self.execution.on_posture(_now_s(self), positions)

    # ------------------------------------------------------------------ services

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if self._turn_setting is not None:  # the resume after a turn is cancelled
            self._turn_setting = None
            self._turn_set_state, self._turn_set_message = '', ''
            self.get_logger().info('pause: the resume after the device turn is cancelled')
        return self._service(response, self.execution.pause)

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if self._turn_clients and self.execution.waiting_for_turn:
            return self._resume_after_turn(response)
        return self._service(response, self.execution.resume)

    def _on_abort(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        return self._service(response, self.execution.abort)

    def _service(self, response: Trigger.Response, action) -> Trigger.Response:
        if self.execution.state == REFUSED:
            response.success, response.message = False, self.execution.refusal
            return response
        success, message, commands = action(_now_s(self))
        self._send(commands)
        self._drain_messages()
        self._publish_status(force=True)
        response.success, response.message = success, message
        return response

    # ------------------------------------------------------------------ turning the device

    def _resume_after_turn(self, response: Trigger.Response) -> Trigger.Response:
        """Ask device_turn_nodes to set device_turn; the posture begins once they have answered
        (`_turn_setting_step`)."""
        execution = self.execution
        turn = float(execution.turn_needed)
        names = ', '.join(self.device_turn_nodes)
        if self._turn_setting is None:
            self._begin_turn_setting(turn, 'resume after the device turn')
            message = (
                f'setting {TURN_PARAMETER} {turn:.6g} rad on {names}; posture '
                f'{execution.index + 1} of {execution.total} begins once they answer'
            )
        else:
            message = f'already resuming: waiting for {names} to set {TURN_PARAMETER}'
        self._publish_status(force=True)
        response.success, response.message = True, message
        return response

    def _begin_turn_setting(self, turn: float, why: str, start: bool = False) -> None:
        self._turn_setting = {
            'turn': turn,
            'started': _now_s(self),
            'futures': {},
            'problems': {},
            'done': [],
            'start': start,
        }
        self._turn_set_state, self._turn_set_message = 'pending', ''
        self.get_logger().info(
            f'{why}: setting {TURN_PARAMETER} {turn:.6g} rad on '
            f'{", ".join(self.device_turn_nodes)}'
        )
        self._turn_setting_step()

    def _turn_setting_step(self) -> None:
        """Send the requests whose services are there, collect answers; resume when all settled."""
        setting = self._turn_setting
        if setting is None:
            return
        now = _now_s(self)
        late = now - setting['started'] > TURN_SET_TIMEOUT_S
        settled = set(setting['done']) | set(setting['problems'])
        for name, client in self._turn_clients.items():
            if name in settled:
                continue
            future = setting['futures'].get(name)
            if future is None:
                if client.services_are_ready():
                    setting['futures'][name] = client.set_parameters(
                        [Parameter(TURN_PARAMETER, Parameter.Type.DOUBLE, setting['turn'])]
                    )
                elif late:
                    setting['problems'][name] = (
                        f'its parameter services did not appear within {TURN_SET_TIMEOUT_S:g} s'
                    )
                continue
            if not future.done():
                if late:
                    future.cancel()
                    setting['problems'][name] = f'no answer within {TURN_SET_TIMEOUT_S:g} s'
                continue
            try:
                results = future.result().results
            except Exception as error:  # noqa: BLE001 - the status must say what happened
                setting['problems'][name] = f'{type(error).__name__}: {error}'
                continue
            if len(results) == 1 and results[0].successful:
                setting['done'].append(name)
            else:
                setting['problems'][name] = 'refused: ' + (
                    results[0].reason if results else 'no result'
                )
        if len(setting['done']) + len(setting['problems']) < len(self._turn_clients):
            return
        self._turn_setting = None
        turn = setting['turn']
        self._start_turn_set = self._start_turn_set or setting['start']
        if setting['problems']:
            self._turn_set_state = 'failed'
            self._turn_set_message = '; '.join(
                f'{name}: {why}' for name, why in setting['problems'].items()
            )
            self.get_logger().error(
                f'{TURN_PARAMETER} {turn:.6g} rad not set on every node '
                f'({self._turn_set_message}); the plan goes on'
            )
        else:
            self._turn_set_state = 'done'
            self._turn_set_message = (
                f'{TURN_PARAMETER} {turn:.6g} rad set on {", ".join(setting["done"])}'
            )
            self.get_logger().info(self._turn_set_message)
        if self.execution.waiting_for_turn and same_turn(self.execution.turn_needed, turn):
            self._service(Trigger.Response(), self.execution.resume)
        else:
            self._publish_status(force=True)

    # ------------------------------------------------------------------ the loop

    def _tick(self) -> None:
        now = _now_s(self)
        execution = self.execution
        if execution.state == WAITING:
            self._try_start(now)
        elif execution.state == RUNNING:
            self._send(execution.step(now))
        if self._turn_setting is not None:
            self._turn_setting_step()
        elif execution.state == DONE and self.calibrate_when_done:
            self._calibrate(now)
        self._drain_messages()
        self._publish_status()
        if self.shutdown_when_done and not self._stopping and self._finished():
            self._stopping = True
            self.get_logger().info('shutdown_when_done: stopping')
            self.context.try_shutdown()

    def _finished(self) -> bool:
        state = self.execution.state
        if state in (ABORTED, REFUSED):
            return True
        return state == DONE and self._calibration not in ('pending', 'running')

    def _try_start(self, now: float) -> None:
        waiting = []
        if self.execution.actuators.latest is None:
            waiting.append(f'actuator readings on {self.resolve_topic_name(SLIDERS_TOPIC)}')
        if self._command_pub.get_subscription_count() == 0:
            waiting.append(f'a controller on {self._command_pub.topic_name}')
        if self.settings.wait_for_posture and self.count_publishers(POSTURE_TOPIC) == 0:
            waiting.append(f'a collector on {self.resolve_topic_name(POSTURE_TOPIC)}')
        if not self._start_turn_set:
            if self._turn_setting is None:
                self._begin_turn_setting(
                    self.execution.mounted_turn, 'the mounting at the start', start=True
                )
            if not self._start_turn_set:
                waiting.append(
                    f'{", ".join(self.device_turn_nodes)} to set {TURN_PARAMETER} '
                    f'{self.execution.mounted_turn:.6g} rad (the mounting at the start)'
                )
        if tuple(waiting) != self._waiting_for:
            self._waiting_for = tuple(waiting)
            if waiting:
                self.get_logger().info('waiting for ' + ', '.join(waiting))
            self._publish_status(force=True)
        if waiting:
            return
        self.get_logger().info(f'starting: {len(self.plan.poses)} postures')
        self._send(self.execution.start(now))
        if self.execution.state == REFUSED:
            self._publish_status(force=True)

    def _send(self, commands: list[Command]) -> None:
        for command in commands:
            message = JointTrajectory()  # header.stamp zero: the controller starts it on receipt
            message.joint_names = list(self.actuator_joints)
            message.points = [
                JointTrajectoryPoint(
                    positions=[float(p) for p in point], time_from_start=_duration(seconds)
                )
                for point, seconds in zip(command.points, command.times)
            ]
            self._command_pub.publish(message)
            self.commands_sent += 1
            what = (
                f'posture {command.posture + 1} of {self.execution.total}'
                if command.posture >= 0
                else 'hold'
            )
            self.get_logger().debug(
                f'{command.purpose} ({what}): {len(command.points)} points to '
                f'[{", ".join(f"{p * 1e3:.3f}" for p in command.positions)}] mm in '
                f'{command.duration_s:.2f} s'
            )

    def _drain_messages(self) -> None:
        messages, self.execution.messages = self.execution.messages, []
        for level, text in messages:
            if level == 'error':
                self.get_logger().error(text)
            elif level == 'warn':
                self.get_logger().warning(text)
            else:
                self.get_logger().info(text)

    def _calibrate(self, now: float) -> None:
        if self._calibration == 'pending':
            if self._calibration_requested_at is None:
                self._calibration_requested_at = now
                self.get_logger().info(f'plan done: calling {self._calibrate_client.srv_name}')
            if not self._calibrate_client.service_is_ready():
                if now - self._calibration_requested_at > SERVICE_WAIT_S:
                    self._calibration = 'failed'
                    self._calibration_message = (
                        f'{self._calibrate_client.srv_name} did not appear '
                        f'within {SERVICE_WAIT_S:g} s'
                    )
                    self.get_logger().error(f'calibration not run: {self._calibration_message}')
                    self._publish_status(force=True)
                return
            self._calibration = 'running'
            self._calibration_future = self._calibrate_client.call_async(Trigger.Request())
            self._calibration_future.add_done_callback(self._on_calibrated)
            self._publish_status(force=True)

    def _on_calibrated(self, future) -> None:
        try:
            answer = future.result()
        except Exception as error:  # noqa: BLE001 - the status must say what happened
            self._calibration, self._calibration_message = (
                'failed',
                f'{type(error).__name__}: {error}',
            )
        else:
            self._calibration = 'success' if answer.success else 'failed'
            self._calibration_message = answer.message
        if self._calibration == 'success':
            self.get_logger().info(f'calibration: {self._calibration_message}')
        else:
            self.get_logger().error(f'calibration failed: {self._calibration_message}')
        self._publish_status(force=True)

    # ------------------------------------------------------------------ status

    def status_values(self, now: float) -> dict[str, object]:
        values: dict[str, object] = dict(self.execution.progress(now))
        values['plan'] = self.plan.name
        values['model'] = self.model
        values['commands_sent'] = self.commands_sent
        if self.execution.state == REFUSED:
            values['refused_postures'] = ', '.join(str(i + 1) for i in self.refused_postures)
            values['reason'] = self.execution.refusal
        if self.execution.state == WAITING and self._waiting_for:
            values['waiting_for'] = '; '.join(self._waiting_for)
        if self.calibrate_when_done:
            values['calibration'] = self._calibration
            if self._calibration_message:
                values['calibration_message'] = self._calibration_message
        if self.execution.waiting_for_turn:
            values['notice'] = self.execution.turn_notice
        if self._turn_set_state:
            values['device_turn_set'] = self._turn_set_state
            if self._turn_set_message:
                values['device_turn_set_message'] = self._turn_set_message
        if self.invalid_readings:
            values['invalid_readings'] = self.invalid_readings
        return values

    def _publish_status(self, force: bool = False) -> None:
        now = _now_s(self)
        values = self.status_values(now)
        key = tuple(
            (k, v) for k, v in values.items() if k not in ('eta_s', 'elapsed_s', 'paused_s')
        )
        if not force and key == self._last_published and now - self._last_status < STATUS_PERIOD_S:
            return
        self._last_published, self._last_status = key, now
        state = self.execution.state
        if state == REFUSED or self._calibration == 'failed':
            level = 'ERROR'
        elif state == ABORTED or values.get('skipped') or self._turn_set_state == 'failed':
            level = 'WARN'
        else:
            level = 'OK'
        self._status_pub.publish(
            diagnostic_status(
                level,
                EXECUTOR_STATUS_NAME,
                self._status_text(values),
                values,
                hardware_id=self.get_fully_qualified_name(),
                stamp=self.get_clock().now().nanoseconds,
            )
        )

    def _status_text(self, values: dict[str, object]) -> str:
        state = self.execution.state
        if state == REFUSED:
            return self.execution.refusal
        if state == WAITING:
            return (
                'waiting for ' + ', '.join(self._waiting_for) if self._waiting_for else 'starting'
            )
        text = (
            f'{state}: posture {values["posture"]} of {values["postures"]}, '
            f'{values["measured"]} measured, {values["skipped"]} skipped'
        )
        if 'eta_s' in values and state in (RUNNING, PAUSED):
            text += f', ETA {values["eta_s"]:.0f} s'
        if self.execution.waiting_for_turn:
            text += f'; {self.execution.turn_notice}'
            if self._turn_set_state == 'pending':
                text += f' (setting {TURN_PARAMETER} on {", ".join(self.device_turn_nodes)})'
        if self.calibrate_when_done and state == DONE:
            text += f'; calibration {self._calibration}'
            if self._calibration_message:
                text += f': {self._calibration_message}'
        return text

    def summary(self) -> str:
        return (
            f"plan '{self.plan.name}' {self.execution.state}: {self.execution.summary()}; "
            f'{self.commands_sent} commands sent'
        )


def _finish(node: ExecutorNode) -> list[str]:
    time.sleep(SHUTDOWN_LINGER_S)  # let the last status and command reach their subscribers
    return [node.summary()]


def main(args: list[str] | None = None) -> int:
    return run_node(
        NODE_NAME,
        ExecutorNode,
        args=args,
        finish=_finish,
        startup_errors=(
            ExecutorConfigurationError,
            PlanRefusedError,
            InvalidParameterValueException,
            InvalidParameterTypeException,
        ),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
