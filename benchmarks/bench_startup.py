#!/usr/bin/env python3
"""
Start-up wall time of the command line and the nodes, against `python -c "import numpy"`.

Measures, median of ``--repeats`` runs each (after one unmeasured warm-up run
that fills the page cache and the __pycache__ files):

- baseline: ``.venv/bin/python -c "import numpy"``;
- ``.venv/bin/hexacal --help``;
- ``.venv/bin/hexacal calibrate bags/sphere50_noise10 --nominal <nominal set 2, seed 0>
  --output <tmp>``
  (the whole command: start-up, bag reading, identification, writing the YAML);
- node start-up to first subscription (publisher for the driver, which has no
  subscription): ``.venv/bin/collector`` until its subscription on
  <ns>/hexacal/sliders is on the graph, ``.venv/bin/identify`` until its
  subscription on <ns>/hexacal/posture is, ``.venv/bin/driver`` until its
  publisher on <ns>/hexacal/sliders is (<ns>: a namespace of its own per run).
  Each node runs in its own process group in a ROS domain of its own (same
  lock files as tests/conftest.py) with
  ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; an rclpy probe in this process,
  created before the node starts, polls the graph; the node is stopped with
  SIGINT once its constructor has returned. The graph time includes DDS
  discovery of the new participant by the probe (with Fast DDS here anything
  from ~0.05 s to ~3 s, its announcement period), so each node also gets a row
  from its own log: the wall-clock stamp of the line it logs right after
  creating that subscription (publisher), minus the time of Popen.

Run: ``.venv/bin/python benchmarks/bench_startup.py [--json] [--repeats N]``
Targets: ``hexacal --help`` within 2x the baseline, ``hexacal calibrate`` of the
50-posture bag within 3x, every node's first subscription within 1 s.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from hexacal_identify.ros_domain import claim_domain_id

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
BAG = REPO / 'bags' / 'sphere50_noise10'
NODE_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 15.0
# name -> (graph query, topic relative to the run's namespace) whose count >= 1 marks the node as
# started.
NODE_SIGNS = {
    'collector': ('subscriptions', 'hexacal/sliders'),
    'identify': ('subscriptions', 'hexacal/posture'),
    'driver': ('publishers', 'hexacal/sliders'),
}
# What each node logs right after it created that subscription (publisher): the wall-clock stamp of
# this log line is the node's own start-up, without DDS discovery.
READY_LINES = {
    'collector': 'collecting postures on',
    'identify': 'collecting postures on',
    'driver': 'holding the first posture until',
}
# What each node logs once its constructor has returned (as tests/test_executables.py waits for):
# the benchmark waits for it and then SPIN_WAIT_S more, untimed, before the SIGINT. A SIGINT that
# lands inside the constructor or just before spinning starts (between rclpy.init and
# rclpy.spin/executor.spin) can end a node with a traceback or hang it (seen here: RCLError
# 'context is invalid' in create_service, rclpy.spin's executor None, identify not exiting): a
# shutdown race of the nodes, not what this benchmark measures. Such stops are reported under the
# table instead of aborting the run.
STARTED_LINES = {
    'collector': 'recording to',
    'identify': 'collecting postures on',
    'driver': 'holding the first posture until',
}
SPIN_WAIT_S = 0.5
STOP_PROBLEMS: list[str] = []  # nodes that did not exit 0 on SIGINT (logs kept)
LOG_FORMAT = (
    '[{severity}] [{time}] [{name}]: {message}'  # rcutils' default, set explicitly: parsed below
)


def time_command(argv: list[str], repeats: int) -> list[float]:
    """Wall times of `repeats` runs of argv (after one warm-up); a failing run is an error."""
    times = []
    for index in range(repeats + 1):
        started = time.perf_counter()
        result = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        elapsed = time.perf_counter() - started
        if result.returncode != 0:
            raise RuntimeError(
                f'{" ".join(argv)} exited with {result.returncode}: {result.stderr}'
            )
        if index:
            times.append(elapsed)
    return times


class GraphProbe:
    """An rclpy node in this process that reads the graph; created once, before any node starts."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('hexacal_bench_startup_probe', context=self.context)

    def count(self, kind: str, topic: str) -> int:
        if kind == 'subscriptions':
            return self.node.count_subscribers(topic)
        return self.node.count_publishers(topic)

    def close(self) -> None:
        import rclpy

        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _ros_args(parameters: dict[str, str]) -> list[str]:
    argv = ['--ros-args']
    for name, value in parameters.items():
        argv += ['-p', f'{name}:={value}']
    return argv


