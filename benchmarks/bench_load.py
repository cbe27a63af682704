#!/usr/bin/env python3
"""
Load benchmark: the driver at 1 kHz per stream into the collector, for minutes.

Starts a real `collector` (recording a bag) and a real `driver` (plan 'mixed',
looping) publishing each of its three sensor streams at ``--rate-hz``, lets them
run for ``--minutes``, samples the collector's resident memory (VmRSS from
/proc/<pid>/status) and CPU time every ``--sample-s``, then stops the driver,
waits until the collector reports the streams stopped (its queue is drained)
and stops the collector. Reports, per stream, the messages the driver published
(its exit log), the collector received (its summary) and the bag holds
(metadata.yaml), the postures the driver dwelt at and the collector detected,
and the collector's memory over time.

With ``--busy-core`` a CPU hog (a Python busy loop, started before the nodes
and killed by PID at the end) keeps one core busy beside them, as another job
on a shared CI machine does.

Run: ``.venv/bin/python benchmarks/bench_load.py [--minutes 10] [--busy-core] [--json]``
Targets (issue #12): zero messages lost on every stream (everything the driver
managed to publish is in the bag), with or without a busy core; the collector
at most 35% of one core at 3 x 1 kHz on an otherwise idle machine; one posture
per dwell; flat memory (growth after the first minute within a few MiB). CPU
figures are CPU time from the plan start to its stop over that wall time. A
short run at a rate with ample headroom is tests/test_load_short.py.
"""

from __future__ import annotations

import argparse
from dataclasses import asdict, dataclass, field
import json
import os
from pathlib import Path
import re
import signal
import struct
import subprocess
import sys
import tempfile
import time

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / 'tests'))

from hexacal_identify.bag import open_bag  # noqa: E402, I100 - after the sys.path entry
from hexacal_identify.ros_domain import claim_domain_id  # noqa: E402
from rosproc import RosProcess, start_node, stop, venv_executable, wait_for  # noqa: E402

STREAMS = ('/hexacal/sliders', '/hexacal/inclinometer', '/hexacal/encoder')
START_TIMEOUT_S = 60.0
DRAIN_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 30.0
# Issue #12 item 4: the collector's share of one core at 3 streams x 1 kHz (idle machine).
COLLECTOR_CPU_TARGET = 0.35
TARGET_RATE_HZ = 1000.0


_STAMP = struct.Struct('<iI')  # builtin_interfaces/Time after the 4-byte CDR encapsulation header


