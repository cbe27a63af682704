"""
System tests of deployment: only a deployed calibration reaches the kinematics node's commands.

Real `identify` and `kinematics` processes over Fast DDS, one calibration store. The test
process is the "unrelated node" that publishes a calibration on hexacal/parameters, the
posture source of identify, and the machine's actuator readings and target poses:

* a calibration published on hexacal/parameters by another node does not change the
  commands (follow_calibrations stays at its default, false);
* an unverified calibration is refused by hexacal/deploy (the store says why, naming force);
* deploying a verified calibration changes the commands to its inverse kinematics; a second
  one too; a rollback restores the previous commands exactly;
* a surprising jump (`hexacal deploy ID --store DIR`, a parameter 5 cm off) is refused;
* a SIGKILL of identify in the middle of a calibration leaves the store whole.
"""

from __future__ import annotations

import json
import os
import signal

from hexacal_identify.core.architectures import parameters_for
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.live import home_pose
from hexacal_identify.store import CalibrationStore, file_digest
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
import numpy as np
import pytest
from system_support import (
    hexacal,
    node_argv,
    NODE_START_TIMEOUT_S,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    STOP_TIMEOUT_S,
    write_parameter_files,
)

MODEL = 'hexa_slide'
TARGET = home_pose() + np.array([0.004, -0.003, 0.002, 0.01, -0.01, 0.02])
THRESHOLD_M = 5e-4  # verification threshold: 10 um reading noise passes well under it


class Machine:
    """The test process as the machine's readings, its operator (targets) and a status monitor."""

    def __init__(self, node, truth) -> None:
        from geometry_msgs.msg import PoseStamped
        from hexacal_msgs_py.qos import COMMAND_QOS, SENSOR_QOS
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory

        self.probe = node
        self.truth = truth
        self.commands: list[np.ndarray] = []
        node.subscribe_status()
        node.node.create_subscription(
            JointTrajectory,
            '/command',
            lambda m: self.commands.append(np.array(m.points[0].positions)),
            COMMAND_QOS,
        )
        self.targets = node.node.create_publisher(
            PoseStamped, '/hexacal/target_pose', COMMAND_QOS
        )
        self.readings = node.node.create_publisher(JointState, '/hexacal/sliders', SENSOR_QOS)

    def kinematics_statuses(self) -> list[dict]:
        return [v for _, _, v in self.probe.statuses if 'parameters_updates' in v]

    def track(self, details) -> None:
        """Publish the machine's readings at the workspace centre until the node tracks it."""
        from hexacal_msgs_py.conversions import actuator_reading_to_joint_state
        from hexacal_msgs_py.readings import ActuatorReading

        readings = inverse_kinematics(self.truth, home_pose()[None])[0]
        stamp = [1]

        def tracking() -> bool:
            stamp[0] += 10**8  # 10 Hz of stamps: under max_pose_rate_hz
            reading = ActuatorReading(stamp[0], tuple(readings))
            self.readings.publish(actuator_reading_to_joint_state(reading, model=MODEL))
            return any(v['outcome'] == 'tracking' for v in self.kinematics_statuses())

        self.probe.spin_until(tracking, NODE_START_TIMEOUT_S, 'the node tracking', details)

    def command(self, details) -> np.ndarray:
        """Send TARGET; return the actuator targets of the command it becomes."""
        from geometry_msgs.msg import PoseStamped
        from hexacal_msgs_py.poses import fill_pose_message

        self.probe.spin_until(
            lambda: self.targets.get_subscription_count() >= 1,
            NODE_START_TIMEOUT_S,
            'the kinematics node on hexacal/target_pose',
            details,
        )
        before = len(self.commands)
        message = fill_pose_message(PoseStamped(), TARGET)
        message.header.frame_id = 'hexacal_base'
        self.targets.publish(message)
        self.probe.spin_until(lambda: len(self.commands) > before, 30.0, 'a command', details)
        return self.commands[-1]

    def wait_kinematics(self, predicate, what: str, details) -> dict:
        def found():
            return next((v for v in reversed(self.kinematics_statuses()) if predicate(v)), None)

        return self.probe.spin_until(found, 30.0, what, details)


def expected_command(entry_or_file) -> np.ndarray:
    """Return the IK of TARGET with the parameters of a store entry (or a parameters file)."""
    path = getattr(entry_or_file, 'parameters_path', entry_or_file)
    saved = read_parameters_file(path)
    return inverse_kinematics(parameters_for(saved.model, saved.vector), TARGET[None])[0]


