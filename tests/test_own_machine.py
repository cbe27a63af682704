"""README "Your own machine": its commands, run as written, against a stand-in for a real machine.

The stand-in is a ros2_control Gough-Stewart platform as hexacal meets it: the
simulated driver in commanded mode follows JointTrajectory commands on
/joint_trajectory_controller/joint_trajectory, and its three sensor streams
(remapped to machine/*) are merged by joint_states_relay.py into one
/joint_states with the legs in another order, the inclinometer as tilt_x/tilt_y,
the rotary sensor as link_rotary and extra joints (a joint_state_broadcaster).
The true machine (the default hexapod) is known only to the stand-in; hexacal
gets nominal set 2 as `nominal.yaml`.

Every command of the README section's ``sh`` blocks runs in order, as written,
in the test's directory (`.venv/bin/<exe>` for the executable); the stand-in
moves faster than a real machine, so the bringup lines get the executor's
speed and settle time appended (and a stop timeout for a loaded test machine). Each ``text`` block's `ros2 launch` line is
checked to start the same nodes, with the same parameters, as the bringup line of
the same step; there is no ros2 launch here, so the verification's launch line runs
through a stand-in (ROS2_LAUNCH: the launch file's own nodes, ended with the executor
as its shutdown_when_done does) instead of the bringup line, and `hexacal verify`
reads what it left. Real processes in their own process groups, this session's ROS
domain on localhost (conftest.py), waits on conditions.
"""

from __future__ import annotations

import json
from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys

from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC
import numpy as np
import pytest
from rosproc import venv_executable, wait_for
from system_support import (
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)

REPO = Path(__file__).resolve().parents[1]
README = REPO / 'docs' / 'user-guide.md'  # the user guide's "Your own machine"
LAUNCH_FILE = REPO / 'ros2_ws/src/hexacal_identify/launch/hexacal.launch.py'
RELAY = Path(__file__).resolve().parent / 'joint_states_relay.py'
MODEL = 'gough_stewart'
# The stand-in moves at up to 1 m/s; the executor may go at 0.5 m/s and settle in 0.3 s.
FAST_EXECUTOR = [
    '--param',
    'executor:max_actuator_speed_m_s=0.5',
    '--param',
    'executor:settle_s=0.3',
]
# How long a node may take to exit once stopped: identify finishes its HTML report first, which
# took over 20 s on a loaded 2-core machine (the default 10 s then SIGKILLs it).
STOP_ALLOWANCE_S = 120.0
EXECUTABLES = ('hexacal', 'bringup', 'kinematics')
ROS2_LAUNCH_PREFIX = ['ros2', 'launch', 'hexacal_identify', 'hexacal.launch.py']
# `ros2 launch hexacal_identify hexacal.launch.py ARG:=VALUE...` without ros2 launch: the nodes
# of the launch file's node_launches (those its generate_launch_description starts) in this
# directory, until a node ends (the executor, with shutdown_when_done) or SIGINT.
# argv: launch file, executor parameters (JSON), stop timeout (s), the launch arguments.
ROS2_LAUNCH = """
import importlib.util, json, signal, sys, time
from hexacal_identify.bringup.supervisor import NodeGroup
spec = importlib.util.spec_from_file_location('hexacal_launch', sys.argv[1])
launch_file = importlib.util.module_from_spec(spec)
spec.loader.exec_module(launch_file)
values = dict(item.split(':=', 1) for item in sys.argv[4:])
unknown = sorted(set(values) - set(launch_file.ARGUMENTS))
if unknown:
    sys.exit(f'not an argument of the launch file: {unknown}')
nodes = launch_file.node_launches(values)
for node in nodes:
    if node.executable == 'executor':
        node.parameters.update(json.loads(sys.argv[2]))
received = []
for signum in (signal.SIGINT, signal.SIGTERM):
    signal.signal(signum, lambda signum, frame: received.append(signum))
group = NodeGroup(die_with_parent=True)
for node in nodes:
    group.start(node)
    print('launch: started', node.executable, flush=True)
while not received and not group.exited():
    time.sleep(0.1)
ended = [node.name for node in group.exited()]
order = ('executor', 'driver', 'collector', 'kinematics', 'identify')
codes = group.stop(float(sys.argv[3]), order=order)
print('launch: exit codes', codes, flush=True)
if ended == ['executor'] and codes['executor'] == 0:
    print('launch: the executor is done', flush=True)
if any(codes.values()):
    sys.exit(1)
print('launch: all nodes stopped cleanly', flush=True)
"""


def readme_section() -> str:
    text = README.read_text()
    start = text.index('\n## Your own machine\n')
    end = text.index('\n## ', start + 1)
    return text[start:end]


