"""Each console script starts, shows a sign of life, exits 0 on Ctrl-C; the launch file loads."""

from __future__ import annotations

import importlib.util
from pathlib import Path
import re
import subprocess
import sys

import pytest
from rosproc import venv_executable
import system_support
from system_support import node_argv, pid_alive, STOP_TIMEOUT_S, write_parameter_files

probe = system_support.probe  # the probe fixture, for this module's tests

REPO = Path(__file__).resolve().parents[1]
LAUNCH_FILE = REPO / 'ros2_ws/src/hexacal_identify/launch/hexacal.launch.py'


@pytest.mark.slow
@pytest.mark.parametrize(
    'executable, startup_line',
    [
        ('driver', 'holding the first posture until'),
        ('collector', 'recording to'),
        ('identify', 'collecting postures on'),
        ('executor', 'waiting for actuator readings'),
    ],
)
def test_node_starts_and_exits_0_on_ctrl_c(
    ros_processes, tmp_path, probe, executable, startup_line
):
    parameters = {
        'collector': {'output_dir': str(tmp_path / 'bags'), 'bag_name': 'smoke'},
        'identify': {'output_dir': str(tmp_path)},
        'executor': _executor_files(tmp_path),
    }.get(executable, {})
    process = ros_processes.start(node_argv(executable, parameters))
    probe.wait_for_node(executable, process=process)  # on the graph
    probe.spin_until(
        lambda: startup_line in process.log_text(),
        15.0,
        f'{startup_line!r} in the log',
        process.describe,
    )
    code = ros_processes.stop(process, STOP_TIMEOUT_S)
    log = process.log_path.read_text(errors='replace')
    assert code == 0, log
    assert 'Traceback' not in log, log
    if executable == 'collector':
        assert (tmp_path / 'bags' / 'smoke' / 'metadata.yaml').exists()


