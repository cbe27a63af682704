"""
Test that every node stops cleanly on Ctrl-C as a terminal and `ros2 launch` send it, and SIGTERM.

Ctrl-C under `ros2 launch`: the terminal sends SIGINT to the process group, then
launch forwards another SIGINT to each node ~50 ms later, while the node is
shutting down. Either way, and on SIGTERM, a node exits 0 with no traceback and
leaves its files finished: the bag with metadata.yaml and its MCAP footer
(readable by rosbags), the parameters file and report complete or untouched.
During start-up the same holds from the moment the entry point has installed its
handlers (nodes.entry), observed in /proc, not guessed with a delay.
"""

from __future__ import annotations

from collections.abc import Callable
import os
from pathlib import Path
import signal
import time

from hexacal_identify.bag import open_bag
from hexacal_msgs_py.parameters_file import load_parameters
import pytest
from rosproc import RosProcess, venv_executable, wait_for
import system_support
from system_support import (
    fast_collector_parameters,
    fast_driver_parameters,
    hexacal_plan,
    node_argv,
    STOP_TIMEOUT_S,
    write_parameter_files,
)

probe = system_support.probe  # the fixture, for this module's tests

REPOSITORY = Path(__file__).resolve().parents[1]
SAMPLE_BAG = REPOSITORY / 'bags' / 'sphere60_fixed20_noise10'
LAUNCH_FORWARD_DELAY_S = 0.05  # launch's SIGINT follows the terminal's by about this much

PATTERNS = ('ctrl-c-under-launch', 'sigterm')


def send(process: RosProcess, pattern: str) -> None:
    if pattern == 'sigterm':
        os.killpg(process.pid, signal.SIGTERM)
        return
    os.killpg(process.pid, signal.SIGINT)  # the terminal: the whole group
    time.sleep(LAUNCH_FORWARD_DELAY_S)  # the signal pattern itself, not a wait for a condition
    try:
        os.kill(process.pid, signal.SIGINT)  # ros2 launch: the node itself, during its shutdown
    except ProcessLookupError:
        pass  # already gone: nothing left to interrupt


def assert_clean_exit(process: RosProcess, pattern: str) -> str:
    send(process, pattern)
    process.popen.wait(STOP_TIMEOUT_S)
    log = process.log_text()
    assert process.popen.returncode == 0, log
    assert 'Traceback' not in log and 'KeyboardInterrupt' not in log, log
    return log


def assert_bag_finished(bag: Path) -> None:
    from rosbags.rosbag2 import Reader

    assert (bag / 'metadata.yaml').exists()
    assert not open_bag(bag).info().truncated  # the MCAP footer is there
    with Reader(bag) as reader:  # an independent reader accepts the directory as it is
        assert reader.message_count == sum(1 for _ in reader.messages())
        assert reader.message_count > 0
    assert not list(bag.glob('.*.tmp'))


@pytest.mark.slow
@pytest.mark.parametrize('pattern', PATTERNS)
def test_collector_and_driver_stop_cleanly_while_recording(
    pattern, ros_processes, tmp_path, probe
):
    truth, _ = write_parameter_files(tmp_path)
    probe.subscribe_postures()
    collector = ros_processes.start(
        node_argv('collector', fast_collector_parameters(tmp_path / 'bags', bag_name='stopped'))
    )
    probe.wait_for_node('collector', process=collector)
    driver = ros_processes.start(
        node_argv('driver', fast_driver_parameters(postures=30, seed=4, true_params=str(truth)))
    )
    probe.spin_until(
        lambda: len(probe.postures) >= 2,
        60.0,
        'two postures',
        lambda: collector.describe() + '\n' + driver.describe(),
    )

    # The collector first: it is still receiving all three streams when the signals arrive.
    # (Whatever an assertion leaves running, the fixture's teardown stops.)
    assert_clean_exit(collector, pattern)
    assert_clean_exit(driver, pattern)
    assert_bag_finished(tmp_path / 'bags' / 'stopped')


@pytest.mark.slow
@pytest.mark.parametrize('pattern', PATTERNS)
def test_identify_stops_cleanly_during_a_calibration(pattern, ros_processes, tmp_path, probe):
    _, nominal = write_parameter_files(tmp_path)
    out = tmp_path / 'out'
    identify = ros_processes.start(
        node_argv(
            'identify', {'nominal': str(nominal), 'bag': str(SAMPLE_BAG), 'output_dir': str(out)}
        )
    )
    probe.wait_for_node('identify', process=identify)
    probe.trigger_async()
    probe.spin_until(
        lambda: 'calibrating from' in identify.log_text(),
        60.0,
        'the calibration to start',
        identify.describe,
    )

    log = assert_clean_exit(identify, pattern)
    # What the node logs while it stops comes after it is destroyed: no rcl error from a rosout
    # publisher whose context the signal shut down.
    assert 'Failed to publish log message to rosout' not in log, log
    assert "publisher's context is invalid" not in log, log
    # Complete or untouched: a parameters file, if there is one, loads whole; no temp files left.
    written = sorted(p.name for p in out.rglob('*') if p.is_file()) if out.exists() else []
    assert not [name for name in written if name.endswith('.tmp')], written
    for path in out.glob('*.yaml'):
        assert load_parameters(path).shape == (54,)
    for path in out.rglob('*.html'):
        assert path.read_text().rstrip().endswith('</html>'), path