def readme_commands(kind: str = 'sh') -> list[list[str]]:
    """argv of every command in the section's ```kind blocks, in order (\\ continuations joined)."""
    commands = []
    for block in re.findall(rf'```{kind}\n(.*?)```', readme_section(), re.S):
        for line in block.replace('\\\n', ' ').splitlines():
            if line.strip() and not line.lstrip().startswith('#'):
                commands.append(shlex.split(line))
    return commands


def _in(directory: Path, argv: list[str]) -> list[str]:
    """The command as written, run in `directory` (exec: the process is the command itself)."""
    return [
        '/bin/sh',
        '-c',
        'cd "$0" && exec "$@"',
        str(directory),
        venv_executable(argv[0]),
        *argv[1:],
    ]


def launch_commands() -> list[list[str]]:
    """argv of the section's `ros2 launch` lines (its ```text blocks): measure, verify."""
    return readme_commands('text')


def test_readme_section_has_each_step():
    commands = readme_commands()
    steps = [(argv[0], argv[1] if argv[0] == 'hexacal' else '') for argv in commands]
    assert steps == [
        ('hexacal', 'plan'),
        ('hexacal', 'plan'),
        ('bringup', ''),
        ('hexacal', 'calibrate'),
        ('bringup', ''),
        ('hexacal', 'verify'),
        ('kinematics', ''),
        ('hexacal', 'export'),
    ]
    assert all(argv[0] in EXECUTABLES for argv in commands)
    measure = commands[2]
    for option in ('--no-driver', '--executor-plan', '--calibrate-when-done'):
        assert option in measure
    assert measure[measure.index('--sliders-topic') + 1] == '/joint_states'
    assert '/joint_trajectory_controller/joint_trajectory' in readme_section()
    # A ros2 launch line for each bringup line, naming the bag the next command reads.
    launches = launch_commands()
    assert [argv[:4] for argv in launches] == [ROS2_LAUNCH_PREFIX] * 2
    for argv, bag in zip(launches, ('measure', 'verify')):
        assert f'bag_name:={bag}' in argv and 'bag_dir:=bags' in argv
    assert commands[3][2] == 'bags/measure' and commands[5][2] == 'bags/verify'


