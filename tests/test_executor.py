"""The executor walks a plan on the commanded simulated machine (real nodes, real processes).

The driver stands in for a real machine behind ros2_control's joint_trajectory_controller:
JointTrajectory commands in on /joint_trajectory_controller/joint_trajectory, the three sensor
streams out. The plan comes from `hexacal plan` (O1) written in each test.
"""

from __future__ import annotations

from pathlib import Path
import subprocess

from hexacal_identify.core.architectures import parameters_for
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.planning.planner import Plan
from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC, EXECUTOR_STATUS_NAME
from hexacal_msgs_py.parameters_file import read_parameters_file
import numpy as np
import pytest
from system_support import (
    fast_collector_parameters,
    hexacal_plan,
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)

COMMAND_TOPIC = DEFAULT_COMMAND_TOPIC
GS = 'gough_stewart'
# A quick machine and executor: moves at up to 1 m/s (driver) / 0.5 m/s (executor), 0.3 s settle
# with the two inclinometer windows within it, as the defaults are within the default settle_s:
# a fixed position is judged before the fast collector's posture of the stop, so a correction
# interrupts its capture and the stop gives one posture (not one before, one after).
FAST_EXECUTOR = {
    'max_actuator_speed_m_s': 0.5,
    'settle_s': 0.3,
    'timeout_s': 30.0,
    'inclinometer_settle_s': 0.15,
}


def _plan(tmp_path: Path, nominal: Path, postures: int, name: str = 'plan.yaml') -> Path:
    return hexacal_plan(
        tmp_path / name,
        nominal,
        '--postures',
        postures,
        '--index',
        'O1',
        '--cost',
        'sphere-fixed',
        '--candidates',
        500,
    )


def _driver(truth: Path, **overrides) -> list[str]:
    parameters = {
        'command_topic': COMMAND_TOPIC,
        'true_params': str(truth),
        'max_actuator_speed_m_s': 1.0,
        'slider_noise_m': 1e-5,
        'angle_noise_rad': 1e-5,
    }
    parameters.update(overrides)
    return node_argv('driver', parameters)


def _executor(plan: Path, nominal: Path, *extra: str, **overrides) -> list[str]:
    parameters = {'plan': str(plan), 'nominal': str(nominal), **FAST_EXECUTOR, **overrides}
    argv = node_argv('executor', parameters)
    for item in extra:  # list-valued parameters, spelled as YAML
        argv += ['-p', item]
    return argv


class ExecutorWatch:
    """The executor's statuses and the commands on the command topic, as the probe receives them."""

    def __init__(self, probe) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from hexacal_msgs_py.conversions import status_values
        from hexacal_msgs_py.qos import COMMAND_QOS, STATUS_MONITOR_QOS
        from trajectory_msgs.msg import JointTrajectory

        self.probe = probe
        self.statuses: list[tuple[int, str, dict[str, str]]] = []
        self.commands: list = []

        def on_status(message: DiagnosticArray) -> None:
            for status in message.status:
                if status.name == EXECUTOR_STATUS_NAME:
                    level = (
                        status.level[0] if isinstance(status.level, bytes) else int(status.level)
                    )
                    self.statuses.append((level, status.message, status_values(status)))

        probe.node.create_subscription(
            DiagnosticArray, 'hexacal/calibration_status', on_status, STATUS_MONITOR_QOS
        )
        probe.node.create_subscription(
            JointTrajectory, COMMAND_TOPIC, self.commands.append, COMMAND_QOS
        )

    @property
    def latest(self) -> dict[str, str]:
        return self.statuses[-1][2] if self.statuses else {}

    def wait(self, predicate, timeout: float, what: str, *processes):
        def check():
            for process in processes:
                if not process.running():
                    raise AssertionError(f'a node exited early\n{process.describe()}')
            return predicate(self.latest) if self.statuses else None

        return self.probe.spin_until(
            check,
            timeout,
            what,
            lambda: (
                f'latest executor status: {self.statuses[-1] if self.statuses else None}\n'
                + '\n'.join(p.describe(15) for p in processes)
            ),
        )


def _machine_and_collector(
    ros_processes, probe, tmp_path, truth, nominal, driver=None, bag_name='executor', **collector
):
    """Start the driver (`driver`: its overrides) and the fast collector; wait for both."""
    driver_process = ros_processes.start(_driver(truth, **(driver or {})))
    collector_process = ros_processes.start(
        node_argv(
            'collector',
            fast_collector_parameters(
                tmp_path / 'bags', bag_name=bag_name, parameters_file=str(nominal), **collector
            ),
        )
    )
    probe.wait_for_node('driver', process=driver_process)
    probe.wait_for_node('collector', process=collector_process)
    return driver_process, collector_process


# --------------------------------------------------------------------------- (a) end to end


