"""
Node `executor`: walk a plan from `hexacal plan` on the machine through its trajectory controller.

    ros2 run hexacal_identify executor --ros-args -p plan:=plan.yaml -p nominal:=nominal.yaml

Commands (trajectory_msgs/JointTrajectory) on ``command_topic``; actuators, inclinometer (a
JointState or an Imu, read as the collector reads it: the InputMapping parameters of
nodes/input_parameters.py) and the collector's postures in; pause/resume/abort services;
progress on ``hexacal/calibration_status``.  What decides is ROS-free:
core/planning/plan_check.py (the plan is checked before anything moves), core/walk/execution.py
(the walk), core/walk_device/turns.py (device turns), core/walk/drive_calls.py (release calls, the
drive's mode, the trajectory sent), core/sessions/executor_session.py (set-up, status,
calibration call, parameter checks).  This node hears, publishes and keeps time; its ROS
adapters are nodes/executor_io.py, its parameters nodes/executor_parameters.py.

Full reference: docs/nodes.md
"""

from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from hexacal_msgs_py.conversions import (
    diagnostic_status,
    imu_to_inclinometer_reading,
    joint_state_to_inclinometer_reading,
    multiarray_to_parameters,
    status_values,
)
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.inputs import IMU_INCLINOMETER, InputMapping, InputMappingError
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_TOPIC,
    DRIVER_STATUS_NAME,
    EXECUTOR_ABORT_SERVICE,
    EXECUTOR_PAUSE_SERVICE,
    EXECUTOR_RESUME_SERVICE,
    EXECUTOR_STATUS_NAME,
    INCLINOMETER_TOPIC,
    LINK_TOPIC,
    PARAMETERS_TOPIC,
    POSTURE_TOPIC,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.node_runtime import run_node
from hexacal_msgs_py.qos import COMMAND_QOS, PARAMETERS_QOS, POSTURE_QOS, SENSOR_QOS
from hexacal_msgs_py.qos import STATUS_MONITOR_QOS, STATUS_QOS
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from .executor_io import log_lines, log_messages, now_s as _now_s, ReleaseClient, TurnClient
from .executor_io import trajectory_message, trigger_answer
from .executor_parameters import declare_model_parameters, declare_parameters
from ..core.machine.device import DeviceMountError
from ..core.planning.plan_check import PlanRefusedError
from ..core.sessions.executor_session import CalibrationCall, input_mapping, load_plan
from ..core.sessions.executor_session import model_defaults, refine_step, setup_walk, start_waits
from ..core.walk.drive_calls import command_text, DriveMode, lvdt_extension, ReleaseCalls
from ..core.walk.drive_calls import trajectory
from ..core.walk.messages import joint_positions
from ..core.walk.platform_paths import Command
from ..core.walk.settings import ExecutionState
from ..core.walk_device.turns import DeviceTurnSetter, same_turn
from ..core.walk_refine.refined_targets import RefineCall

NODE_NAME = 'executor'
CONTROL_PERIOD_S = 0.05  # the state machine steps this often
INVALID_LOG_PERIOD_S = 5.0
SHUTDOWN_LINGER_S = 0.3  # the last status (and hold command) reach their subscribers


class ExecutorConfigurationError(Exception):
    """The node's parameters do not describe a plan it can walk on this machine."""