@pytest.mark.slow
@pytest.mark.parametrize(
    'executable, parameters, problem',
    [
        ('driver', {'rate_hz': 0.5}, 'rate_hz out of range'),
        ('driver', {'plan': 'spiral'}, "plan 'spiral' is neither"),
        ('identify', {'cost': 'quadratic'}, 'cost must be one of'),
        ('identify', {'output': '/etc/hexacal.yaml'}, 'is outside output_dir'),
        ('collector', {'bag_name': 'a/b'}, 'bag_name must be a plain directory name'),
        ('collector', {'detector': 'median'}, "detector must be 'settled', got 'median'"),
        ('collector', {'encoder_clock_offset_s': 2.0}, 'encoder_clock_offset_s'),
    ],
)
def test_bad_parameters_stop_a_node_with_the_reason(tmp_path, executable, parameters, problem):
    if executable == 'identify':
        parameters = {'output_dir': str(tmp_path), **parameters}
    result = subprocess.run(
        node_argv(executable, parameters), capture_output=True, text=True, timeout=60, cwd=tmp_path
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert problem in result.stdout + result.stderr


def _executor_files(directory: Path, model: str | None = None) -> dict[str, str]:
    """Return the plan and nominal parameters of an executor: a generated 8-posture mixed plan."""
    from hexacal_driver.plan import generated_plan, save_plan
    from hexacal_identify.core.architectures import default_parameters

    _, nominal = write_parameter_files(directory, model)
    plan = directory / f'plan_{model or "hexa_slide"}.yaml'
    save_plan(plan, generated_plan('mixed', default_parameters(model), 8, seed=0))
    return {'plan': str(plan), 'nominal': str(nominal)}


@pytest.mark.slow
@pytest.mark.parametrize(
    'parameters, problem',
    [
        ({}, "parameter 'plan' is required"),
        ({'settle_s': 0.0}, 'settle_s out of range'),
        ({'max_corrections': -1}, 'max_corrections out of range'),
        ({'command_topic': 'bad topic'}, 'command_topic'),
        ({'inclinometer_joints': '[a, a]'}, 'inclinometer_joints must be 2 distinct joint names'),
        ({'stroke_limits_m': '[0.9, 0.1]'}, 'stroke limits must be two finite numbers'),
        ({'nominal': '/nonexistent.yaml'}, 'nominal:'),
        ({'model': 'gough_stewart'}, 'was made for a gough_stewart'),
    ],
)
def test_bad_executor_parameters_stop_it_with_the_reason(tmp_path, parameters, problem):
    parameters = dict(parameters)
    files = _executor_files(tmp_path)
    if parameters.pop('model', None):  # a Gough-Stewart plan for the Hexa Slide nominal
        files['plan'] = _executor_files(tmp_path, 'gough_stewart')['plan']
    if problem.startswith("parameter 'plan'"):
        files = {}
    values = {**files, **parameters}
    lists = {name: value for name, value in values.items() if str(value).startswith('[')}
    argv = node_argv('executor', {k: v for k, v in values.items() if k not in lists})
    argv += [item for name, value in lists.items() for item in ('-p', f'{name}:={value}')]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert problem in result.stdout + result.stderr


@pytest.mark.parametrize(
    'command, expected',
    [
        (['bringup', '--help'], '--namespace'),
        (['hexacal', '--help'], 'demo'),
        (['hexacal', 'demo', '--help'], '--noise-um'),
    ],
)
def test_help_exits_0(command, expected):
    result = subprocess.run(
        [venv_executable(command[0]), *command[1:]], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert expected in result.stdout


def _launch_module():
    spec = importlib.util.spec_from_file_location('hexacal_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # imports nothing from launch at module level
    return module


def _pids(bringup) -> set[int]:
    return {int(pid) for pid in re.findall(r'started \w+ \(pid (\d+)\)', bringup.log_text())}


@pytest.mark.slow
def test_bringup_starts_its_nodes_and_stops_them_on_ctrl_c(ros_processes, tmp_path, probe):
    """Without an executor plan: the driver walks its own plan (as before), plus kinematics."""
    bringup = ros_processes.start(
        [
            venv_executable('bringup'),
            '--namespace',
            'smoke',
            '--bag-dir',
            str(tmp_path / 'bags'),
            '--output-dir',
            str(tmp_path / 'out'),
            '--plan',
            'random',
            '--postures',
            '3',
            '--param',
            'collector:bag_name=smoke_bag',
        ]
    )
    for name in ('driver', 'collector', 'identify', 'kinematics'):
        probe.wait_for_node(name, '/smoke', bringup)
    pids = _pids(bringup)
    assert len(pids) == 4
    assert 'started executor' not in bringup.log_text()
    assert 'command_topic' not in re.search(r'started driver .*', bringup.log_text()).group(0)
    code = ros_processes.stop(bringup, STOP_TIMEOUT_S)
    log = bringup.log_path.read_text(errors='replace')
    assert code == 0, log
    assert 'all nodes stopped cleanly' in log, log
    assert not [pid for pid in pids if pid_alive(pid)]
    assert (tmp_path / 'bags' / 'smoke_bag' / 'metadata.yaml').exists()


@pytest.mark.slow
def test_bringup_with_an_executor_plan_commands_the_simulated_driver(
    ros_processes, tmp_path, probe
):
    """--executor-plan: the executor walks it on the driver in commanded mode; --no-kinematics."""
    from diagnostic_msgs.msg import DiagnosticArray
    from hexacal_msgs_py.conversions import status_values
    from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC, EXECUTOR_STATUS_NAME
    from hexacal_msgs_py.qos import COMMAND_QOS, STATUS_MONITOR_QOS
    from trajectory_msgs.msg import JointTrajectory

    files = _executor_files(tmp_path)
    commands, states = [], []
    probe.node.create_subscription(
        JointTrajectory, DEFAULT_COMMAND_TOPIC, commands.append, COMMAND_QOS
    )
    probe.node.create_subscription(
        DiagnosticArray,
        'hexacal/calibration_status',
        lambda m: [
            states.append(status_values(s).get('state'))
            for s in m.status
            if s.name == EXECUTOR_STATUS_NAME
        ],
        STATUS_MONITOR_QOS,
    )
    bringup = ros_processes.start(
        [
            venv_executable('bringup'),
            '--bag-dir',
            str(tmp_path / 'bags'),
            '--output-dir',
            str(tmp_path / 'out'),
            '--nominal',
            files['nominal'],
            '--executor-plan',
            files['plan'],
            '--no-kinematics',
            '--param',
            'collector:bag_name=exec_bag',
            '--param',
            'executor:max_actuator_speed_m_s=0.5',
        ]
    )
    for name in ('driver', 'collector', 'identify', 'executor'):
        probe.wait_for_node(name, '/', bringup)
    log = bringup.log_text()
    assert len(_pids(bringup)) == 4 and 'started kinematics' not in log
    driver_line = re.search(r'started driver .*', log).group(0)
    assert f'command_topic:={DEFAULT_COMMAND_TOPIC}' in driver_line
    assert 'plan:=' not in driver_line.split('--ros-args')[1].replace('command_topic', '')
    probe.spin_until(
        lambda: commands and 'running' in states,
        60.0,
        'the executor commanding the simulated machine',
        bringup.describe,
    )
    assert list(commands[0].joint_names) == [f'slider_{i}' for i in range(1, 7)]
    code = ros_processes.stop(bringup, STOP_TIMEOUT_S)
    log = bringup.log_path.read_text(errors='replace')
    assert code == 0, log
    assert 'all nodes stopped cleanly' in log and 'Traceback' not in log, log


def test_launch_file_compiles():
    source = LAUNCH_FILE.read_text()
    compile(source, str(LAUNCH_FILE), 'exec')
    module = _launch_module()
    assert callable(module.generate_launch_description)
    assert {
        'namespace',
        'nominal',
        'plan',
        'postures',
        'use_driver',
        'executor_plan',
        'command_topic',
        'calibrate_when_done',
        'kinematics_parameters',
        'sliders_topic',
        'inclinometer_topic',
        'encoder_topic',
        'inclinometer_type',
        'actuator_joints',
        'inclinometer_joints',
        'rotary_joint',
        'measuring_mode',
    } <= set(module.ARGUMENTS)


# The launch file passes its declared defaults, which are the nodes' own defaults that bringup
# leaves unset.
LAUNCH_DEFAULTS = {
    ('collector', 'output_dir', 'bags'),
    ('driver', 'plan', 'random'),
    ('driver', 'postures', '50'),
}


def _nodes(nodes) -> dict[str, tuple]:
    """Return executable -> (namespace, parameters without the launch defaults, remaps)."""
    return {
        node.executable: (
            node.namespace,
            {
                name: value
                for name, value in node.parameters.items()
                if (node.executable, name, str(value)) not in LAUNCH_DEFAULTS
            },
            node.remaps,
        )
        for node in nodes
    }


@pytest.mark.parametrize(
    'launch_arguments, bringup_options',
    [
        ({}, []),
        (
            {
                'namespace': 'left',
                'plan': 'mixed',
                'postures': '7',
                'record': 'false',
                'use_kinematics': 'false',
            },
            [
                '--namespace',
                'left',
                '--plan',
                'mixed',
                '--postures',
                '7',
                '--no-record',
                '--no-kinematics',
            ],
        ),
        (
            {
                'nominal': 'n.yaml',
                'executor_plan': 'p.yaml',
                'calibrate_when_done': 'true',
                'command_topic': '/arm_controller/joint_trajectory',
                'kinematics_parameters': 'c.yaml',
            },
            [
                '--nominal',
                'n.yaml',
                '--executor-plan',
                'p.yaml',
                '--calibrate-when-done',
                '--command-topic',
                '/arm_controller/joint_trajectory',
                '--kinematics-parameters',
                'c.yaml',
            ],
        ),
        (
            {
                'use_driver': 'false',
                'nominal': 'n.yaml',
                'executor_plan': 'p.yaml',
                'sliders_topic': '/joint_states',
                'inclinometer_topic': '/joint_states',
                'encoder_topic': '/joint_states',
                'actuator_joints': '[a1, a2, a3, a4, a5, a6]',
                'inclinometer_joints': 'tilt_x,tilt_y',
                'rotary_joint': 'roll',
                'inclinometer_signs': '1,-1',
                'inclinometer_offsets_rad': '[0.0, 0.002]',
                'shutdown_when_done': 'true',
            },
            [
                '--no-driver',
                '--nominal',
                'n.yaml',
                '--executor-plan',
                'p.yaml',
                '--sliders-topic',
                '/joint_states',
                '--inclinometer-topic',
                '/joint_states',
                '--encoder-topic',
                '/joint_states',
                '--actuator-joints',
                'a1,a2,a3,a4,a5,a6',
                '--inclinometer-joints',
                '[tilt_x, tilt_y]',
                '--rotary-joint',
                'roll',
                '--inclinometer-signs',
                '1,-1',
                '--inclinometer-offsets-rad',
                '0,0.002',
                '--shutdown-when-done',
            ],
        ),
        (
            {'nominal': 'n.yaml', 'executor_plan': 'p.yaml', 'measuring_mode': 'lvdt'},
            ['--nominal', 'n.yaml', '--executor-plan', 'p.yaml', '--measuring-mode', 'lvdt'],
        ),
    ],
)
def test_launch_file_and_bringup_start_the_same_nodes(launch_arguments, bringup_options):
    """
    Check that the launch file's nodes (through launches_from_arguments) are bringup's.

    Argument for option: the same executables, parameters and remaps.
    """
    from hexacal_identify.bringup import cli as bringup

    from_launch = _nodes(_launch_module().node_launches(launch_arguments))
    from_bringup = _nodes(
        bringup.node_launches(bringup.build_parser().parse_args(bringup_options))
    )
    assert from_launch == from_bringup


@pytest.mark.parametrize('mode', ['passive_actuator', 'lvdt', 'compliant'])
def test_measuring_mode_goes_to_the_driver_and_an_executor_that_declares_it(mode):
    """One name, `measuring_mode`, from bringup and the launch file to the nodes."""
    from hexacal_identify.bringup import cli as bringup
    from hexacal_identify.bringup.system import executor_takes_measuring_mode

    options = ['--nominal', 'n.yaml', '--executor-plan', 'p.yaml', '--measuring-mode', mode]
    for nodes in (
        _nodes(bringup.node_launches(bringup.build_parser().parse_args(options))),
        _nodes(
            _launch_module().node_launches(
                {'nominal': 'n.yaml', 'executor_plan': 'p.yaml', 'measuring_mode': mode}
            )
        ),
    ):
        assert nodes['driver'][1]['measuring_mode'] == mode
        # Until the executor declares it, it follows the mode its plan carries.
        declared = executor_takes_measuring_mode()
        assert ('measuring_mode' in nodes['executor'][1]) == declared
        if declared:
            assert nodes['executor'][1]['measuring_mode'] == mode
        assert 'measuring_mode' not in nodes['collector'][1]


def test_without_a_measuring_mode_the_nodes_keep_their_defaults_and_a_wrong_one_is_refused():
    from hexacal_identify.bringup import cli as bringup

    nodes = _nodes(_launch_module().node_launches({'nominal': 'n.yaml', 'executor_plan': 'p'}))
    assert all('measuring_mode' not in parameters for _, parameters, _ in nodes.values())
    with pytest.raises(ValueError, match='measuring_mode must be one of'):
        _launch_module().node_launches({'measuring_mode': 'rigid'})
    with pytest.raises(SystemExit):
        bringup.build_parser().parse_args(['--measuring-mode', 'rigid'])


def test_launch_nodes_of_a_real_ros2_control_machine():
    """
    Check the nodes of use_driver:=false with everything on /joint_states.

    No driver; each reader remapped; the mapping to the collector (joints to the executor too);
    commands on the controller's topic.
    """
    nodes = {
        node.executable: node
        for node in _launch_module().node_launches(
            {
                'use_driver': 'false',
                'nominal': 'n.yaml',
                'executor_plan': 'p.yaml',
                'calibrate_when_done': 'true',
                'sliders_topic': '/joint_states',
                'inclinometer_topic': '/joint_states',
                'encoder_topic': '/joint_states',
                'inclinometer_joints': 'tilt_x,tilt_y',
                'rotary_joint': 'link_rotary',
                'inclinometer_signs': '[1, -1]',
            }
        )
    }
    assert set(nodes) == {'collector', 'identify', 'kinematics', 'executor'}
    everything = {
        'hexacal/sliders': '/joint_states',
        'hexacal/inclinometer': '/joint_states',
        'hexacal/encoder': '/joint_states',
    }
    assert nodes['collector'].remaps == everything
    assert nodes['executor'].remaps == {
        k: everything[k] for k in everything if k != 'hexacal/encoder'
    }
    assert nodes['kinematics'].remaps == {'hexacal/sliders': '/joint_states'}
    assert nodes['identify'].remaps == {}
    collector, executor = nodes['collector'].parameters, nodes['executor'].parameters
    assert collector['inclinometer_joints'] == ['tilt_x', 'tilt_y']
    assert collector['rotary_joint'] == 'link_rotary' and collector['inclinometer_signs'] == [
        1,
        -1,
    ]
    assert executor['inclinometer_joints'] == ['tilt_x', 'tilt_y']
    assert executor['calibrate_when_done'] is True
    assert (
        executor['command_topic']
        == nodes['kinematics'].parameters['command_topic']
        == '/joint_trajectory_controller/joint_trajectory'
    )
    assert Path(executor['plan']).is_absolute() and Path(executor['nominal']).is_absolute()
    argv = nodes['collector'].command()
    assert argv[argv.index('-p', argv.index('inclinometer_signs:=[1, -1]') - 1)] == '-p'
    # An Imu inclinometer: the executor reads it as the collector does (same type and topic).
    imu = {
        node.executable: node
        for node in _launch_module().node_launches(
            {
                'use_driver': 'false',
                'nominal': 'n.yaml',
                'executor_plan': 'p.yaml',
                'inclinometer_topic': '/imu',
                'inclinometer_type': 'imu',
            }
        )
    }
    assert imu['collector'].remaps == {'hexacal/inclinometer': '/imu'}
    assert imu['collector'].parameters['inclinometer_type'] == 'imu'
    assert imu['executor'].remaps == {'hexacal/inclinometer': '/imu'}
    assert imu['executor'].parameters['inclinometer_type'] == 'imu'
    assert 'inclinometer_joints' not in imu['executor'].parameters


def test_bringup_spells_the_contract_names():
    from hexacal_identify.bringup import cli as bringup
    from hexacal_identify.bringup.launch_spec import ros_parameter_text
    from hexacal_msgs_py import inputs, names

    assert (bringup.SLIDERS, bringup.INCLINOMETER, bringup.ENCODER) == (
        names.SLIDERS_TOPIC,
        names.INCLINOMETER_TOPIC,
        names.ENCODER_TOPIC,
    )
    assert bringup.DEFAULT_COMMAND_TOPIC == names.DEFAULT_COMMAND_TOPIC
    assert bringup.INCLINOMETER_TYPES == inputs.INCLINOMETER_TYPES
    assert ros_parameter_text(['leg_a', 'true', 1, 0.0]) == '[leg_a, "true", 1, 0.0]'


def test_bringup_and_the_launch_file_import_no_numpy():
    """`bringup --help` and the launch file stay quick: the contract names they use are light."""
    code = (
        'import sys\n'
        'import hexacal_identify.bringup.cli, hexacal_identify.bringup.system\n'
        'assert "numpy" not in sys.modules, sorted(m for m in sys.modules if "numpy" in m)\n'
    )
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_bringup_refuses_an_executor_plan_without_nominal():
    result = subprocess.run(
        [venv_executable('bringup'), '--executor-plan', 'p.yaml'],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2 and '--executor-plan needs --nominal' in result.stderr


def test_launch_description_builds_where_launch_is_installed():
    pytest.importorskip(
        'launch_ros', reason='launch/launch_ros are not on PyPI; ROS installs only'
    )
    module = _launch_module()
    description = module.generate_launch_description()
    assert len(description.entities) == len(module.ARGUMENTS) + 1  # + the nodes' OpaqueFunction


def test_driver_validates_parameter_changes_at_runtime(ros_processes, probe):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    driver = ros_processes.start(node_argv('driver', {'plan': 'fixed', 'postures': 3}))
    probe.wait_for_node('driver', process=driver)
    client = AsyncParameterClient(probe.node, '/driver')
    probe.spin_until(client.services_are_ready, 15.0, "the driver's parameter services")

    def set_one(name: str, value: object):
        future = client.set_parameters([Parameter(name, value=value)])
        return probe.spin_until(
            lambda: future.result() if future.done() else None, 15.0, f'setting {name}'
        ).results[0]

    accepted = set_one('slider_noise_m', 2e-5)
    assert accepted.successful, accepted.reason
    negative = set_one('slider_noise_m', -1e-5)
    assert not negative.successful and 'out of range' in negative.reason
    read_only = set_one('plan', 'random')
    assert not read_only.successful and 'read-only' in read_only.reason
    future = client.describe_parameters(['settle_s', 'plan_name'])
    settle, plan_name = probe.spin_until(
        lambda: future.result() if future.done() else None, 15.0, 'parameter descriptors'
    ).descriptors
    assert settle.description and settle.floating_point_range[0].from_value > 0
    assert plan_name.read_only
    future = client.get_parameters(['plan_name'])
    values = probe.spin_until(
        lambda: future.result() if future.done() else None, 15.0, 'plan_name'
    ).values
    assert values[0].string_value == 'fixed-3-seed0'
    probe.spin_until(
        lambda: 'noise now +-2e-05 m' in driver.log_text(),
        10.0,
        'the noise change in the log',
        driver.describe,
    )
