#!/usr/bin/env python3
"""
Print the measuring modes of issue #18 side by side, today's compliant demo the baseline.

For each machine model: the three modes (passive_actuator, lvdt, compliant) walked with targets
from the nominal model (set 2) then refined from intermediate calibrations, and the compliant
mode on nominal targets only (hexacal's procedure before #18: the baseline of this run), each
calibrated with the core and judged on fresh validation poses against the simulated truth.
Printed per mode: the largest deviation of a commanded actuator from its setpoint at rest, the
servos' force (compliant), the LVDT link's extension (lvdt) and the released actuator's offset
from the model's prediction (passive_actuator), before -> after refinement, and the pose error
(mean / max over the validation poses; mean and spread over the seeds).

Run: ``.venv/bin/python benchmarks/bench_measuring_modes.py [--seeds 3] [--json]``
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import json
import statistics

from hexacal_identify.cli.study_modes import print_table
from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.studies.measuring_mode_accuracy import ModeStudyRun, run_mode

MODES = ('passive_actuator', 'lvdt', 'compliant')
MODELS = ('hexa_slide', 'gough_stewart')


def runs(model: str, seed: int, postures: int, noise_um: float) -> list[ModeStudyRun]:
    """Return the three refined runs and the unrefined compliant baseline of one seed."""
    base = ModeStudyRun(
        true_params=default_parameters(model), postures=postures, noise_um=noise_um, seed=seed
    )
    return [replace(base, mode=mode) for mode in MODES] + [
        replace(base, mode='compliant', refine=False)
    ]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--seeds', type=int, default=3, help='seeds per model (default 3)')
    parser.add_argument('--postures', type=int, default=50, help='postures (default 50)')
    parser.add_argument('--noise-um', type=float, default=10.0, help='noise (default 10)')
    parser.add_argument('--json', action='store_true', help='print the rows as JSON')
    args = parser.parse_args()
    rows = []
    for model in MODELS:
        per_seed = [
            [run_mode(run).to_json() for run in runs(model, seed, args.postures, args.noise_um)]
            for seed in range(args.seeds)
        ]
        for payloads in per_seed:
            rows.extend({'model': model, **payload} for payload in payloads)
        if args.json:
            continue
        print(f'\n{model}, seed 0 ({args.postures} postures, +-{args.noise_um:g} um noise):')
        print_table(per_seed[0])
        print(f'  pose error mean over {args.seeds} seeds (mean +- spread), um:')
        for column, payload in enumerate(per_seed[0]):
            values = [seed_rows[column]['pose_error_mean_m'] * 1e6 for seed_rows in per_seed]
            spread = statistics.stdev(values) if len(values) > 1 else 0.0
            refined = 'refined' if payload['refine'] else 'nominal targets (baseline)'
            print(
                f'    {payload["measuring_mode"]:<17} {refined:<27} '
                f'{statistics.mean(values):6.2f} +- {spread:.2f}'
            )
    if args.json:
        print(json.dumps(rows))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
