"""The executor reaches fixed positions on an Imu inclinometer (real nodes, real processes).

The commanded driver publishes its inclinometer also as a sensor_msgs/Imu on /sim/imu
(`imu_topic`). The executor and the collector read it there, configured alike: one parameters
file (`inclinometer_type: imu`) for both and the same remap of hexacal/inclinometer. The plan
alternates sphere and fixed-position postures, so each fixed position is reached in closed loop
on the Imu after a move that tilted the link.
"""

from __future__ import annotations

from pathlib import Path

from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
from hexacal_identify.core.planning.planner import Plan
import numpy as np
import pytest
from system_support import (
    fast_collector_parameters,
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)
from test_executor import _driver, _executor, ExecutorWatch

L = 0.75
IMU_TOPIC = '/sim/imu'
KINDS = ['sphere', 'fixed', 'sphere', 'fixed']
FIXED_RAD = 5e-5  # identify counts a posture as fixed below this; the loop aims at 2e-5


def _plan(tmp_path: Path) -> Path:
    """Sphere and fixed-position postures, alternating, that the executor can command."""
    nominal = nominal_set(2, seed=0)
    stroke = default_stroke(nominal)
    workspace = nominal.architecture.default_workspace()
    for seed in range(20):
        rng = np.random.default_rng(seed)
        poses = np.concatenate([sample_poses(nominal, 1, rng, kind, workspace) for kind in KINDS])
        try:
            check_plan(nominal, poses, KINDS, stroke, L, path_step_m=0.02)
        except ValueError:
            continue
        break
    else:
        raise AssertionError('no commandable plan in 20 seeds')
    path = tmp_path / 'imu-plan.yaml'
    Plan('imu-test', L, poses, KINDS).save(path)
    return path


def _imu_reader(argv: list[str], parameters_file: Path) -> list[str]:
    """Return `argv` reading the inclinometer from the Imu topic, as the parameters file says."""
    remap = f'hexacal/inclinometer:={IMU_TOPIC}'
    return argv + ['--params-file', str(parameters_file), '-r', remap]


@pytest.mark.slow
def test_the_executor_reaches_fixed_positions_on_an_imu_inclinometer(
    ros_processes, tmp_path, probe
):  # noqa: F811
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
    from hexacal_msgs_py.conversions import (
        imu_to_inclinometer_reading,
        joint_state_to_inclinometer_reading,
    )
    from hexacal_msgs_py.qos import SENSOR_QOS
    from sensor_msgs.msg import Imu, JointState

    # The driver's two inclinometer messages, as the probe receives them (stamp ns -> angles).
    heard: dict[str, dict[int, tuple[float, float]]] = {'imu': {}, 'joint_state': {}}

    def keep(kind: str, convert):
        def on_message(message) -> None:
            reading = convert(message)
            heard[kind][reading.stamp_ns] = (reading.alpha, reading.beta)

        return on_message

    probe.node.create_subscription(
        Imu, IMU_TOPIC, keep('imu', imu_to_inclinometer_reading), SENSOR_QOS
    )
    probe.node.create_subscription(
        JointState,
        'hexacal/inclinometer',
        keep('joint_state', joint_state_to_inclinometer_reading),
        SENSOR_QOS,
    )
    truth, nominal = write_parameter_files(tmp_path)
    plan = _plan(tmp_path)
    inputs = tmp_path / 'inputs.yaml'  # one file for both nodes
    inputs.write_text('/**:\n  ros__parameters:\n    inclinometer_type: imu\n')
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(_driver(truth, imu_topic=IMU_TOPIC))
    collector_parameters = fast_collector_parameters(
        tmp_path / 'bags', bag_name='imu', parameters_file=str(nominal)
    )
    collector = ros_processes.start(
        _imu_reader(node_argv('collector', collector_parameters), inputs)
    )
    probe.wait_for_node('driver', process=driver)
    probe.wait_for_node('collector', process=collector)
    executor = ros_processes.start(_imu_reader(_executor(plan, nominal), inputs))
    nodes = (driver, collector, executor)
    done = watch.wait(
        lambda s: s.get('state') in ('done', 'aborted') and s, 240.0, 'the plan walked', *nodes
    )
    assert done['state'] == 'done' and done['measured'] == '4' and done['skipped'] == '0', done
    assert int(done['corrections']) >= 1  # the nominal machine is not the true one

    # Both read the Imu there; neither reads the driver's JointState inclinometer.
    def readers(topic: str) -> dict[str, str]:
        return {
            info.node_name: info.topic_type
            for info in probe.node.get_subscriptions_info_by_topic(topic)
        }

    imu_readers = readers(IMU_TOPIC)
    assert imu_readers.get('executor') == imu_readers.get('collector') == 'sensor_msgs/msg/Imu'
    assert not {'executor', 'collector'} & set(readers('/hexacal/inclinometer'))
    log = executor.log_text()
    assert f'fixed positions: inclinometer <- {IMU_TOPIC} (sensor_msgs/Imu orientation)' in log
    assert 'settled' in log and 'Traceback' not in log and 'invalid' not in log
    # The Imu is the JointState inclinometer message's reading: same stamps, same angles.
    common = sorted(set(heard['imu']) & set(heard['joint_state']))
    assert len(common) >= 100, {kind: len(values) for kind, values in heard.items()}
    imu = np.array([heard['imu'][stamp] for stamp in common])
    joint_state = np.array([heard['joint_state'][stamp] for stamp in common])
    assert np.abs(imu - joint_state).max() < 1e-12
    assert np.abs(joint_state).max() > 1e-3  # sphere postures among them: tilted readings
    for process in (executor, collector, driver):
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_text()
    # The collector's postures, read from the Imu too: the fixed positions were reached.
    recorded = postures_from_bag(tmp_path / 'bags' / 'imu').postures
    fixed = [p for p in recorded if max(abs(p.alpha), abs(p.beta)) < FIXED_RAD]
    assert len(fixed) >= 2, [(p.alpha, p.beta) for p in recorded]


def test_a_bad_inclinometer_mapping_is_a_named_start_up_error(tmp_path):
    import subprocess

    truth, nominal = write_parameter_files(tmp_path)
    plan = _plan(tmp_path)
    result = subprocess.run(
        _executor(plan, nominal, 'inclinometer_signs:=[1, 2]', inclinometer_type='imu'),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert 'inclinometer_signs: each sign must be 1 or -1' in result.stdout + result.stderr
