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


def _start_when_ready(group: NodeGroup, programs: dict[str, str], log_dir) -> None:
    """Start each program as a node and return once each has set up its signal handling."""
    logs = {name: log_dir / f'{name}.log' for name in programs}
    for name, program in programs.items():
        ready = 'print("ready", flush=True)\ntime.sleep(600)\n'
        group.start(_Command(name, program + ready), log_path=logs[name])
    # A signal during start-up ends any process: stop only once each handles signals as it will.
    deadline = time.monotonic() + 120.0
    while not all(p.exists() and 'ready' in p.read_text() for p in logs.values()):
        assert time.monotonic() < deadline and not group.exited(), 'the children did not start'
        time.sleep(0.01)


def test_the_supervisor_stops_in_order(tmp_path):
    # Each child notes its SIGINT in one file, then dies of it as Python does.
    stopped = tmp_path / 'stopped'
    noting = (
        'import signal, time\n'
        'def note(signum, frame):\n'
        f'    open({str(stopped)!r}, "a").write(NAME + "\\n")\n'
        '    raise KeyboardInterrupt\n'
        'signal.signal(signal.SIGINT, note)\n'
    )
    group = NodeGroup(die_with_parent=True)
    programs = {name: f'NAME = {name!r}\n' + noting for name in ('collector', 'driver')}
    _start_when_ready(group, programs, tmp_path)
    # A polite node exits as soon as it can: the timeout only bounds a hung one.
    codes = group.stop(timeout=120.0, order=('driver',))
    assert codes == {'driver': -signal.SIGINT, 'collector': -signal.SIGINT}
    # The driver was stopped (and gone) before the collector heard of it.
    assert stopped.read_text().split() == ['driver', 'collector']
    assert group.nodes == []


def test_the_supervisor_escalates_to_sigterm_then_sigkill(tmp_path):
    # Escalation waits out the timeout, whatever the load: these children ignore the signal.
    group = NodeGroup(die_with_parent=True)
    ignores = 'import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n'
    deaf = ignores + 'signal.signal(signal.SIGTERM, signal.SIG_IGN)\n'
    _start_when_ready(group, {'driver': ignores, 'collector': deaf}, tmp_path)
    codes = group.stop(timeout=0.5, order=('driver',))
    # SIGTERM's default action ends the driver in the kernel (no Python code runs); the
    # collector ignores it too and gets SIGKILL, which the supervisor waits for without limit.
    assert codes == {'driver': -signal.SIGTERM, 'collector': -signal.SIGKILL}
    assert group.nodes == []