@pytest.mark.slow
def test_only_a_deployed_calibration_changes_the_commands(ros_processes, tmp_path, probe):
    truth_path, nominal_path = write_parameter_files(tmp_path)
    truth = parameters_for(MODEL, read_parameters_file(truth_path).vector)
    store_path = tmp_path / 'store'
    identify = ros_processes.start(
        node_argv(
            'identify',
            {
                'nominal': str(nominal_path),
                'output_dir': str(tmp_path / 'out'),
                'report_dir': '',
                'calibration_store': str(store_path),
                'verify_threshold_m': THRESHOLD_M,
            },
        ),
        name='identify',
    )
    kinematics = ros_processes.start(
        node_argv(
            'kinematics',
            {
                'parameters': str(nominal_path),
                'calibration_store': str(store_path),
                'command_topic': 'command',
                'markers_rate_hz': 0.0,
            },
        ),
        name='kinematics',
    )

    def details() -> str:
        return identify.describe(20) + '\n' + kinematics.describe(20)

    probe.wait_for_node('identify', '/', identify)
    probe.wait_for_node('kinematics', '/', kinematics)
    machine = Machine(probe, truth)
    machine.track(details)
    nominal_command = machine.command(details)
    np.testing.assert_allclose(nominal_command, expected_command(nominal_path), atol=1e-12)

    # 1. An unrelated node publishes a calibration (the truth, even): it is not deployed.
    from hexacal_msgs_py.conversions import parameters_to_multiarray
    from hexacal_msgs_py.qos import PARAMETERS_QOS
    from std_msgs.msg import Float64MultiArray

    stranger = probe.node.create_publisher(
        Float64MultiArray, '/hexacal/parameters', PARAMETERS_QOS
    )
    stranger.publish(parameters_to_multiarray(truth.vector, MODEL))
    machine.wait_kinematics(
        lambda v: v['outcome'] == 'not-deployed', 'the calibration refused (not deployed)', details
    )
    assert np.array_equal(machine.command(details), nominal_command)

    # 2. identify calibrates (kept in the store); deploying it unverified is refused.
    probe.publish_postures(simulated_postures(40, seed=1), subscribers=1)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 40, 60.0, '40 postures', details
    )
    response = probe.call_trigger('/hexacal/calibrate')
    assert response.success, response.message
    store = CalibrationStore(store_path)
    (first,) = store.entries()
    assert first.state == 'stored' and first.record['postures'] == 40
    response = probe.call_trigger('/hexacal/deploy')
    assert not response.success
    assert 'unverified' in response.message and '--force' in response.message, response.message
    assert store.active() is None
    assert np.array_equal(machine.command(details), nominal_command)

    # 3. Verified on fresh postures, then deployed: the commands are its IK.
    probe.publish_postures(simulated_postures(12, seed=7), subscribers=1)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 52, 60.0, '52 postures', details
    )
    response = probe.call_trigger('/hexacal/verify')
    assert response.success, response.message
    response = probe.call_trigger('/hexacal/deploy')
    assert response.success, response.message
    status = machine.wait_kinematics(
        lambda v: v.get('active_calibration') == first.id and v['outcome'] == 'parameters',
        'the kinematics node on the deployed calibration',
        details,
    )
    assert status['active_reason'] == 'verified' and status['active_since']
    first_command = machine.command(details)
    np.testing.assert_allclose(first_command, expected_command(first), atol=1e-12)
    assert np.abs(first_command - nominal_command).max() > 1e-4  # nominal set 2: mm off

    # 4. A second verified calibration is deployed (plausible: micrometres from the first).
    probe.publish_postures(simulated_postures(20, seed=3), subscribers=1)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 72, 60.0, '72 postures', details
    )
    assert probe.call_trigger('/hexacal/calibrate').success
    second = store.entries()[-1]
    assert second.id != first.id
    probe.publish_postures(simulated_postures(12, seed=9), subscribers=1)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 84, 60.0, '84 postures', details
    )
    assert probe.call_trigger('/hexacal/verify').success
    response = probe.call_trigger('/hexacal/deploy')
    assert response.success, response.message
    machine.wait_kinematics(
        lambda v: v.get('active_calibration') == second.id, 'the second deploy', details
    )
    second_command = machine.command(details)
    np.testing.assert_allclose(second_command, expected_command(second), atol=1e-12)
    assert not np.array_equal(second_command, first_command)

    # 5. A surprising jump: verified, but a parameter 5 cm off the active one's. Refused.
    jump_file = tmp_path / 'jump.yaml'
    vector = read_parameters_file(second.parameters_path).vector.copy()
    vector[0] += 0.05
    save_parameters(jump_file, vector, model=MODEL)
    jump = store.add(jump_file, {'postures_digest': 'fitted-elsewhere'})
    store.attach_verification(jump.id, {'verdict': 'pass'}, postures_digest='fresh-postures')
    refused = hexacal('deploy', jump.id, '--store', str(store_path), script=True, timeout=120)
    assert refused.returncode == 1, refused.stdout + refused.stderr
    assert 'parameter-jump' in refused.stdout + refused.stderr
    assert store.active().id == second.id
    probe.spin_for(1.0)  # two looks of the kinematics node at the store: nothing changed
    assert np.array_equal(machine.command(details), second_command)

    # 6. Rollback (identify's service): the first calibration's commands, bit for bit.
    response = probe.call_trigger('/hexacal/rollback')
    assert response.success, response.message
    status = machine.wait_kinematics(
        lambda v: v.get('active_reason') == 'rolled-back' and v['outcome'] == 'parameters',
        'the rollback',
        details,
    )
    assert status['active_calibration'] == first.id
    assert np.array_equal(machine.command(details), first_command)


