"""System tests of shutdown: a SIGKILLed collector's bag is recoverable; Ctrl-C is clean.

Real driver, collector and identify processes over Fast DDS.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import signal
import subprocess

from hexacal_identify.bag import open_bag, reindex
from hexacal_msgs_py.conversions import joint_state_to_posture_reading
from hexacal_msgs_py.parameters_file import load_parameters
import numpy as np
import pytest
from rosproc import RosProcesses, venv_executable
from system_support import (
    fast_collector_parameters,
    fast_driver_parameters,
    node_argv,
    Probe,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)

POSTURES_BEFORE_KILL = 16  # enough for the 54 parameters (4 residuals per posture)


@dataclass
class KilledRecording:
    bag: Path
    received: list  # postures the probe received; all were published before the kill
    metadata_after_kill: bool
    nominal: Path
    truth: Path


@pytest.fixture(scope='module')
def killed_recording(tmp_path_factory) -> KilledRecording:
    """Record with collector + driver, SIGKILL the collector after 16 postures."""
    tmp_path = tmp_path_factory.mktemp('killed')
    truth, nominal = write_parameter_files(tmp_path)
    processes = RosProcesses(tmp_path / 'logs')
    probe = Probe()
    try:
        probe.subscribe_postures()
        collector = processes.start(
            node_argv('collector', fast_collector_parameters(tmp_path / 'bags', bag_name='killed'))
        )
        probe.wait_for_node('collector', process=collector)
        probe.spin_until(
            lambda: probe.node.count_publishers('/hexacal/posture') >= 1,
            30.0,
            'the posture publisher',
            collector.describe,
        )
        driver = processes.start(
            node_argv(
                'driver', fast_driver_parameters(postures=40, seed=1, true_params=str(truth))
            )
        )

        def enough() -> bool:
            for process in (collector, driver):
                if not process.running():
                    raise AssertionError(f'a node exited early\n{process.describe()}')
            return len(probe.postures) >= POSTURES_BEFORE_KILL

        probe.spin_until(
            enough,
            120.0,
            f'{POSTURES_BEFORE_KILL} postures',
            lambda: collector.describe() + '\n' + driver.describe(),
        )
        os.killpg(collector.pid, signal.SIGKILL)
        collector.popen.wait(STOP_TIMEOUT_S)
        assert collector.popen.returncode == -signal.SIGKILL
        probe.spin_for(0.5)  # postures still in flight were published before the kill
        bag = tmp_path / 'bags' / 'killed'
        return KilledRecording(
            bag, list(probe.postures), (bag / 'metadata.yaml').exists(), nominal, truth
        )
    finally:
        probe.close()
        processes.stop_all(STOP_TIMEOUT_S)


@pytest.mark.slow
def test_sigkilled_recording_is_recovered_with_every_published_posture(killed_recording):
    bag = killed_recording.bag
    assert not killed_recording.metadata_after_kill  # a real crash: the bag was never closed
    info = reindex(bag)
    assert (bag / 'metadata.yaml').exists()
    assert info.truncated  # no MCAP footer: read up to the last complete record
    reader = open_bag(bag)
    in_bag = [
        joint_state_to_posture_reading(m.decoded) for m in reader.messages(['/hexacal/posture'])
    ]
    received = killed_recording.received
    assert len(received) >= POSTURES_BEFORE_KILL
    # Recorded and flushed before publishing: every received posture is in the bag, in order,
    # plus at most the one being published when the process died.
    first = in_bag.index(received[0])
    assert first <= 1  # the probe may miss the first if its match came late, not more
    assert in_bag[first : first + len(received)] == received
    assert len(in_bag) - (first + len(received)) <= 1
    counts = {name: topic.count for name, topic in reader.topics().items()}
    assert counts['/hexacal/posture'] == len(in_bag)
    assert counts == {
        t['topic_metadata']['name']: t['message_count']
        for t in _metadata(bag)['topics_with_message_count']
    }
    for stream in ('/hexacal/sliders', '/hexacal/inclinometer', '/hexacal/encoder'):
        assert counts[stream] > 100 * len(in_bag) * 0.5  # ~100 Hz for ~1 s per posture


def _metadata(bag: Path) -> dict:
    import yaml

    return yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


@pytest.mark.slow
def test_hexacal_calibrate_works_on_the_recovered_bag(killed_recording, tmp_path):
    hexacal = venv_executable('hexacal')
    usage = subprocess.run(
        [hexacal, 'calibrate', '--help'], capture_output=True, text=True, timeout=60
    )
    if usage.returncode != 0 or '--nominal' not in usage.stdout or '--output' not in usage.stdout:
        pytest.skip(
            f'`hexacal calibrate --nominal --output` is not available: {usage.stderr[-300:]}'
        )
    bag = killed_recording.bag
    if not (bag / 'metadata.yaml').exists():
        reindex(bag)
    output = tmp_path / 'from_bag.yaml'
    result = subprocess.run(
        [
            hexacal,
            'calibrate',
            str(bag),
            '--nominal',
            str(killed_recording.nominal),
            '--output',
            str(output),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    error = np.abs(load_parameters(output) - load_parameters(killed_recording.truth)).max()
    assert error < 1e-3, f'max parameter error {error * 1e3:.3f} mm'


@pytest.mark.slow
def test_ctrl_c_stops_each_node_cleanly_and_closes_its_files(ros_processes, tmp_path, probe):
    truth, nominal = write_parameter_files(tmp_path)
    probe.subscribe_postures()
    probe.subscribe_status()
    collector = ros_processes.start(
        node_argv('collector', fast_collector_parameters(tmp_path / 'bags', bag_name='clean'))
    )
    identify = ros_processes.start(
        node_argv('identify', {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out')})
    )
    probe.wait_for_node('collector', process=collector)
    probe.wait_for_node('identify', process=identify)
    driver = ros_processes.start(
        node_argv('driver', fast_driver_parameters(postures=20, seed=2, true_params=str(truth)))
    )
    probe.spin_until(
        lambda: probe.postures_received_by_identify() >= 3,
        60.0,
        'identify to receive 3 postures',
        lambda: '\n'.join(p.describe() for p in (collector, identify, driver)),
    )

    for process in (driver, collector, identify):  # Ctrl-C = SIGINT to the process group
        code = ros_processes.stop(process, STOP_TIMEOUT_S)
        log = process.log_path.read_text(errors='replace')  # stop() closed the log handle
        assert code == 0, log
        assert 'Traceback' not in log and 'rosout' not in log, log
    bag = tmp_path / 'bags' / 'clean'
    assert (bag / 'metadata.yaml').exists()  # closed: metadata written on shutdown
    info = open_bag(bag).info()
    assert not info.truncated  # the MCAP has its footer
    assert info.topics['/hexacal/posture'].count >= 3
    assert not list(bag.glob('.*.tmp'))


def test_sigterm_also_stops_the_collector_cleanly(ros_processes, tmp_path, probe):
    collector = ros_processes.start(
        node_argv('collector', {'output_dir': str(tmp_path / 'bags'), 'bag_name': 'terminated'})
    )
    probe.wait_for_node('collector', process=collector)
    # The node is in the graph before its constructor ends; the bag opens last. A signal before
    # that stops it with no bag (start-up); this test is about a collector that is recording.
    bag = tmp_path / 'bags' / 'terminated'
    probe.spin_until(bag.is_dir, 60.0, 'the collector to open its bag', collector.describe)
    os.killpg(collector.pid, signal.SIGTERM)
    collector.popen.wait(STOP_TIMEOUT_S)
    assert collector.popen.returncode == 0, collector.describe()
    assert (bag / 'metadata.yaml').exists()


@pytest.mark.slow
def test_identify_calibrates_from_the_recovered_bag(
    killed_recording, ros_processes, tmp_path, probe
):
    bag = killed_recording.bag
    if not (bag / 'metadata.yaml').exists():
        reindex(bag)
    identify = ros_processes.start(
        node_argv(
            'identify',
            {
                'nominal': str(killed_recording.nominal),
                'bag': str(bag),
                'output_dir': str(tmp_path),
            },
        )
    )
    probe.wait_for_node('identify', process=identify)
    received = probe.subscribe_parameters()
    response = probe.call_trigger()
    assert response.success, response.message
    assert f'bag {bag}' in identify.log_text()
    vector = probe.spin_until(lambda: received, 10.0, 'hexacal/parameters')[0]
    assert np.abs(vector - load_parameters(killed_recording.truth)).max() < 1e-3
