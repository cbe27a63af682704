"""The bringup package without DDS: argument spelling, the nodes of a system, the supervisor."""

import signal
import sys
import time

from hexacal_identify.bringup.cli import build_parser, node_launches
from hexacal_identify.bringup.launch_spec import NodeLaunch, normalize_namespace
from hexacal_identify.bringup.launch_spec import ros_parameter_text
from hexacal_identify.bringup.supervisor import NodeGroup
from hexacal_identify.bringup.system import launches, MachineInputs, number_list, truthy
import pytest


@pytest.mark.parametrize(
    'value, text',
    [
        (True, 'true'),
        (100.0, '100.0'),
        (3, '3'),
        ('true', '"true"'),
        ('leg_1', 'leg_1'),
        (['a', 1, 0.5], '[a, 1, 0.5]'),
    ],
)
def test_parameter_text_keeps_the_type(value, text):
    assert ros_parameter_text(value) == text


def test_namespaces_and_argument_lists():
    assert [normalize_namespace(n) for n in ('', '/', 'left', '/left/')] == [
        '',
        '',
        '/left',
        '/left',
    ]
    assert number_list('[1, -1]', int) == (1, -1)
    assert truthy('On') and not truthy('')
    with pytest.raises(ValueError, match='expected true or false'):
        truthy('maybe')


def test_an_executor_plan_adds_the_executor_and_commands_the_driver():
    nodes = {n.executable: n for n in launches(executor_plan='plan.yaml', nominal='n.yaml')}
    assert list(nodes) == ['collector', 'identify', 'executor', 'driver']
    topic = '/joint_trajectory_controller/joint_trajectory'
    assert nodes['executor'].parameters['command_topic'] == topic
    assert nodes['driver'].parameters['command_topic'] == topic
    inputs = MachineInputs(sliders_topic='/joint_states', inclinometer_type='imu')
    nodes = {n.executable: n for n in launches(with_kinematics=True, inputs=inputs)}
    assert nodes['kinematics'].remaps == {'hexacal/sliders': '/joint_states'}


def test_bringup_options_become_node_parameters():
    args = build_parser().parse_args(['--namespace', 'left', '--param', 'driver:settle_s=0.5'])
    nodes = {n.executable: n for n in node_launches(args)}
    assert nodes['driver'].parameters['settle_s'] == 0.5
    assert '__ns:=/left' in nodes['collector'].command()


class _Command(NodeLaunch):
    """A node launch whose process is a given Python program (the supervisor's real child)."""

    def __init__(self, name: str, program: str) -> None:
        super().__init__(name)
        self.program = program

    def command(self) -> list[str]:
        """Return the program's argv."""
        return [sys.executable, '-c', self.program]


def test_the_supervisor_stops_in_order_and_escalates(tmp_path):
    group = NodeGroup(die_with_parent=True)
    stubborn = 'import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n'
    polite = 'import time\n'
    ready = 'print("ready", flush=True)\ntime.sleep(60)\n'
    logs = {'driver': tmp_path / 'driver.log', 'collector': tmp_path / 'collector.log'}
    group.start(_Command('driver', stubborn + ready), log_path=logs['driver'])
    group.start(_Command('collector', polite + ready), log_path=logs['collector'])
    # Stop only once both handle signals as they will (a signal during start-up ends any process).
    deadline = time.monotonic() + 30.0
    while not all(p.exists() and 'ready' in p.read_text() for p in logs.values()):
        assert time.monotonic() < deadline and not group.exited(), 'the children did not start'
        time.sleep(0.01)
    codes = group.stop(timeout=2.0, order=('driver',))
    # SIGINT ends the collector (Python dies of it); the driver ignores it and gets SIGTERM.
    assert codes == {'driver': -signal.SIGTERM, 'collector': -signal.SIGINT}
    assert group.nodes == []
