#!/usr/bin/env python3
"""
Offline re-detection benchmark: raw readings per second, and `hexacal calibrate` of a raw bag.

Makes (or takes, ``--bag``) a raw recording of the simulated machine with every sensor effect
(hexacal_driver.recording: ``--postures`` postures, settle 2 s, dwell 3 s, 100 Hz: about
75 000 messages, 12 MB, no posture topic), then, in the same run, with the code before the
batched detector (git ``--before``, default ca4aa69, exported with ``git archive`` into a
temporary directory) and with this checkout:

- re-detection: ``postures_from_bag(bag, source='raw')`` in a fresh process, raw readings
  (messages) per second of its CPU time (import excluded), best of ``--repeats``; the postures
  of both must be identical (every field, float bits: their repr);
- ``hexacal calibrate BAG --nominal ...`` wall time in a fresh process, best of ``--repeats``,
  against a bare ``python -c 'import numpy'``; the parameter values of both must agree to
  ``PARAMETER_TOLERANCE`` (identical files when the fit did not change since "before"; the
  largest difference is printed).

Target: the calibrate within 10x a bare numpy import (wall, best of the repeats). Prints
"met" / "NOT met", and the CPU times (user + system) beside: on a busy machine the wall
times wait for the cores, the CPU times do not.
Run: ``.venv/bin/python benchmarks/bench_redetect.py [--bag DIR] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ('hexacal_msgs_py', 'hexacal_identify', 'hexacal_driver')
TARGET_FACTOR = 10.0
# A parameter value may differ this much (m, rad) from "before": a later fit's own rounding.
PARAMETER_TOLERANCE = 1e-8
_REDETECT = (
    'import sys, time\n'
    'try:\n'
    '    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag\n'
    'except ImportError:  # a revision before the layout of 2026-11 (pipeline.py)\n'
    '    from hexacal_identify.pipeline import postures_from_bag\n'
    'start = time.process_time()\n'
    'found = postures_from_bag(sys.argv[1], source="raw")\n'
    'seconds = time.process_time() - start\n'
    'print(seconds)\n'
    'print(repr([p for p in found.postures]))\n'
)


def _environment(root: Path) -> dict[str, str]:
    environment = dict(os.environ)
    environment['PYTHONPATH'] = os.pathsep.join(
        str(root / 'ros2_ws' / 'src' / package) for package in PACKAGES
    )
    return environment


def _cpu_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(arguments: list[str], root: Path | None) -> tuple[float, str, float]:
    """Run a process; return its wall time, its output and its CPU time (user + system)."""
    environment = _environment(root) if root is not None else dict(os.environ)
    cpu = _cpu_children()
    start = time.perf_counter()
    done = subprocess.run(
        arguments, env=environment, capture_output=True, text=True, check=False
    )
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f'{" ".join(arguments)} failed:\n{done.stdout}\n{done.stderr}')
    return wall, done.stdout, _cpu_children() - cpu


def make_recording(directory: Path, postures: int) -> tuple[Path, int]:
    """Write the raw recording (every sensor effect) into `directory`; return it and its size."""
    sys.path[:0] = [str(REPO / 'ros2_ws' / 'src' / package) for package in PACKAGES]
    from hexacal_driver.recording import simulate_recording, write_recording_bag

    recording = simulate_recording(
        sensor_effects='all', postures=postures, seed=0, settle_s=2.0, dwell_s=3.0
    )
    return write_recording_bag(directory / 'raw', recording), recording.message_count


def message_count(bag: Path) -> int:
    """Return the number of messages of a bag."""
    sys.path[:0] = [str(REPO / 'ros2_ws' / 'src' / package) for package in PACKAGES]
    from hexacal_identify.bag import open_bag

    return sum(1 for _ in open_bag(bag).messages())


def main() -> int:
    """Measure before and after; print the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--bag', type=Path, help='a raw recording (default: made here)')
    parser.add_argument('--postures', type=int, default=50)
    parser.add_argument('--before', default='ca4aa69', help='git revision of "before"')
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    python = sys.executable
    with tempfile.TemporaryDirectory() as temporary:
        work = Path(temporary)
        if args.bag is None:
            bag, messages = make_recording(work, args.postures)
        else:
            bag, messages = args.bag, message_count(args.bag)
        before = work / 'before'
        before.mkdir()
        archive = subprocess.run(
            ['git', '-C', str(REPO), 'archive', args.before], capture_output=True, check=True
        )
        subprocess.run(['tar', '-x', '-C', str(before)], input=archive.stdout, check=True)
        nominal = work / 'nominal2.yaml'
        cli = [python, '-m', 'hexacal_identify.cli']
        _run([*cli, 'params', 'nominal', '--set', '2', '--seed', '0', '--out', str(nominal)], REPO)
        results: dict[str, dict[str, float]] = {}
        postures: dict[str, str] = {}
        outputs: dict[str, bytes] = {}
        numpy_runs = [_run([python, '-c', 'import numpy'], None) for _ in range(args.repeats)]
        numpy_s = min(run[0] for run in numpy_runs)
        numpy_cpu_s = min(run[2] for run in numpy_runs)
        for name, root in (('before', before), ('after', REPO)):
            redetect, calibrate, calibrate_cpu = [], [], []
            for _ in range(args.repeats):
                output = _run([python, '-c', _REDETECT, str(bag)], root)[1].split('\n', 1)
                redetect.append(float(output[0]))
                postures[name] = output[1]
                out = work / f'{name}.yaml'
                wall, _, cpu = _run(
                    [
                        *cli,
                        'calibrate',
                        str(bag),
                        '--nominal',
                        str(nominal),
                        '--output',
                        str(out),
                        '--no-store',
                    ],
                    root,
                )
                calibrate.append(wall)
                calibrate_cpu.append(cpu)
                outputs[name] = out.read_bytes()
            results[name] = {
                'redetect_s': min(redetect),
                'readings_per_s': messages / min(redetect),
                'calibrate_s': min(calibrate),
                'calibrate_over_numpy': min(calibrate) / numpy_s,
                'calibrate_cpu_s': min(calibrate_cpu),
                'calibrate_cpu_over_numpy': min(calibrate_cpu) / numpy_cpu_s,
            }
    same_postures = postures['before'] == postures['after']
    same_parameters = outputs['before'] == outputs['after']
    difference = _largest_difference(outputs['before'], outputs['after'])
    met = results['after']['calibrate_over_numpy'] <= TARGET_FACTOR
    summary = {
        'messages': messages,
        'postures': postures['after'].count('PostureReading('),
        'numpy_import_s': numpy_s,
        'numpy_import_cpu_s': numpy_cpu_s,
        **results,
        'same_postures': same_postures,
        'same_parameters': same_parameters,
        'largest_parameter_difference': difference,
        'target_met': met,
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f'raw recording: {messages} messages, {summary["postures"]} postures')
        print(f'bare numpy import: {numpy_s:.3f} s wall, {numpy_cpu_s:.3f} s CPU')
        for name in ('before', 'after'):
            r = results[name]
            print(
                f'{name:6}: re-detection {r["redetect_s"]:.2f} s CPU '
                f'({r["readings_per_s"]:,.0f} readings/s); hexacal calibrate '
                f'{r["calibrate_s"]:.2f} s = {r["calibrate_over_numpy"]:.1f}x numpy import '
                f'(CPU {r["calibrate_cpu_s"]:.2f} s = {r["calibrate_cpu_over_numpy"]:.1f}x)'
            )
        print(
            f'same postures: {same_postures}; same parameter file: {same_parameters} '
            f'(largest difference of a parameter value {difference:.3g}; the fit itself may '
            'have changed since "before")'
        )
        print(
            f'target (calibrate within {TARGET_FACTOR:.0f}x a bare numpy import): '
            f'{"met" if met else "NOT met"}'
        )
    return 0 if same_postures and difference <= PARAMETER_TOLERANCE else 1


def _largest_difference(before: bytes, after: bytes) -> float:
    """Return the largest difference of a parameter value between two parameter files."""
    import numpy as np
    import yaml

    def values(text: bytes) -> dict:
        return yaml.safe_load(text)['/**']['ros__parameters']

    old, new = values(before), values(after)
    if old.keys() != new.keys():
        return float('inf')
    largest = 0.0
    for key, value in old.items():
        try:
            gap = np.max(np.abs(np.asarray(value, float) - np.asarray(new[key], float)))
        except (TypeError, ValueError):
            gap = 0.0 if value == new[key] else float('inf')
        largest = max(largest, float(gap))
    return largest


if __name__ == '__main__':
    sys.exit(main())
