"""
The demo's view of the running system: one rclpy node that watches it and calls its services.

The nodes themselves run as child processes of bringup's supervisor (NodeGroup); ``DemoSession``
is the operator's console beside them, what ``ros2 topic echo`` and ``ros2 service call`` would
be: it counts the postures, follows every status (executor, identify, the simulated drives),
calls ``hexacal/calibrate`` and ``hexacal/verify`` and receives the parameters. ``walk`` starts an
executor on a plan, shows its progress and waits until the plan is walked; a drive fault, a
paused or refused plan or a node that exits stops the demo with a DemoError naming it.
"""

from __future__ import annotations

from pathlib import Path
import sys
import time
from typing import Callable, TYPE_CHECKING

from .demo import DemoError
from .demo_refinement import refined_at, RestLog
from ..bringup.system import executor_takes_measuring_mode

if TYPE_CHECKING:  # numpy and the process launcher are imported where the demo runs
    import numpy as np

    from ..bringup.launch_spec import NodeLaunch
    from ..bringup.supervisor import NodeGroup, RunningNode

GRAPH_TIMEOUT_S = 30.0
CALIBRATE_TIMEOUT_S = 300.0
DRIVE_FAULT_NOTICE = 'the drive faulted: '  # how the executor's notice names a drive fault


def walk(
    session: DemoSession,
    group: NodeGroup,
    executor_launch: NodeLaunch,
    label: str,
    env: dict,
    log: Path,
    mode: str,
) -> int:
    """
    Start the executor of ``executor_launch``, show its progress, wait until done.

    Return the postures measured. ``label`` names the plan (calibration, verification),
    ``mode`` the measuring mode the demo asked for (named when the drives fault).
    """
    from tqdm import tqdm

    from ..core.planning.planner import Plan

    total = len(Plan.load(executor_launch.parameters['plan']))
    session.executor_values = {}
    session.walk_label = label
    session.walk_nominal = Path(str(executor_launch.parameters['nominal']))
    executor = group.start(executor_launch, env, log)
    interactive = sys.stderr.isatty()
    bar = tqdm(
        total=total,
        desc=f'{label} postures',
        unit='posture',
        file=sys.stderr,
        disable=not interactive,
    )
    shown = 0

    def progress():
        nonlocal shown
        values = session.executor_values
        count = min(
            int(values.get('measured', 0) or 0) + int(values.get('skipped', 0) or 0), total
        )
        if count > shown:
            bar.update(count - shown)
            if not interactive and (count % 10 == 0 or count == total):
                print(f'{label} postures: {count}/{total}', flush=True)
            shown = count
        state = values.get('state')
        if state in ('refused', 'aborted'):
            raise DemoError(f'the executor {state} the {label} plan: {values}')
        if state == 'paused':
            # Paused by itself (its guard, a refused release, the drive's fault it heard first):
            # nobody here would resume it.
            what = f'the executor to walk the {label} plan'
            session.check_drives(what)
            notice = values.get('notice') or str(values)
            if notice.startswith(DRIVE_FAULT_NOTICE):
                faulted = session.driver_values.get('measuring_mode') or mode
                raise DemoError(
                    f'the simulated drives faulted ({faulted}) while waiting for {what}: '
                    f'{notice[len(DRIVE_FAULT_NOTICE):]}'
                )
            raise DemoError(f'the executor paused the {label} plan: {notice}')
        return values if state == 'done' else None

    try:
        # The executor may take its own timeout_s per posture before it skips one: wait as long.
        per_posture_s = float(executor_launch.parameters.get('timeout_s', 30.0))
        done = session.wait(
            f'the executor to walk the {label} plan', 60.0 + per_posture_s * total, group, progress
        )
    finally:
        bar.close()
    stop(group, executor)  # the next plan gets an executor of its own
    skipped = int(done.get('skipped', 0) or 0)
    if skipped:
        print(f'hexacal demo: {skipped} {label} posture(s) skipped: see {log}', flush=True)
    return int(done.get('measured', 0) or 0)


