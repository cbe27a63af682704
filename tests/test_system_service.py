"""System tests of the identify node's service: busy, refusals, restart, namespaces.

Real `identify` processes over Fast DDS; the test process publishes simulated
postures and calls the service through an in-process probe node.
"""

from __future__ import annotations

import time

from hexacal_identify.bag import open_bag
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.parameters_file import load_parameters, save_parameters
import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from system_support import (
    node_argv,
    Probe,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    STOP_TIMEOUT_S,
    write_parameter_files,
)

ERROR_LEVEL = 2
BUSY = 'busy: a calibration is running'


def start_identify(ros_processes, tmp_path, probe, namespace='', name='identify', **parameters):
    parameters.setdefault('output_dir', str(tmp_path / 'out'))
    process = ros_processes.start(node_argv('identify', parameters, namespace), name=name)
    probe.wait_for_node('identify', f'/{namespace}' if namespace else '/', process)
    return process


@pytest.mark.slow
def test_second_call_while_calibrating_is_answered_busy_at_once(ros_processes, tmp_path, probe):
    # Nominal set 3 and 600 postures: a solve of ~0.5 s, far longer than a busy answer takes.
    nominal = tmp_path / 'nominal_set3.yaml'
    save_parameters(nominal, nominal_set(3, seed=0).vector)
    identify = start_identify(ros_processes, tmp_path, probe, nominal=str(nominal))
    probe.subscribe_status()
    received = probe.subscribe_parameters()
    postures = simulated_postures(600, seed=1)
    probe.publish_postures(postures)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == len(postures),
        60.0,
        'identify to hold 600 postures',
        identify.describe,
    )

    answered: dict[int, float] = {}
    sent = time.monotonic()
    futures = [probe.trigger_async(), probe.trigger_async()]

    def both_answered() -> bool:
        for index, future in enumerate(futures):
            if future.done():
                answered.setdefault(index, time.monotonic() - sent)
        return len(answered) == len(futures)

    probe.spin_until(both_answered, 120.0, 'both responses', identify.describe)
    responses = [f.result() for f in futures]
    busy = [i for i, r in enumerate(responses) if not r.success]
    assert len(busy) == 1, [(r.success, r.message) for r in responses]
    done = 1 - busy[0]
    assert responses[busy[0]].message == BUSY
    assert responses[done].success, responses[done].message
    assert 'of 600 postures' in responses[done].message
    # The busy answer did not wait for the calibration.
    assert answered[busy[0]] < answered[done], answered
    probe.spin_until(lambda: received, 10.0, 'the published parameters')
    assert len(received) == 1  # one calibration ran


def test_calibrate_without_nominal_names_the_missing_parameter(ros_processes, tmp_path, probe):
    identify = start_identify(ros_processes, tmp_path, probe)
    probe.subscribe_status()
    probe.publish_postures(simulated_postures(20))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 20,
        30.0,
        'identify to hold 20 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert not response.success
    assert "parameter 'nominal' is not set" in response.message
    level, message, values = probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('outcome') == 'missing-parameter'],
        10.0,
        'the ERROR status',
    )[-1]
    assert level == ERROR_LEVEL and 'nominal' in message
    received = probe.subscribe_parameters()  # transient local: a result would arrive now
    probe.spin_until(
        lambda: probe.node.count_publishers('/hexacal/parameters') >= 1,
        10.0,
        'the parameters publisher',
    )
    probe.spin_for(1.0)
    assert received == []
    assert not (tmp_path / 'out' / 'hexacal_calibration.yaml').exists()


@pytest.mark.slow
def test_too_few_postures_is_refused_and_publishes_nothing(ros_processes, tmp_path, probe):
    _, nominal = write_parameter_files(tmp_path)
    identify = start_identify(ros_processes, tmp_path, probe, nominal=str(nominal))
    probe.subscribe_status()
    probe.publish_postures(simulated_postures(5))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 5,
        30.0,
        'identify to hold 5 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert not response.success
    assert response.message.startswith('too-few-postures:'), response.message
    level, _, values = probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('outcome') == 'too-few-postures'],
        10.0,
        'the ERROR status',
    )[-1]
    assert level == ERROR_LEVEL and values['postures_received'] == '5'
    received = probe.subscribe_parameters()
    probe.spin_until(
        lambda: probe.node.count_publishers('/hexacal/parameters') >= 1,
        10.0,
        'the parameters publisher',
    )
    probe.spin_for(1.0)
    assert received == []
    assert not (tmp_path / 'out' / 'hexacal_calibration.yaml').exists()
    # Nothing collected is lost: more postures, and the same node calibrates.
    probe.publish_postures(simulated_postures(25, seed=2))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 30,
        30.0,
        'identify to hold 30 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert response.success, response.message
    assert '30 of 30 postures' in response.message


@pytest.mark.slow
def test_restarted_identify_republishes_the_saved_calibration(ros_processes, tmp_path, probe):
    truth, nominal = write_parameter_files(tmp_path)
    identify = start_identify(ros_processes, tmp_path, probe, nominal=str(nominal))
    probe.subscribe_status()
    first = probe.subscribe_parameters()
    probe.publish_postures(simulated_postures(30))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 30,
        30.0,
        'identify to hold 30 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert response.success, response.message
    published = probe.spin_until(lambda: first, 10.0, 'the published parameters')[0]
    saved = tmp_path / 'out' / 'hexacal_calibration.yaml'
    assert np.array_equal(load_parameters(saved), published)
    assert np.abs(published - load_parameters(truth)).max() < 1e-3
    assert ros_processes.stop(identify, STOP_TIMEOUT_S) == 0

    restarted = start_identify(ros_processes, tmp_path, probe, name='identify-restarted')
    probe.spin_until(
        lambda: 'republished the saved calibration' in restarted.log_text(),
        30.0,
        'the restarted node to republish',
        restarted.describe,
    )
    late = Probe()  # a subscriber that joins after the publication
    try:
        again = late.subscribe_parameters()
        late.spin_until(lambda: again, 15.0, 'the republished parameters', restarted.describe)
        assert np.array_equal(again[0], published)
    finally:
        late.close()