class ExecutorNode(Node):
    """Plan walker: commands on command_topic, readings in, services, progress out."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        value = declare_parameters(self)
        self.nominal, self.plan = self._load(value['nominal'], value['plan'])
        self.model = self.nominal.model
        # The model's defaults: the stroke the plan was made within, the model's joint names.
        defaults, stroke_source = model_defaults(self.plan.metadata, self.nominal)
        value.update(declare_model_parameters(self, self.plan.name, defaults))
        self.posture_joints = self.nominal.layout.actuator_names  # the collector's (contract)
        self.shutdown_when_done = bool(value['shutdown_when_done'])
        try:
            setup = setup_walk(
                value, self.nominal, self.plan, stroke_source, defaults['stroke_limits_m']
            )
        except ValueError as error:
            raise ExecutorConfigurationError(str(error)) from error
        if setup.problems and self.shutdown_when_done:
            raise PlanRefusedError(setup.refusal, setup.problems)  # a start-up error (exit 2)
        self.actuator_joints, self.settings = setup.actuator_joints, setup.settings
        self.execution = setup.execution
        self._setup = setup
        self.mode = setup.mode
        passive = any(chain is not None for chain in self.mode.released)
        clients = [ReleaseClient(self, j) for j in self.actuator_joints] if passive else []
        self.releases = ReleaseCalls(clients, self.actuator_joints, value['release_wait_s'])
        self.drive = DriveMode()
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
        for service, callback in (
            (EXECUTOR_PAUSE_SERVICE, self._on_pause),
            (EXECUTOR_RESUME_SERVICE, self._on_resume),
            (EXECUTOR_ABORT_SERVICE, self._on_abort),
        ):
            self.create_service(Trigger, service, callback)
        self._calibrate_client = self.create_client(Trigger, CALIBRATE_SERVICE)
        self.turns = DeviceTurnSetter(
            {name: TurnClient(self, name) for name in setup.device_turn_nodes}
        )
        # refine_targets: intermediate calibrations at rest (core/walk_refine/refined_targets.py).
        self.refine = RefineCall(self.nominal, float(value['refine_timeout_s']))
        self.create_subscription(
            Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters, PARAMETERS_QOS
        )
        self.calibration = CalibrationCall(
            bool(value['calibrate_when_done']), self._calibrate_client.srv_name
        )
        self.status = setup.status(self.plan.name, self.model, self.calibration, self.turns)
        self._stopping = False
        topic = self._command_pub.topic_name
        lines = setup.start_messages(self.plan, self.model, topic, self.mapping)
        log_lines(self.get_logger(), lines)
        self._publish_status(force=True)
        self._timer = self.create_timer(CONTROL_PERIOD_S, self._tick)

    # ------------------------------------------------------------------ configuration

    def _load(self, nominal_path: str, plan_path: str):
        """Return the nominal machine and the plan to walk on it."""
        from ..calibration_steps.machine_files import load_machine_and_mount

        try:
            nominal, mount = load_machine_and_mount(nominal_path)
        except (HexacalContractError, DeviceMountError, ValueError) as error:
            raise ExecutorConfigurationError(f'nominal: {error}') from error
        try:
            return nominal, load_plan(plan_path, nominal_path, mount, nominal.model)
        except ValueError as error:
            raise ExecutorConfigurationError(str(error)) from error

    def _input_mapping(self, value: dict) -> InputMapping:
        """Return how the inputs are read, as the collector reads them (InputMapping)."""
        topics = [self.resolve_topic_name(topic) for topic in (SLIDERS_TOPIC, INCLINOMETER_TOPIC)]
        try:
            return input_mapping(value, self._setup, topics)
        except InputMappingError as error:
            raise ExecutorConfigurationError(str(error)) from error

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
            commands = self.drive.hear(
                status_values(status), self.execution, self.actuator_joints, _now_s(self)
            )
            if commands is not None:  # the drive faulted
                self._report(commands)

    def _on_link(self, message: JointState) -> None:
        extension = lvdt_extension(message.name, message.position, self.plan.link_length)
        if extension is None:
            return
        guard = self._setup.guard
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
        turn = execution.turn_needed  # set while waiting for a turn
        if self.turns.clients and execution.waiting_for_turn and turn is not None:
            # The posture begins once the nodes have answered (`_step_turns`).
            now = _now_s(self)
            response.message = self.turns.resume(
                float(turn), now, execution.index, execution.total
            )
            self._step_turns(now)
            response.success = True
            self._report()
            return response
        return self._service(response, execution.resume)

    def _on_abort(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        return self._service(response, self.execution.abort)

    def _service(self, response: Trigger.Response, action) -> Trigger.Response:
        if self.execution.state == ExecutionState.REFUSED:
            response.success, response.message = False, self.execution.refusal
            return response
        success, message, commands = action(_now_s(self))
        self._report(commands)
        response.success, response.message = success, message
        return response

    def _step_turns(self, now: float) -> None:
        """Advance the device_turn requests; once all answered, begin the posture waiting."""
        settled = self.turns.step(now)
        if settled is None:
            return
        execution = self.execution
        turn = execution.turn_needed  # set while waiting for a turn
        if execution.waiting_for_turn and turn is not None and same_turn(turn, settled.turn):
            self._service(Trigger.Response(), execution.resume)
        else:
            self._report()

    # ------------------------------------------------------------------ the loop

    def _tick(self) -> None:
        now = _now_s(self)
        execution = self.execution
        if execution.state == ExecutionState.WAITING:
            self._try_start(now)
        elif execution.state == ExecutionState.RUNNING:
            self._send(execution.step(now))
        if self.releases.active or (
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
        waiting = start_waits(
            self.execution.actuators.latest is not None,
            self.resolve_topic_name(SLIDERS_TOPIC),
            self._command_pub.get_subscription_count(),
            self._command_pub.topic_name,
            self.settings.wait_for_posture and self.count_publishers(POSTURE_TOPIC) == 0,
            self.resolve_topic_name(POSTURE_TOPIC),
        )
        turn = self.turns.start_waiting(self.execution.mounted_turn, now)
        self._drain_messages()
        if turn is not None:
            waiting.append(turn)
        if self.status.wait_for(waiting):  # changed
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
        outcome = self.releases.step(now, self.execution.release_request, lambda: _now_s(self))
        if outcome is None:
            return
        self._report(self.execution.on_release(now, *outcome))

    def _confirm_mode(self, now: float) -> list[str]:
        """Return what the start waits for to drive the plan's mode (core.walk.drive_calls)."""
        ready = any(client.service_is_ready() for client in self.releases.clients)
        self.mode, waiting = self.drive.confirm(self.mode, self.execution, now, ready)
        self.status.measuring_mode = self.mode.mode.value
        return waiting

    def _send(self, commands: list[Command]) -> None:
        for command in commands:
            released = self.execution.released_now  # not commanded: left out
            message = trajectory_message(*trajectory(command, self.actuator_joints, released))
            self._command_pub.publish(message)
            self.status.commands_sent += 1
            self.get_logger().debug(command_text(command, self.execution.total))

    def _report(self, commands: list[Command] | None = None) -> None:
        """Send `commands`, log what the parts say and publish the status now."""
        self._send(commands or [])
        self._drain_messages()
        self._publish_status(force=True)

    def _drain_messages(self) -> None:
        owners = (self.releases, self.drive, self.execution, self.turns, self.calibration)
        log_messages(self.get_logger(), (*owners, self.refine))

    def _calibrate(self, now: float) -> None:
        state = self.calibration.state
        if self.calibration.due(now, self._calibrate_client.service_is_ready()):
            future = self._calibrate_client.call_async(Trigger.Request())
            future.add_done_callback(self._on_calibrated)
        if self.calibration.state != state:
            self._report()

    def _on_calibrated(self, future) -> None:
        self.calibration.answer(*trigger_answer(future))
        self._report()

    def _step_refine(self, now: float) -> None:
        """Carry the execution's intermediate calibration out through hexacal/calibrate."""
        ready = self._calibrate_client.service_is_ready()
        call, commands = refine_step(self.refine, self._setup, now, ready)
        if call:
            future = self._calibrate_client.call_async(Trigger.Request())
            future.add_done_callback(self._on_refine_answer)
        if commands is not None:
            self._report(commands)

    def _on_refine_answer(self, future) -> None:
        self.refine.answer(*trigger_answer(future))

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
