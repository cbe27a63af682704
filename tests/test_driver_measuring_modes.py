"""The driver node's measuring modes in its own process: release a joint, fault and reset."""

from __future__ import annotations

from hexacal_driver.parameters import PARAMETERS
import numpy as np
import pytest
from system_support import node_argv, probe  # noqa: F401 - fixture

RELEASED = 'slider_3'
WAIT_S = 60.0  # generous: both cores are busy with other tests


def start_driver(ros_processes, **overrides):
    parameters = {
        'command_topic': 'command',
        'measuring_mode': 'passive_actuator',
        'rate_hz': 50.0,
        'max_actuator_speed_m_s': 0.05,
        'slider_noise_m': 1e-6,
        'angle_noise_rad': 0.0,
    }
    parameters.update(overrides)
    return ros_processes.start(node_argv('driver', parameters), name='driver')


class Machine:
    """The probe's view of the driver: sliders, statuses, commands, services."""

    def __init__(self, probe, driver) -> None:  # noqa: F811 - the fixture
        from hexacal_msgs_py.qos import COMMAND_QOS, SENSOR_QOS
        from sensor_msgs.msg import JointState
        from trajectory_msgs.msg import JointTrajectory

        self.probe, self.driver = probe, driver
        self.sliders: list[tuple[list[str], np.ndarray]] = []
        self.efforts: list[np.ndarray] = []
        probe.subscribe_status()
        probe.node.create_subscription(
            JointState,
            'hexacal/sliders',
            lambda m: (
                self.sliders.append((list(m.name), np.array(m.position))),
                self.efforts.append(np.array(m.effort)),
            ),
            SENSOR_QOS,
        )
        self.commands = probe.node.create_publisher(JointTrajectory, 'command', COMMAND_QOS)
        probe.wait_for_node('driver', process=driver)
        self.wait(
            lambda: self.sliders and self.commands.get_subscription_count() >= 1,
            'the driver publishing and subscribed to its command topic',
        )

    def wait(self, predicate, what: str):
        return self.probe.spin_until(predicate, WAIT_S, what, self.driver.describe)

    def driver_status(self, predicate=lambda values: True):
        """Return the values of the latest 'hexacal driver' status satisfying predicate."""
        for _level, _message, values in reversed(self.probe.statuses):
            if values.get('measuring_mode') is not None and predicate(values):
                return values
        return None

    def positions(self) -> np.ndarray:
        return self.sliders[-1][1]

    def command(self, names: list[str], positions, duration_s: float) -> None:
        from builtin_interfaces.msg import Duration
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        seconds = int(duration_s)
        point = JointTrajectoryPoint(
            positions=[float(v) for v in positions],
            time_from_start=Duration(sec=seconds, nanosec=int((duration_s - seconds) * 1e9)),
        )
        self.commands.publish(JointTrajectory(joint_names=names, points=[point]))

    def set_bool(self, service: str, data: bool):
        from std_srvs.srv import SetBool

        client = self.probe.node.create_client(SetBool, service)
        self.wait(client.service_is_ready, f'service {service}')
        future = client.call_async(SetBool.Request(data=data))
        return self.wait(lambda: future.result() if future.done() else None, service)


def released_truth(index: int, five_targets: np.ndarray) -> float:
    """Return where the released actuator stands on the default machine (core solve_passive)."""
    from hexacal_identify.core.architectures import architecture
    from hexacal_identify.core.machine.device import fixed_point
    from hexacal_identify.core.modes.passive_actuator import solve_passive

    truth = architecture('hexa_slide').default_parameters()
    home = np.concatenate([fixed_point(0.75), np.zeros(3)])  # where the driver starts
    setpoints = np.insert(five_targets, index, 0.0)
    solved = solve_passive(truth, setpoints[None], index, home[None], 0.75)
    assert solved.converged[0]
    return float(solved.actuators[0, index])


def test_a_released_joint_follows_the_link_and_five_stand_at_their_setpoints(
    ros_processes, probe  # noqa: F811 - fixture
):
    machine = Machine(probe, start_driver(ros_processes))
    names = machine.sliders[-1][0]
    start = machine.positions().copy()
    answer = machine.set_bool(f'/hexacal/release/{RELEASED}', True)
    assert answer.success, answer.message
    machine.wait(
        lambda: machine.driver_status(lambda v: v['released_joint'] == RELEASED),
        'the status naming the released joint',
    )
    refused = machine.set_bool('/hexacal/release/slider_1', True)
    assert not refused.success and RELEASED in refused.message

    index = names.index(RELEASED)
    five = [name for name in names if name != RELEASED]
    targets = np.delete(start, index) + np.array([2e-3, -1e-3, 1.5e-3, 0.0, -2e-3])
    machine.command(five, targets, 1.0)

    def arrived() -> bool:
        return bool(np.max(np.abs(np.delete(machine.positions(), index) - targets)) < 3e-6)

    machine.wait(arrived, 'the five commanded actuators at their setpoints')
    machine.wait(
        lambda: machine.driver_status(lambda v: float(v['actuator_deviation_m']) < 1e-9
                                      and v['state'] == 'ok' and v['released_joint'] == RELEASED),
        'the status at rest: the five commanded at their setpoints',
    )
    # The released one is where the link puts the true machine (noise +-1e-6 m).
    assert abs(machine.positions()[index] - start[index]) > 1e-4
    assert abs(machine.positions()[index] - released_truth(index, targets)) < 3e-6

    # A command naming the released joint is refused, and the status says why.
    machine.command(names, machine.positions(), 1.0)
    status = machine.wait(
        lambda: machine.driver_status(lambda v: RELEASED in v['refused_command']),
        'the refusal of a command naming the released joint in the status',
    )
    assert status['state'] == 'ok'
    assert machine.efforts[-1].size == 0  # effort only in compliant mode