@pytest.mark.slow
def test_namespaced_nodes_do_not_talk_to_the_default_namespace(ros_processes, tmp_path, probe):
    _, nominal = write_parameter_files(tmp_path)
    default = start_identify(ros_processes, tmp_path, probe, nominal=str(nominal))
    left = start_identify(
        ros_processes,
        tmp_path,
        probe,
        namespace='left',
        name='identify-left',
        nominal=str(nominal),
        output_dir=str(tmp_path / 'left'),
    )
    left_probe = Probe(namespace='left')
    try:
        probe.subscribe_status()
        left_probe.subscribe_status()
        default_parameters = probe.subscribe_parameters()
        left_parameters = left_probe.subscribe_parameters()

        probe.publish_postures(simulated_postures(20, seed=3))
        probe.spin_until(
            lambda: probe.postures_received_by_identify() == 20,
            30.0,
            '/identify to hold 20 postures',
            default.describe,
        )
        left_probe.publish_postures(simulated_postures(16, seed=4))  # on /left/hexacal/posture
        left_probe.spin_until(
            lambda: left_probe.postures_received_by_identify() == 16,
            30.0,
            '/left/identify to hold 16 postures',
            left.describe,
        )
        probe.spin_for(0.5)
        assert probe.postures_received_by_identify() == 20  # the left postures stayed left

        response = left_probe.call_trigger()  # /left/hexacal/calibrate
        assert response.success, response.message
        assert '16 of 16 postures' in response.message
        left_probe.spin_until(lambda: left_parameters, 10.0, '/left/hexacal/parameters')
        assert (tmp_path / 'left' / 'hexacal_calibration.yaml').exists()
        probe.spin_for(1.0)
        assert default_parameters == []  # /hexacal/parameters heard nothing of it
        assert not (tmp_path / 'out' / 'hexacal_calibration.yaml').exists()
        names = dict(probe.node.get_service_names_and_types())
        assert '/left/hexacal/calibrate' in names and '/hexacal/calibrate' in names
    finally:
        left_probe.close()


# --------------------------------------------------------------------------- collector


def test_collector_recording_services_open_and_close_bags(ros_processes, tmp_path, probe):
    bags = tmp_path / 'bags'
    collector = ros_processes.start(
        node_argv('collector', {'output_dir': str(bags), 'bag_name': 'session', 'record': False})
    )
    probe.wait_for_node('collector', process=collector)
    assert not bags.exists()  # record:=false: nothing until asked
    stopped = probe.call_trigger('hexacal/stop_recording')
    assert not stopped.success and stopped.message == 'not recording'
    started = probe.call_trigger('hexacal/start_recording')
    assert started.success and started.message == f'recording to {bags / "session"}'
    again = probe.call_trigger('hexacal/start_recording')
    assert again.success and again.message.startswith('already recording')
    stopped = probe.call_trigger('hexacal/stop_recording')
    assert stopped.success, stopped.message
    assert (bags / 'session' / 'metadata.yaml').exists()
    started = probe.call_trigger('hexacal/start_recording')  # a new bag, never the closed one
    assert started.success and started.message == f'recording to {bags / "session_2"}'
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0
    assert (bags / 'session_2' / 'metadata.yaml').exists()


def test_collector_counts_invalid_messages_and_keeps_running(ros_processes, tmp_path, probe):
    from hexacal_msgs_py.qos import SENSOR_QOS
    from sensor_msgs.msg import JointState

    collector = ros_processes.start(
        node_argv('collector', {'output_dir': str(tmp_path / 'bags'), 'bag_name': 'invalid'})
    )
    probe.wait_for_node('collector', process=collector)
    publisher = probe.node.create_publisher(JointState, 'hexacal/sliders', SENSOR_QOS)
    probe.spin_until(lambda: publisher.get_subscription_count() >= 1, 30.0, 'the collector')
    names = [f'slider_{i}' for i in range(1, 7)]
    bad = [
        JointState(name=names, position=[0.3, 0.3, float('nan'), 0.3, 0.3, 0.3]),
        JointState(name=names[:5] + ['elbow'], position=[0.3] * 6),
        JointState(name=names, position=[0.3] * 5),
    ]
    sent = 0

    def warned() -> bool:  # best effort: publish rounds until the collector has heard some
        nonlocal sent
        for message in bad:
            sent += 1
            message.header.stamp.sec = sent
            publisher.publish(message)
        return (
            sent >= 30 and 'ignored an invalid message on /hexacal/sliders' in collector.log_text()
        )

    probe.spin_until(warned, 15.0, 'the invalid-message warning', collector.describe)
    assert collector.running()
    still_serving = probe.call_trigger('hexacal/start_recording')
    assert still_serving.success and still_serving.message.startswith('already recording')
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0  # closes the bag
    log = collector.log_path.read_text()
    # Every message that arrived (the bag has them all, as received) was counted as invalid.
    recorded = [
        deserialize_message(m.data_bytes, JointState)
        for m in open_bag(tmp_path / 'bags' / 'invalid').messages(['/hexacal/sliders'])
    ]
    assert 0 < len(recorded) <= sent
    assert f"invalid messages {{'hexacal/sliders': {len(recorded)}}}" in log, log
    assert {message.header.stamp.sec % 3 for message in recorded} == {0, 1, 2}  # all 3 kinds