def _walk_to_a_calibration(ros_processes, tmp_path, probe, model, postures):
    truth_path, nominal_path = write_parameter_files(tmp_path, model)
    plan = _plan(tmp_path, nominal_path, postures)
    watch = ExecutorWatch(probe)
    published = probe.subscribe_parameters()
    identify = ros_processes.start(
        # No HTML report: it is not what this test checks, and on a loaded machine its rendering
        # outlasts the stop timeout (a stopping node finishes the report under way).
        node_argv(
            'identify',
            {'nominal': str(nominal_path), 'output_dir': str(tmp_path / 'out'), 'report_dir': ''},
        )
    )
    probe.wait_for_node('identify', process=identify)
    driver, collector = _machine_and_collector(
        ros_processes, probe, tmp_path, truth_path, nominal_path
    )
    executor = ros_processes.start(_executor(plan, nominal_path, calibrate_when_done=True))
    nodes = (driver, collector, identify, executor)
    done = watch.wait(
        lambda s: s.get('calibration') in ('success', 'failed') and s,
        30.0 + 4.0 * postures + 60.0,
        'the plan walked and calibrated',
        *nodes,
    )
    assert done['calibration'] == 'success', done
    assert (
        done['state'] == 'done' and done['measured'] == str(postures) and done['skipped'] == '0'
    ), {k: v for k, v in done.items() if 'skip' in k or k in ('measured', 'state')}
    assert int(done['corrections']) >= 1  # fixed-position postures were reached in closed loop
    assert watch.statuses[-1][0] == 0  # OK
    assert 'converged' in done['calibration_message']
    calibrated = probe.spin_until(lambda: published, 10.0, 'hexacal/parameters')[-1]

    truth_file, nominal_file = read_parameters_file(truth_path), read_parameters_file(nominal_path)
    truth = parameters_for(truth_file.model, truth_file.vector)
    nominal = parameters_for(nominal_file.model, nominal_file.vector)
    error = np.abs(calibrated - truth.vector).max()
    poses = validation_poses(truth, 50, seed=0)
    before = pose_errors(truth, nominal, poses).summary()
    after = pose_errors(truth, truth.with_vector(calibrated), poses).summary()
    log = executor.log_text()
    assert 'plan done in' in log and 'Traceback' not in log
    for process in (executor, driver, collector, identify):
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
    assert len(watch.commands) >= postures  # one per posture, more for the corrections
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    recorded = postures_from_bag(tmp_path / 'bags' / 'executor')
    # The collector records a posture at each stop: the one before the first move, the plan's
    # postures and those of the corrections it saw as moves (how many depends on timing).
    assert postures <= len(recorded.postures) <= len(watch.commands) + 1
    return error, before, after, done


@pytest.mark.slow
def test_executor_walks_an_o1_plan_on_the_commanded_machine_to_a_good_calibration(
    ros_processes, tmp_path, probe
):
    error, before, after, done = _walk_to_a_calibration(ros_processes, tmp_path, probe, None, 20)
    assert error < 1e-3, f'max parameter error {error * 1e3:.3f} mm'  # ~0.08 mm
    assert before['position_mean_m'] > 1e-3, before  # millimetres before
    assert after['position_max_m'] < 100e-6, after  # ~5 um mean, ~13 um max after
    assert after['failed_postures'] == 0
    print(
        f'\n20 postures in {done["elapsed_s"]} s, {done["corrections"]} corrections; max parameter '
        f'error {error * 1e3:.3f} mm; validation position error mean '
        f'{after["position_mean_m"] * 1e6:.1f} um (before {before["position_mean_m"] * 1e6:.0f} um)'
    )


@pytest.mark.slow
def test_executor_calibrates_a_gough_stewart_platform(ros_processes, tmp_path, probe):
    error, before, after, done = _walk_to_a_calibration(ros_processes, tmp_path, probe, GS, 16)
    assert error < 2e-3, f'max parameter error {error * 1e3:.3f} mm'
    assert before['position_mean_m'] > 1e-3, before
    assert after['position_max_m'] < 200e-6, after
    print(
        f'\nGough-Stewart: 16 postures in {done["elapsed_s"]} s; max parameter error '
        f'{error * 1e3:.3f} mm; validation position error mean '
        f'{after["position_mean_m"] * 1e6:.1f} um (before {before["position_mean_m"] * 1e6:.0f} um)'
    )


# --------------------------------------------------------------------------- (b) pause, resume, abort


