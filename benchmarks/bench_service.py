#!/usr/bin/env python3
"""
Calibrate-service latency of a real identify node beside the bare solve time.

For each posture count: start a real ``identify`` node (own process group, a ROS
domain of its own - same lock files as tests/conftest.py -,
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, output under a temporary directory),
publish that many simulated sphere postures (Table 1 machine, +-10 um / urad
noise) on hexacal/posture, wait until its status counts them all, then call
hexacal/calibrate ``--calls`` times. Per call it measures, from just before
``call_async`` in this process (an rclpy probe; times taken in the callbacks):

- response: the Trigger response arrives;
- parameters: the transient-local hexacal/parameters message of that calibration
  arrives;
- report (extra): the status saying the HTML report is written (a node that
  writes the report before answering says so in its result status).

Between calls it waits for the report, so each call starts on an idle node.
The bare solve time is ``calibration_run.calibrate`` on the same nominal model and
postures in this process: after a warm-up, ``--solve-repeats`` runs before each
call (interleaved, so both see the same load), median of all.

Run: ``.venv/bin/python benchmarks/bench_service.py [--json] [--postures 50 200] [--calls 5]``
Target (issue 12): the response and the published parameters within the solve
time + 50 ms at 50 and 200 postures (medians over the calls). ``--json`` prints
one row per posture count with ``postures``, ``solve_seconds``,
``response_seconds``, ``parameters_seconds`` (medians) plus extras.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

from hexacal_identify.ros_domain import claim_domain_id

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / 'tests'))

POSTURE_COUNTS = (50, 200)
MARGIN_S = 0.050  # the target: solve + 50 ms
START_TIMEOUT_S = 60.0
CALL_TIMEOUT_S = 120.0
REPORT_TIMEOUT_S = 120.0
STOP_TIMEOUT_S = 60.0
REPORT_DONE = ('ready', 'failed')


class BareSolve:
    """Return wall times of calibration_run.calibrate (the node's solve call), after a warm-up."""

    def __init__(self, nominal_path: Path, postures: list) -> None:
        from hexacal_identify.calibration_steps.calibration_run import calibrate
        from hexacal_identify.core.machine.model import HexaParameters
        from hexacal_msgs_py.parameters_file import load_parameters

        self.calibrate = calibrate
        self.nominal = HexaParameters(load_parameters(nominal_path))
        self.postures = postures
        self.times: list[float] = []
        self.calibrate(self.nominal, postures)  # warm-up: imports, caches

    def run(self, repeats: int) -> None:
        for _ in range(repeats):
            started = time.perf_counter()
            self.calibrate(self.nominal, self.postures)
            self.times.append(time.perf_counter() - started)


class ServiceClock:
    """The probe's subscriptions and client, each arrival stamped with perf_counter."""

    def __init__(self, probe) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from hexacal_msgs_py.conversions import status_values
        from hexacal_msgs_py.qos import PARAMETERS_QOS, STATUS_QOS
        from std_msgs.msg import Float64MultiArray
        from std_srvs.srv import Trigger

        self.probe = probe
        self.parameters: list[float] = []  # arrival times
        self.statuses: list[tuple[float, dict]] = []  # (arrival time, values)

        def on_status(message) -> None:
            now = time.perf_counter()
            for status in message.status:
                self.statuses.append((now, status_values(status)))

        probe.node.create_subscription(
            Float64MultiArray,
            'hexacal/parameters',
            lambda _: self.parameters.append(time.perf_counter()),
            PARAMETERS_QOS,
        )
        probe.node.create_subscription(
            DiagnosticArray, 'hexacal/calibration_status', on_status, STATUS_QOS
        )
        self.trigger = Trigger
        self.client = probe.node.create_client(Trigger, 'hexacal/calibrate')

    def spin_until(self, predicate, timeout: float, what: str, details=None):
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f'timed out after {timeout:g} s waiting for {what}'
                    + (f'\n{details()}' if details else '')
                )
            self.probe.executor.spin_once(timeout_sec=0.01)

    def postures_received(self) -> int:
        counts = [
            int(v['postures_received'])
            for _, v in self.statuses
            if v.get('outcome') == 'collecting'
        ]
        return counts[-1] if counts else 0

    def call(self, details) -> dict:
        """One calibrate call on an idle node: response, parameters and report times (s)."""
        parameters_before, statuses_before = len(self.parameters), len(self.statuses)
        answered: list[float] = []
        started = time.perf_counter()
        future = self.client.call_async(self.trigger.Request())
        future.add_done_callback(lambda _: answered.append(time.perf_counter()))
        self.spin_until(
            lambda: answered and len(self.parameters) > parameters_before,
            CALL_TIMEOUT_S,
            'the response and the parameters',
            details,
        )
        response = future.result()
        if not response.success:
            raise RuntimeError(f'calibrate failed: {response.message}\n{details()}')

        def report_done():
            for stamp, values in self.statuses[statuses_before:]:
                state = values.get('report_state')
                finished = values.get('outcome') not in ('running', 'collecting')
                # A node without report_state wrote the report before its result status.
                if state in REPORT_DONE or (finished and state != 'writing'):
                    return stamp, values
            return None

        self.spin_until(report_done, REPORT_TIMEOUT_S, 'the report', details)
        report_stamp, report_values = report_done()
        result = [v for _, v in self.statuses[statuses_before:] if 'solve_seconds' in v]
        return {
            'response_seconds': answered[0] - started,
            'parameters_seconds': self.parameters[parameters_before] - started,
            'report_seconds': report_stamp - started,
            'report_state': report_values.get('report_state', 'ready (before the response)'),
            'node_solve_seconds': float(result[0]['solve_seconds']) if result else None,
        }