def _wait_count(
    probe: GraphProbe,
    kind: str,
    topic: str,
    wanted,
    timeout: float,
    process: subprocess.Popen | None,
    what: str,
) -> float:
    deadline = time.monotonic() + timeout
    while True:
        if wanted(probe.count(kind, topic)):
            return time.perf_counter()
        if process is not None and process.poll() is not None:
            raise RuntimeError(f'{what} exited with {process.returncode} before it started')
        if time.monotonic() >= deadline:
            raise RuntimeError(f'timed out after {timeout:g} s waiting for {what}')
        time.sleep(0.002)


def _wait_log(path: Path, line: str, process: subprocess.Popen, what: str) -> None:
    deadline = time.monotonic() + NODE_TIMEOUT_S
    while line not in path.read_text(errors='replace'):
        if process.poll() is not None:
            raise RuntimeError(f'{what} exited with {process.returncode} before logging {line!r}')
        if time.monotonic() >= deadline:
            raise RuntimeError(f'timed out waiting for {what} to log {line!r}')
        time.sleep(0.01)


def _stop(process: subprocess.Popen) -> int:
    """SIGINT the node's process group; SIGKILL after STOP_TIMEOUT_S."""
    import signal

    try:
        os.killpg(process.pid, signal.SIGINT)
        return process.wait(STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        return process.wait()
    except ProcessLookupError:
        return process.wait()


def _log_stamp(text: str, line: str) -> float:
    """Return when (s since the epoch) the first log line starting with `line` was logged."""
    match = re.search(r'\[(\d+\.\d+)\] \[[^\]]*\]: ' + re.escape(line), text)
    if match is None:
        raise RuntimeError(f'no log line {line!r} in:\n{text}')
    return float(match.group(1))


def time_node(
    probe: GraphProbe, name: str, work_dir: Path, repeats: int
) -> tuple[list[float], list[float]]:
    """
    Return the seconds from Popen to the node's first subscription (publisher).

    (on the probe's graph, in its own log): the graph time includes DDS discovery of the new
    participant by the probe; the log time is when the node logged the line it logs right after
    creating the subscription (publisher).
    """
    kind, relative_topic = NODE_SIGNS[name]
    on_graph, in_log = [], []
    env = dict(os.environ, RCUTILS_CONSOLE_OUTPUT_FORMAT=LOG_FORMAT, RCUTILS_COLORIZED_OUTPUT='0')
    for index in range(repeats + 1):
        parameters = {
            'collector': {'output_dir': str(work_dir / 'bags'), 'bag_name': f'startup_{index}'},
            'identify': {'output_dir': str(work_dir / f'identify_{index}')},
        }.get(name, {})
        # A namespace of its own per run: what the probe sees is this node, not a previous run's
        # endpoint that the graph still lists (or another process in the domain).
        namespace = f'/hexacal_bench_startup_{os.getpid()}_{name}_{index}'
        topic = f'{namespace}/{relative_topic}'
        log_path = work_dir / f'{name}_{index}.log'
        log = open(log_path, 'wb')  # noqa: SIM115
        started_wall = time.time()
        started = time.perf_counter()
        argv = [str(BIN / name), *_ros_args(parameters), '-r', f'__ns:={namespace}']
        process = subprocess.Popen(
            argv,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
        )
        try:
            seen = _wait_count(
                probe,
                kind,
                topic,
                lambda n: n >= 1,
                NODE_TIMEOUT_S,
                process,
                f'{name} ({kind} on {topic})',
            )
            _wait_log(log_path, STARTED_LINES[name], process, name)
            time.sleep(SPIN_WAIT_S)
        finally:
            code = _stop(process)
            log.close()
        text = log_path.read_text(errors='replace')
        if code != 0:
            last = next((line for line in reversed(text.splitlines()) if line.strip()), '')
            STOP_PROBLEMS.append(
                f'{name} run {index}: exit code {code} after SIGINT (log {log_path}): {last}'
            )
        if index:
            on_graph.append(seen - started)
            in_log.append(_log_stamp(text, READY_LINES[name]) - started_wall)
    return on_graph, in_log


def measure(repeats: int, nodes: bool = True) -> list[dict]:
    rows = []

    def add(
        name: str,
        times: list[float],
        target_ratio: float | None = None,
        target_s: float | None = None,
    ) -> None:
        rows.append(
            {
                'name': name,
                'median_s': statistics.median(times),
                'min_s': min(times),
                'max_s': max(times),
                'runs': len(times),
                'target_ratio': target_ratio,
                'target_s': target_s,
            }
        )

    python = str(BIN / 'python')
    hexacal = str(BIN / 'hexacal')
    add(
        'python -c "import numpy" (baseline)',
        time_command([python, '-c', 'import numpy'], repeats),
    )
    add('hexacal --help', time_command([hexacal, '--help'], repeats), target_ratio=2.0)
    work = Path(tempfile.mkdtemp(prefix='hexacal-bench-startup-'))
    try:
        nominal = work / 'nominal2.yaml'
        subprocess.run(
            [hexacal, 'params', 'nominal', '--set', '2', '--seed', '0', '--out', str(nominal)],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        add(
            f'hexacal calibrate {BAG.name}',
            time_command(
                [
                    hexacal,
                    'calibrate',
                    str(BAG),
                    '--nominal',
                    str(nominal),
                    '--output',
                    str(work / 'calibrated.yaml'),
                ],
                repeats,
            ),
            target_ratio=3.0,
        )
        if nodes:
            os.environ['ROS_DOMAIN_ID'] = str(claim_domain_id('HEXACAL_TEST_DOMAIN_ID'))
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
            probe = GraphProbe()
            try:
                for name in NODE_SIGNS:
                    kind = NODE_SIGNS[name][0][:-1]
                    on_graph, in_log = time_node(probe, name, work, repeats)
                    add(f'{name}: first {kind} on the graph', on_graph, target_s=1.0)
                    add(f'{name}: first {kind} created (its log)', in_log, target_s=1.0)
            finally:
                probe.close()
    finally:
        if not STOP_PROBLEMS:  # else keep the logs the problems name
            shutil.rmtree(work, ignore_errors=True)
    baseline = rows[0]['median_s']
    for row in rows:
        row['ratio'] = row['median_s'] / baseline
        if row['target_ratio'] is not None:
            row['met'] = row['ratio'] <= row['target_ratio']
        elif row['target_s'] is not None:
            row['met'] = row['median_s'] <= row['target_s']
        else:
            row['met'] = None
    return rows


def format_table(rows: list[dict]) -> str:
    lines = [
        f'{"what":<48} {"median s":>9} {"min s":>7} {"max s":>7} {"x base":>7}  '
        f'{"target":<10} result',
        '-' * 100,
    ]
    for row in rows:
        if row['target_ratio'] is not None:
            target = f'<= {row["target_ratio"]:g}x'
        elif row['target_s'] is not None:
            target = f'<= {row["target_s"]:g} s'
        else:
            target = ''
        verdict = '' if row['met'] is None else ('met' if row['met'] else 'NOT met')
        lines.append(
            f'{row["name"]:<48} {row["median_s"]:>9.3f} {row["min_s"]:>7.3f} {row["max_s"]:>7.3f} '
            f'{row["ratio"]:>7.2f}  {target:<10} {verdict}'
        )
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--json', action='store_true', help='print {"rows": [...], "stop_problems": [...]} as JSON'
    )
    parser.add_argument('--repeats', type=int, default=5, help='measured runs per row (default 5)')
    parser.add_argument('--no-nodes', action='store_true', help='skip the node start-up rows')
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error('--repeats must be at least 1')
    rows = measure(args.repeats, nodes=not args.no_nodes)
    if args.json:
        print(json.dumps({'rows': rows, 'stop_problems': STOP_PROBLEMS}))
    else:
        print(format_table(rows))
        for problem in STOP_PROBLEMS:
            print(f'stop problem: {problem}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