@pytest.mark.slow
def test_pause_resume_and_abort_through_the_services(ros_processes, tmp_path, probe):
    truth, nominal = write_parameter_files(tmp_path)
    plan = _plan(tmp_path, nominal, 12)
    watch = ExecutorWatch(probe)
    driver, collector = _machine_and_collector(ros_processes, probe, tmp_path, truth, nominal)
    executor = ros_processes.start(_executor(plan, nominal))
    nodes = (driver, collector, executor)
    watch.wait(
        lambda s: s.get('state') == 'running' and int(s['measured']) >= 1,
        60.0,
        'the first posture measured',
        *nodes,
    )

    response = probe.call_trigger('hexacal/executor/pause')
    assert response.success and 'paused at posture' in response.message, response.message
    paused = watch.wait(lambda s: s.get('state') == 'paused' and s, 10.0, 'state paused', *nodes)
    assert paused['eta_s']  # an ETA is still reported
    if 'the move under way ends at its target' not in response.message:
        # At rest: the hold is one point, the drive's setpoints (the moves have many).
        probe.spin_until(
            lambda: watch.commands and len(watch.commands[-1].points) == 1,
            10.0,
            'the hold command',
        )
    commands_when_paused = len(watch.commands)
    probe.spin_for(2.0)  # paused: no posture is finished, nothing more is commanded
    assert watch.latest['measured'] == paused['measured'] and watch.latest['state'] == 'paused'
    assert len(watch.commands) == commands_when_paused

    response = probe.call_trigger('hexacal/executor/resume')
    assert response.success and 'resumed at posture' in response.message
    measured = int(paused['measured'])
    resumed = watch.wait(
        lambda s: s.get('state') == 'running' and int(s['measured']) > measured and s,
        60.0,
        'a posture measured after resuming',
        *nodes,
    )
    assert int(resumed['posture']) > measured

    response = probe.call_trigger('hexacal/executor/abort')
    assert response.success and response.message.startswith('aborted at posture')
    aborted = watch.wait(
        lambda s: s.get('state') == 'aborted' and s, 10.0, 'state aborted', *nodes
    )
    assert watch.statuses[-1][0] == 1  # WARN
    assert int(aborted['measured']) < 12
    after_abort = len(watch.commands)
    assert not probe.call_trigger('hexacal/executor/resume').success  # aborted is final
    assert not probe.call_trigger('hexacal/executor/abort').success
    probe.spin_for(1.5)
    assert len(watch.commands) == after_abort  # nothing is commanded after the abort's hold
    assert ros_processes.stop(executor, STOP_TIMEOUT_S) == 0, executor.log_text()
    assert 'aborted at posture' in executor.log_path.read_text()


# --------------------------------------------------------------------------- (c) stroke refused


@pytest.mark.slow
def test_a_plan_outside_the_stroke_is_refused_and_nothing_is_published(
    ros_processes, tmp_path, probe
):
    truth, nominal = write_parameter_files(tmp_path)
    plan = _plan(tmp_path, nominal, 12)
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(_driver(truth))
    probe.wait_for_node('driver', process=driver)
    # The Hexa Slide's stroke is [0, 0.9] m; this plan needs sliders beyond 0.35 m.
    executor = ros_processes.start(_executor(plan, nominal, 'stroke_limits_m:=[0.0, 0.35]'))
    refused = watch.wait(
        lambda s: s.get('state') == 'refused' and s, 30.0, 'the refusal', driver, executor
    )
    assert watch.statuses[-1][0] == 2  # ERROR
    assert refused['refused_postures'] and 'outside the stroke [0, 0.35] m' in refused['reason']
    assert refused['commands_sent'] == '0'
    # The executor's command publisher is matched with the probe (and the driver) - and silent.
    probe.spin_until(
        lambda: probe.node.count_publishers(COMMAND_TOPIC) >= 1,
        10.0,
        "the executor's command publisher",
    )
    probe.spin_for(2.0)
    assert watch.commands == []
    assert not probe.call_trigger('hexacal/executor/resume').success
    assert ros_processes.stop(executor, STOP_TIMEOUT_S) == 0
    log = executor.log_path.read_text()
    assert 'plan refused before anything moved' in log and 'postures [' in log
    assert 'commands: 0 followed' in _stop_log(ros_processes, driver)