@dataclass
class LoadResult:
    rate_hz: float
    seconds: float  # from the driver's plan start to its stop
    published: int  # per stream since the plan started (the driver publishes the three together)
    received: dict[
        str, int
    ]  # per stream, everything the collector received (also before the plan)
    recorded: dict[str, int]  # per stream, bag messages stamped at or after the plan's first stamp
    postures_walked: int  # dwells the driver began
    postures_detected: int  # postures the collector published
    postures_in_bag: int
    memory: list[tuple[float, float]]  # (s since start, collector VmRSS MiB)
    collector_cpu_s: float  # CPU time from the plan start to its stop
    driver_cpu_s: float
    collector_summary: str
    bag: str
    problems: list[str] = field(default_factory=list)
    cpu_window_s: float = 0.0  # wall time of the CPU figures (plan start to just before the stop)
    busy_core: bool = False  # a CPU hog ran beside the nodes
    hog_cpu_s: float = 0.0

    @property
    def collector_cpu(self) -> float:
        """Share of one core the collector used while the plan ran."""
        return self.collector_cpu_s / self.cpu_window_s if self.cpu_window_s else 0.0

    @property
    def driver_cpu(self) -> float:
        return self.driver_cpu_s / self.cpu_window_s if self.cpu_window_s else 0.0

    def targets(self) -> list[tuple[str, bool | None]]:
        """(target, met); met is None where this run cannot tell (e.g. another rate)."""
        lost = sum(self.lost.values())
        cpu: bool | None = None
        if self.rate_hz == TARGET_RATE_HZ and not self.busy_core:
            cpu = self.collector_cpu <= COLLECTOR_CPU_TARGET
        return [
            (f'0 messages lost to the collector (lost {lost})', lost == 0),
            (
                f'collector <= {100 * COLLECTOR_CPU_TARGET:.0f}% of one core at 3 x '
                f'{TARGET_RATE_HZ:g} Hz, idle machine ({100 * self.collector_cpu:.0f}%)',
                cpu,
            ),
            (
                f'one posture per dwell (dwelt {self.postures_walked}, detected '
                f'{self.postures_detected}, in bag {self.postures_in_bag})',
                self.postures_walked - 1 <= self.postures_detected <= self.postures_walked
                and self.postures_in_bag == self.postures_detected,
            ),
        ]

    @property
    def lost(self) -> dict[str, int]:
        # `published` counts complete ticks; a stop can interrupt the last tick after some of its
        # three publishes, so a stream may hold one message more than that, never fewer if nothing
        # was lost.
        return {
            stream: max(self.published - self.recorded.get(stream, 0), 0) for stream in STREAMS
        }

    @property
    def achieved_rate_hz(self) -> float:
        return self.published / self.seconds if self.seconds else 0.0

    def memory_growth_mib(self, warm_up_s: float) -> float:
        """Return VmRSS at the end minus the first sample after warm_up_s (MiB)."""
        after = [rss for t, rss in self.memory if t >= warm_up_s] or [r for _, r in self.memory]
        return after[-1] - after[0] if after else 0.0

    def memory_slope_mib_per_min(self, warm_up_s: float) -> float:
        points = [(t, r) for t, r in self.memory if t >= warm_up_s]
        if len(points) < 3:
            return 0.0
        n = len(points)
        mean_t = sum(t for t, _ in points) / n
        mean_r = sum(r for _, r in points) / n
        var = sum((t - mean_t) ** 2 for t, _ in points)
        cov = sum((t - mean_t) * (r - mean_r) for t, r in points)
        return 60.0 * cov / var if var else 0.0

    def to_json(self, warm_up_s: float) -> dict:
        payload = asdict(self)
        payload.update(
            lost=self.lost,
            achieved_rate_hz=self.achieved_rate_hz,
            collector_cpu=self.collector_cpu,
            driver_cpu=self.driver_cpu,
            targets=dict(self.targets()),
            memory_growth_mib=self.memory_growth_mib(warm_up_s),
            memory_slope_mib_per_min=self.memory_slope_mib_per_min(warm_up_s),
            warm_up_s=warm_up_s,
        )
        return payload

    def table(self, warm_up_s: float) -> str:
        lines = [
            f'driver at {self.rate_hz:g} Hz per stream for {self.seconds:.1f} s '
            f'(achieved {self.achieved_rate_hz:.1f} Hz); counts from the plan start, '
            'received also before it; '
            + ('one core busy with a CPU hog' if self.busy_core else 'no CPU hog'),
            f'{"stream":<24}{"published":>11}{"received":>11}{"recorded":>11}{"lost":>7}',
        ]
        for stream in STREAMS:
            lines.append(
                f'{stream:<24}{self.published:>11}{self.received.get(stream, 0):>11}'
                f'{self.recorded.get(stream, 0):>11}{self.lost[stream]:>7}'
            )
        lines.append(
            f'postures: driver dwelt at {self.postures_walked}, collector detected '
            f'{self.postures_detected}, bag holds {self.postures_in_bag}'
        )
        lines.append(
            f'CPU (plan start to stop): collector {self.collector_cpu_s:.1f} s '
            f'({100 * self.collector_cpu:.0f}% of one core), driver '
            f'{self.driver_cpu_s:.1f} s ({100 * self.driver_cpu:.0f}%)'
            + (f', CPU hog {self.hog_cpu_s:.1f} s' if self.busy_core else '')
        )
        step = max(1, len(self.memory) // 12)
        shown = self.memory[::step] + ([self.memory[-1]] if (len(self.memory) - 1) % step else [])
        lines.append(
            'collector VmRSS (MiB): '
            + ', '.join(f'{t / 60:.1f} min {rss:.1f}' for t, rss in shown)
        )
        lines.append(
            f'memory after {warm_up_s:g} s warm-up: growth '
            f'{self.memory_growth_mib(warm_up_s):+.2f} MiB, slope '
            f'{self.memory_slope_mib_per_min(warm_up_s):+.3f} MiB/min'
        )
        lines.append(f'collector: {self.collector_summary}')
        for problem in self.problems:
            lines.append(f'PROBLEM: {problem}')
        lines.append('targets:')
        for text, met in self.targets():
            verdict = 'n/a' if met is None else 'met' if met else 'NOT met'
            lines.append(f'  {verdict:<8}{text}')
        return '\n'.join(lines)


def proc_status(pid: int) -> tuple[float, float]:
    """(VmRSS MiB, CPU s) of a process, from /proc."""
    rss_kib = 0
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            rss_kib = int(line.split()[1])
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(') ', 1)[1].split()
    ticks = int(fields[11]) + int(fields[12])  # utime + stime
    return rss_kib / 1024.0, ticks / os.sysconf('SC_CLK_TCK')


def recorded_since(bag: Path, first_stamp_ns: int) -> dict[str, int]:
    """Per raw stream, the bag's messages whose header stamp is >= first_stamp_ns."""
    counts = dict.fromkeys(STREAMS, 0)
    for message in open_bag(bag).messages(list(STREAMS)):
        seconds, nanoseconds = _STAMP.unpack_from(message.data_bytes, 4)
        if seconds * 1_000_000_000 + nanoseconds >= first_stamp_ns:
            counts[message.topic] += 1
    return counts


def _ros_args(parameters: dict[str, object]) -> list[str]:
    argv = ['--ros-args']
    for name, value in parameters.items():
        text = ('true' if value else 'false') if isinstance(value, bool) else str(value)
        argv += ['-p', f'{name}:={text}']
    return argv


def _last_match(pattern: str, text: str) -> re.Match | None:
    matches = list(re.finditer(pattern, text))
    return matches[-1] if matches else None


def start_cpu_hog() -> subprocess.Popen:
    """Start a process that keeps one core busy until killed (by PID: stop_cpu_hog)."""
    return subprocess.Popen(
        [sys.executable, '-c', 'while True: pass'],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
    )


def stop_cpu_hog(hog: subprocess.Popen) -> float:
    """Kill the hog by its PID; returns the CPU s it used."""
    cpu = 0.0
    if hog.poll() is None:
        try:
            cpu = proc_status(hog.pid)[1]
        except OSError:
            pass
        os.kill(hog.pid, signal.SIGKILL)
    hog.wait()
    return cpu


def run_load(
    seconds: float,
    work_dir: Path,
    rate_hz: float = 1000.0,
    sample_s: float = 5.0,
    settle_s: float = 1.0,
    dwell_s: float = 1.5,
    progress=None,
    busy_core: bool = False,
) -> LoadResult:
    """
    Run driver + collector for `seconds` in the current ROS domain; stop both; measure.

    With `busy_core`, a CPU hog process runs beside them for the whole run.
    """
    work_dir.mkdir(parents=True, exist_ok=True)
    bag = work_dir / 'bags' / 'load'
    hog = start_cpu_hog() if busy_core else None
    try:
        result = _run_load(seconds, work_dir, bag, rate_hz, sample_s, settle_s, dwell_s, progress)
    finally:
        hog_cpu = stop_cpu_hog(hog) if hog is not None else 0.0
    result.busy_core, result.hog_cpu_s = busy_core, hog_cpu
    return result


def _run_load(
    seconds: float,
    work_dir: Path,
    bag: Path,
    rate_hz: float,
    sample_s: float,
    settle_s: float,
    dwell_s: float,
    progress,
) -> LoadResult:
    collector = start_node(
        [
            venv_executable('collector'),
            *_ros_args({'output_dir': str(work_dir / 'bags'), 'bag_name': 'load'}),
        ],
        log_path=work_dir / 'collector.log',
    )
    driver: RosProcess | None = None
    try:
        wait_for(
            lambda: 'recording to' in collector.log_text(),
            START_TIMEOUT_S,
            what='the collector to start recording',
            details=collector.describe,
        )
        driver = start_node(
            [
                venv_executable('driver'),
                *_ros_args(
                    {
                        'plan': 'mixed',
                        'postures': 50,
                        'loop': True,
                        'seed': 3,
                        'rate_hz': rate_hz,
                        'settle_s': settle_s,
                        'dwell_s': dwell_s,
                    }
                ),
            ],
            log_path=work_dir / 'driver.log',
        )
        running = driver

        def started() -> bool:
            for process in (collector, running):
                if not process.running():
                    raise AssertionError(f'a node exited early\n{process.describe()}')
            return 'starting plan' in running.log_text()

        wait_for(
            started,
            START_TIMEOUT_S,
            what='the driver to start its plan',
            details=lambda: collector.describe() + '\n' + running.describe(),
        )
        started_at = time.monotonic()
        collector_cpu_start = proc_status(collector.pid)[1]
        driver_cpu_start = proc_status(driver.pid)[1]
        memory: list[tuple[float, float]] = []
        next_sample = started_at
        while True:
            now = time.monotonic()
            if now >= next_sample:
                for process in (collector, driver):
                    if not process.running():
                        raise AssertionError(f'a node exited during the run\n{process.describe()}')
                rss, _ = proc_status(collector.pid)
                memory.append((now - started_at, rss))
                if progress:
                    progress(f'{now - started_at:7.1f} s  collector VmRSS {rss:.1f} MiB')
                next_sample += sample_s
            if now - started_at >= seconds:
                break
            time.sleep(max(0.0, min(next_sample, started_at + seconds) - time.monotonic()))
        collector_cpu = proc_status(collector.pid)[1] - collector_cpu_start
        driver_cpu = proc_status(driver.pid)[1] - driver_cpu_start
        cpu_window = time.monotonic() - started_at
        stop_code = stop(driver, STOP_TIMEOUT_S)
        elapsed = time.monotonic() - started_at
        driver_log = driver.log_path.read_text(errors='replace')
        if stop_code != 0:
            raise AssertionError(f'the driver exited with {stop_code}\n{driver_log[-3000:]}')
        published_match = _last_match(
            r'(\d+) of them since the plan started \(first stamp '
            r'(\d+) ns\)',
            driver_log,
        )
        if published_match is None:
            raise AssertionError(f'the driver did not report its count\n{driver_log[-3000:]}')
        published, first_stamp = int(published_match.group(1)), int(published_match.group(2))
        walked = len(re.findall(r'\] \[driver\]: posture \d+/\d+', driver_log))
        # Stopped = no message for STREAM_STOPPED_S by receipt time: the collector's queue is
        # empty.
        wait_for(
            lambda: 'stream(s) stopped' in collector.log_text(),
            DRAIN_TIMEOUT_S,
            what='the collector to see the streams stop',
            details=collector.describe,
        )
        code = stop(collector, STOP_TIMEOUT_S)
        collector_log = collector.log_path.read_text(errors='replace')
        if code != 0:
            raise AssertionError(f'the collector exited with {code}\n{collector_log[-3000:]}')
    finally:
        for process in (driver, collector):
            if process is not None and process.running():
                stop(process, STOP_TIMEOUT_S)
    summary = _last_match(
        r'(\d+) postures published; messages received (\{[^}]*\}).*', collector_log
    )
    if summary is None:
        raise AssertionError(f'no collector summary\n{collector_log[-3000:]}')
    received = {('/' + topic): count for topic, count in yaml.safe_load(summary.group(2)).items()}
    metadata = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    in_bag = {
        t['topic_metadata']['name']: t['message_count']
        for t in metadata['topics_with_message_count']
    }
    # Anything the collector did not use, other than the posture the driver's stop cut short.
    problems = [
        line
        for line in collector_log.splitlines()
        if 'recording stopped' in line
        or 'not used:' in line
        or 'ignored an invalid message' in line
    ]
    return LoadResult(
        rate_hz=rate_hz,
        seconds=elapsed,
        published=published,
        received=received,
        recorded=recorded_since(bag, first_stamp),
        postures_walked=walked,
        postures_detected=int(summary.group(1)),
        postures_in_bag=in_bag.get('/hexacal/posture', 0),
        memory=memory,
        collector_cpu_s=collector_cpu,
        driver_cpu_s=driver_cpu,
        cpu_window_s=cpu_window,
        collector_summary=summary.group(0).strip(),
        bag=str(bag),
        problems=problems,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=10.0, help='run time (default 10)')
    parser.add_argument(
        '--rate-hz', type=float, default=1000.0, help='driver rate per stream (default 1000)'
    )
    parser.add_argument(
        '--sample-s', type=float, default=10.0, help='memory sampling period (default 10 s)'
    )
    parser.add_argument(
        '--warm-up-s',
        type=float,
        default=60.0,
        help='memory growth is measured after this (default 60 s)',
    )
    parser.add_argument(
        '--work-dir',
        type=Path,
        default=None,
        help='keep logs and the bag here (default: a temporary directory, removed)',
    )
    parser.add_argument(
        '--busy-core',
        action='store_true',
        help='run a CPU hog (busy loop) beside the nodes, killed at the end',
    )
    parser.add_argument('--json', action='store_true', help='print one JSON object')
    args = parser.parse_args(argv)

    os.environ['ROS_DOMAIN_ID'] = str(claim_domain_id('HEXACAL_TEST_DOMAIN_ID'))
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ.pop('ROS_STATIC_PEERS', None)
    progress = None if args.json else (lambda line: print(line, flush=True))
    with tempfile.TemporaryDirectory(prefix='hexacal-load-') as scratch:
        work_dir = args.work_dir or Path(scratch)
        result = run_load(
            args.minutes * 60.0,
            work_dir,
            rate_hz=args.rate_hz,
            sample_s=args.sample_s,
            progress=progress,
            busy_core=args.busy_core,
        )
    warm_up = min(args.warm_up_s, result.seconds / 4)
    if args.json:
        print(json.dumps(result.to_json(warm_up)))
    else:
        print(result.table(warm_up))
    lost = any(result.lost.values())
    return 1 if lost or result.problems else 0


if __name__ == '__main__':
    sys.exit(main())