def _launch_file():
    import importlib.util

    spec = importlib.util.spec_from_file_location('hexacal_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize('step, bringup_line', [(0, 2), (1, 4)], ids=['measure', 'verify'])
def test_the_ros2_launch_line_starts_what_the_bringup_line_starts(step, bringup_line):
    from hexacal_identify.bringup import cli as bringup

    module = _launch_file()
    launch = launch_commands()[step]
    arguments = dict(item.split(':=', 1) for item in launch[4:])
    assert set(arguments) <= set(module.ARGUMENTS)
    line = readme_commands()[bringup_line]
    from_bringup = bringup.node_launches(bringup.build_parser().parse_args(line[1:]))
    from_launch = module.node_launches(arguments)

    def nodes(launches):
        return {n.executable: (n.parameters, n.remaps, n.namespace) for n in launches}

    assert nodes(from_launch) == nodes(from_bringup)
    assert set(nodes(from_launch)) == {'collector', 'identify', 'kinematics', 'executor'}


def test_the_launch_file_offers_what_bringup_does_by_the_same_names():
    """Every bringup option that is a node setting is the launch argument of the same name."""
    from hexacal_identify.bringup import cli as bringup

    module = _launch_file()
    # bringup's own: its other node parameters, its stop timeout; a negated flag is the
    # launch argument it sets false.
    own = {'param', 'stop_timeout', 'help'}
    negated = {'no_driver': 'use_driver', 'no_kinematics': 'use_kinematics', 'no_record': 'record'}
    options = {a.dest for a in bringup.build_parser()._actions} - own
    assert {negated.get(o, o) for o in options} == set(module.ARGUMENTS)
    store = 'machine_store'
    values = {'bag_name': 'measure', 'calibration_store': store, 'use_driver': 'false'}
    nodes = {n.executable: n.parameters for n in module.node_launches(values)}
    options = ['--bag-name', 'measure', '--calibration-store', store, '--no-driver']
    options += ['--bag-dir', 'bags']  # the launch file's default, the collector's own
    from_bringup = bringup.node_launches(bringup.build_parser().parse_args(options))
    assert nodes == {n.executable: n.parameters for n in from_bringup}
    assert nodes['collector']['bag_name'] == 'measure'
    # identify stores and deploys, kinematics follows the deploys: one store for both.
    assert nodes['identify']['calibration_store'] == str(Path(store).resolve())
    assert nodes['kinematics']['calibration_store'] == str(Path(store).resolve())


def _standin(ros_processes, probe, truth: Path):
    """The commanded driver behind /joint_trajectory_controller/joint_trajectory + the relay."""
    from hexacal_msgs_py.qos import SENSOR_QOS
    from sensor_msgs.msg import JointState

    driver = ros_processes.start(
        node_argv(
            'driver',
            {
                'command_topic': DEFAULT_COMMAND_TOPIC,
                'true_params': str(truth),
                'max_actuator_speed_m_s': 1.0,
                'slider_noise_m': 1e-5,
                'angle_noise_rad': 1e-5,
            },
        )
        + [
            '-r',
            'hexacal/sliders:=machine/sliders',
            '-r',
            'hexacal/inclinometer:=machine/inclinometer',
            '-r',
            'hexacal/encoder:=machine/encoder',
        ]
    )
    relay = ros_processes.start([sys.executable, str(RELAY)], name='joint_state_broadcaster')
    joint_states: list = []
    probe.node.create_subscription(JointState, '/joint_states', joint_states.append, SENSOR_QOS)
    probe.spin_until(
        lambda: joint_states,
        60.0,
        'the stand-in on /joint_states',
        lambda: driver.describe() + '\n' + relay.describe(),
    )
    names = list(joint_states[-1].name)
    assert names[0] == 'gripper' and 'tilt_x' in names and 'link_rotary' in names
    assert names.index('leg_6') < names.index('leg_1')  # not hexacal's order
    return driver, relay, joint_states


def _run(tmp_path: Path, argv: list[str], timeout: float = 300.0) -> subprocess.CompletedProcess:
    return subprocess.run(_in(tmp_path, argv), capture_output=True, text=True, timeout=timeout)


def _launched_in(directory: Path, argv: list[str]) -> list[str]:
    """A `ros2 launch` line as written, run in `directory` by the stand-in (ROS2_LAUNCH)."""
    assert argv[:4] == ROS2_LAUNCH_PREFIX, argv
    fast = {}  # FAST_EXECUTOR's executor parameters, as bringup's --param gives them
    for option in FAST_EXECUTOR[1::2]:
        name, value = option.removeprefix('executor:').split('=')
        fast[name] = float(value)
    return [
        '/bin/sh',
        '-c',
        'cd "$0" && exec "$@"',
        str(directory),
        sys.executable,
        '-c',
        ROS2_LAUNCH,
        str(LAUNCH_FILE),
        json.dumps(fast),
        str(STOP_ALLOWANCE_S),
        *argv[4:],
    ]


def _walk(ros_processes, tmp_path, argv, postures: int, machine) -> str:
    """A bringup or ros2 launch line with shutdown when done: runs until the plan is walked."""
    if argv[0] == 'ros2':
        process = ros_processes.start(_launched_in(tmp_path, argv), name='ros2_launch')
    else:
        stop = ['--stop-timeout', str(STOP_ALLOWANCE_S)]
        process = ros_processes.start(_in(tmp_path, argv + FAST_EXECUTOR + stop), name='bringup')
    wait_for(
        lambda: not process.running() or any(not p.running() for p in machine),
        60.0 + 6.0 * postures + 60.0,
        interval=0.2,
        what=f'{argv[0]} to finish the plan',
        details=process.describe,
    )
    for p in machine:
        assert p.running(), p.describe()
    code = ros_processes.stop(process, STOP_TIMEOUT_S)
    log = process.log_path.read_text(errors='replace')
    assert code == 0, log[-6000:]
    assert 'the executor is done' in log and 'all nodes stopped cleanly' in log, log[-6000:]
    assert 'Traceback' not in log, log[-6000:]
    return log


@pytest.mark.slow  # about 50 s on 2 cores
def test_readme_own_machine_commands_on_a_ros2_control_standin(ros_processes, tmp_path, probe):
    from geometry_msgs.msg import PoseStamped
    from hexacal_identify.core.architectures import parameters_for
    from hexacal_identify.core.machine.live import solve_pose
    from hexacal_msgs_py.parameters_file import read_parameters_file
    from hexacal_msgs_py.poses import pose_from_message
    from hexacal_msgs_py.qos import POSE_QOS, SENSOR_QOS
    from sensor_msgs.msg import JointState

    truth_path, nominal_set2 = write_parameter_files(tmp_path / 'standin', MODEL)
    shutil.copy(nominal_set2, tmp_path / 'nominal.yaml')
    truth = parameters_for(MODEL, read_parameters_file(truth_path).vector)
    nominal = read_parameters_file(tmp_path / 'nominal.yaml').vector
    commands = iter(readme_commands())
    machine = _standin(ros_processes, probe, truth_path)[:2]

    # Plan the measurement and the verification.
    for _ in range(2):
        argv = next(commands)
        result = _run(tmp_path, argv)
        assert result.returncode == 0, result.stderr
    measured_postures = int(readme_commands()[0][readme_commands()[0].index('--postures') + 1])
    verify_postures = int(readme_commands()[1][readme_commands()[1].index('--postures') + 1])

    # Measure and calibrate (executor -> controller, collector on /joint_states, identify).
    log = _walk(ros_processes, tmp_path, next(commands), measured_postures, machine)
    assert 'started driver' not in log
    calibrated_path = tmp_path / 'out' / 'hexacal_calibration.yaml'
    calibrated = read_parameters_file(calibrated_path)
    assert calibrated.model == MODEL
    error_before = np.abs(nominal - truth.vector).max()
    error_after = np.abs(calibrated.vector - truth.vector).max()
    assert error_before > 1e-3 and error_after < 2e-4, (error_before, error_after)
    assert (tmp_path / 'bags' / 'measure' / 'metadata.yaml').exists()
    bag_metadata = (tmp_path / 'bags' / 'measure' / 'metadata.yaml').read_text()
    assert '/joint_states' in bag_metadata and 'tilt_x' in bag_metadata

    # The same recording, calibrated offline.
    result = _run(tmp_path, next(commands))
    assert result.returncode == 0, result.stderr
    offline = read_parameters_file(tmp_path / 'out' / 'offline.yaml').vector
    assert np.abs(offline - truth.vector).max() < 2e-4

    # Verify on a second recording, never used in the fit: the step's ros2 launch line (the
    # same nodes as its bringup line, test_the_ros2_launch_line_starts_what_the_bringup_line_starts).
    assert next(commands)[0] == 'bringup'
    log = _walk(ros_processes, tmp_path, launch_commands()[1], verify_postures, machine)
    assert 'started driver' not in log and 'started executor' in log
    assert (tmp_path / 'bags' / 'verify' / 'metadata.yaml').exists()
    argv = next(commands)
    result = _run(tmp_path, argv)
    assert result.returncode == 0, result.stdout + result.stderr  # pass
    figures = json.loads(_run(tmp_path, argv + ['--json']).stdout)
    assert figures['verdict'] == 'pass' and figures['postures'] >= verify_postures - 1
    assert figures['nominal']['position_rms_m'] > 1e-3  # millimetres off before
    assert figures['calibrated']['position_rms_m'] < 5e-5  # the noise level after
    assert figures['improvement'] > 20

    # Deploy: the kinematics node with the calibrated file publishes the platform pose.
    poses: list = []
    probe.node.create_subscription(PoseStamped, 'hexacal/platform_pose', poses.append, POSE_QOS)
    readings: dict[tuple[int, int], np.ndarray] = {}

    def on_joint_states(message) -> None:
        values = dict(zip(message.name, message.position))
        readings[(message.header.stamp.sec, message.header.stamp.nanosec)] = np.array(
            [values[f'leg_{i}'] for i in range(1, 7)]
        )

    probe.node.create_subscription(JointState, '/joint_states', on_joint_states, SENSOR_QOS)
    kinematics = ros_processes.start(_in(tmp_path, next(commands)), name='kinematics')

    def matched_pose():
        if not kinematics.running():
            raise AssertionError(kinematics.describe())
        for message in reversed(poses):
            stamp = (message.header.stamp.sec, message.header.stamp.nanosec)
            if stamp in readings:
                return message, readings[stamp]
        return None

    message, reading = probe.spin_until(
        matched_pose, 60.0, 'a platform pose of a reading', kinematics.describe
    )
    assert message.header.frame_id == 'hexacal_base'
    pose = np.array(pose_from_message(message.pose))
    true_pose = solve_pose(truth, reading, pose)
    assert np.abs(pose[:3] - true_pose[:3]).max() < 5e-5, (pose, true_pose)
    assert np.abs(pose[3:] - true_pose[3:]).max() < 1e-4
    code = ros_processes.stop(kinematics, STOP_TIMEOUT_S)
    assert code == 0, kinematics.log_path.read_text(errors='replace')

    # LinuxCNC settings of the calibrated hexapod.
    result = _run(tmp_path, next(commands))
    assert result.returncode == 0, result.stderr
    hal = (tmp_path / 'hexapod.hal').read_text()
    base_x = float(re.search(r'^setp genhexkins\.base\.0\.x\s+(\S+)', hal, re.M).group(1))
    assert base_x == pytest.approx(calibrated.vector[0] * 1000.0, abs=1e-5)  # leg 1's A_x, mm
    assert next(commands, None) is None  # every command of the section ran