def measure(count: int, calls: int, solve_repeats: int, work_dir: Path, seed: int) -> dict:
    from rosproc import start_node, stop
    from system_support import node_argv, Probe, simulated_postures, write_parameter_files

    work_dir.mkdir(parents=True, exist_ok=True)
    _, nominal = write_parameter_files(work_dir)
    postures = simulated_postures(count, seed=seed)
    bare = BareSolve(nominal, postures)

    probe = Probe()
    node = None
    try:
        clock = ServiceClock(probe)
        node = start_node(
            node_argv('identify', {'nominal': str(nominal), 'output_dir': str(work_dir / 'out')}),
            log_path=work_dir / 'identify.log',
        )
        probe.wait_for_node('identify', process=node, timeout=START_TIMEOUT_S)
        clock.spin_until(
            clock.client.service_is_ready, START_TIMEOUT_S, 'hexacal/calibrate', node.describe
        )
        probe.publish_postures(postures)
        clock.spin_until(
            lambda: clock.postures_received() == count,
            START_TIMEOUT_S,
            f'identify to hold {count} postures',
            node.describe,
        )
        samples = []
        for _ in range(calls):
            # Interleaved with the calls, so both see the same load of a shared machine.
            bare.run(solve_repeats)
            samples.append(clock.call(node.describe))
    finally:
        probe.close()
        if node is not None:
            stop(node, STOP_TIMEOUT_S)

    def median(key: str) -> float:
        return statistics.median(s[key] for s in samples)

    solve = statistics.median(bare.times)
    row = {
        'postures': count,
        'solve_seconds': solve,
        'response_seconds': median('response_seconds'),
        'parameters_seconds': median('parameters_seconds'),
        'report_seconds': median('report_seconds'),
        'first_response_seconds': samples[0]['response_seconds'],
        'max_response_seconds': max(s['response_seconds'] for s in samples),
        'max_parameters_seconds': max(s['parameters_seconds'] for s in samples),
        'node_solve_seconds': statistics.median(
            s['node_solve_seconds'] for s in samples if s['node_solve_seconds'] is not None
        )
        if any(s['node_solve_seconds'] is not None for s in samples)
        else None,
        'report_states': sorted({s['report_state'] for s in samples}),
        'calls_response_seconds': [s['response_seconds'] for s in samples],
        'calls_parameters_seconds': [s['parameters_seconds'] for s in samples],
        'calls_node_solve_seconds': [s['node_solve_seconds'] for s in samples],
        'calls': calls,
    }
    row['met'] = max(row['response_seconds'], row['parameters_seconds']) <= solve + MARGIN_S
    return row


def table(rows: list[dict]) -> str:
    ms = 1e3
    lines = [
        f'{"postures":>8} {"solve":>9} {"node solve":>10} {"response":>10} {"parameters":>10} '
        f'{"report":>9} {"1st resp":>9} {"max resp":>9}  target (solve + 50 ms)',
        f'{"":>8} {"(ms)":>9} {"(ms)":>10} {"(ms)":>10} {"(ms)":>10} {"(ms)":>9} {"(ms)":>9} '
        f'{"(ms)":>9}',
    ]
    for row in rows:
        node_solve = row['node_solve_seconds']
        lines.append(
            f'{row["postures"]:>8} {row["solve_seconds"] * ms:>9.1f} '
            f'{(node_solve * ms if node_solve is not None else float("nan")):>10.1f} '
            f'{row["response_seconds"] * ms:>10.1f} {row["parameters_seconds"] * ms:>10.1f} '
            f'{row["report_seconds"] * ms:>9.0f} {row["first_response_seconds"] * ms:>9.1f} '
            f'{row["max_response_seconds"] * ms:>9.1f}  {"met" if row["met"] else "NOT met"}'
        )
    lines.append(
        f"medians over {rows[0]['calls'] if rows else 0} calls per row; 'report' = call to "
        'the status saying the report is written'
    )
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--json', action='store_true', help='print the rows as a JSON list')
    parser.add_argument('--postures', type=int, nargs='*', default=list(POSTURE_COUNTS))
    parser.add_argument('--calls', type=int, default=5, help='calibrate calls per posture count')
    parser.add_argument(
        '--solve-repeats',
        type=int,
        default=3,
        help='bare solves before each call (their median is solve_seconds)',
    )
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument(
        '--work-dir',
        type=Path,
        default=None,
        help='keep the outputs and logs here (default: a temporary directory)',
    )
    args = parser.parse_args(argv)

    os.environ['ROS_DOMAIN_ID'] = str(claim_domain_id('HEXACAL_TEST_DOMAIN_ID'))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_STATIC_PEERS', None)
    rows = []
    with tempfile.TemporaryDirectory(prefix='hexacal-bench-service-') as scratch:
        base = args.work_dir or Path(scratch)
        for count in args.postures:
            rows.append(
                measure(
                    count, args.calls, args.solve_repeats, base / f'postures_{count}', args.seed
                )
            )
            if not args.json:
                print(f'{count} postures done', file=sys.stderr, flush=True)
    print(json.dumps(rows) if args.json else table(rows))
    return 0 if all(row['met'] for row in rows) else 1


if __name__ == '__main__':
    sys.exit(main())
