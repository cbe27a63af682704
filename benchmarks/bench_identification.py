#!/usr/bin/env python3
"""Identification wall time versus the paper-style baseline, in one process.

For each posture count: simulate nominal set 2 with 10 um / 10 urad noise on the
Table 1 machine, time ``identify`` (median of several runs after a warm-up), and
time the baseline once (per-posture FK, finite-difference Jacobian re-solving FK
for every column and posture, scipy ``least_squares``) on the identical problem.
Postures whose FK fails with the nominal parameters are left out of both, since
the baseline has no way to set them aside.

Run: ``.venv/bin/python benchmarks/bench_identification.py [--json] [--baseline-max 200]``
Targets (issue 12, 2-core machine), checked on the rows of this run: at 50 postures
at least 2000x the baseline measured in the same run, and the time at 5000
postures at most 20x the time at 50 (the solver's per-posture work is one pass
over the Jacobian; everything else is n x n).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from hexacal_identify.core.architectures import ARCHITECTURES, default_parameters
from hexacal_identify.core.fit.baseline import absolute_residuals, identify_baseline
from hexacal_identify.core.fit.identification import identify
from hexacal_identify.core.machine.measurements import Measurements
from hexacal_identify.studies.accuracy import simulate_run_measurements, StudyRun
import numpy as np

POSTURE_COUNTS = (25, 50, 200, 1000, 5000, 20000)
TARGET_RATIO_AT_50 = 2000.0  # identify at 50 postures vs the paper-style baseline at 50
TARGET_GROWTH_50_TO_5000 = 20.0  # t(5000) / t(50), for 100x the postures


def problem(postures: int, seed: int, model: str = 'hexa_slide') -> tuple[StudyRun, Measurements]:
    run = StudyRun(
        true_params=default_parameters(model),
        postures=int(postures * 1.2) + 5,
        noise_um=10.0,
        seed=seed,
    )
    measurements = simulate_run_measurements(run)
    finite = np.all(
        np.isfinite(
            absolute_residuals(run.nominal().vector, measurements, model=model).reshape(-1, 4)
        ),
        axis=1,
    )
    return run, measurements.subset(np.flatnonzero(finite)[:postures])


def time_identify(run: StudyRun, measurements: Measurements, repeats: int) -> tuple[float, int]:
    identify(run.nominal(), measurements)  # warm-up: imports, caches
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        result = identify(run.nominal(), measurements)
        times.append(time.perf_counter() - started)
    return statistics.median(times), result.iterations


def print_table(rows: list[dict]) -> None:
    print(
        f'{"postures":>9} {"hexacal ms":>11} {"baseline ms":>12} {"ratio":>8} {"LM iters":>9} {"us/posture":>11}'
    )
    for row in rows:
        baseline = (
            f'{row["baseline_seconds"] * 1e3:12.1f}'
            if row['baseline_seconds']
            else f'{"skipped":>12}'
        )
        ratio = f'{row["ratio"]:8.0f}' if row['ratio'] else f'{"-":>8}'
        print(
            f'{row["postures"]:9d} {row["seconds"] * 1e3:11.2f} {baseline} {ratio} {row["iterations"]:9d} '
            f'{row["microseconds_per_posture"]:11.1f}'
        )


def target_checks(rows: list[dict]) -> list[str]:
    """One 'met' / 'NOT met' line per target, from this run's rows ('not measured' without the rows)."""
    by_count = {row['postures']: row for row in rows}
    lines = []
    at_50 = by_count.get(50)
    if at_50 and at_50['ratio']:
        verdict = 'met' if at_50['ratio'] >= TARGET_RATIO_AT_50 else 'NOT met'
        lines.append(
            f'target ratio at 50 postures >= {TARGET_RATIO_AT_50:.0f}x the baseline: '
            f'{at_50["ratio"]:.0f}x, {verdict}'
        )
    else:
        lines.append(
            'target ratio at 50 postures: not measured (run 50 postures with the baseline)'
        )
    at_5000 = by_count.get(5000)
    if at_50 and at_5000:
        growth = at_5000['seconds'] / at_50['seconds']
        verdict = 'met' if growth <= TARGET_GROWTH_50_TO_5000 else 'NOT met'
        lines.append(
            f'target t(5000)/t(50) <= {TARGET_GROWTH_50_TO_5000:.0f}: {growth:.1f}, {verdict}'
        )
    else:
        lines.append('target t(5000)/t(50): not measured (run 50 and 5000 postures)')
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--json', action='store_true', help='print the rows as a JSON list')
    parser.add_argument(
        '--baseline-max', type=int, default=200, help='skip the baseline above this many postures'
    )
    parser.add_argument('--postures', type=int, nargs='*', default=list(POSTURE_COUNTS))
    parser.add_argument('--seed', type=int, default=3)
    parser.add_argument(
        '--model',
        choices=sorted(ARCHITECTURES),
        default='hexa_slide',
        help='machine model: its default machine, nominal set 2 (default hexa_slide)',
    )
    args = parser.parse_args(argv)
    rows = []
    for count in args.postures:
        run, measurements = problem(count, args.seed, args.model)
        seconds, iterations = time_identify(run, measurements, repeats=15 if count <= 200 else 3)
        baseline = (
            identify_baseline(run.nominal(), measurements).seconds
            if count <= args.baseline_max
            else None
        )
        rows.append(
            {
                'model': args.model,
                'postures': len(measurements),
                'seconds': seconds,
                'baseline_seconds': baseline,
                'ratio': (baseline / seconds) if baseline else None,
                'iterations': iterations,
                'microseconds_per_posture': seconds / len(measurements) * 1e6,
            }
        )
        if not args.json:
            print(f'  measured {len(measurements)} postures', file=sys.stderr)
    if args.json:
        print(json.dumps(rows))
        return 0
    print_table(rows)
    for line in target_checks(rows):
        print(line)
    return 0


if __name__ == '__main__':
    sys.exit(main())
