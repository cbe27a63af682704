"""
Node `identify`: keep every posture received, calibrate and verify on request.

Subscribes `hexacal/posture` (POSTURE_QOS) and stores every valid posture of the nominal
file's machine model (others are counted as rejected on the status). Service
`hexacal/calibrate` (std_srvs/Trigger) calibrates from the live postures or the `bag`
parameter, writes `output` under `output_dir` and publishes the result on
`hexacal/parameters` (transient local) with the outcome on `hexacal/calibration_status`;
the HTML report (`report_dir`) follows in the background (`report_state`). Service
`hexacal/verify` verifies the latest calibration on the postures received after it. Every
calibration is kept in the calibration store (`calibration_store`) with its verifications;
`hexacal/deploy` makes the latest one active (refused unless verified and plausible;
`hexacal/deploy_force` deploys it anyway, recorded as forced), `hexacal/rollback` goes back.
The decisions live in the ROS-free hexacal_identify.session; this module is the ROS glue.

Full reference: docs/nodes.md
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
import functools
import sys
import threading

from diagnostic_msgs.msg import DiagnosticArray
from hexacal_msgs_py.conversions import (
    diagnostic_status,
    joint_state_to_posture_reading,
    parameters_to_multiarray,
)
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_TOPIC,
    DEPLOY_FORCE_SERVICE,
    DEPLOY_SERVICE,
    PARAMETERS_TOPIC,
    POSTURE_TOPIC,
    ROLLBACK_SERVICE,
    VERIFY_SERVICE,
)
from hexacal_msgs_py.node_parameters import parameter_descriptor
from hexacal_msgs_py.node_runtime import run_node, ShutdownLog
from hexacal_msgs_py.qos import PARAMETERS_QOS, POSTURE_QOS, STATUS_QOS
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from .identify_parameters import PARAMETERS
from ..session import (
    CalibrationSession,
    Level,
    Outcome,
    output_path,
    parameter_problem,
    PRIOR_PARAMETERS,
    Settings,
    SETTINGS_PARAMETERS,
)

# output_path: tests and tools import it from here (it lives in the session).
__all__ = ['IdentifyNode', 'main', 'NODE_NAME', 'output_path']

NODE_NAME = 'identify'
BUSY_MESSAGE = 'busy: a calibration is running'
BUSY_VERIFYING_MESSAGE = 'busy: a verification is running'
BUSY_DEPLOYING_MESSAGE = 'busy: a deploy or rollback is running'
INVALID_LOG_PERIOD_S = 5.0
PROGRESS_LOG_PERIOD_S = 5.0
# The report task lets the answer go out first: rendering holds the GIL in long stretches, and
# the executor thread that sends the response would wait for it (a few ms per switch).
REPORT_START_DELAY_S = 0.05


class _Publishers:
    """The session's StatusSink: the node's publishers."""

    def __init__(self, node: IdentifyNode) -> None:
        self._node = node

    def status(self, name: str, level: Level, message: str, values: dict[str, object]) -> None:
        """Publish a calibration or verification status on hexacal/calibration_status."""
        node = self._node
        node.status_pub.publish(
            diagnostic_status(
                level,
                name,
                message,
                values,
                hardware_id=node.get_fully_qualified_name(),
                stamp=node.get_clock().now().nanoseconds,
            )
        )

    def parameters(self, vector: Sequence[float] | np.ndarray, model: str) -> None:
        """Publish a calibrated vector on hexacal/parameters, transient local."""
        self._node.parameters_pub.publish(parameters_to_multiarray(vector, model))


class IdentifyNode(Node):
    """Posture store + calibration and verification services + transient-local result."""

    def __init__(self) -> None:
        """Declare the parameters, wire the session to the topics and services."""
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        for name, spec in PARAMETERS.items():  # settable at run time (read at each call)
            self.declare_parameter(
                name, spec.default, parameter_descriptor(name, spec, read_only=False)
            )
        self._busy = threading.Lock()
        self._busy_message = BUSY_MESSAGE  # what a call answers while _busy is held
        # One calibration or verification at a time, off the executor's threads.
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix='calibration')
        # The report of the latest calibration, written after the answer on a worker of its own.
        self._report_worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix='report')
        self._shutdown_log: ShutdownLog | None = None  # set while the node stops
        self.parameters_pub = self.create_publisher(
            Float64MultiArray, PARAMETERS_TOPIC, PARAMETERS_QOS
        )
        self.status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self.session = CalibrationSession(
            _Publishers(self),
            self.get_logger(),
            lambda: self._report_worker.submit(self._write_reports),
            self.resolve_service_name(CALIBRATE_SERVICE),
        )
        self.create_subscription(
            JointState,
            POSTURE_TOPIC,
            self._on_posture,
            POSTURE_QOS,
            callback_group=MutuallyExclusiveCallbackGroup(),
        )
        self.create_service(
            Trigger, CALIBRATE_SERVICE, self._on_calibrate, callback_group=ReentrantCallbackGroup()
        )
        self.create_service(
            Trigger, VERIFY_SERVICE, self._on_verify, callback_group=ReentrantCallbackGroup()
        )
        deployments: dict[str, Callable[[Settings], Outcome]] = {
            DEPLOY_SERVICE: lambda settings: self._deploy(settings, False),
            DEPLOY_FORCE_SERVICE: lambda settings: self._deploy(settings, True),
            ROLLBACK_SERVICE: self._rollback,
        }
        for service, run in deployments.items():
            self.create_service(
                Trigger,
                service,
                functools.partial(self._on_deployment, run),
                callback_group=ReentrantCallbackGroup(),
            )
        self.session.republish_saved(self.settings())
        self.session.announce_active(self.settings())
        self.get_logger().info(
            f'collecting postures on {self.resolve_topic_name(POSTURE_TOPIC)}; calibrate with '
            f'{self.resolve_service_name(CALIBRATE_SERVICE)}, verify with '
            f'{self.resolve_service_name(VERIFY_SERVICE)}'
        )

    # ------------------------------------------------------------------ parameters

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        def current(name: str, fallback: object) -> object:
            new = [p.value for p in parameters if p.name == name]
            if new:
                return new[0]
            return self.get_parameter(name).value if self.has_parameter(name) else fallback

        for parameter in parameters:
            problem = parameter_problem(parameter.name, parameter.value, current)
            if problem is not None:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def settings(self) -> Settings:
        """Return the parameters a calibration or verification reads, as they are now."""
        value = self.get_parameter
        return Settings(
            **{name: value(name).value for name in SETTINGS_PARAMETERS},
            device_prior={name: value(name).value for name in PRIOR_PARAMETERS},
        )

    # ------------------------------------------------------------------ postures

    def _on_posture(self, message: JointState) -> None:
        receipt = self.session.receive_posture(
            message.name,
            lambda model: joint_state_to_posture_reading(message, model),
            self.get_parameter('nominal').value,
        )
        if not receipt.stored:
            self.get_logger().warning(
                f'ignored an invalid posture ({receipt.rejected} so far): {receipt.rejection}',
                throttle_duration_sec=INVALID_LOG_PERIOD_S,
            )
            return
        self.get_logger().info(
            f'{receipt.count} postures received', throttle_duration_sec=PROGRESS_LOG_PERIOD_S
        )

    def posture_count(self) -> int:
        """Return the number of postures stored."""
        return len(self.session.postures)

    # ------------------------------------------------------------------ services

    def _on_calibrate(
        self, request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        return self._serve(response, self._calibrate, BUSY_MESSAGE)

    def _on_verify(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        return self._serve(response, self._verify, BUSY_VERIFYING_MESSAGE)

    def _on_deployment(
        self,
        run: Callable[[Settings], Outcome],
        request: Trigger.Request,
        response: Trigger.Response,
    ) -> Trigger.Response:
        return self._serve(response, run, BUSY_DEPLOYING_MESSAGE)

    def _serve(
        self,
        response: Trigger.Response,
        run: Callable[[Settings], Outcome],
        busy_message: str,
    ) -> Trigger.Response:
        """Answer at once 'busy' while a call runs, else run `run` on the worker and answer."""
        if not self._busy.acquire(blocking=False):
            response.success, response.message = False, self._busy_message
            return response
        self._busy_message = busy_message
        try:
            # The work runs on the worker (serialised); this executor thread only waits for it,
            # while the others keep receiving postures.
            outcome = self._worker.submit(run, self.settings()).result()
            response.success, response.message = outcome.success, outcome.message
        except Exception as error:  # noqa: BLE001 - a caller must always get an answer
            response.success = False
            response.message = f'internal-error: {type(error).__name__}: {error}'
        finally:
            self._busy_message = BUSY_MESSAGE
            self._busy.release()
        return response

    def _calibrate(self, settings: Settings) -> Outcome:
        outcome = self.session.calibrate(settings)
        # One call site per severity: rclpy refuses a severity change at the same line.
        if outcome.success:
            self._log().info(outcome.message)
        else:
            self._log().error(outcome.message)
        return outcome

    def _verify(self, settings: Settings) -> Outcome:
        outcome = self.session.verify(settings)
        if outcome.level == Level.OK:
            self._log().info(f'verification: {outcome.message}')
        else:
            self._log().warning(f'verification: {outcome.message}')
        return outcome

    def _deploy(self, settings: Settings, force: bool) -> Outcome:
        return self._logged('deploy', self.session.deploy(settings, force))

    def _rollback(self, settings: Settings) -> Outcome:
        return self._logged('rollback', self.session.rollback(settings))

    def _logged(self, what: str, outcome: Outcome) -> Outcome:
        if outcome.success:
            self._log().info(f'{what}: {outcome.message}')
        else:
            self._log().warning(f'{what}: {outcome.message}')
        return outcome

    def _write_reports(self) -> None:
        threading.Event().wait(REPORT_START_DELAY_S)  # let the answer go out first
        self.session.write_reports()

    def _log(self):
        """Return the node's logger, or while it stops the ShutdownLog that keeps the lines."""
        return self._shutdown_log or self.get_logger()

    def shutdown(self) -> list[tuple[str, str]]:
        """Finish the calibration under way, then the reports (written whole); their lines."""
        # What the workers log from now on is kept and logged once the node is destroyed: the
        # context may already be gone (a signal), and with it the rosout publisher.
        self._shutdown_log = ShutdownLog()
        self.session.use_log(self._shutdown_log)
        self._worker.shutdown(wait=True, cancel_futures=True)
        # After the calibration worker: a calibration that finished during shutdown queues its
        # report. The report under way and the latest one waiting are written whole.
        self._report_worker.shutdown(wait=True)
        return self._shutdown_log.lines


def _finish(node: IdentifyNode) -> list[tuple[str, str]]:
    return node.shutdown()  # a calibration under way finishes: its files are written whole


def main(args: list[str] | None = None) -> int:
    """Run the node until it is stopped."""
    # Several threads: a waiting service call must not block postures or a second call.
    return run_node(
        NODE_NAME,
        IdentifyNode,
        args=args,
        finish=_finish,
        make_executor=lambda: MultiThreadedExecutor(num_threads=4),
        startup_errors=(InvalidParameterValueException,),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
