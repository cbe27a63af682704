"""Each console script starts, shows a sign of life and exits 0 on Ctrl-C; the launch file compiles."""
from __future__ import annotations

import importlib.util
from pathlib import Path
import re
import subprocess

import pytest

from rosproc import venv_executable
from system_support import (  # noqa: F401 - probe is a fixture
    STOP_TIMEOUT_S,
    node_argv,
    pid_alive,
    probe,
    write_parameter_files,
)

REPO = Path(__file__).resolve().parents[1]
LAUNCH_FILE = REPO / 'ros2_ws/src/hexacal_identify/launch/hexacal.launch.py'


@pytest.mark.parametrize('executable, startup_line', [
    ('driver', 'holding the first posture until'),
    ('collector', 'recording to'),
    ('identify', 'collecting postures on'),
    ('executor', 'waiting for actuator readings'),
])
def test_node_starts_and_exits_0_on_ctrl_c(ros_processes, tmp_path, probe, executable,
                                           startup_line):
    parameters = {'collector': {'output_dir': str(tmp_path / 'bags'), 'bag_name': 'smoke'},
                  'identify': {'output_dir': str(tmp_path)},
                  'executor': _executor_files(tmp_path)}.get(executable, {})
    process = ros_processes.start(node_argv(executable, parameters))
    probe.wait_for_node(executable, process=process)  # on the graph
    probe.spin_until(lambda: startup_line in process.log_text(), 15.0,
                     f'{startup_line!r} in the log', process.describe)
    code = ros_processes.stop(process, STOP_TIMEOUT_S)
    log = process.log_path.read_text(errors='replace')
    assert code == 0, log
    assert 'Traceback' not in log, log
    if executable == 'collector':
        assert (tmp_path / 'bags' / 'smoke' / 'metadata.yaml').exists()


@pytest.mark.parametrize('executable, parameters, problem', [
    ('driver', {'rate_hz': 0.5}, 'rate_hz out of range'),
    ('driver', {'plan': 'spiral'}, "plan 'spiral' is neither"),
    ('identify', {'cost': 'quadratic'}, 'cost must be one of'),
    ('identify', {'output': '/etc/hexacal.yaml'}, 'is outside output_dir'),
    ('collector', {'bag_name': 'a/b'}, 'bag_name must be a plain directory name'),
])
def test_bad_parameters_stop_a_node_with_the_reason(tmp_path, executable, parameters, problem):
    if executable == 'identify':
        parameters = {'output_dir': str(tmp_path), **parameters}
    result = subprocess.run(node_argv(executable, parameters), capture_output=True, text=True,
                            timeout=60, cwd=tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert problem in result.stdout + result.stderr


def _executor_files(directory: Path, model: str | None = None) -> dict[str, str]:
    """plan and nominal parameters of an executor: a generated mixed plan of 8 postures."""
    from hexacal_driver.plan import generated_plan, save_plan
    from hexacal_identify.core.architectures import default_parameters

    _, nominal = write_parameter_files(directory, model)
    plan = directory / f'plan_{model or "hexa_slide"}.yaml'
    save_plan(plan, generated_plan('mixed', default_parameters(model), 8, seed=0))
    return {'plan': str(plan), 'nominal': str(nominal)}


@pytest.mark.parametrize('parameters, problem', [
    ({}, "parameter 'plan' is required"),
    ({'settle_s': 0.0}, 'settle_s out of range'),
    ({'max_corrections': -1}, 'max_corrections out of range'),
    ({'command_topic': 'bad topic'}, 'command_topic'),
    ({'inclinometer_joints': '[a, a]'}, 'inclinometer_joints must be 2 distinct joint names'),
    ({'stroke_limits_m': '[0.9, 0.1]'}, 'stroke limits must be two finite numbers'),
    ({'nominal': '/nonexistent.yaml'}, 'nominal:'),
    ({'model': 'gough_stewart'}, 'was made for a gough_stewart'),
])
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


@pytest.mark.parametrize('command, expected', [
    (['bringup', '--help'], '--namespace'),
    (['hexacal', '--help'], 'demo'),
    (['hexacal', 'demo', '--help'], '--noise-um'),
])
def test_help_exits_0(command, expected):
    result = subprocess.run([venv_executable(command[0]), *command[1:]], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert expected in result.stdout


@pytest.mark.slow
def test_bringup_starts_three_nodes_and_stops_them_on_ctrl_c(ros_processes, tmp_path, probe):
    bringup = ros_processes.start([
        venv_executable('bringup'), '--namespace', 'smoke', '--bag-dir', str(tmp_path / 'bags'),
        '--output-dir', str(tmp_path / 'out'), '--plan', 'random', '--postures', '3',
        '--param', 'collector:bag_name=smoke_bag'])
    for name in ('driver', 'collector', 'identify'):
        probe.wait_for_node(name, '/smoke', bringup)
    pids = {int(pid) for pid in re.findall(r'started \w+ \(pid (\d+)\)', bringup.log_text())}
    assert len(pids) == 3
    code = ros_processes.stop(bringup, STOP_TIMEOUT_S)
    log = bringup.log_path.read_text(errors='replace')
    assert code == 0, log
    assert 'all nodes stopped cleanly' in log, log
    assert not [pid for pid in pids if pid_alive(pid)]
    assert (tmp_path / 'bags' / 'smoke_bag' / 'metadata.yaml').exists()


def test_launch_file_compiles():
    source = LAUNCH_FILE.read_text()
    compile(source, str(LAUNCH_FILE), 'exec')
    spec = importlib.util.spec_from_file_location('hexacal_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # imports nothing from launch at module level
    assert callable(module.generate_launch_description)
    assert {'namespace', 'nominal', 'plan', 'postures'} <= set(module.ARGUMENTS)


def test_launch_description_builds_where_launch_is_installed():
    pytest.importorskip('launch_ros', reason='launch/launch_ros are not on PyPI; ROS installs only')
    spec = importlib.util.spec_from_file_location('hexacal_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    assert len(description.entities) == len(module.ARGUMENTS) + 3


def test_driver_validates_parameter_changes_at_runtime(ros_processes, probe):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    driver = ros_processes.start(node_argv('driver', {'plan': 'fixed', 'postures': 3}))
    probe.wait_for_node('driver', process=driver)
    client = AsyncParameterClient(probe.node, '/driver')
    probe.spin_until(client.services_are_ready, 15.0, "the driver's parameter services")

    def set_one(name: str, value: object):
        future = client.set_parameters([Parameter(name, value=value)])
        return probe.spin_until(lambda: future.result() if future.done() else None, 15.0,
                                f'setting {name}').results[0]

    accepted = set_one('slider_noise_m', 2e-5)
    assert accepted.successful, accepted.reason
    negative = set_one('slider_noise_m', -1e-5)
    assert not negative.successful and 'out of range' in negative.reason
    read_only = set_one('plan', 'random')
    assert not read_only.successful and 'read-only' in read_only.reason
    future = client.describe_parameters(['settle_s', 'plan_name'])
    settle, plan_name = probe.spin_until(lambda: future.result() if future.done() else None,
                                         15.0, 'parameter descriptors').descriptors
    assert settle.description and settle.floating_point_range[0].from_value > 0
    assert plan_name.read_only
    future = client.get_parameters(['plan_name'])
    values = probe.spin_until(lambda: future.result() if future.done() else None, 15.0,
                              'plan_name').values
    assert values[0].string_value == 'fixed-3-seed0'
    probe.spin_until(lambda: 'noise now +-2e-05 m' in driver.log_text(), 10.0,
                     'the noise change in the log', driver.describe)