@pytest.mark.slow
@pytest.mark.parametrize('pattern', PATTERNS)
def test_replay_stops_cleanly_while_publishing(pattern, ros_processes, probe):
    replay = ros_processes.start(
        [venv_executable('replay'), str(SAMPLE_BAG), '--loop', '--rate', '5']
    )
    probe.spin_until(
        lambda: probe.node.count_publishers('/hexacal/sliders') >= 1,
        60.0,
        'the replay publishers',
        replay.describe,
    )

    assert_clean_exit(replay, pattern)


def _plan(tmp_path: Path, nominal: Path) -> Path:
    out = tmp_path / 'plan.yaml'
    if not out.exists():
        hexacal_plan(out, nominal, '--postures', 12, '--candidates', 200)
    return out


@pytest.mark.slow
@pytest.mark.parametrize('pattern', PATTERNS)
@pytest.mark.parametrize('executable', ('executor', 'kinematics'))
def test_executor_and_kinematics_stop_cleanly_while_running(
    executable, pattern, ros_processes, tmp_path, probe
):
    """
    Stop the executor waiting for its machine and the kinematics node waiting for readings.

    Both exit 0 on the launch pattern and on SIGTERM.
    """
    _, nominal = write_parameter_files(tmp_path)
    parameters = {
        'executor': {'plan': str(_plan(tmp_path, nominal)), 'nominal': str(nominal)},
        'kinematics': {'parameters': str(nominal)},
    }[executable]
    process = ros_processes.start(node_argv(executable, parameters))
    probe.wait_for_node(executable, process=process)
    assert_clean_exit(process, pattern)


def _proc(process: RosProcess, name: str) -> str:
    """Return /proc/<pid>/<name> of a running process; fail with its log if it has exited."""
    if not process.running():
        raise AssertionError(f'exited during start-up\n{process.describe()}')
    try:
        return (Path('/proc') / str(process.pid) / name).read_text()
    except (FileNotFoundError, ProcessLookupError):  # exited since running() looked
        raise AssertionError(f'exited during start-up\n{process.describe()}') from None


def _catches_sigterm(process: RosProcess) -> bool:
    """
    Tell whether the entry point's remember_termination_signals() has run.

    The interpreter catches SIGINT from its own start (default_int_handler), but not SIGTERM:
    a caught SIGTERM in SigCgt shows the node's handlers are in place.
    """
    for line in _proc(process, 'status').splitlines():
        if line.startswith('SigCgt:'):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGTERM - 1)))
    return False


def _maps(fragment: str) -> Callable[[RosProcess], bool]:
    return lambda process: fragment in _proc(process, 'maps')


# What a process can promise starts where its handlers exist: before that (the interpreter's own
# start-up, importing `signal`) a SIGINT is the interpreter's KeyboardInterrupt, which no Python
# code can catch. From there on, observable moments of start-up, in order:
STARTUP_STAGES = {
    'handlers installed, importing the node module': _catches_sigterm,
    'rclpy loaded': _maps('_rclpy_pybind11'),
    # rclpy.init has created the DDS participant (Fast DDS maps its shared-memory segments): the
    # signal lands in rclpy.init or the node's constructor.
    'participant created': _maps('/dev/shm/'),
}


@pytest.mark.slow
@pytest.mark.parametrize(
    'executable', ('collector', 'identify', 'driver', 'executor', 'kinematics')
)
def test_ctrl_c_while_a_node_starts_is_a_clean_stop(executable, ros_processes, tmp_path):
    """
    Stop cleanly on a Ctrl-C during start-up, once the entry point has installed its handlers.

    Exit 0, no traceback, no 'cannot start', bags finished, at each stage of STARTUP_STAGES.
    """
    _, nominal = write_parameter_files(tmp_path)
    parameters = {
        'collector': {'output_dir': str(tmp_path / 'bags')},
        'identify': {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out')},
        'driver': fast_driver_parameters(postures=5),
        'executor': {'plan': str(_plan(tmp_path, nominal)), 'nominal': str(nominal)},
        'kinematics': {'parameters': str(nominal)},
    }[executable]
    for stage, reached in STARTUP_STAGES.items():
        process = ros_processes.start(node_argv(executable, parameters))
        # Polled every millisecond: the signal lands at this stage or a few ms after it.
        wait_for(lambda: reached(process), 60.0, 0.001, stage, process.describe)
        log = assert_clean_exit(process, 'ctrl-c-under-launch')
        assert 'cannot start' not in log, f'{stage}:\n{log}'
    for bag in (tmp_path / 'bags').glob('*') if executable == 'collector' else ():
        if any(bag.glob('*.mcap')):  # a bag that was opened is finished
            assert (bag / 'metadata.yaml').exists(), sorted(p.name for p in bag.iterdir())
