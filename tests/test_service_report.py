"""System tests of the identify node's report: written after the answer, in the background.

Real `identify` processes; the probe calls hexacal/calibrate and follows
hexacal/calibration_status. The answer and the parameters come first; the
result status says `report_state: writing`, a later one `ready` (with the page's
path in `report`) or `failed` (with `report_error`), never changing the result.
No timing assertions: only what arrives, in which order, and what is on disk.
"""

from __future__ import annotations

from hexacal_msgs_py.parameters_file import load_parameters
import numpy as np
import pytest
from system_support import (
    node_argv,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    STOP_TIMEOUT_S,
    write_parameter_files,
)

OK_LEVEL = 0
REPORT_TIMEOUT_S = 120.0  # matplotlib on a loaded 2-core machine


def _start(ros_processes, tmp_path, probe, **parameters):
    _, nominal = write_parameter_files(tmp_path)
    parameters = {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out'), **parameters}
    identify = ros_processes.start(node_argv('identify', parameters))
    probe.wait_for_node('identify', process=identify)
    probe.subscribe_status()
    received = probe.subscribe_parameters()
    probe.publish_postures(simulated_postures(25, seed=6))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 25,
        30.0,
        'identify to hold 25 postures',
        identify.describe,
    )
    return identify, received


def _report_status(probe, state: str, identify, after: int = 0):
    return probe.spin_until(
        lambda: [s for s in probe.statuses[after:] if s[2].get('report_state') == state],
        REPORT_TIMEOUT_S,
        f'a status with report_state {state!r}',
        identify.describe,
    )[-1]


def _result_statuses(probe, after: int = 0) -> list:
    return [s for s in probe.statuses[after:] if s[2].get('outcome') == 'converged']


@pytest.mark.slow
def test_answer_and_parameters_come_before_the_report_status(ros_processes, tmp_path, probe):
    identify, received = _start(ros_processes, tmp_path, probe)
    out = tmp_path / 'out'
    response = probe.call_trigger()
    assert response.success, response.message
    assert 'report' not in response.message  # the answer does not speak for the report
    published = probe.spin_until(lambda: received, 10.0, 'the published parameters')[0]
    assert np.array_equal(load_parameters(out / 'hexacal_calibration.yaml'), published)

    level, message, ready = _report_status(probe, 'ready', identify)
    page = out / 'report' / 'index.html'
    assert ready['report'] == str(page)
    assert message.startswith(response.message) and f'report ready: {page}' in message
    text = page.read_text()
    assert text.rstrip().endswith('</html>') and 'converged' in text  # complete
    assert not list(out.rglob('*.tmp'))

    # Order on the status topic: running, the result (report writing), then the same result with
    # the report ready; the follow-up keeps every value of the result and adds the report.
    # ('running' may be replaced unseen by the result: the subscription keeps the latest only.)
    states = [
        (s[2].get('outcome'), s[2].get('report_state'))
        for s in probe.statuses
        if s[2].get('outcome') in ('running', 'converged')
    ]
    assert states[-2:] == [('converged', 'writing'), ('converged', 'ready')], states
    assert states[:-2] in ([], [('running', None)]), states
    writing = _result_statuses(probe)[0]
    assert writing[0] == level == OK_LEVEL and writing[1] == response.message
    assert 'report' not in writing[2]
    assert {k: v for k, v in ready.items() if k not in ('report_state', 'report')} == {
        k: v for k, v in writing[2].items() if k != 'report_state'
    }
    assert ready['output'] == str(out / 'hexacal_calibration.yaml')
    assert 0 < float(ready['std.chain_1.A0x']) < 1e-3
    assert 'calibration report written' in identify.log_text()
    assert len(received) == 1  # the report published no parameters


@pytest.mark.slow
def test_failed_report_leaves_the_result_and_the_parameters(ros_processes, tmp_path, probe):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    out = tmp_path / 'out'
    out.mkdir()
    (out / 'report').write_text('not a directory\n')  # report_dir is a file: the report must fail
    identify, received = _start(ros_processes, tmp_path, probe)
    response = probe.call_trigger()
    assert response.success, response.message
    published = probe.spin_until(lambda: received, 10.0, 'the published parameters')[0]

    level, message, failed = _report_status(probe, 'failed', identify)
    assert level == OK_LEVEL and failed['outcome'] == 'converged'  # the result stands
    assert message.startswith(response.message) and 'report failed' in message
    assert failed['report_error'] and 'report' not in failed
    assert np.array_equal(load_parameters(out / 'hexacal_calibration.yaml'), published)
    assert (out / 'report').read_text() == 'not a directory\n'
    assert not list(out.rglob('*.tmp'))
    assert 'calibration report not written' in identify.log_text()
    assert len(received) == 1

    # The node carries on; without a report the result says so and nothing follows it.
    client = AsyncParameterClient(probe.node, '/identify')
    probe.spin_until(client.services_are_ready, 15.0, "identify's parameter services")
    future = client.set_parameters([Parameter('report_dir', value='')])
    assert (
        probe.spin_until(
            lambda: future.result() if future.done() else None, 15.0, 'setting report_dir'
        )
        .results[0]
        .successful
    )
    count = len(probe.statuses)
    again = probe.call_trigger()
    assert again.success, again.message
    probe.spin_until(lambda: len(received) == 2, 10.0, 'the second parameters')
    result = probe.spin_until(lambda: _result_statuses(probe, count), 10.0, 'the result status')
    assert [s[2]['report_state'] for s in result] == ['disabled']


@pytest.mark.slow
def test_stopping_right_after_the_answer_finishes_the_report(ros_processes, tmp_path, probe):
    identify, received = _start(ros_processes, tmp_path, probe)
    out = tmp_path / 'out'
    response = probe.call_trigger()
    assert response.success, response.message
    probe.spin_until(lambda: received, 10.0, 'the published parameters')
    # SIGINT while the report is being written (or about to be): the node waits for it.
    assert ros_processes.stop(identify, STOP_TIMEOUT_S) == 0, identify.log_path.read_text()
    log = identify.log_path.read_text()
    assert 'Traceback' not in log, log
    page = out / 'report' / 'index.html'
    assert page.read_text().rstrip().endswith('</html>')
    assert not list(out.rglob('*.tmp'))
    assert np.array_equal(load_parameters(out / 'hexacal_calibration.yaml'), received[0])
