"""
``hexacal study --plan``: its options, and the table and figure of the planning study.

The study itself (planned against random postures, over seeds) is studies.planning.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .command_line import Progress
from ..core.planning.observability import CRITERIA
from ..core.planning.planner import METHODS
from ..studies.planning import (
    DEFAULT_KS,
    planned_vs_random,
    PlanningStudy,
    REFERENCE_RANDOM_POSTURES,
    UM,
)


def add_arguments(parser) -> None:
    """
    Add the options of ``hexacal study --plan``.

    Options of ``hexacal study --plan`` (it also uses --seed, --noise-um, --cost, --nominal-set,
    --out, --json).
    """
    group = parser.add_argument_group('posture planning study (--plan)')
    group.add_argument(
        '--plan',
        action='store_true',
        help='compare planned and random postures: validation error vs number of postures',
    )
    group.add_argument(
        '--plan-ks',
        type=lambda text: [int(v) for v in text.split(',')],
        default=list(DEFAULT_KS),
        help='numbers of postures to compare, comma-separated (default 15,20,25,30,40,50)',
    )
    group.add_argument(
        '--index',
        choices=CRITERIA,
        default='O1',
        help='index to plan for (default O1); the I-optimal plan is always compared as well',
    )
    group.add_argument(
        '--method', choices=METHODS, default='greedy', help='selection method (default greedy)'
    )
    group.add_argument(
        '--candidates', type=int, default=2000, help='candidate postures per plan (default 2000)'
    )
    group.add_argument(
        '--plan-seeds', type=int, default=30, help='seeds, from --seed on (default 30)'
    )


def run(args) -> int:
    """Run ``hexacal study --plan``."""
    from ..report import figures

    seeds = list(range(args.seed, args.seed + args.plan_seeds))
    progress = Progress(enabled=not args.json)
    try:
        study = planned_vs_random(
            args.plan_ks,
            seeds,
            args.noise_um,
            args.cost,
            args.nominal_set,
            args.index,
            args.method,
            args.candidates,
            progress.step,
            model=getattr(args, 'model', None),
        )
    finally:
        progress.close()
    if args.json:
        print(json.dumps(study.to_json()))
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    _print_table(study)
    # Error bars: standard error of the mean over the seeds that calibrated.
    curves = {
        name: (
            study.mean(name) * UM,
            study.spread(name)
            * UM
            / np.sqrt(np.maximum(len(study.seeds) - study.failed(name), 1)),
        )
        for name in study.position_error_m
    }
    path = figures.planning_accuracy(
        study.ks,
        curves,
        study.reference_m() * UM,
        f'{REFERENCE_RANDOM_POSTURES} random postures',
        Path(args.out) / 'plan_accuracy_vs_postures.png',
    )
    print(f'\nfigure written to {path}')
    return 0


def _print_table(study: PlanningStudy) -> None:
    names = list(study.position_error_m)
    from ..core.architectures import architecture

    arch = architecture(study.model)
    print(
        f'Planned vs random postures, {arch.layout.title}: mean validation '
        f'position error [um] over {len(study.seeds)} seeds (mean +- std; failed calibrations in '
        f'brackets), +-{study.noise_um:g} {arch.actuator_quantities.small} noise, cost '
        f'{study.cost}, index {study.index}, '
        f'{study.method}:'
    )
    print(f'  {"K":>3} ' + ' '.join(f'{name:>26}' for name in names))
    for row, k in enumerate(study.ks):
        cells = []
        for name in names:
            mean, spread, failed = (
                study.mean(name)[row],
                study.spread(name)[row],
                study.failed(name)[row],
            )
            text = f'{mean * UM:.1f} +- {spread * UM:.1f}' if np.isfinite(mean) else 'failed'
            cells.append(f'{text + (f" [{failed}]" if failed else ""):>26}')
        print(f'  {k:>3} ' + ' '.join(cells))
    for name in names[1:]:
        claim = study.claim(name)
        verdict = 'holds' if claim['holds'] else 'does NOT hold'
        reached = (
            f'reached at K = {claim["smallest_k"]}'
            if claim['smallest_k'] is not None
            else 'not reached at any K tried'
        )
        print(
            f'  claim ({name}): {REFERENCE_RANDOM_POSTURES} random postures give '
            f'{claim["reference_position_mean_m"] * UM:.1f} um; {reached} -> K <= '
            f'{claim["limit_k"]} {verdict}'
        )