def test_six_stiff_drives_against_the_link_fault_and_hold(
    ros_processes, probe  # noqa: F811 - fixture
):
    machine = Machine(probe, start_driver(ros_processes, slider_noise_m=0.0))
    names = machine.sliders[-1][0]
    target = machine.positions() + np.array([5e-3, 0, 0, 0, 0, 0])
    machine.command(names, target, 2.0)
    status = machine.wait(
        lambda: machine.driver_status(lambda v: v['state'] == 'fault'),
        'the drives faulting on their following error',
    )
    assert 'over-constrained' in status['fault']
    assert float(status['fault_limit']) == pytest.approx(5e-4)
    assert float(status['fault_value']) > 5e-4 >= float(status['following_error_m'])
    assert any(level == 2 for level, message, values in probe.statuses
               if values.get('state') == 'fault')
    # Held: nothing moves any more.
    count = len(machine.sliders)
    held = machine.positions().copy()
    machine.wait(lambda: len(machine.sliders) >= count + 20, 'twenty more readings')
    assert all(np.array_equal(p, held) for _, p in machine.sliders[count:])
    assert np.max(np.abs(held - target)) > 1e-3  # stopped well before the target

    from std_srvs.srv import Trigger

    client = probe.node.create_client(Trigger, '/hexacal/driver/reset')
    machine.wait(client.service_is_ready, 'the reset service')
    future = client.call_async(Trigger.Request())
    answer = machine.wait(lambda: future.result() if future.done() else None, 'reset')
    assert answer.success, answer.message
    status = machine.wait(
        lambda: machine.driver_status(lambda v: v['state'] == 'ok'
                                      and float(v['following_error_m']) == 0.0),
        'the drives re-enabled where they stand',
    )
    assert status['fault'] == ''


def test_lvdt_link_length_is_published_and_six_stand_at_their_setpoints(
    ros_processes, probe  # noqa: F811 - fixture
):
    from hexacal_msgs_py.qos import SENSOR_QOS
    from sensor_msgs.msg import JointState

    links: list[tuple[list[str], float]] = []
    probe.node.create_subscription(
        JointState,
        'hexacal/link',
        lambda m: links.append((list(m.name), float(m.position[0]))),
        SENSOR_QOS,
    )
    machine = Machine(probe, start_driver(ros_processes, measuring_mode='lvdt'))
    machine.wait(lambda: links, 'the LVDT link length on hexacal/link')
    assert links[-1][0] == ['link_length'] and abs(links[-1][1] - 0.75) < 2e-6
    names = machine.sliders[-1][0]
    target = machine.positions() + np.array([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3])
    machine.command(names, target, 1.0)
    machine.wait(
        lambda: np.max(np.abs(machine.positions() - target)) < 3e-6,
        'the six commanded actuators at their setpoints',
    )
    # At rest the latest status (every second) and the LVDT agree on the extension.

    def consistent():
        status = machine.driver_status()
        extension = float(status['link_extension_m'])
        return abs(extension) > 1e-4 and abs(links[-1][1] - (0.75 + extension)) < 2e-6

    machine.wait(consistent, 'the LVDT reading the extended link (noise +-1e-6 m)')
    status = machine.driver_status()
    assert status['state'] == 'ok' and float(status['actuator_deviation_m']) == 0.0
    assert sorted(machine.sliders[-1][0]) == sorted(names)


def test_compliant_servos_publish_their_force_as_effort(
    ros_processes, probe  # noqa: F811 - fixture
):
    stiffness = PARAMETERS['servo_stiffness_n_per_m'].default  # N/m, the driver's default
    machine = Machine(probe, start_driver(ros_processes, measuring_mode='compliant'))
    names = machine.sliders[-1][0]
    target = machine.positions() + np.array([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3])
    machine.command(names, target, 1.0)
    status = machine.wait(
        lambda: machine.driver_status(
            lambda v: float(v['actuator_deviation_m']) > 1e-4
            and float(v['force_n']) > stiffness * 1e-4
        ),
        'the status at rest with the servos strained by the link',
    )
    force = float(status['force_n'])
    machine.wait(
        lambda: machine.efforts[-1].size == 6
        and abs(np.max(np.abs(machine.efforts[-1])) - force) < 1e-6 * force,
        'the efforts of the strained servos',
    )
    # effort = stiffness x (true position - setpoint); the readings carry +-1e-6 m of noise.
    expected = stiffness * (machine.positions() - target)
    assert np.max(np.abs(machine.efforts[-1] - expected)) < stiffness * 1.5e-6
