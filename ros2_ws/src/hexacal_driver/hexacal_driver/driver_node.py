"""
Node `driver`: a simulated machine (Hexa Slide or Gough-Stewart) with the measuring device.

Walks a posture plan (or, with `command_topic`, follows JointTrajectory commands like a
trajectory controller with mock hardware) and publishes the actuator, inclinometer and rotary
readings at `rate_hz` (SENSOR_QOS, SI units). What it simulates is decided in machine.py,
parameters.py, plan.py, drives.py and simulation.py, what it logs and its drives' status in
reports.py; this node keeps time, converts messages and publishes. Full reference: docs/nodes.md.
"""

from __future__ import annotations

import functools
import math
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from hexacal_driver.machine import DriverConfigurationError, SimulatedMachine, true_machine
from hexacal_driver.parameters import (
    actuator_parameter_defaults,
    ACTUATOR_PARAMETERS,
    MODEL_CHOICES,
    parameter_problem,
    PARAMETERS,
    RUNTIME_PARAMETERS,
)
from hexacal_driver.reports import (
    actuator_quantities_of,
    command_text,
    commanded_start_text,
    device_turn_text,
    drives_start_text,
    DriveStatusReport,
    finish_lines,
    link_overload_warning,
    machine_source,
    MotionReport,
    noise_text,
    plan_start_text,
    STRAIN_WARNING_M,
    STRAIN_WARNING_PERIOD_S,
    WalkReport,
)
from hexacal_driver.simulation import WalkSample
from hexacal_msgs_py.conversions import (
    actuator_reading_to_joint_state,
    diagnostic_status,
    encoder_reading_to_joint_state,
    inclinometer_angles_to_imu,
    inclinometer_reading_to_joint_state,
    NS_PER_S,
    stamp_ns,
)
from hexacal_msgs_py.measuring_modes import LINK_LENGTH_JOINT, MeasuringMode
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.names import (
    CALIBRATION_STATUS_TOPIC,
    DRIVER_RESET_SERVICE,
    DRIVER_STATUS_NAME,
    ENCODER_TOPIC,
    INCLINOMETER_TOPIC,
    LINK_TOPIC,
    release_service,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.node_parameters import parameter_descriptor
from hexacal_msgs_py.node_runtime import run_node
from hexacal_msgs_py.qos import COMMAND_QOS, SENSOR_QOS, STATUS_QOS
from hexacal_msgs_py.readings import ActuatorReading, EncoderReading, InclinometerReading
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterValueException, InvalidTopicNameException
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory

NODE_NAME = 'driver'
# The timer wakes at most this often and publishes rate_hz / MAX_WAKE_HZ samples per wake-up,
# each stamped with its own sampling time (1 / rate_hz apart, the last one now): an executor
# wake-up costs more than the publishing, so 1 kHz costs 200 wake-ups per second, not 1000.
MAX_WAKE_HZ = 200.0
SHUTDOWN_LINGER_S = 0.3
# With wait_for_subscriber, the plan starts this long after all three writers matched a reader:
# a writer matches before its reader has matched it back, and a best-effort sample sent in
# between is dropped (seen: a stream's first plan sample lost, the two others whole).
MATCH_SETTLE_S = 0.2

__all__ = ['DriverConfigurationError', 'DriverNode', 'main', 'MODEL_CHOICES', 'PARAMETERS',
           'RUNTIME_PARAMETERS', 'STRAIN_WARNING_M']


class DriverNode(Node):
    """Simulated machine + device: plan walker, noisy sensors, three SENSOR_QOS publishers."""

    def __init__(self) -> None:
        """Declare the parameters, decide the machine, create the publishers and the timer."""
        super().__init__(NODE_NAME)
        # Registered before declaring, so command-line overrides are validated too.
        self.add_on_set_parameters_callback(self._validate_parameters)
        for name, spec in PARAMETERS.items():
            if name not in ACTUATOR_PARAMETERS:
                self._declare(name, spec.default)
        # The actuator quantities' defaults are the true machine's model's (rad for cranks).
        truth = true_machine(
            self.get_parameter('true_params').value, self.get_parameter('model').value
        )
        for name, default in actuator_parameter_defaults(truth[0].model).items():
            self._declare(name, default)
        self.add_post_set_parameters_callback(self._apply_parameters)
        value = {name: self.get_parameter(name).value for name in PARAMETERS}
        self.machine = SimulatedMachine(value, truth)
        self.command_topic = value['command_topic']
        plan = self.machine.plan
        self.declare_parameter(
            'plan_name',
            f'commanded on {self.command_topic}' if plan is None else plan.name,
            ParameterDescriptor(
                description='name of the plan being walked (set by the node)', read_only=True
            ),
            ignore_override=True,
        )
        self.rate_hz = float(value['rate_hz'])
        self.wait_for_subscriber = bool(value['wait_for_subscriber'])
        self._sliders_pub = self.create_publisher(JointState, SLIDERS_TOPIC, SENSOR_QOS)
        self._inclinometer_pub = self.create_publisher(JointState, INCLINOMETER_TOPIC, SENSOR_QOS)
        self._encoder_pub = self.create_publisher(JointState, ENCODER_TOPIC, SENSOR_QOS)
        try:  # the inclinometer as an Imu too (imu_topic): what a real Imu inclinometer sends
            topic = value['imu_topic']
            self._imu_pub = self.create_publisher(Imu, topic, SENSOR_QOS) if topic else None
        except InvalidTopicNameException as error:
            raise DriverConfigurationError(f'imu_topic: {error}') from error
        self._imu_stamp_ns = -1  # of the last Imu published
        self._ticks = 0  # plan time is ticks / rate_hz: every posture gets its samples under load
        self.published = 0  # messages published on each of the three streams (load accounting)
        self.published_before_plan = 0  # ... of which while holding for a subscriber
        self.plan_start_stamp_ns: int | None = None  # stamp of the first message of the plan
        self._started = False
        self._started_monotonic = 0.0
        self._matched_monotonic: float | None = None  # when all three writers matched a reader
        self._walk_report = None if plan is None else WalkReport(
            plan, self.machine.require_walker().loop
        )
        self._motion_report = MotionReport()
        self._per_wake = max(1, math.ceil(self.rate_hz / MAX_WAKE_HZ - 1e-9))
        self._period_ns = int(round(NS_PER_S / self.rate_hz))
        self._last_stamp_ns = -1
        # Preallocated messages: each tick sets the stamps and positions only.
        self._messages = {
            'sliders': actuator_reading_to_joint_state(
                ActuatorReading(0, (0.0,) * 6), model=self.machine.model
            ),
            'inclinometer': inclinometer_reading_to_joint_state(InclinometerReading(0, 0.0, 0.0)),
            'encoder': encoder_reading_to_joint_state(EncoderReading(0, 0.0)),
        }
        # The inclinometer message of a turned device: the device_turn joint too.
        self._turned_inclinometer = inclinometer_reading_to_joint_state(
            InclinometerReading(0, 0.0, 0.0, math.pi)
        )
        self.commands_accepted = 0
        self.commands_rejected = 0
        if self.machine.follower is not None:
            try:
                self.create_subscription(
                    JointTrajectory, self.command_topic, self._on_command, COMMAND_QOS
                )
            except InvalidTopicNameException as error:
                raise DriverConfigurationError(f'command_topic: {error}') from error
            self._create_drive_interfaces()
        self._timer = self.create_timer(self._per_wake / self.rate_hz, self._wake)
        source = machine_source(value['true_params'], self.machine)
        if plan is None:
            topic = self.resolve_topic_name(self.command_topic)
            self.get_logger().info(commanded_start_text(self.machine, topic, source, self.rate_hz))
            self.get_logger().info(drives_start_text(self.machine.require_follower()))
            return
        self.get_logger().info(plan_start_text(self.machine, source, self.rate_hz))
        if self.wait_for_subscriber:
            self.get_logger().info(
                f'holding the first posture until {self._sliders_pub.topic_name} has a subscriber'
            )

    # ------------------------------------------------------------------ the drives (commanded)

    def _create_drive_interfaces(self) -> None:
        """Create the drives' status, reset, release services (passive) and link stream (lvdt)."""
        mode = self.machine.drive_settings.mode
        self._status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self._drive_status = DriveStatusReport()
        self.create_service(Trigger, DRIVER_RESET_SERVICE, self._on_reset)
        if mode == MeasuringMode.PASSIVE_ACTUATOR:
            for joint in MODELS[self.machine.model].actuator_names:
                self.create_service(
                    SetBool,
                    release_service(joint),
                    functools.partial(self._on_release, joint),
                )
        self._link_pub = None
        if mode == MeasuringMode.LVDT:
            self._link_pub = self.create_publisher(JointState, LINK_TOPIC, SENSOR_QOS)
            self._link_message = JointState(name=[LINK_LENGTH_JOINT], position=[0.0])

    def _on_release(
        self, joint: str, request: SetBool.Request, response: SetBool.Response
    ) -> SetBool.Response:
        """Release (data true) or lock (false) `joint`, at rest only."""
        now_s = self.get_clock().now().nanoseconds / NS_PER_S
        response.success, response.message = self.machine.require_follower().release(
            joint, bool(request.data), now_s
        )
        text = f'{"release" if request.data else "lock"} {joint}: {response.message}'
        # One call site per severity: rclpy refuses a severity change at a call site.
        if response.success:
            self.get_logger().info(text)
        else:
            self.get_logger().warning(text)
        self._publish_drive_status(force=True)
        return response

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Clear a fault: the drives are re-enabled where they stand."""
        response.success, response.message = self.machine.require_follower().reset()
        self.get_logger().info(f'reset: {response.message}')
        self._publish_drive_status(force=True)
        return response

    def _publish_drive_status(self, force: bool = False) -> None:
        """Publish 'hexacal driver' when due (reports.DriveStatusReport); log a new fault."""
        now_ns = self.get_clock().now().nanoseconds
        report = self._drive_status.report(self.machine.require_follower(), now_ns, force)
        if report is None:
            return
        level, message, values, new_fault = report
        if new_fault:
            self.get_logger().error(
                f'drive fault: {new_fault}; holding, trajectories refused until '
                f'{self.resolve_service_name(DRIVER_RESET_SERVICE)} is called'
            )
        self._status_pub.publish(
            diagnostic_status(
                level,
                DRIVER_STATUS_NAME,
                message,
                values,
                hardware_id=self.get_fully_qualified_name(),
                stamp=now_ns,
            )
        )

    # ------------------------------------------------------------------ parameters and commands

    def _on_command(self, message: JointTrajectory) -> None:
        """Follow a JointTrajectory command, or reject it with the reason."""
        points = [
            (
                list(point.positions),
                point.time_from_start.sec + point.time_from_start.nanosec * 1e-9,
            )
            for point in message.points
        ]
        now_ns = self.get_clock().now().nanoseconds
        start_ns = message.header.stamp.sec * NS_PER_S + message.header.stamp.nanosec
        checked, problem = self.machine.check_command(
            list(message.joint_names), points, start_ns, now_ns
        )
        follower = self.machine.require_follower()
        if problem is not None:
            self.commands_rejected += 1
            self.get_logger().warning(f'rejected a JointTrajectory command: {problem}')
            follower.last_refusal = problem
            self._publish_drive_status(force=True)
            return
        assert checked is not None  # no problem: the checked points
        self.commands_accepted += 1
        end_s = follower.command(
            now_ns / NS_PER_S, checked, start_ns / NS_PER_S if start_ns else None
        )
        self.get_logger().info(
            command_text(
                self.commands_accepted,
                checked[-1].positions,
                end_s - now_ns / NS_PER_S,
                actuator_quantities_of(self.machine),
            )
        )

    def _declare(self, name: str, default: object) -> None:
        descriptor = parameter_descriptor(
            name, PARAMETERS[name], read_only=name not in RUNTIME_PARAMETERS
        )
        self.declare_parameter(name, default, descriptor)

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse the first parameter with a problem (parameters.parameter_problem)."""
        for parameter in parameters:
            problem = parameter_problem(parameter.name, parameter.value)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        """Apply the run-time parameters: the noise half-widths and the device turn."""
        if not hasattr(self, 'machine'):
            return  # still declaring
        given = {parameter.name: parameter.value for parameter in parameters}
        if self.machine.set_noise(given.get('slider_noise_m'), given.get('angle_noise_rad')):
            noise = noise_text(self.machine.sensors.noise, actuator_quantities_of(self.machine))
            self.get_logger().info(f'noise now {noise}')
        if 'device_turn' in given:
            previous = self.machine.set_device_turn(given['device_turn'])
            if previous is not None:
                self.get_logger().info(
                    device_turn_text(previous, self.machine.device_turn, self.machine.plan)
                )

    # ------------------------------------------------------------------ publishing

    def _wake(self) -> None:
        """Publish the samples of one timer period, stamped 1 / rate_hz apart up to now."""
        now = self.get_clock().now().nanoseconds
        for remaining in range(self._per_wake - 1, -1, -1):
            # Strictly increasing and never ahead of the clock, even after a late wake-up.
            stamp = max(now - remaining * self._period_ns, self._last_stamp_ns + 1)
            self._last_stamp_ns = stamp
            self._tick(stamp)

    def _matched_long_enough(self) -> bool:
        """Return True once all three writers have had a reader for MATCH_SETTLE_S."""
        if min(self._subscription_counts()) == 0:
            self._matched_monotonic = None
            return False
        now = time.monotonic()
        if self._matched_monotonic is None:
            self._matched_monotonic = now
        return now - self._matched_monotonic >= MATCH_SETTLE_S

    def _tick(self, stamp: int) -> None:
        """Publish the sample at `stamp` (ns): the follower's, or the plan walker's."""
        machine = self.machine
        if machine.follower is not None:
            if not self._started:
                self._started = True
                self.published_before_plan = self.published
            sample = machine.follower.sample(stamp / NS_PER_S)
            self._publish(sample, stamp)
            self._report_motion(sample.phase)
            self._publish_drive_status()
            return
        if not self._started:
            # Matched (DDS), not just on the graph, on all three, and the readers given time to
            # match back (MATCH_SETTLE_S): no plan sample goes to nobody.
            if self.wait_for_subscriber and not self._matched_long_enough():
                self._publish(machine.require_walker().sample(0.0), stamp)
                return
            self._started = True
            self._started_monotonic = time.monotonic()
            self.published_before_plan = self.published
            self.get_logger().info(f"starting plan '{machine.require_plan().name}'")
        sample = machine.require_walker().sample(self._ticks / self.rate_hz)
        self._ticks += 1
        self._publish(sample, stamp)
        elapsed = time.monotonic() - self._started_monotonic
        turn = machine.posture_turn(sample.posture_index)
        walk_report = self._walk_report
        assert walk_report is not None  # plan mode
        for line in walk_report.lines(
            sample.posture_index, sample.lap, sample.phase, elapsed, turn
        ):
            self.get_logger().info(line)

    def _publish(self, sample: WalkSample, stamp: int) -> None:
        """Publish the three sensor messages of `sample`, sampled at `stamp` (ns)."""
        output, turn = self.machine.read_streams(sample, stamp)
        readings = output.readings
        if self._started and self.plan_start_stamp_ns is None:
            self.plan_start_stamp_ns = stamp
        messages = self._messages
        messages['sliders'].position = readings.actuators_m.tolist()
        follower = self.machine.follower
        forces = None if follower is None else follower.forces()
        if forces is not None:
            # Compliant servos: the force each carries (N), stiffness x deviation.
            messages['sliders'].effort = forces.tolist()
        if turn == 0.0:  # the normal mounting: the message as it always was
            inclinometer = messages['inclinometer']
            inclinometer.position = [readings.alpha_rad, readings.beta_rad]
        else:
            inclinometer = self._turned_inclinometer
            inclinometer.position = [readings.alpha_rad, readings.beta_rad, turn]
        messages['encoder'].position = [readings.phi_rad]
        # One stamp for the three (the sensors are sampled together) unless the sensor effect
        # `clock` stamps each by its own clock; None: `drops` lost the message.
        for publisher, message, message_stamp in zip(
            (self._sliders_pub, self._inclinometer_pub, self._encoder_pub),
            (messages['sliders'], inclinometer, messages['encoder']),
            output.stamps_ns,
        ):
            if message_stamp is not None:
                message.header.stamp.sec, message.header.stamp.nanosec = divmod(
                    message_stamp, NS_PER_S
                )
                publisher.publish(message)
        if self.machine.follower is not None and self._link_pub is not None:
            self._publish_link(output.stamps_ns[0])
        # Complete ticks: Ctrl-C may cut the last one after some of its publishes.
        self.published += 1
        self._publish_imu(inclinometer)

    def _publish_link(self, sliders_stamp_ns: int | None) -> None:
        """Publish the LVDT's link length (lvdt mode), read with the actuators."""
        value, stamp = self.machine.read_link(sliders_stamp_ns)
        if stamp is None or self._link_pub is None:
            return
        message = self._link_message
        message.position = [value]
        message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, NS_PER_S)
        self._link_pub.publish(message)

    def _subscription_counts(self) -> tuple[int, int, int]:
        """Return the matched subscriptions of the three streams (inclinometer: either type)."""
        imu = self._imu_pub.get_subscription_count() if self._imu_pub is not None else 0
        return (
            self._sliders_pub.get_subscription_count(),
            self._inclinometer_pub.get_subscription_count() + imu,
            self._encoder_pub.get_subscription_count(),
        )

    def _publish_imu(self, inclinometer: JointState) -> None:
        """Publish the inclinometer message's angles as an Imu on imu_topic, same stamp."""
        stamp = stamp_ns(inclinometer.header.stamp)
        # A message not published this tick (lost) kept the stamp of the last one: no Imu.
        if self._imu_pub is not None and stamp != self._imu_stamp_ns:
            self._imu_stamp_ns = stamp
            alpha, beta = inclinometer.position[:2]
            reading = InclinometerReading(stamp, alpha, beta)
            self._imu_pub.publish(inclinometer_angles_to_imu(reading))

    def _report_motion(self, phase: str) -> None:
        """Log the link's strain (throttled) and the end of each commanded motion."""
        warning, line = self._motion_report.lines(self.machine, phase, self.commands_accepted)
        if warning is not None:
            self.get_logger().warning(warning, throttle_duration_sec=STRAIN_WARNING_PERIOD_S)
        if line is not None:
            self.get_logger().info(line)
            overload = link_overload_warning(self.machine.require_follower())
            if overload is not None:
                self.get_logger().warning(overload)
            # One status per rest: a monitor (the demo) hears every rest and its motion's peaks.
            self.machine.require_follower().rest_reached()
            self._publish_drive_status(force=True)


def _finish(node: DriverNode) -> list[str]:
    """Return the lines printed at exit, after the in-flight samples had time to leave."""
    # Best-effort samples of the last ticks may still sit in Fast DDS's writer queues: give its
    # send threads a moment before the publishers are destroyed, so a stop loses nothing in flight.
    time.sleep(SHUTDOWN_LINGER_S)
    commanded = node.machine.follower is not None
    return finish_lines(
        node.published,
        node.published_before_plan,
        node.plan_start_stamp_ns,
        (node.commands_accepted, node.commands_rejected) if commanded else None,
        tuple(node.machine.streams.dropped),
    )


def main(args: list[str] | None = None) -> int:
    """Run the driver node until Ctrl-C or SIGTERM; return the exit code."""
    return run_node(
        NODE_NAME,
        DriverNode,
        args=args,
        finish=_finish,
        startup_errors=(DriverConfigurationError, InvalidParameterValueException),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
