#!/usr/bin/env python3
"""
Wall and CPU time of `hexacal plan` per measuring mode and model, before and after the batching.

Before: the code of git ``--before`` (default 8620458: the stacked rehearsal gathering and
indexing its rows in every Newton pass; ca4aa69 is the machine-by-machine rehearsal before the
stacking), exported with ``git archive`` to a temporary directory and run with it first on
PYTHONPATH; after: this checkout.  Each run is one ``python -m hexacal_identify.cli plan --postures K
--measuring-mode M [--nominal <model's default file>] --out <tmp>`` in a child process: its
wall time and its CPU time (user + sys, from the children's rusage; less sensitive to a busy
machine).  Then the rehearsal alone, in this process: the releases of the first
``--rehearsal-postures`` postures of the 25-posture passive plan, walked in order, by the
stacked rehearsal and by the machine-by-machine reference kept beside it (``batched=False``),
with the Newton solves (one posture row of one continuation step on one machine) per second.

Run: ``nice .venv/bin/python benchmarks/bench_plan_speed.py [--sizes 25 50]
[--before-passive-sizes 25] [--models hexa_slide gough_stewart] [--json]`` (the before
passive plans take minutes each: by default only the 25-posture one is run before).
Target: a passive_actuator plan within 3x the compliant plan of the same size, both models.
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
MODES = ('passive_actuator', 'lvdt', 'compliant')
MODELS = {
    'hexa_slide': None,  # the CLI's default nominal
    'gough_stewart': 'gough_stewart_default.yaml',
}


def python_path(root: Path) -> str:
    return os.pathsep.join(str(root / 'ros2_ws' / 'src' / p) for p in PACKAGES)


def export(commit: str, into: Path) -> Path:
    """Export the packages of `commit` into `into` (git archive); return the root."""
    archive = subprocess.run(
        ['git', '-C', str(REPO), 'archive', commit, 'ros2_ws/src'], check=True,
        capture_output=True,
    ).stdout
    into.mkdir(parents=True, exist_ok=True)
    subprocess.run(['tar', '-x', '-C', str(into)], input=archive, check=True)
    return into


def run_plan(root: Path, model: str, mode: str, size: int, out: Path) -> tuple[float, float]:
    """Return (wall s, CPU s) of one `hexacal plan` run with `root`'s packages."""
    argv = [sys.executable, '-m', 'hexacal_identify.cli', 'plan', '--postures', str(size),
            '--measuring-mode', mode, '--out', str(out)]
    if MODELS[model]:
        data = root / 'ros2_ws/src/hexacal_identify/hexacal_identify/data' / MODELS[model]
        argv += ['--nominal', str(data)]
    env = dict(os.environ, PYTHONPATH=python_path(root))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    result = subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        raise RuntimeError(f'{" ".join(argv)} exited with {result.returncode}: {result.stderr}')
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def rehearsal_rates(model: str, plan_file: Path, postures: int) -> dict:
    """Return the stacked and reference rehearsal of a plan's first postures: s, solves/s."""
    sys.path[:0] = python_path(REPO).split(os.pathsep)
    import numpy as np

    from hexacal_identify.core.modes import release_rehearsal
    from hexacal_identify.core.architectures import default_parameters
    from hexacal_identify.core.modes.released_actuator import choose_released_actuators
    from hexacal_msgs_py.plan_file import read_plan_file

    plan = read_plan_file(str(plan_file))
    params = default_parameters(model)
    workspace = params.architecture.default_workspace()
    poses = plan.poses[:postures]
    solves = {'n': 0}
    stacked, reference = release_rehearsal.solve_stacked, release_rehearsal.solve_passive
    settle = release_rehearsal._Continuation._settle

    def count_stacked(stack, machine, *args, **kwargs):
        solves['n'] += len(machine)
        return stacked(stack, machine, *args, **kwargs)

    def count_settled(self, settled, *args, **kwargs):  # rows' samples solved (or failed)
        solves['n'] += int(np.count_nonzero(settled))
        return settle(self, settled, *args, **kwargs)

    def count_reference(params, commanded, *args, **kwargs):
        solves['n'] += len(commanded)
        return reference(params, commanded, *args, **kwargs)

    release_rehearsal.solve_stacked = count_stacked
    release_rehearsal.solve_passive = count_reference
    release_rehearsal._Continuation._settle = count_settled
    rows = {}
    try:
        for batched in (True, False):
            solves['n'] = 0
            started = time.perf_counter()
            choice = choose_released_actuators(
                params, poses, workspace.link_length, workspace.actuator_stroke_m,
                batched=batched,
            )
            elapsed = time.perf_counter() - started
            rows['stacked' if batched else 'reference'] = {
                'seconds': elapsed, 'solves': solves['n'],
                'solves_per_s': solves['n'] / elapsed,
                'released': [int(c) for c in choice.released],
                'jams': [int(j) for j in choice.jams],
            }
    finally:
        release_rehearsal.solve_stacked = stacked
        release_rehearsal.solve_passive = reference
        release_rehearsal._Continuation._settle = settle
    rows['same_decisions'] = (
        rows['stacked']['released'] == rows['reference']['released']
        and rows['stacked']['jams'] == rows['reference']['jams']
    )
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--before', default='8620458', help='git commit of the before code')
    parser.add_argument('--sizes', type=int, nargs='+', default=[25, 50])
    parser.add_argument('--before-passive-sizes', type=int, nargs='*', default=[25],
                        help='sizes of the before passive_actuator plans (minutes each)')
    parser.add_argument('--models', nargs='+', choices=list(MODELS), default=list(MODELS))
    parser.add_argument('--rehearsal-postures', type=int, default=6)
    parser.add_argument('--rates-only', action='store_true',
                        help='only the rehearsal rates (on an after plan of the smallest size)')
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    results = []
    with tempfile.TemporaryDirectory(prefix='bench_plan_speed_') as tmp:
        before_root = export(args.before, Path(tmp) / 'before')
        for model in args.models:
            if args.rates_only:
                size = min(args.sizes)
                run_plan(REPO, model, 'passive_actuator', size,
                         Path(tmp) / f'{model}_passive_actuator_{size}.yaml')
                continue
            for size in args.sizes:
                for mode in MODES:
                    row = {'model': model, 'postures': size, 'mode': mode}
                    out = Path(tmp) / f'{model}_{mode}_{size}.yaml'
                    row['after_wall_s'], row['after_cpu_s'] = run_plan(REPO, model, mode, size,
                                                                       out)
                    if mode != 'passive_actuator' or size in args.before_passive_sizes:
                        row['before_wall_s'], row['before_cpu_s'] = run_plan(
                            before_root, model, mode, size, Path(tmp) / 'before.yaml')
                    results.append(row)
                    print(json.dumps(row), file=sys.stderr, flush=True)
        rates = {
            model: rehearsal_rates(
                model, Path(tmp) / f'{model}_passive_actuator_{min(args.sizes)}.yaml',
                args.rehearsal_postures,
            )
            for model in args.models
        }
    if args.json:
        print(json.dumps({'plans': results, 'rehearsal': rates}, indent=2))
        return 0
    print(f'hexacal plan, wall / CPU seconds (before: {args.before}; after: this checkout)')
    print(f'{"model":14s} {"K":>3s} {"mode":17s} {"before wall":>11s} {"before CPU":>10s} '
          f'{"x compliant":>11s} {"after wall":>10s} {"after CPU":>9s} {"x compliant":>11s}')
    for row in results:
        compliant = next(r for r in results if r['model'] == row['model']
                         and r['postures'] == row['postures'] and r['mode'] == 'compliant')
        ratio = row['after_cpu_s'] / compliant['after_cpu_s']
        before_wall = f'{row["before_wall_s"]:11.1f}' if 'before_wall_s' in row else f'{"-":>11s}'
        before_cpu = f'{row["before_cpu_s"]:10.1f}' if 'before_cpu_s' in row else f'{"-":>10s}'
        before_ratio = (
            f'{row["before_cpu_s"] / compliant["before_cpu_s"]:11.2f}'
            if 'before_cpu_s' in row and 'before_cpu_s' in compliant else f'{"-":>11s}'
        )
        print(f'{row["model"]:14s} {row["postures"]:3d} {row["mode"]:17s} {before_wall} '
              f'{before_cpu} {before_ratio} {row["after_wall_s"]:10.1f} '
              f'{row["after_cpu_s"]:9.1f} {ratio:11.2f}')
    print(f'\nrehearsal of the first {args.rehearsal_postures} postures in order (9 machines):')
    for model, rows in rates.items():
        for name in ('stacked', 'reference'):
            r = rows[name]
            print(f'  {model:14s} {name:9s} {r["seconds"]:7.2f} s  {r["solves"]:7d} solves  '
                  f'{r["solves_per_s"]:9.0f} solves/s')
        print(f'  {model:14s} same released actuators and jams: {rows["same_decisions"]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