def stop(group: NodeGroup, node: RunningNode) -> None:
    """Stop one node of the group; warn when it exits with an error."""
    code = group.stop_node(node, 10.0)
    if code != 0:
        print(f'hexacal demo: warning: {node.name} exited with {code}', file=sys.stderr)


def log_tail(node: RunningNode, lines: int = 15) -> str:
    """Return the last lines of a node's log, headed by its name and path ('' without one)."""
    if node.log_file is None:
        return ''
    path = Path(node.log_file.name)
    node.log_file.flush()
    text = path.read_text(errors='replace').splitlines()[-lines:]
    return f'--- {node.name} ({path}) ---\n' + '\n'.join(text)


class DemoSession:
    """The demo's rclpy node: watches postures and statuses, calls the services."""

    def __init__(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from hexacal_msgs_py.names import (
            CALIBRATE_SERVICE,
            CALIBRATION_STATUS_TOPIC,
            PARAMETERS_TOPIC,
            POSTURE_TOPIC,
            VERIFY_SERVICE,
        )
        from hexacal_msgs_py.qos import PARAMETERS_QOS, POSTURE_QOS, STATUS_MONITOR_QOS
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        from std_srvs.srv import Trigger

        self.context = Context()
        # Python keeps SIGINT: Ctrl-C raises KeyboardInterrupt and the children are stopped.
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('hexacal_demo', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.postures = 0  # seen here
        self.identify_postures = 0  # received by identify, from its status
        self.verification_postures = (
            0  # received by identify since the calibration, from its status
        )
        self.executor_values: dict[str, str] = {}  # the executor's latest status
        self.verification_values: dict[str, str] = {}  # identify's latest verification status
        self.fit_values: dict[str, str] = {}  # identify's latest status with a fit's adequacy
        self.driver_values: dict[str, str] = {}  # the simulated drives' latest status
        self.driver_statuses = 0  # driver statuses received (a fresh one: the count grows)
        self.parameters: np.ndarray | None = None
        # The drives' rests, tagged with the model the targets came from (demo_refinement.py).
        self.rest_log = RestLog()
        self.walk_label = ''  # the plan walked: calibration, verification
        self.walk_nominal: Path | None = None  # the executor's nominal file for that plan
        self.nominal_file: Path | None = None  # the demo's nominal model (set by _run)
        self.targets_models: list[str] = []  # the calibration walk's targets_model values
        self._trigger = Trigger
        self.node.create_subscription(JointState, POSTURE_TOPIC, self._on_posture, POSTURE_QOS)
        self.node.create_subscription(
            Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters, PARAMETERS_QOS
        )
        self.node.create_subscription(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, self._on_status, STATUS_MONITOR_QOS
        )
        self.client = self.node.create_client(Trigger, CALIBRATE_SERVICE)
        self.verify_client = self.node.create_client(Trigger, VERIFY_SERVICE)
        self.posture_topic = self.node.resolve_topic_name(POSTURE_TOPIC)

    def _on_posture(self, message) -> None:
        self.postures += 1

    def _on_status(self, message) -> None:
        from hexacal_msgs_py.conversions import status_values
        from hexacal_msgs_py.names import (
            DRIVER_STATUS_NAME,
            EXECUTOR_STATUS_NAME,
            VERIFICATION_STATUS_NAME,
        )

        for status in message.status:
            values = status_values(status)
            if status.name == EXECUTOR_STATUS_NAME:
                self.executor_values = values
                model = values.get('targets_model', '')
                if self.walk_label == 'calibration' and model and (
                    not self.targets_models or self.targets_models[-1] != model
                ):
                    self.targets_models.append(model)
            elif status.name == DRIVER_STATUS_NAME:
                self.driver_values = values
                self.driver_statuses += 1
                self.rest_log.hear(values, self.targets_refined())
            elif status.name == VERIFICATION_STATUS_NAME:
                self.verification_values = values
            elif values.get('outcome') == 'collecting':
                self.identify_postures = int(values.get('postures_received', 0))
                self.verification_postures = int(values.get('verification_postures', 0) or 0)
            if status.name != VERIFICATION_STATUS_NAME and 'adequacy.verdict' in values:
                self.fit_values = values

    def _on_parameters(self, message) -> None:
        from hexacal_msgs_py.conversions import multiarray_to_parameters

        self.parameters = multiarray_to_parameters(message)

    def targets_refined(self) -> bool:
        """Return whether the executor's targets now come from a calibration, not nominal."""
        if self.walk_nominal is not None and self.walk_nominal != self.nominal_file:
            return True  # the verification plan on the calibration's targets
        return refined_at(self.executor_values.get('targets_model', '')) is not None

    def graph_ready(self) -> bool:
        # The collector publishes postures and identify receives them (as this node does).
        return (
            self.node.count_publishers(self.posture_topic) >= 1
            and self.node.count_subscribers(self.posture_topic) >= 2
            and self.client.service_is_ready()
        )

    def wait(self, what: str, timeout_s: float, group: NodeGroup, condition: Callable[[], object]):
        deadline = time.monotonic() + timeout_s
        while True:
            result = condition()
            if result is not None and result is not False:
                return result
            self.check_drives(what)
            exited = group.exited()
            if exited:
                node = exited[0]
                raise DemoError(
                    f'{node.name} exited with {node.popen.returncode} while waiting '
                    f'for {what}\n{log_tail(node)}'
                )
            if time.monotonic() > deadline:
                raise DemoError(f'timed out after {timeout_s:.0f} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.1)

    def check_drives(self, what: str) -> None:
        """Raise DemoError when the simulated drives are in fault: they hold, nothing moves."""
        values = self.driver_values
        if values.get('state') != 'fault':
            return
        mode = values.get('measuring_mode', '?')
        hint = ''
        if mode != 'compliant' and not executor_takes_measuring_mode():
            hint = (
                f'; the executor of this install commands all six actuators and does not drive '
                f'{mode} yet: try --measuring-mode compliant'
            )
        raise DemoError(
            f'the simulated drives faulted ({mode}) while waiting for {what}: '
            f'{values.get("fault") or "no reason given"}{hint}'
        )

    def fresh_driver_values(self, group: NodeGroup) -> dict[str, str]:
        """Return the driver's status values from a status received from now on (at rest)."""
        seen = self.driver_statuses
        return self.wait(
            'a fresh status of the simulated drives',
            GRAPH_TIMEOUT_S,
            group,
            lambda: self.driver_values if self.driver_statuses > seen else None,
        )

    def calibrate(self, group: NodeGroup) -> tuple[bool, str]:
        future = self.client.call_async(self._trigger.Request())
        response = self.wait(
            'the hexacal/calibrate response',
            CALIBRATE_TIMEOUT_S,
            group,
            lambda: future.result() if future.done() else None,
        )
        return bool(response.success), str(response.message)

    def verify(self, group: NodeGroup) -> dict[str, str]:
        """Call hexacal/verify; the verification status once its report section is written."""
        self.verification_values = {}
        future = self.verify_client.call_async(self._trigger.Request())
        response = self.wait(
            'the hexacal/verify response',
            CALIBRATE_TIMEOUT_S,
            group,
            lambda: future.result() if future.done() else None,
        )

        def figures():
            values = self.verification_values
            if values.get('outcome') == 'verified':
                return values if values.get('report_state') != 'writing' else None
            if values.get('outcome'):  # a refusal (no calibration, no postures since)
                raise DemoError(f'hexacal/verify refused: {response.message}')
            return None

        return self.wait('the verification figures', 60.0, group, figures)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
