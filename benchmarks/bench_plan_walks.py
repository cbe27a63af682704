#!/usr/bin/env python3
"""
Passive-actuator plans made as the demo makes them, walked offline on the demo's true machine.

For each model, each size K and seed: the demo's machines (``hexacal demo``, cli/demo_run.py:
the true machine is the architecture's default parameters, the nominal is Table 2 set 2 of
the seed), its calibration plan (``mixed``: sphere-fixed, a quarter fixed positions, O1 over
1000 candidates, 10 um noise, the seed) and its verification plan (20 postures, absolute, seed
+ 1000), both planned on the nominal in passive_actuator mode, with the model-change margin off
(``model_error_m=0``) and on (None: the architecture's Table 2 set 2 RMS).  Each plan is walked
offline on the true machine (hexacal_driver.plan_walk): the calibration plan on the nominal's
targets until the executor's first refinement checkpoint, on the calibration's afterwards; the
verification plan on the calibration's targets.  The calibration is stood in for by the true
machine (a calibration is micrometres from it; no fit is run here).  A fixed-position posture is
walked to its planned pose: the executor's closed-loop corrections on the inclinometer (which
can leave the platform far from the plan, docs/results.md) are not emulated.

The table per model, margin and K (summed over the seeds): plans walked, moves that jam the
drive, plans with a jam, the closest approach to a fold (the largest condition number of the
passive system met along a move that did not jam; inf: a fold reached), and the targets
outside the stroke (the executor refuses such a plan).  Planning and walking times are printed.

Each plan is walked without and with the executor's checks at rest (``--at-rest``) and, with
``--measured-standing off on``, with the checks made from the model's estimate of the standing
alone and again from the inclinometer's, in the same run.

Run: ``nice .venv/bin/python benchmarks/bench_plan_walks.py [--models hexa_slide gough_stewart]
[--sizes 20 30 50 80] [--seeds 5] [--margins off on] [--verify-postures 20] [--at-rest off on]
[--measured-standing off on]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def plans(model: str, size: int, seed: int, margin: bool, verify: int):
    """Return the true machine, the nominal, the calibration and verification plans."""
    from hexacal_identify.core.architectures import architecture
    from hexacal_identify.core.machine.measurements import NoiseModel
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_identify.core.planning.planner import plan_postures

    truth = architecture(model).default_parameters()
    nominal = nominal_set(2, seed=seed, model=model)
    error = None if margin else 0.0
    noise = NoiseModel.from_microns(10.0)
    calibration = plan_postures(
        nominal, size, index='O1', cost='sphere-fixed', fixed_fraction=0.25, n_candidates=1000,
        seed=seed, noise=noise, name='demo-calibration', measuring_mode='passive_actuator',
        model_error_m=error,
    ).plan
    verification = plan_postures(
        nominal, verify, index='O1', cost='absolute', n_candidates=1000, seed=seed + 1000,
        noise=noise, name='demo-verification', measuring_mode='passive_actuator',
        model_error_m=error,
    ).plan
    return truth, nominal, calibration, verification


def walk(truth, model, plan, refined=None, refine_at=None, check_at_rest=True,
         measured_standing=True):
    """Return the plan walked offline on `truth` (plan_walk.walk_plan)."""
    from hexacal_driver.plan_walk import walk_plan
    from hexacal_identify.core.planning.plan_check import plan_stroke

    stroke, _ = plan_stroke(plan.metadata, model)
    names = list(model.layout.actuator_names)
    released = [names.index(name) for name in plan.released_actuators]
    return walk_plan(truth, model, plan.poses, released, plan.link_length, stroke,
                     mount=plan.mount, refine_at=refine_at, refined=refined,
                     check_at_rest=check_at_rest, measured_standing=measured_standing)


def _count(row: dict, walked) -> None:
    """Add the walks' jams, refusals and closest approach to a fold to `row`."""
    for plan_walk in walked:
        row['plans'] += 1
        row['jams'] += plan_walk.jams
        row['jammed'] += plan_walk.jams > 0
        row['outside'] += plan_walk.refused
        closed = [m.worst_condition for m in plan_walk.moves if not m.refused and not m.jammed]
        row['closest'] = max(row['closest'], max(closed, default=0.0))