@pytest.mark.slow
def test_a_sigkill_mid_calibration_leaves_the_store_whole(ros_processes, tmp_path, probe):
    _, nominal_path = write_parameter_files(tmp_path)
    store_path, output_dir = tmp_path / 'store', tmp_path / 'out'
    parameters = {
        'nominal': str(nominal_path),
        'output_dir': str(output_dir),
        'report_dir': '',
        'calibration_store': str(store_path),
    }
    identify = ros_processes.start(node_argv('identify', parameters), name='identify')
    probe.wait_for_node('identify', '/', identify)
    probe.subscribe_status()
    probe.publish_postures(simulated_postures(40, seed=1), subscribers=1)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 40, 60.0, '40 postures', identify.describe
    )
    assert probe.call_trigger('/hexacal/calibrate').success
    store = CalibrationStore(store_path)
    (kept,) = store.entries()
    output = output_dir / 'hexacal_calibration.yaml'
    written = output.read_bytes()

    # A long calibration (600 postures), killed once it runs.
    probe.publish_postures(simulated_postures(560, seed=2), subscribers=1)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 600,
        120.0,
        '600 postures',
        identify.describe,
    )
    probe.statuses.clear()
    probe.trigger_async('/hexacal/calibrate')
    probe.spin_until(
        lambda: any(v.get('outcome') == 'running' for _, _, v in probe.statuses),
        60.0,
        'the calibration running',
        identify.describe,
    )
    os.killpg(identify.pid, signal.SIGKILL)
    identify.popen.wait(STOP_TIMEOUT_S)
    assert identify.popen.returncode == -signal.SIGKILL

    # The store holds the one whole entry; its file is the output as it was, byte for byte.
    assert [e.id for e in store.entries()] == [kept.id]
    assert file_digest(store.get(kept.id).parameters_path) == kept.digest
    assert output.read_bytes() == written
    entries = sorted(p.name for p in (store_path / 'entries').iterdir())
    assert entries == [kept.id]
    history = hexacal('history', '--store', str(store_path), '--json', script=True, timeout=120)
    assert history.returncode == 0, history.stderr
    assert [e['id'] for e in json.loads(history.stdout)] == [kept.id]

    # A restarted identify keeps adding to it. (In a namespace of its own: DDS may still count
    # the killed node's subscription on /hexacal/posture for a while.)
    identify = ros_processes.start(
        node_argv('identify', parameters, 'again'), name='identify-again'
    )
    probe.wait_for_node('identify', '/again', identify)
    probe.subscribe_status('/again/hexacal/calibration_status')
    probe.publish_postures(
        simulated_postures(40, seed=5), topic='/again/hexacal/posture', subscribers=1
    )
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 40,
        60.0,
        '40 postures again',
        identify.describe,
    )
    response = probe.call_trigger('/again/hexacal/calibrate')
    assert response.success, response.message
    assert [e.id for e in store.entries()][0] == kept.id and len(store.entries()) == 2
    assert all(file_digest(e.parameters_path) == e.digest for e in store.entries())
