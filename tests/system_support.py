"""Helpers of the hexacal system tests: a probe node, parameter files, postures, the CLI.

The probe joins the session's ROS domain (set by conftest.py before any context
exists) and spins only while a test waits on it, so every wait is a bounded
wait on a condition.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
import os
from pathlib import Path
import subprocess
import sys
import time
from typing import Any, TypeVar

import numpy as np
import pytest
from rosproc import RosProcess, venv_executable

T = TypeVar('T')

NODE_START_TIMEOUT_S = 30.0  # a node process appears on the graph (import + DDS discovery)
SERVICE_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 15.0
CLI_TIMEOUT_S = 300.0  # a calibration or a study in the CLI, with both cores busy


@dataclass
class Probe:
    """An rclpy node in the test process, in its own context, spun by its waits."""

    namespace: str = ''
    context: Any = None
    node: Any = None
    executor: Any = None
    postures: list = field(default_factory=list)
    posture_joint_names: list = field(default_factory=list)
    parameters: list = field(default_factory=list)
    statuses: list = field(default_factory=list)
    posture_subscriptions: list = field(default_factory=list)

    def __post_init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(
            'hexacal_test_probe', namespace=self.namespace or None, context=self.context
        )
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    # ------------------------------------------------------------------ waiting

    def spin_until(
        self,
        predicate: Callable[[], T],
        timeout: float,
        what: str,
        details: Callable[[], str] | None = None,
    ) -> T:
        """Spin until predicate() is truthy (returned); AssertionError naming `what` on timeout."""
        deadline = time.monotonic() + timeout
        while True:
            result = predicate()
            if result:
                return result
            if time.monotonic() >= deadline:
                message = f'timed out after {timeout:g} s waiting for {what}'
                if details is not None:
                    message += '\n' + details()
                raise AssertionError(message)
            self.executor.spin_once(timeout_sec=0.05)

    def spin_for(self, seconds: float) -> None:
        """Keep receiving for a fixed time: only to show that something does NOT arrive."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def wait_for_node(
        self,
        name: str,
        namespace: str = '/',
        process: RosProcess | None = None,
        timeout: float = NODE_START_TIMEOUT_S,
    ) -> None:
        def present() -> bool:
            if process is not None and not process.running():
                raise AssertionError(f'{name} exited early\n{process.describe()}')
            return (name, namespace) in self.node.get_node_names_and_namespaces()

        self.spin_until(
            present,
            timeout,
            f'node {namespace.rstrip("/")}/{name} on the graph',
            process.describe if process else None,
        )

    # ------------------------------------------------------------------ topics

    def subscribe_postures(self, topic: str = 'hexacal/posture', model: str | None = None) -> None:
        """Postures of `model` (default: the Hexa Slide's joints) are appended to self.postures;
        the joint names of every message to self.posture_joint_names."""
        from hexacal_msgs_py.conversions import joint_state_to_posture_reading
        from hexacal_msgs_py.qos import POSTURE_QOS
        from sensor_msgs.msg import JointState

        def on_posture(message: JointState) -> None:
            self.posture_joint_names.append(tuple(message.name))
            self.postures.append(joint_state_to_posture_reading(message, model))

        self.posture_subscriptions.append(
            self.node.create_subscription(JointState, topic, on_posture, POSTURE_QOS)
        )

    def wait_for_posture_publisher(self, timeout: float = 30.0) -> None:
        """
        Wait until the posture subscriptions are matched with a publisher (the collector's).

        The posture topic is volatile: a posture published before discovery matched the two
        (seconds on a loaded machine) never reaches this probe.
        """
        self.spin_until(
            lambda: all(s.get_publisher_count() >= 1 for s in self.posture_subscriptions),
            timeout,
            'a posture publisher matched with the probe',
        )

    def subscribe_parameters(self, topic: str = 'hexacal/parameters') -> list:
        """A new transient-local subscription; returns the list its vectors are appended to."""
        from hexacal_msgs_py.conversions import multiarray_to_parameters
        from hexacal_msgs_py.qos import PARAMETERS_QOS
        from std_msgs.msg import Float64MultiArray

        received: list[np.ndarray] = []

        def on_parameters(message: Float64MultiArray) -> None:
            vector = multiarray_to_parameters(message)
            received.append(vector)
            self.parameters.append(vector)

        self.node.create_subscription(Float64MultiArray, topic, on_parameters, PARAMETERS_QOS)
        return received

    def subscribe_status(self, topic: str = 'hexacal/calibration_status') -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from hexacal_msgs_py.conversions import status_values
        from hexacal_msgs_py.qos import STATUS_MONITOR_QOS

        def on_status(message: DiagnosticArray) -> None:
            for status in message.status:
                self.statuses.append(
                    (
                        int.from_bytes(status.level, 'little')
                        if isinstance(status.level, bytes)
                        else int(status.level),
                        status.message,
                        status_values(status),
                    )
                )

        self.node.create_subscription(DiagnosticArray, topic, on_status, STATUS_MONITOR_QOS)

    def postures_received_by_identify(self) -> int:
        """The count in identify's latest 'collecting' status (0 before any)."""
        counts = [
            int(values['postures_received'])
            for _, _, values in self.statuses
            if values.get('outcome') == 'collecting'
        ]
        return counts[-1] if counts else 0

    def publish_postures(
        self,
        postures: Sequence,
        topic: str = 'hexacal/posture',
        subscribers: int = 1,
        model: str | None = None,
    ) -> None:
        """Publish postures (with `model`'s joint names, default the Hexa Slide's) once
        `subscribers` subscriptions (besides ours) are matched."""
        from hexacal_msgs_py.conversions import posture_reading_to_joint_state
        from hexacal_msgs_py.qos import POSTURE_QOS
        from sensor_msgs.msg import JointState

        publisher = self.node.create_publisher(JointState, topic, POSTURE_QOS)
        own = (
            1 if any(s.topic_name == publisher.topic_name for s in self.node.subscriptions) else 0
        )
        self.spin_until(
            lambda: publisher.get_subscription_count() >= subscribers + own,
            NODE_START_TIMEOUT_S,
            f'{subscribers} subscriber(s) on {topic}',
        )
        for posture in postures:
            publisher.publish(posture_reading_to_joint_state(posture, model=model))

    # ------------------------------------------------------------------ services

    def call_trigger(self, service: str = 'hexacal/calibrate', timeout: float = SERVICE_TIMEOUT_S):
        future = self.trigger_async(service)
        return self.spin_until(
            lambda: future.result() if future.done() else None,
            timeout,
            f'the response of {service}',
        )

    def trigger_async(self, service: str = 'hexacal/calibrate'):
        from std_srvs.srv import Trigger

        client = self.node.create_client(Trigger, service)
        self.spin_until(client.service_is_ready, NODE_START_TIMEOUT_S, f'service {service}')
        return client.call_async(Trigger.Request())


