"""
``hexacal study --plan``: accuracy versus number of postures.

Accuracy versus number of postures, planned against random, over seeds.

For each seed the machine, its nominal model, the noise and the 50 validation
postures are those of ``studies.accuracy`` (``StudyRun``, on the default machine of
the model studied: ``hexacal study --plan --model gough_stewart`` runs the
default Gough-Stewart platform); random postures go through
``run_calibration`` unchanged.  Planned postures are chosen at the nominal model
(the planner never sees the true machine) within the study's workspace and device,
measured on the true machine with the same noise, identified with the same solver
and validated on the same postures.

Claim checked: planned postures reach the mean validation position error of
50 random postures with at most half as many (K <= 25).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from hexacal_msgs_py.models import DEFAULT_MODEL
import numpy as np

from .accuracy import run_calibration, study_truth, StudyOutcome, StudyRun
from ..core.errors import CalibrationError
from ..core.fit.identification import identify, SolverOptions
from ..core.fit.validation import pose_errors, validation_poses
from ..core.machine.measurements import NoiseModel, simulate_measurements
from ..core.planning.observability import PREDICTION
from ..core.planning.planner import plan_postures
from ..core.planning.posture_limits import PostureLimits
from ..core.planning.selection import exchange_design

DEFAULT_KS = (15, 20, 25, 30, 40, 50)
REFERENCE_RANDOM_POSTURES = 50
RANDOM = 'random'
UM = 1e6


@dataclass
class PlanningStudy:
    ks: list[int]
    seeds: list[int]
    noise_um: float
    cost: str
    index: str
    method: str
    model: str = DEFAULT_MODEL
    # variant -> (len(ks), len(seeds)) mean validation position error, m; NaN where the calibration
    # failed
    position_error_m: dict[str, np.ndarray] = field(default_factory=dict)
    orientation_error_rad: dict[str, np.ndarray] = field(default_factory=dict)
    failures: dict[str, list[str]] = field(default_factory=dict)

    def mean(self, variant: str) -> np.ndarray:
        with np.errstate(all='ignore'):
            return np.array(
                [
                    np.nanmean(row) if np.any(np.isfinite(row)) else np.nan
                    for row in self.position_error_m[variant]
                ]
            )

    def spread(self, variant: str) -> np.ndarray:
        return np.array(
            [
                np.nanstd(row, ddof=1) if np.sum(np.isfinite(row)) > 1 else 0.0
                for row in self.position_error_m[variant]
            ]
        )

    def failed(self, variant: str) -> np.ndarray:
        return np.sum(~np.isfinite(self.position_error_m[variant]), axis=1)

    def reference_m(self) -> float:
        """Mean validation error of 50 random postures."""
        return float(self.mean(RANDOM)[self.ks.index(REFERENCE_RANDOM_POSTURES)])

    def smallest_k_reaching(self, variant: str) -> int | None:
        # A K where some seed failed does not count: the claim is about dependable calibrations.
        reached = [
            k
            for k, mean, failed in zip(self.ks, self.mean(variant), self.failed(variant))
            if failed == 0 and mean <= self.reference_m()
        ]
        return min(reached) if reached else None

    def claim(self, variant: str) -> dict:
        k = self.smallest_k_reaching(variant)
        limit = REFERENCE_RANDOM_POSTURES // 2
        return {
            'variant': variant,
            'reference_random_postures': REFERENCE_RANDOM_POSTURES,
            'reference_position_mean_m': self.reference_m(),
            'smallest_k': k,
            'holds': k is not None and k <= limit,
            'limit_k': limit,
        }

    def to_json(self) -> dict:
        variants = {}
        for name in self.position_error_m:
            variants[name] = {
                'position_mean_m': _nan_to_none(self.mean(name)),
                'position_spread_m': _nan_to_none(self.spread(name)),
                'failed_seeds': self.failed(name).tolist(),
                'per_seed_position_mean_m': [
                    _nan_to_none(row) for row in self.position_error_m[name]
                ],
                'failures': self.failures.get(name, []),
            }
        return {
            'model': self.model,
            'ks': self.ks,
            'seeds': self.seeds,
            'noise_um': self.noise_um,
            'cost': self.cost,
            'index': self.index,
            'method': self.method,
            'variants': variants,
            'claims': {name: self.claim(name) for name in variants if name != RANDOM},
        }


def _nan_to_none(values) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(values, dtype=float)]


def calibrate_at(run: StudyRun, poses: np.ndarray, kinds: np.ndarray) -> StudyOutcome:
    """
    Run ``run_calibration`` with given postures instead of random ones.

    ``run_calibration`` with given postures instead of random ones (same noise model, solver,
    validation).
    """
    rng = np.random.default_rng([run.seed, len(poses), 0x9EA5])
    measurements = simulate_measurements(
        run.true_params, poses, kinds, run.device, NoiseModel.from_microns(run.noise_um), rng
    )
    result = identify(run.nominal(), measurements, SolverOptions(cost=run.cost, device=run.device))
    validation = validation_poses(
        run.true_params, run.validation_postures, run.seed, run.resolved_workspace
    )
    before = pose_errors(run.true_params, run.nominal(), validation)
    after = pose_errors(run.true_params, result.parameters, validation)
    return StudyOutcome(run, result, before, after)


def planned_variants(
    index: str, cost: str, noise_um: float
) -> dict[str, tuple[str, NoiseModel | None]]:
    """
    Return name -> (index, noise weighting) of the planned variants.

    The index asked for, weighted and not, and the I-optimal plan.
    """
    noise = NoiseModel.from_microns(
        noise_um if noise_um > 0 else 1.0
    )  # only the actuator/angle ratio matters
    if cost == 'relative':  # no noise weighting for the relative cost
        return {
            f'planned-{name}-unweighted': (name, None)
            for name in dict.fromkeys([index, PREDICTION])
        }
    variants: dict[str, tuple[str, NoiseModel | None]] = {f'planned-{index}': (index, noise)}
    if index != PREDICTION:
        variants[f'planned-{PREDICTION}'] = (PREDICTION, noise)
    variants[f'planned-{index}-unweighted'] = (index, None)
    return variants


def planned_vs_random(
    ks=DEFAULT_KS,
    seeds=range(10),
    noise_um: float = 10.0,
    cost: str = 'absolute',
    nominal_set_number: int = 2,
    index: str = 'O1',
    method: str = 'greedy',
    candidates: int = 2000,
    progress: Callable[[str], None] = lambda _: None,
    model: str | None = None,
    true_params=None,
) -> PlanningStudy:
    """
    Return the validation error vs K for random and planned postures.

    Validation error vs K for random postures and the planned variants (``planned_variants``).

    The machine: ``true_params``, else the default machine of ``model`` (default: the Table 1 Hexa
    Slide).
    """
    truth = study_truth(true_params, model)
    ks = sorted({int(k) for k in ks} | {REFERENCE_RANDOM_POSTURES})
    seeds = [int(s) for s in seeds]
    study = PlanningStudy(ks, seeds, noise_um, cost, index, method, truth.model)
    weighting = planned_variants(index, cost, noise_um)
    variants = [RANDOM, *weighting]
    for name in variants:
        study.position_error_m[name] = np.full((len(ks), len(seeds)), np.nan)
        study.orientation_error_rad[name] = np.full((len(ks), len(seeds)), np.nan)
        study.failures[name] = []
    for column, seed in enumerate(seeds):
        base = StudyRun(
            true_params=truth,
            nominal_set_number=nominal_set_number,
            noise_um=noise_um,
            seed=seed,
            cost=cost,
        )
        # Candidates where the study draws its random postures: its workspace, on its device.
        limits = PostureLimits.from_workspace(base.resolved_workspace, mount=base.device.mount)
        for name, (variant_index, noise) in weighting.items():
            progress(f'seed {seed}: planning {name}')
            planning = plan_postures(
                base.nominal(),
                max(ks),
                index=variant_index,
                method='greedy',
                n_candidates=candidates,
                cost=cost,
                limits=limits,
                seed=seed,
                noise=noise,
            )
            for row, k in enumerate(ks):
                # Greedy is prefix-consistent: its first K picks are its K-posture plan.
                design = planning.selection_order[:k]
                if method == 'exchange':
                    design, _ = exchange_design(planning.candidates, design, variant_index)
                run = StudyRun(
                    true_params=truth,
                    nominal_set_number=nominal_set_number,
                    noise_um=noise_um,
                    seed=seed,
                    cost=cost,
                    postures=k,
                )
                _record(
                    study,
                    name,
                    row,
                    column,
                    k,
                    seed,
                    progress,
                    lambda: calibrate_at(
                        run, planning.candidates.poses[design], planning.candidates.kinds[design]
                    ),
                )
        for row, k in enumerate(ks):
            run = StudyRun(
                true_params=truth,
                nominal_set_number=nominal_set_number,
                noise_um=noise_um,
                seed=seed,
                cost=cost,
                postures=k,
            )
            _record(study, RANDOM, row, column, k, seed, progress, lambda: run_calibration(run))
    return study


def _record(
    study: PlanningStudy, name: str, row: int, column: int, k: int, seed: int, progress, calibrate
) -> None:
    progress(f'seed {seed}: {name} K={k}')
    try:
        outcome = calibrate()
    except CalibrationError as error:  # counted and reported: a failed calibration is a finding
        study.failures[name].append(
            f'K={k} seed {seed}: {getattr(error, "reason", "error")}: {error}'
        )
        return
    after = outcome.after.summary()
    study.position_error_m[name][row, column] = after['position_mean_m']
    study.orientation_error_rad[name][row, column] = after['orientation_mean_rad']
