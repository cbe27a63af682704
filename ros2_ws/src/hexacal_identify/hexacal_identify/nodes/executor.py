"""
Node `executor`: walk a plan from `hexacal plan` on the machine through its trajectory controller.

    ros2 run hexacal_identify executor --ros-args -p plan:=plan.yaml -p nominal:=nominal.yaml

Commands (trajectory_msgs/JointTrajectory) on ``command_topic``; actuators,
inclinometer (a JointState or an Imu, read as the collector reads it: the InputMapping
parameters of nodes/input_parameters.py) and the collector's postures in;
pause/resume/abort services;
progress on ``hexacal/calibration_status``.  What decides is ROS-free:
core/planning/plan_check.py (the plan is checked before anything moves), core/walk/execution.py
(the walk), core/walk/turns.py (device turns), core/sessions/executor_session.py (set-up,
status, calibration call, parameter checks).  This node hears, publishes and keeps time.

Full reference: docs/nodes.md
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import sys
import time
from typing import Any

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from hexacal_msgs_py.conversions import (
    diagnostic_status,
    imu_to_inclinometer_reading,
    joint_state_to_inclinometer_reading,
    multiarray_to_parameters,
    NS_PER_S,
    status_values,
)
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.inputs import (
    DEFAULT_OFFSETS_RAD,
    DEFAULT_SIGNS,
    IMU_INCLINOMETER,
    InputMapping,
    InputMappingError,
)
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY as MOUNT_PARAMETER
from hexacal_msgs_py.node_parameters import parameter_descriptor
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_TOPIC,
    DRIVER_STATUS_NAME,
    EXECUTOR_ABORT_SERVICE,
    EXECUTOR_PAUSE_SERVICE,
    EXECUTOR_RESUME_SERVICE,
    EXECUTOR_STATUS_NAME,
    INCLINOMETER_TOPIC,
    LINK_LENGTH_JOINT,
    LINK_TOPIC,
    PARAMETERS_TOPIC,
    POSTURE_TOPIC,
    release_service,
    RELEASE_SERVICE_PREFIX,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.parameters_file import read_parameters_file
from hexacal_msgs_py.qos import (
    COMMAND_QOS,
    PARAMETERS_QOS,
    POSTURE_QOS,
    SENSOR_QOS,
    STATUS_MONITOR_QOS,
    STATUS_QOS,
)
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    InvalidTopicNameException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from .executor_parameters import MODEL_PARAMETERS, PARAMETERS
from .input_parameters import declare_mapping_parameters, INCLINOMETER_READING_PARAMETERS
from .runtime import run_node
from ..core.machine.device import DEFAULT_MOUNT, DeviceMountError
from ..core.machine.measurements import FIXED
from ..core.planning.measuring_plan import walking_notice
from ..core.planning.plan_check import PlanRefusedError
from ..core.sessions.executor_session import CalibrationCall, ExecutorStatus, model_defaults
from ..core.sessions.executor_session import (
    parameter_problem,
    plan_mismatch,
    refined_guard,
    setup_walk,
)
from ..core.walk.messages import joint_positions, LogLevel, Messages
from ..core.walk.platform_paths import Command
from ..core.walk.refined_targets import RefineCall, RefineState
from ..core.walk.settings import ExecutionState
from ..core.walk.turns import DeviceTurnSetter, same_turn, TURN_PARAMETER

NODE_NAME = 'executor'
CONTROL_PERIOD_S = 0.05  # the state machine steps this often
INVALID_LOG_PERIOD_S = 5.0
SHUTDOWN_LINGER_S = 0.3
# A plan made for passive_actuator (not the parameter) on a drive without release services
# walks as before the modes had names (compliant, with a warning) once this has passed.
RELEASE_DISCOVERY_S = 3.0  # the last status (and hold command) reach their subscribers


class ExecutorConfigurationError(Exception):
    """The node's parameters do not describe a plan it can walk on this machine."""


@dataclass
class _ReleaseCalls:
    """The SetBool calls carrying out one release request, one at a time (lock, release)."""

    steps: list[tuple[int, bool]]  # (chain, release?) still to call
    released: int | None  # the chain released now, as the drive has answered so far
    since: float  # when the current step began waiting (s)
    future: Any = field(default=None)