@pytest.fixture
def probe():
    """An in-process node in the default namespace; closed at teardown."""
    node = Probe()
    try:
        yield node
    finally:
        node.close()


# --------------------------------------------------------------------------- the CLI


def hexacal(
    *args: object,
    timeout: float = CLI_TIMEOUT_S,
    cwd: Path | str | None = None,
    script: bool = False,
) -> subprocess.CompletedProcess:
    """
    Run the hexacal CLI in a subprocess of the venv, as a user does; output captured as text.

    By default ``python -m hexacal_identify.cli`` with this interpreter; ``script=True`` runs
    the installed ``hexacal`` console script instead, so that its entry point is tested too.
    Arguments are passed through str().
    """
    program = (
        [venv_executable('hexacal')]
        if script
        else [sys.executable, '-m', 'hexacal_identify.cli']
    )
    return subprocess.run(
        [*program, *map(str, args)], capture_output=True, text=True, timeout=timeout, cwd=cwd
    )


def hexacal_plan(out: Path, nominal: Path, *options: object, timeout: float = 120.0) -> Path:
    """Write `out` with ``hexacal plan OPTIONS --nominal NOMINAL --out OUT`` (console script)."""
    result = hexacal(
        'plan', *options, '--nominal', nominal, '--out', out, timeout=timeout, script=True
    )
    assert result.returncode == 0, result.stderr
    return out


# --------------------------------------------------------------------------- data


