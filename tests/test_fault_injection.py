"""Process-level faults (issue #7): kill a node at the worst moment, fill the disk.

Real driver, collector and identify processes over Fast DDS; SIGKILL to the
process group; a small tmpfs made by the test for the disk-full case. The
collector SIGKILLed mid-recording is tests/test_system_kill.py.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import tempfile
import textwrap

from hexacal_identify.bag import open_bag
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.conversions import joint_state_to_posture_reading, stamp_ns
from hexacal_msgs_py.parameters_file import load_parameters, save_parameters
import numpy as np
import pytest
from rosproc import wait_for
from system_support import (
    fast_collector_parameters,
    fast_driver_parameters,
    node_argv,
    Probe,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    STOP_TIMEOUT_S,
    write_parameter_files,
)

ERROR = 2


def _collector_status(probe: Probe) -> dict:
    found = [
        values
        for _, _, values in probe.statuses
        if values.get('outcome') in ('recording', 'not-recording', 'recording-stopped')
    ]
    return found[-1] if found else {}


def _kill_group(process) -> None:
    os.killpg(process.pid, signal.SIGKILL)
    process.popen.wait(STOP_TIMEOUT_S)
    assert process.popen.returncode == -signal.SIGKILL


def _dwell_start_ns(log: str, posture: int) -> int | None:
    """ROS time at which the driver logged the start of the dwell at `posture` (1-based)."""
    match = re.search(rf'\[(\d+)\.(\d+)\] \[driver\]: posture {posture}/', log)
    return int(match.group(1)) * 10**9 + int(match.group(2)) if match else None


# --------------------------------------------------------------------------- driver


@pytest.mark.slow
def test_driver_killed_mid_posture_drops_the_partial_posture_and_reports_it(
    ros_processes, tmp_path, probe
):
    from hexacal_msgs_py.qos import SENSOR_QOS
    from sensor_msgs.msg import JointState

    truth, nominal = write_parameter_files(tmp_path)
    probe.subscribe_postures()
    probe.subscribe_status()
    newest_actuator_ns = [0]
    probe.node.create_subscription(
        JointState,
        'hexacal/sliders',
        lambda m: newest_actuator_ns.__setitem__(
            0, max(newest_actuator_ns[0], stamp_ns(m.header.stamp))
        ),
        SENSOR_QOS,
    )
    # Capture 2 s of a 3 s dwell: a kill 0.6 s into the dwell lands mid-capture.
    collector = ros_processes.start(
        node_argv(
            'collector',
            fast_collector_parameters(tmp_path / 'bags', bag_name='killed_driver', capture_s=2.0),
        )
    )
    identify = ros_processes.start(
        node_argv('identify', {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out')})
    )
    probe.wait_for_node('collector', process=collector)
    probe.wait_for_node('identify', process=identify)
    driver_parameters = fast_driver_parameters(
        plan='fixed', postures=4, dwell_s=3.0, true_params=str(truth)
    )
    driver = ros_processes.start(node_argv('driver', driver_parameters))
    nodes = lambda: '\n'.join(p.describe(15) for p in (collector, identify, driver))  # noqa: E731

    probe.spin_until(lambda: len(probe.postures) == 1, 60.0, 'the first posture', nodes)
    dwell = probe.spin_until(
        lambda: _dwell_start_ns(driver.log_text(), 2), 30.0, 'the dwell at posture 2', nodes
    )
    probe.spin_until(
        lambda: newest_actuator_ns[0] >= dwell + 600_000_000,
        10.0,
        '0.6 s of the dwell at posture 2',
        nodes,
    )
    _kill_group(driver)

    # Each stream is reported stopped once its own last message is stale: under load they need not go
    # stale in the same status, so wait for the one that names all three.
    every_stream = {'/hexacal/sliders', '/hexacal/inclinometer', '/hexacal/encoder'}
    status = probe.spin_until(
        lambda: (
            _collector_status(probe).get('dropped.stream_stopped') == '1'
            and set(_collector_status(probe).get('streams_stopped', '').split(', '))
            == every_stream
            and _collector_status(probe)
        ),
        15.0,
        'the dropped partial posture and all three streams stopped',
        nodes,
    )
    assert status['dropped.stream_stopped'] == '1'
    assert set(status['streams_stopped'].split(', ')) == every_stream
    assert 'dropped a partial posture' in collector.log_text()
    assert len(probe.postures) == 1  # the half-measured posture was never published ...
    assert probe.postures_received_by_identify() == 1  # ... so identify never stored it

    # The driver comes back: the collector goes on, the standing posture is measured in full.
    driver = ros_processes.start(node_argv('driver', driver_parameters), name='driver-restarted')
    probe.spin_until(
        lambda: len(probe.postures) == 2, 60.0, 'a posture from the restarted driver', nodes
    )
    probe.spin_until(
        lambda: 'streams_stopped' not in _collector_status(probe),
        15.0,
        'the streams reported back',
        nodes,
    )
    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0
    log = collector.log_path.read_text()
    # The summary counts the partial posture once; under load a capture window with a gap may
    # be dropped besides (its own kind, 'gap').
    dropped = re.search(r'periods dropped (\{[^}]*\})', log)
    assert dropped and ast.literal_eval(dropped.group(1)).get('stream_stopped') == 1, log
    in_bag = [
        joint_state_to_posture_reading(m.decoded)
        for m in open_bag(tmp_path / 'bags' / 'killed_driver').messages(['/hexacal/posture'])
    ]
    assert in_bag == probe.postures


# --------------------------------------------------------------------------- identify


@pytest.mark.slow
def test_identify_killed_during_a_calibration_keeps_the_last_good_one(
    ros_processes, tmp_path, probe
):
    out = tmp_path / 'out'
    previous = nominal_set(1, seed=4).vector  # the last good calibration, already on disk
    saved = out / 'hexacal_calibration.yaml'
    save_parameters(saved, previous, header_comment='previous calibration')
    before = saved.read_bytes()
    nominal = tmp_path / 'nominal_set3.yaml'
    save_parameters(nominal, nominal_set(3, seed=0).vector)
    # 600 postures from nominal set 3 with a robust loss: a solve of seconds to kill into.
    identify = ros_processes.start(
        node_argv(
            'identify',
            {
                'nominal': str(nominal),
                'output_dir': str(out),
                'robust_loss': 'huber',
                'report_dir': '',
            },
        )
    )
    probe.wait_for_node('identify', process=identify)
    probe.subscribe_status()
    republished = probe.subscribe_parameters()
    assert np.array_equal(
        probe.spin_until(lambda: republished, 15.0, 'the saved calibration')[0], previous
    )
    postures = simulated_postures(600, seed=21)
    probe.publish_postures(postures)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 600,
        60.0,
        'identify to hold 600 postures',
        identify.describe,
    )
    future = probe.trigger_async()
    probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('outcome') == 'running'],
        30.0,
        'the calibration to run',
        identify.describe,
    )
    _kill_group(identify)

    assert not future.done()  # killed before it answered
    assert saved.read_bytes() == before  # the previous file, whole
    assert sorted(p.name for p in out.iterdir()) == ['hexacal_calibration.yaml']

    restarted = ros_processes.start(
        node_argv('identify', {'nominal': str(nominal), 'output_dir': str(out)}),
        name='identify-restarted',
    )
    probe.spin_until(
        lambda: 'republished the saved calibration' in restarted.log_text(),
        30.0,
        'the restarted node to republish',
        restarted.describe,
    )
    late = Probe()  # a subscriber that joins after the restart
    try:
        again = late.subscribe_parameters()
        late.spin_until(lambda: again, 15.0, 'the republished calibration', restarted.describe)
        assert np.array_equal(again[0], previous)
    finally:
        late.close()


_WRITER = textwrap.dedent("""
    import sys
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_msgs_py.parameters_file import save_parameters
    vectors = [nominal_set(1, seed=1).vector, nominal_set(2, seed=2).vector]
    count = 0
    while True:
        save_parameters(sys.argv[1], vectors[count % 2], header_comment="x" * 20000)
        count += 1
        print(count, flush=True)