def main() -> None:
    """Plan, walk and print the table (module doc)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--models', nargs='+', default=['hexa_slide', 'gough_stewart'])
    parser.add_argument('--sizes', nargs='+', type=int, default=[20, 30, 50, 80])
    parser.add_argument('--seeds', type=int, default=5)
    parser.add_argument('--margins', nargs='+', default=['off', 'on'], choices=['off', 'on'])
    parser.add_argument('--verify-postures', type=int, default=20)
    parser.add_argument(
        '--at-rest', nargs='+', default=['off', 'on'], choices=['off', 'on'],
        help="the executor's check_releases_at_rest: each plan walked without and with it",
    )
    parser.add_argument(
        '--measured-standing', nargs='+', default=['on'], choices=['off', 'on'],
        help='the checks at rest again from where the inclinometer puts the platform (the '
        "executor's; off: from the model's estimate alone, as before 2026-11-28)",
    )
    args = parser.parse_args()
    from hexacal_identify.core.walk_refine.refinement import full_rank_postures

    started = time.perf_counter()
    rows = []
    for model_name in args.models:
        for margin in args.margins:
            for size in args.sizes:
                by_check = {
                    (check, measured): {'plans': 0, 'jams': 0, 'jammed': 0, 'closest': 0.0,
                                        'outside': 0, 'plan_s': 0.0, 'walk_s': 0.0, 'failed': 0}
                    for check in args.at_rest for measured in args.measured_standing
                }
                for seed in range(args.seeds):
                    t0 = time.perf_counter()
                    try:
                        truth, nominal, calibration, verification = plans(
                            model_name, size, seed, margin == 'on', args.verify_postures)
                    except ValueError as error:  # no release, no margin: the planner refuses
                        for row in by_check.values():
                            row['failed'] += 1
                        print(f'  {model_name} {margin} K={size} seed {seed}: {error}',
                              flush=True)
                        continue
                    t1 = time.perf_counter()
                    first = full_rank_postures(nominal.layout.n_parameters)
                    for (check, measured), row in by_check.items():
                        t2 = time.perf_counter()
                        walked = [
                            walk(truth, nominal, calibration, truth,
                                 first if first < size else None, check == 'on',
                                 measured == 'on'),
                            walk(truth, truth, verification, check_at_rest=check == 'on',
                                 measured_standing=measured == 'on'),
                        ]
                        t3 = time.perf_counter()
                        row['plan_s'] += t1 - t0
                        row['walk_s'] += t3 - t2
                        _count(row, walked)
                        first_jams = [next((m.posture for m in w.moves if m.jammed), None)
                                      for w in walked]
                        worst = [round(w.worst_condition) if np.isfinite(w.worst_condition)
                                 else 'inf' for w in walked]
                        print(f'  {model_name} {margin} K={size} seed {seed} at rest {check} '
                              f'measured {measured}: '
                              f'jams {[w.jams for w in walked]} (first at {first_jams}, '
                              f'recovered {[w.recovered for w in walked]}), '
                              f'outside {[w.refused for w in walked]}, worst cond {worst} '
                              f'({t1 - t0:.0f} s plan, {t3 - t2:.0f} s walk)', flush=True)
                rows.extend((model_name, margin, size, check, row)
                            for check, row in by_check.items())
    print()
    print(f'{"model":14} {"margin":6} {"K":>3} {"at rest":>7} {"measured":>8} {"plans":>5} '
          f'{"jams":>5} '
          f'{"jammed":>6} {"closest cond":>12} {"outside":>7} {"refused":>7} {"plan s":>7} '
          f'{"walk s":>7}')
    for model_name, margin, size, (check, measured), row in rows:
        print(f'{model_name:14} {margin:6} {size:3d} {check:>7} {measured:>8} {row["plans"]:5d} '
              f'{row["jams"]:5d} '
              f'{row["jammed"]:6d} {row["closest"]:12.0f} {row["outside"]:7d} '
              f'{row["failed"]:7d} {row["plan_s"]:7.0f} {row["walk_s"]:7.0f}')
    print(f'total {time.perf_counter() - started:.0f} s (jams: moves the drive faulted on; '
          'jammed: plans with one; closest cond: worst condition of the passive system on a '
          'move that closed; outside: targets outside the stroke; refused: plans the planner '
          'could not make)')


if __name__ == '__main__':
    main()