def write_parameter_files(directory: Path, model: str | None = None) -> tuple[Path, Path]:
    """(truth, nominal set 2 seed 0) as parameters YAML in directory.

    The truth is Table 1 (the default) or the default machine of `model`
    (written with its ``model`` key, as is the nominal set).
    """
    from hexacal_identify.core.architectures import default_parameters
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_msgs_py.parameters_file import save_parameters

    if model in (None, 'hexa_slide'):
        true_path, nominal_path = directory / 'true_table1.yaml', directory / 'nominal_set2.yaml'
    else:
        true_path = directory / f'true_{model}.yaml'
        nominal_path = directory / f'nominal_set2_{model}.yaml'
    save_parameters(true_path, default_parameters(model).vector, model=model)
    save_parameters(nominal_path, nominal_set(2, seed=0, model=model).vector, model=model)
    return true_path, nominal_path


def simulated_postures(
    count: int, seed: int = 0, noise_um: float = 10.0, model: str | None = None
) -> list:
    """PostureReadings of sphere postures on the Table 1 machine (or the default machine of
    `model`, in its default workspace) (core simulation)."""
    from hexacal_identify.core.architectures import architecture
    from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
    from hexacal_identify.core.machine.postures import sample_poses
    from hexacal_msgs_py.readings import PostureReading

    rng = np.random.default_rng([seed, 42])
    truth = architecture(model).default_parameters()
    poses = sample_poses(truth, count, rng, 'sphere', architecture(model).default_workspace())
    data = simulate_measurements(
        truth, poses, 'sphere', noise=NoiseModel.from_microns(noise_um), rng=rng
    )
    return [
        PostureReading.from_values(
            1_000_000_000 * (i + 1),
            [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]],
        )
        for i in range(count)
    ]


def node_argv(executable: str, parameters: dict[str, object], namespace: str = '') -> list[str]:
    """argv of a console script with --ros-args, as bringup builds it."""
    from hexacal_identify.bringup.launch_spec import NodeLaunch

    launch = NodeLaunch(executable, parameters, namespace)
    argv = launch.command()
    argv[0] = venv_executable(executable)
    return argv


def fast_driver_parameters(**overrides: object) -> dict[str, object]:
    """A driver that walks a posture every 1.0 s (collector: fast_collector_parameters)."""
    parameters: dict[str, object] = {
        'plan': 'mixed',
        'rate_hz': 100.0,
        'settle_s': 0.3,
        'dwell_s': 0.7,
    }
    parameters.update(overrides)
    return parameters


def fast_collector_parameters(output_dir: Path, **overrides: object) -> dict[str, object]:
    """Detector window 0.2 s + capture 0.3 s: fits the fast driver's 0.7 s dwell."""
    parameters: dict[str, object] = {
        'output_dir': str(output_dir),
        'window_s': 0.2,
        'capture_s': 0.3,
    }
    parameters.update(overrides)
    return parameters


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # A zombie (exited, not yet reaped by its parent) counts as gone.
    try:
        return Path(f'/proc/{pid}/stat').read_text().split(') ')[1][0] != 'Z'
    except (OSError, IndexError):
        return True


def joint_state_dict(stamp_ns: int, names, positions) -> dict:
    """A sensor_msgs/JointState as the bag writer takes it."""
    return {
        'header': {
            'stamp': {'sec': stamp_ns // 10**9, 'nanosec': stamp_ns % 10**9},
            'frame_id': '',
        },
        'name': list(names),
        'position': [float(v) for v in positions],
        'velocity': [],
        'effort': [],
    }


def posture_bag(directory: Path, rows: list[list[float]]) -> Path:
    """A bag holding only /hexacal/posture, one message per row (nine values, any floats)."""
    from hexacal_identify.bag import BagWriter
    from hexacal_msgs_py.names import JOINT_STATE_TYPE, POSTURE_NAMES, POSTURE_TOPIC

    with BagWriter(directory) as writer:
        topic = '/' + POSTURE_TOPIC  # as the collector records it
        writer.add_topic(topic, JOINT_STATE_TYPE)
        for index, row in enumerate(rows):
            stamp = (index + 1) * 10**9
            writer.write(topic, joint_state_dict(stamp, POSTURE_NAMES, row), stamp)
    return directory