def test_a_refused_plan_exits_2_with_shutdown_when_done(tmp_path):
    truth, nominal = write_parameter_files(tmp_path)
    plan = _plan(tmp_path, nominal, 12)
    result = subprocess.run(
        _executor(plan, nominal, 'stroke_limits_m:=[0.0, 0.35]', shutdown_when_done=True),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert 'cannot start: plan refused before anything moved' in result.stdout + result.stderr


# --------------------------------------------------------------------------- (d) not reached


@pytest.mark.slow
def test_a_posture_the_machine_never_reaches_is_skipped_and_reported(
    ros_processes, tmp_path, probe
):
    truth, nominal = write_parameter_files(tmp_path)
    full = Plan.load(_plan(tmp_path, nominal, 12))
    short = Plan(
        'two-postures', full.link_length, full.poses[:2], full.kinds[:2], model=full.model
    )
    plan = short.save(tmp_path / 'two.yaml')
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(_driver(truth, max_actuator_speed_m_s=1e-4))  # 0.1 mm/s
    probe.wait_for_node('driver', process=driver)
    executor = ros_processes.start(_executor(plan, nominal, timeout_s=1.0, wait_for_posture=False))
    done = watch.wait(
        lambda s: s.get('state') == 'done' and s, 30.0, 'the plan to end', driver, executor
    )
    assert done['measured'] == '0' and done['skipped'] == '2'
    assert done['skipped_postures'].startswith('1: not at the target and still within 1 s')
    assert '; 2: not at the target' in done['skipped_postures']
    assert watch.statuses[-1][0] == 1  # WARN
    assert ros_processes.stop(executor, STOP_TIMEOUT_S) == 0
    log = executor.log_path.read_text()
    assert f'posture 1 of 2 ({short.kinds[0]}) skipped: not at the target' in log


# --------------------------------------------------------------------------- (e) the commanded driver


def test_the_commanded_driver_follows_a_joint_trajectory_at_bounded_speed(ros_processes, probe):
    from builtin_interfaces.msg import Duration
    from hexacal_identify.core.architectures import default_parameters
    from hexacal_identify.core.machine.kinematics import inverse_kinematics
    from hexacal_msgs_py.qos import COMMAND_QOS, SENSOR_QOS
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    speed = 0.05
    driver = ros_processes.start(
        node_argv(
            'driver',
            {
                'command_topic': COMMAND_TOPIC,
                'max_actuator_speed_m_s': speed,
                'slider_noise_m': 0.0,
                'angle_noise_rad': 0.0,
            },
        )
    )
    readings: list[tuple[float, np.ndarray]] = []

    def on_sliders(message: JointState) -> None:
        stamp = message.header.stamp.sec + message.header.stamp.nanosec * 1e-9
        readings.append((stamp, np.array(message.position)))

    probe.node.create_subscription(JointState, 'hexacal/sliders', on_sliders, SENSOR_QOS)
    publisher = probe.node.create_publisher(JointTrajectory, COMMAND_TOPIC, COMMAND_QOS)
    probe.spin_until(
        lambda: publisher.get_subscription_count() >= 1 and readings,
        30.0,
        'the driver on the command topic',
        driver.describe,
    )
    start = readings[-1][1]
    truth = default_parameters()
    x = 0.08  # a sphere posture 80 mm beside the fixed point: reachable exactly on the link sphere
    target = inverse_kinematics(truth, np.array([[x, 0.0, -np.sqrt(0.75**2 - x**2), 0, 0, 0]]))[0]
    largest = float(np.max(np.abs(target - start)))

    def command(names, positions, seconds=0.1):
        message = JointTrajectory(joint_names=list(names))
        message.points = [
            JointTrajectoryPoint(
                positions=[float(p) for p in positions],
                time_from_start=Duration(sec=0, nanosec=int(seconds * 1e9)),
            )
        ]
        publisher.publish(message)

    # Rejected: another model's joints; then one outside the stroke. The machine stays.
    command([f'leg_{i}' for i in range(1, 7)], target)
    command([f'slider_{i}' for i in range(1, 7)], [*target[:5], 1.5])
    probe.spin_until(
        lambda: driver.log_text().count('rejected a JointTrajectory command') >= 2,
        10.0,
        'two rejections',
        driver.describe,
    )
    assert "are not this machine's actuators" in driver.log_text()
    assert 'outside the actuator stroke [0, 0.9] m: slider_6 1.5 m' in driver.log_text()
    assert np.abs(readings[-1][1] - start).max() < 1e-9

    # Accepted, in reversed joint order, asking for 0.1 s: the 0.05 m/s limit makes it slower.
    names = [f'slider_{i}' for i in range(6, 0, -1)]
    sent = len(readings)
    command(names, target[::-1])
    probe.spin_until(
        lambda: np.abs(readings[-1][1] - target).max() < 1e-6,
        10.0 + largest / speed,
        'the machine at the target',
        driver.describe,
    )
    moving = readings[sent - 1 :]
    times = np.array([t for t, _ in moving])
    values = np.array([v for _, v in moving])
    rates = np.abs(np.diff(values, axis=0)) / np.diff(times)[:, None]
    assert rates.max() < 1.15 * speed, rates.max()  # bounded speed (the link strain adds a little)
    started = times[np.flatnonzero(np.abs(values - start).max(axis=1) > 1e-6)[0]]
    arrived = times[np.flatnonzero(np.abs(values - target).max(axis=1) < 1e-6)[0]]
    assert arrived - started == pytest.approx(largest / speed, rel=0.15, abs=0.05)
    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0
    assert 'commands: 1 followed, 2 rejected' in driver.log_path.read_text()


def _stop_log(ros_processes, process) -> str:
    assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_text()
    return process.log_path.read_text(errors='replace')