""")


@pytest.mark.slow
def test_a_parameters_file_killed_mid_write_is_old_or_new_never_partial(
    ros_processes, tmp_path, probe
):
    out = tmp_path / 'out'
    target = out / 'hexacal_calibration.yaml'
    vectors = [nominal_set(1, seed=1).vector, nominal_set(2, seed=2).vector]
    save_parameters(target, vectors[1])
    for kill in range(8):
        writer = ros_processes.start(
            [sys.executable, '-c', _WRITER, str(target)], name=f'writer-{kill}'
        )
        wait_for(
            lambda: len(writer.log_text().split()) >= 3 + kill,
            60.0,
            interval=0.001,
            what=f'{3 + kill} writes',
            details=writer.describe,
        )
        _kill_group(writer)
        ros_processes.stop(writer)
        loaded = load_parameters(target)  # parses, validates: a whole file
        index = [i for i, v in enumerate(vectors) if np.array_equal(loaded, v)]
        assert index, 'the target holds neither the old nor the new parameters'
    leftovers = sorted(out.glob('.hexacal_calibration.yaml.*.tmp'))
    # A write cut short leaves at most its temporary file, never a partial target; one more,
    # half written by hand, stands for the case the kills above happened to miss.
    (out / '.hexacal_calibration.yaml.cut1234.tmp').write_text(
        '/**:\n  ros__parameters:\n    chain_1.A0: [0.1,'
    )
    final = load_parameters(target)

    identify = ros_processes.start(node_argv('identify', {'output_dir': str(out)}))
    probe.wait_for_node('identify', process=identify)
    received = probe.subscribe_parameters()
    assert np.array_equal(
        probe.spin_until(lambda: received, 15.0, 'the saved calibration')[0], final
    )
    assert not list(out.glob('.*.tmp'))
    assert identify.log_text().count('an interrupted write') == len(leftovers) + 1


# --------------------------------------------------------------------------- disk full


@pytest.fixture
def small_tmpfs():
    """A 1 MiB tmpfs for the bag directory (root only; skipped otherwise)."""
    mount_point = Path(tempfile.mkdtemp(prefix='hexacal-full-'))
    try:
        result = subprocess.run(
            ['mount', '-t', 'tmpfs', '-o', 'size=1m', 'tmpfs', str(mount_point)],
            capture_output=True,
            text=True,
        )
    except OSError as error:
        mount_point.rmdir()
        pytest.skip(f'cannot run mount: {error}')
    if result.returncode != 0:
        mount_point.rmdir()
        pytest.skip(f'cannot mount a 1 MiB tmpfs (needs root): {result.stderr.strip()}')
    try:
        yield mount_point
    finally:
        if subprocess.run(['umount', str(mount_point)], check=False).returncode != 0:
            subprocess.run(['umount', '-l', str(mount_point)], check=False)
        mount_point.rmdir()


@pytest.mark.slow
def test_disk_full_stops_recording_with_a_clear_error_and_a_readable_bag(
    small_tmpfs, ros_processes, tmp_path, probe
):
    truth, _ = write_parameter_files(tmp_path)
    probe.subscribe_postures()
    probe.subscribe_status()
    collector = ros_processes.start(
        node_argv('collector', fast_collector_parameters(small_tmpfs, bag_name='full'))
    )
    probe.wait_for_node('collector', process=collector)
    driver = ros_processes.start(
        node_argv(
            'driver', fast_driver_parameters(postures=40, rate_hz=400.0, true_params=str(truth))
        )
    )
    nodes = lambda: collector.describe() + '\n' + driver.describe()  # noqa: E731

    level, message, values = probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('outcome') == 'recording-stopped'],
        90.0,
        'the recording to stop on a full disk',
        nodes,
    )[-1]
    assert level == ERROR
    assert 'No space left on device' in message and str(small_tmpfs / 'full') in message
    assert values['recording_error'].startswith('write: ')
    assert 'recording stopped: ' in collector.log_text()
    at_error = len(probe.postures)
    # The collector lives on: postures are still detected and published, just not recorded.
    probe.spin_until(
        lambda: len(probe.postures) >= at_error + 2, 30.0, 'postures after the disk filled', nodes
    )
    assert collector.running()

    # The bag holds everything up to the last flush before the disk filled, and reads.
    reader = open_bag(small_tmpfs / 'full')
    in_bag = [
        joint_state_to_posture_reading(m.decoded) for m in reader.messages(['/hexacal/posture'])
    ]
    assert 1 <= len(in_bag) <= at_error + 1
    first = probe.postures.index(in_bag[0])
    assert first <= 1 and probe.postures[first : first + len(in_bag)] == in_bag
    counts = {name: topic.count for name, topic in reader.topics().items()}
    assert (
        min(counts[s] for s in ('/hexacal/sliders', '/hexacal/inclinometer', '/hexacal/encoder'))
        > 400
    )
    for process in (driver, collector):
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