class _TurnClient:
    """One node's device_turn through its parameter services (core.turns.TurnClient)."""

    def __init__(self, node: Node, name: str):
        # Created with the node, so the services are discovered long before the first turn.
        self._client = AsyncParameterClient(node, name)

    def ready(self) -> bool:
        return self._client.services_are_ready()

    def request(self, turn: float):
        # Never blocks: the executor's timer collects the answer (core.turns.TurnSetting.step).
        parameter = Parameter(TURN_PARAMETER, Parameter.Type.DOUBLE, turn)
        return self._client.set_parameters([parameter])


def _duration(seconds: float) -> Duration:
    nanoseconds = int(round(max(seconds, 0.0) * NS_PER_S))
    return Duration(sec=nanoseconds // NS_PER_S, nanosec=nanoseconds % NS_PER_S)


def _trigger_answer(future: Any) -> tuple[bool, str]:
    """Return a done hexacal/calibrate call's (success, message); a call that raised fails."""
    try:
        answer = future.result()
    except Exception as error:  # noqa: B902 - the status must say what happened
        return False, f'{type(error).__name__}: {error}'
    return answer.success, answer.message


def _now_s(node: Node) -> float:
    return node.get_clock().now().nanoseconds / NS_PER_S


class ExecutorNode(Node):
    """Plan walker: commands on command_topic, readings in, services, progress out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        for name, spec in PARAMETERS.items():
            self.declare_parameter(name, spec.default, parameter_descriptor(name, spec))
        value = {name: self.get_parameter(name).value for name in PARAMETERS}
        value.update(declare_mapping_parameters(self, INCLINOMETER_READING_PARAMETERS))
        self.nominal, nominal_mount = self._load_nominal(value['nominal'])
        self.model = self.nominal.model
        self.plan = self._load_plan(value['plan'], value['nominal'], nominal_mount)
        # As the driver's: a collector with driver_node:=executor records the plan in its bag.
        self.declare_parameter(
            'plan_name',
            self.plan.name,
            ParameterDescriptor(
                description='name of the plan being walked (set by the node)', read_only=True
            ),
            ignore_override=True,
        )
        # The model's defaults: the stroke the plan was made within, the model's joint names.
        defaults, stroke_source = model_defaults(self.plan.metadata, self.nominal)
        for name, spec in MODEL_PARAMETERS.items():
            value[name] = self.declare_parameter(
                name, defaults[name], parameter_descriptor(name, spec)
            ).value
        self.posture_joints = self.nominal.layout.actuator_names  # the collector's (contract)
        self.calibrate_when_done = bool(value['calibrate_when_done'])
        self.shutdown_when_done = bool(value['shutdown_when_done'])
        try:
            setup = setup_walk(
                value, self.nominal, self.plan, stroke_source, defaults['stroke_limits_m']
            )
        except ValueError as error:
            raise ExecutorConfigurationError(str(error)) from error
        if setup.problems and self.shutdown_when_done:
            raise PlanRefusedError(setup.refusal, setup.problems)  # a start-up error (exit 2)
        self.actuator_joints = setup.actuator_joints
        self.inclinometer_joints = setup.inclinometer_joints
        self.stroke, self.stroke_source = setup.stroke, setup.stroke_source
        self.settings, self.device_turn_nodes = setup.settings, setup.device_turn_nodes
        self.execution = setup.execution
        self._setup = setup
        self.mode = setup.mode
        self.guard_settings = setup.guard
        self.release_wait_s = float(value['release_wait_s'])
        self._release_clients = (
            [self.create_client(SetBool, release_service(j)) for j in self.actuator_joints]
            if any(chain is not None for chain in self.mode.released)
            else []
        )
        self._release: _ReleaseCalls | None = None
        self._drive_mode: str | None = None  # the driver's status says its measuring_mode
        self._mode_since: float | None = None  # when the start began to wait for the services
        self.mapping = self._input_mapping(value)
        self.imu = self.mapping.inclinometer_type == IMU_INCLINOMETER

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
        self.create_subscription(
            Imu if self.imu else JointState, INCLINOMETER_TOPIC, self._on_inclinometer, SENSOR_QOS
        )
        self.create_subscription(JointState, POSTURE_TOPIC, self._on_posture, POSTURE_QOS)
        # The guard on what the machine measures: the drive's status, the LVDT link's length.
        self.create_subscription(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, self._on_status, STATUS_MONITOR_QOS
        )
        if self.mode.mode.value == 'lvdt':
            self.create_subscription(JointState, LINK_TOPIC, self._on_link, SENSOR_QOS)
        self.create_service(Trigger, EXECUTOR_PAUSE_SERVICE, self._on_pause)
        self.create_service(Trigger, EXECUTOR_RESUME_SERVICE, self._on_resume)
        self.create_service(Trigger, EXECUTOR_ABORT_SERVICE, self._on_abort)
        self._calibrate_client = self.create_client(Trigger, CALIBRATE_SERVICE)
        self.turns = DeviceTurnSetter(
            {name: _TurnClient(self, name) for name in self.device_turn_nodes}
        )
        # refine_targets: intermediate calibrations at rest (core/walk/refined_targets.py).
        self.refine = RefineCall(self.nominal, float(value['refine_timeout_s']))
        self.create_subscription(
            Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters, PARAMETERS_QOS
        )
        self.calibration = CalibrationCall(
            self.calibrate_when_done, self._calibrate_client.srv_name
        )
        self.status = ExecutorStatus(
            self.execution,
            self.plan.name,
            self.model,
            sorted(setup.problems),
            self.calibration,
            self.turns,
        )
        self.status.measuring_mode = self.mode.mode.value
        self.status.joint_names = self.actuator_joints
        self._stopping = False
        for line in setup.start_lines(self.plan, self.model, self._command_pub.topic_name):
            self.get_logger().info(line)
        if FIXED in setup.execution.kinds:
            self.get_logger().info(self._inclinometer_line())
        if setup.problems:
            self.get_logger().error(setup.refusal)
        self._publish_status(force=True)
        self._timer = self.create_timer(CONTROL_PERIOD_S, self._tick)

    # ------------------------------------------------------------------ configuration

    def _load_nominal(self, path: str):
        """Return the nominal machine and the device mount its file names."""
        from ..calibration_steps.machine_files import load_machine_and_mount

        try:
            return load_machine_and_mount(path)
        except (HexacalContractError, DeviceMountError, ValueError) as error:
            raise ExecutorConfigurationError(f'nominal: {error}') from error

    def _load_plan(self, path: str, nominal_path: str, nominal_mount: str):
        from ..core.planning.planner import Plan

        try:
            plan = Plan.load(path)
        except (OSError, ValueError) as error:
            raise ExecutorConfigurationError(f'plan: {error}') from error
        # A nominal file that names no device.mount (read as the default) takes any plan's mount.
        named = nominal_mount != DEFAULT_MOUNT or (
            plan.mount != nominal_mount
            and MOUNT_PARAMETER in read_parameters_file(nominal_path).extras
        )
        problem = plan_mismatch(
            path, plan.model, plan.mount, self.model, nominal_mount if named else None
        )
        if problem:
            raise ExecutorConfigurationError(problem)
        return plan

    def _input_mapping(self, value: dict) -> InputMapping:
        """Return how the inputs are read, as the collector reads them (InputMapping)."""
        try:
            return InputMapping(
                actuator_joints=self.actuator_joints,
                inclinometer_joints=self.inclinometer_joints,
                inclinometer_type=value['inclinometer_type'],
                inclinometer_signs=value['inclinometer_signs'],
                inclinometer_offsets_rad=value['inclinometer_offsets_rad'],
                topics=(
                    self.resolve_topic_name(SLIDERS_TOPIC),
                    self.resolve_topic_name(INCLINOMETER_TOPIC),
                    '',  # the executor does not read the encoder
                ),
            )
        except InputMappingError as error:
            raise ExecutorConfigurationError(str(error)) from error

    def _inclinometer_line(self) -> str:
        """Return the log line on how fixed positions are judged."""
        mapping = self.mapping
        what = (
            'sensor_msgs/Imu orientation'
            if self.imu
            else f'JointState {", ".join(mapping.inclinometer_joints)}'
        )
        window = self.settings.inclinometer_settle_s
        text = (
            f'fixed positions: inclinometer <- {mapping.input_topic(INCLINOMETER_TOPIC)} ({what})'
        )
        corrections = (mapping.inclinometer_signs, mapping.inclinometer_offsets_rad)
        if corrections != (DEFAULT_SIGNS, DEFAULT_OFFSETS_RAD):
            text += (
                f', signs {list(mapping.inclinometer_signs)}, offsets '
                f'{list(mapping.inclinometer_offsets_rad)} rad'
            )
        return text + (
            f'; judged once settled over two {window:g} s windows'
            if window
            else f'; judged on the mean over settle_s ({self.settings.settle_s:g} s)'
        )

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            problem = parameter_problem(parameter.name, parameter.value)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ inputs

    def _invalid(self, what: str) -> None:
        self.status.invalid_readings += 1
        self.get_logger().warning(
            f'ignored an invalid {what} message ({self.status.invalid_readings} so far)',
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

    def _on_inclinometer(self, message: JointState | Imu) -> None:
        # The collector's conversions: the same joints, Imu convention, signs and offsets.
        try:
            reading = (
                imu_to_inclinometer_reading(message, self.mapping)
                if self.imu
                else joint_state_to_inclinometer_reading(message, self.mapping)
            )
        except InvalidReadingError as error:
            self._invalid(f'inclinometer ({error})')
            return
        self.execution.on_inclinometer(_now_s(self), reading.alpha, reading.beta)

    def _on_posture(self, message: JointState) -> None:
        positions = joint_positions(message.name, message.position, self.posture_joints)
        if positions is not None:
            self.execution.on_posture(_now_s(self), positions)

    def _on_status(self, message: DiagnosticArray) -> None:
        for status in message.status:
            if status.name != DRIVER_STATUS_NAME:
                continue
            values = status_values(status)
            self._drive_mode = values.get('measuring_mode', self._drive_mode)
            joint = values.get('released_joint')
            if joint is not None:  # e.g. left released by an earlier plan: lock it first
                names = list(self.actuator_joints)
                self.execution.on_drive_released(names.index(joint) if joint in names else None)
            if values.get('state') == 'fault':
                self._send(self.execution.on_drive_fault(_now_s(self), values.get('fault', '')))
                self._drain_messages()
                self._publish_status(force=True)

    def _on_link(self, message: JointState) -> None:
        names = list(message.name)
        if LINK_LENGTH_JOINT not in names or len(message.position) != len(names):
            return
        extension = float(message.position[names.index(LINK_LENGTH_JOINT)]) - float(
            self.plan.link_length
        )
        guard = self.guard_settings
        commands = self.execution.on_link(
            _now_s(self), extension, guard.lvdt_stroke_m - guard.lvdt_margin_m
        )
        if commands or self.execution.notice:
            self._send(commands)
            self._drain_messages()

    # ------------------------------------------------------------------ services

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.turns.cancel()  # a pending resume after a turn (the next resume asks again)
        return self._service(response, self.execution.pause)

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        execution = self.execution
        if self.turns.clients and execution.waiting_for_turn:
            # The posture begins once the nodes have answered (`_step_turns`).
            now = _now_s(self)
            response.message = self.turns.resume(
                float(execution.turn_needed), now, execution.index, execution.total
            )
            self._step_turns(now)
            response.success = True
            self._drain_messages()
            self._publish_status(force=True)
            return response
        return self._service(response, execution.resume)

    def _on_abort(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        return self._service(response, self.execution.abort)

    def _service(self, response: Trigger.Response, action) -> Trigger.Response:
        if self.execution.state == ExecutionState.REFUSED:
            response.success, response.message = False, self.execution.refusal
            return response
        success, message, commands = action(_now_s(self))
        self._send(commands)
        self._drain_messages()
        self._publish_status(force=True)
        response.success, response.message = success, message
        return response

    def _step_turns(self, now: float) -> None:
        """Advance the device_turn requests; once all answered, begin the posture waiting."""
        settled = self.turns.step(now)
        if settled is None:
            return
        execution = self.execution
        if execution.waiting_for_turn and same_turn(execution.turn_needed, settled.turn):
            self._service(Trigger.Response(), execution.resume)
        else:
            self._drain_messages()
            self._publish_status(force=True)

    # ------------------------------------------------------------------ the loop

    def _tick(self) -> None:
        now = _now_s(self)
        execution = self.execution
        if execution.state == ExecutionState.WAITING:
            self._try_start(now)
        elif execution.state == ExecutionState.RUNNING:
            self._send(execution.step(now))
        if self._release is not None or (
            execution.release_request is not None and execution.state == ExecutionState.RUNNING
        ):
            self._step_release(now)
        if execution.refine_request is not None:
            self._step_refine(now)
        if self.turns.setting is not None:
            self._step_turns(now)
        elif execution.state == ExecutionState.DONE:
            self._calibrate(now)
        self._drain_messages()
        self._publish_status()
        if self.shutdown_when_done and not self._stopping and self.status.finished():
            self._stopping = True
            self.get_logger().info('shutdown_when_done: stopping')
            self.context.try_shutdown()

    def _try_start(self, now: float) -> None:
        # The plan starts once the machine is there: actuator readings, a controller on the
        # command topic, (wait_for_posture) a collector, and the nodes set to the mounting.
        waiting = []
        if self.execution.actuators.latest is None:
            waiting.append(f'actuator readings on {self.resolve_topic_name(SLIDERS_TOPIC)}')
        if self._command_pub.get_subscription_count() == 0:
            waiting.append(f'a controller on {self._command_pub.topic_name}')
        if self.settings.wait_for_posture and self.count_publishers(POSTURE_TOPIC) == 0:
            waiting.append(f'a collector on {self.resolve_topic_name(POSTURE_TOPIC)}')
        turn = self.turns.start_waiting(self.execution.mounted_turn, now)
        self._drain_messages()
        if turn is not None:
            waiting.append(turn)
        if tuple(waiting) != self.status.waiting_for:
            self.status.waiting_for = tuple(waiting)
            if waiting:
                self.get_logger().info('waiting for ' + ', '.join(waiting))
            self._publish_status(force=True)
        if not waiting:
            waiting += self._confirm_mode(now)
        if waiting:
            return
        self.get_logger().info(f'starting: {len(self.plan.poses)} postures')
        self._send(self.execution.start(now))
        if self.execution.state == ExecutionState.REFUSED:
            self._publish_status(force=True)

    def _step_release(self, now: float) -> None:
        """Carry the execution's release request out through the drive's SetBool services."""
        execution, calls = self.execution, self._release
        if calls is None:
            request = execution.release_request
            assert request is not None
            steps = [(request.lock, False)] if request.lock is not None else []
            steps += [(request.release, True)] if request.release is not None else []
            # Timed from now, not the tick's start: the walk may have rehearsed its releases
            # (seconds) in this tick before asking.
            calls = self._release = _ReleaseCalls(  # type: ignore
                steps, request.lock, _now_s(self)
            )
        if not calls.steps:
            return self._released(now, '')
        chain, release = calls.steps[0]
        client = self._release_clients[chain]
        what = f'{"release" if release else "lock"} {self.actuator_joints[chain]}'
        if calls.future is None:
            if client.service_is_ready():
                calls.future = client.call_async(SetBool.Request(data=release))
                calls.since = _now_s(self)
            elif now - calls.since > self.release_wait_s:
                self._released(
                    now,
                    f'cannot {what}: no service {client.srv_name} (waited '
                    f'{self.release_wait_s:g} s)',
                )
            return None
        if not calls.future.done():
            if now - calls.since > self.release_wait_s:
                self._released(
                    now, f'cannot {what}: {client.srv_name} did not answer within '
                    f'{self.release_wait_s:g} s'
                )
            return None
        try:
            answer = calls.future.result()
        except Exception as error:  # noqa: B902 - the status must say what happened
            return self._released(now, f'cannot {what}: {type(error).__name__}: {error}')
        if not answer.success:
            return self._released(now, f'the drive refused to {what}: {answer.message}')
        self.get_logger().info(f'{what}: {answer.message}')
        calls.released = chain if release else None
        calls.steps.pop(0)
        calls.future, calls.since = None, now
        if not calls.steps:
            self._released(now, '')
        return None

    def _released(self, now: float, problem: str) -> None:
        calls, self._release = self._release, None
        assert calls is not None
        self._send(self.execution.on_release(now, calls.released, problem))
        self._drain_messages()
        self._publish_status(force=True)

    def _confirm_mode(self, now: float) -> list[str]:
        """
        Return what the start waits for to drive the plan's passive_actuator mode.

        Only a plan's mode (not the parameter) is confirmed: on a drive that offers no release
        service (its status names another mode, or none appears within RELEASE_DISCOVERY_S)
        the plan walks as before the modes had names, all six commanded, with a warning.
        """
        mode = self.mode
        if mode.mode.value != 'passive_actuator' or mode.source != 'plan':
            return []
        if self._drive_mode == 'passive_actuator' or any(
            client.service_is_ready() for client in self._release_clients
        ):
            self.mode = replace(mode, source='plan, confirmed')
            return []
        if self._mode_since is None:
            self._mode_since = now
        if self._drive_mode is None and now - self._mode_since < RELEASE_DISCOVERY_S:
            return [
                f'the release services {RELEASE_SERVICE_PREFIX}<joint> (a passive_actuator plan)'
            ]
        why = (
            f"the drive's measuring_mode is {self._drive_mode}"
            if self._drive_mode is not None
            else f'no release service {RELEASE_SERVICE_PREFIX}<joint> within '
            f'{RELEASE_DISCOVERY_S:g} s'
        )
        # Say what to do, on either side: the drive's mode or the plan's.
        self.get_logger().warning(
            f'{why}: {walking_notice(mode.mode.value)}. To walk it as planned, run the drives '
            'in measuring_mode passive_actuator with a release service per joint (the launch '
            'argument measuring_mode:=passive_actuator, bringup --measuring-mode '
            'passive_actuator for the simulated driver); else plan for these drives: hexacal '
            f'plan --measuring-mode {self._drive_mode or "compliant"}'
        )
        self.mode = mode.all_six('the plan is passive_actuator, the drive is not')
        self.execution.released = list(self.mode.released)
        self.execution.guard = None  # as before the modes had names
        self.status.measuring_mode = self.mode.mode.value
        return []

    def _send(self, commands: list[Command]) -> None:
        released = self.execution.released_now
        joints = list(self.actuator_joints)
        if released is not None:  # the released joint is not commanded
            del joints[released]
        for command in commands:
            message = JointTrajectory()  # header.stamp zero: the controller starts it on receipt
            message.joint_names = joints
            message.points = [
                JointTrajectoryPoint(
                    positions=[
                        float(p) for i, p in enumerate(point) if i != released
                    ],
                    time_from_start=_duration(seconds),
                )
                for point, seconds in zip(command.points, command.times)
            ]
            self._command_pub.publish(message)
            self.status.commands_sent += 1
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
        logger = self.get_logger()
        for owner in (self.execution, self.turns, self.calibration, self.refine):
            messages: Messages = owner.messages
            owner.messages = []
            # One call site per severity: rclpy refuses another severity from the same line.
            for level, text in messages:
                if level == LogLevel.ERROR:
                    logger.error(text)
                elif level == LogLevel.WARN:
                    logger.warning(text)
                else:
                    logger.info(text)

    def _calibrate(self, now: float) -> None:
        state = self.calibration.state
        if self.calibration.due(now, self._calibrate_client.service_is_ready()):
            future = self._calibrate_client.call_async(Trigger.Request())
            future.add_done_callback(self._on_calibrated)
        if self.calibration.state != state:
            self._drain_messages()
            self._publish_status(force=True)

    def _on_calibrated(self, future) -> None:
        self.calibration.answer(*_trigger_answer(future))
        self._drain_messages()
        self._publish_status(force=True)

    def _step_refine(self, now: float) -> None:
        """Carry the execution's intermediate calibration out through hexacal/calibrate."""
        refine, execution = self.refine, self.execution
        if refine.state != RefineState.WAITING:
            postures = execution.refine_request
            assert postures is not None
            if refine.start(now, postures, self._calibrate_client.service_is_ready()):
                future = self._calibrate_client.call_async(Trigger.Request())
                future.add_done_callback(self._on_refine_answer)
        refine.poll(now)
        if refine.state == RefineState.DONE:
            refine.state = RefineState.IDLE
            model = refine.model
            guard = refined_guard(self._setup, model) if model is not None else None
            self._send(execution.on_refined(now, model, refine.message, guard))
            self._drain_messages()
            self._publish_status(force=True)

    def _on_refine_answer(self, future) -> None:
        self.refine.answer(*_trigger_answer(future))

    def _on_parameters(self, message: Float64MultiArray) -> None:
        try:
            self.refine.parameters(multiarray_to_parameters(message, self.model))
        except (HexacalContractError, ValueError) as error:
            self.get_logger().warning(f'parameters on {PARAMETERS_TOPIC} ignored: {error}')

    # ------------------------------------------------------------------ status

    def _publish_status(self, force: bool = False) -> None:
        now = _now_s(self)
        values = self.status.values(now)
        if not self.status.due(now, values, force):
            return
        self._status_pub.publish(
            diagnostic_status(
                self.status.level(values),
                EXECUTOR_STATUS_NAME,
                self.status.text(values),
                values,
                hardware_id=self.get_fully_qualified_name(),
                stamp=self.get_clock().now().nanoseconds,
            )
        )

    def summary(self) -> str:
        return (
            f"plan '{self.plan.name}' {self.execution.state}: {self.execution.summary()}; "
            f'{self.status.commands_sent} commands sent'
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
