"""
An imperfect device at no cost.

Prior knowledge, a turning procedure, and the joint estimator's limit.

Why the defects hurt.  Over the sphere postures a 54-parameter machine can
imitate any smooth, nearly affine distortion of its workspace, and that is what
most device defects are to first order: dL moves every measured point by
dL * u (a shift along Z plus a lateral scale of dL / L), gamma shears the
lateral positions, alpha0 turns them about X (seen only at second order) and
beta0 about Y (not at all: a base-frame definition).  Identified jointly from
one mounting, they are therefore weakly determined, and the machine absorbs the
rest.  Two remedies are modelled:

* Prior knowledge (``core.device.DevicePrior``): a caliper measurement of the
  link (+-10 um), a certificate of the inclinometer.  The study's caliper reads
  the true length with its own Gaussian error of the stated std.
* Turning the device about its link axis between walks of the plan
  (``PROCEDURES``, ``core.device`` "Turning the device"): the device's errors
  turn with it, the machine's do not.  A half turn (``reversal``) changes the
  sign of alpha0 and beta0 against the geometry: both become identifiable, so
  the base frame is the true (gravity) frame.  Quarter turns (``quarter-turns``,
  0, 90, 180, 270 deg) also move the skew gamma to the other axis.  phi0 stays a
  platform-frame definition: a rotation about the platform's z' axis through its
  origin, it moves no position, only the orientation's zero.  dL's shift along
  Z is a shift of the base frame's origin O that no turn reveals: only the
  lateral-scale part of dL is seen in the data, so a length reference (the
  caliper) is what pins the origin.

Frames of the figures.  "Device frames": the base frame the device defines
(turned by -beta0 about Y when beta0 is not identified) and the platform frame
of its rotary zero (``device.device_frame_truth``), the frames the controller
works in after a calibration that does not identify beta0.  "True frames": the
gravity-aligned base frame with its origin at O and the platform's own frame;
positions of the platform origin do not depend on the platform frame, so the
true-frame position error includes every beta0 and phi0 effect there is.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from .device import DEFAULT_DEFECTS, device_frame_poses, device_frame_truth, simulate_procedure
from ..core.architectures import default_parameters, KinematicParameters
from ..core.errors import CalibrationError
from ..core.fit.identification import identify, SolverOptions
from ..core.fit.uncertainty import predicted_pose_errors
from ..core.fit.validation import pose_errors, validation_poses
from ..core.machine.device import (
    DEVICE_PARAMETER_NAMES,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
    TURNING_PROCEDURES,
)
from ..core.machine.device import procedure_turns as turns_of
from ..core.machine.measurements import Measurements, NoiseModel, simulate_measurements
from ..core.machine.model import nominal_set

PROCEDURES = TURNING_PROCEDURES  # device turns of each procedure, rad (core.device)
RECOMMENDED_PROCEDURE = 'quarter-turns'
ALL_BUT_PHI0 = ('dL', 'alpha0', 'beta0', 'gamma')
CALIPER_STD_M = 10e-6
CLAIM_RATIO = 1.5
CLAIM_EFFICIENCY = 0.9
PLAN_CANDIDATES = 1000  # candidate postures of a planned row, each offered in every mounting


def procedure_turns(procedure: str, postures: int) -> np.ndarray | None:
    """
    Return the device turn of each of ``postures`` postures (rad).

    Consecutive blocks per turn; None for 'none'.
    """
    turns = turns_of(procedure)
    if len(turns) == 1:
        return None
    blocks = np.array_split(np.arange(postures), len(turns))
    out = np.zeros(postures)
    for turn, block in zip(turns, blocks):
        out[block] = turn
    return out


def simulate_device_run(
    true_params: KinematicParameters,
    defects: DeviceDefects,
    postures: int,
    noise_um: float,
    seed: int,
    procedure: str = 'none',
    fixed: int = 0,
    device: DeviceModel = DeviceModel(),
) -> Measurements:
    """
    Simulate ``postures`` postures of a turning procedure.

    ``fixed`` fixed-position ones (normal mounting), the others sphere postures shared out over the
    ``procedure``'s turns (``device.simulate_procedure``: the true sphere L + dL, distinct poses).
    """
    sphere = postures - fixed
    return simulate_procedure(
        true_params,
        defects,
        sphere,
        fixed,
        noise_um,
        seed,
        device=device,
        device_turn=procedure_turns(procedure, sphere),
    )


def plan_for(
    nominal: KinematicParameters,
    postures: int,
    noise_um: float,
    seed: int,
    identify_device=(),
    procedure: str = 'none',
    device_prior: DevicePrior = DevicePrior(),
    candidates: int = PLAN_CANDIDATES,
):
    """
    Return the planner's choice on the nominal machine.

    I-optimal with the device columns, priors and turns.
    """
    from ..core.planning.planner import plan_postures, PREDICTION

    return plan_postures(
        nominal,
        postures,
        index=PREDICTION,
        n_candidates=candidates,
        seed=seed,
        noise=NoiseModel.from_microns(noise_um) if noise_um > 0 else None,
        device_columns=tuple(identify_device),
        device_prior=device_prior,
        device_turns=turns_of(procedure),
    ).plan


def simulate_planned_run(
    true_params: KinematicParameters,
    nominal: KinematicParameters,
    defects: DeviceDefects,
    postures: int,
    noise_um: float,
    seed: int,
    row: 'DeviceRow',
    prior: DevicePrior,
    device: DeviceModel = DeviceModel(),
) -> Measurements:
    """
    Simulate the planned postures on the true machine.

    The link of true length L + dL puts each planned position on its own sphere (radially scaled),
    the device turned as the plan says.
    """
    # The planner knows the prior's std but not the instrument's reading: plan with the nominal
    # value.
    planning_prior = DevicePrior(tuple((name, 0.0, std) for name, _, std in prior.entries))
    plan = plan_for(nominal, postures, noise_um, seed, row.identify, row.procedure, planning_prior)
    poses = plan.poses.copy()
    poses[:, :3] *= (device.link_length + defects.dL) / device.link_length
    rng = np.random.default_rng([seed, 0x91A5])
    return simulate_measurements(
        true_params,
        poses,
        plan.kinds,
        device,
        NoiseModel.from_microns(noise_um),
        rng,
        defects,
        device_turn=plan.device_turns,
    )


def caliper_prior(
    defects: DeviceDefects, caliper: tuple[tuple[str, float], ...], seed: int
) -> DevicePrior:
    """
    Return priors as a user would have them.

    Each instrument reads the true value with its own N(0, std) error.
    """
    rng = np.random.default_rng([seed, 0xCA1])
    return DevicePrior(
        tuple((name, getattr(defects, name) + rng.normal(0.0, std), std) for name, std in caliper)
    )


@dataclass(frozen=True)
class DeviceRow:
    """One way of calibrating with the defective device."""

    label: str
    identify: tuple[str, ...] = ()
    procedure: str = 'none'
    caliper: tuple[tuple[str, float], ...] = ()  # (name, std) of each prior measurement
    cost: str = 'absolute'
    fixed: int = 0  # fixed-position postures among the total (the relative cost needs them)
    weighted: bool = (
        True  # residuals whitened by the known noise (the paper's relative cost: unweighted)
    )
    # postures (and their turns) chosen by the planner (I-optimal, device columns) per seed
    planned: bool = False
    defective: bool = True
    claim: str = ''  # "prior" or "procedure": the claim this row is judged on


ROWS = (
    DeviceRow('ideal device, eq. 7 (reference)', defective=False),
    DeviceRow('defects ignored, eq. 7'),
    DeviceRow(
        "paper's remedy: relative cost, eqs. 12 + 13", cost='relative', fixed=12, weighted=False
    ),
    DeviceRow('joint: dL, alpha0, gamma', ('dL', 'alpha0', 'gamma')),
    DeviceRow(
        'caliper prior on L (+-10 um) + alpha0, gamma',
        ('alpha0', 'gamma'),
        caliper=(('dL', CALIPER_STD_M),),
    ),
    DeviceRow('reversal (0/180 deg): dL, alpha0, beta0, gamma', ALL_BUT_PHI0, 'reversal'),
    DeviceRow(
        'quarter turns (0/90/180/270): dL, alpha0, beta0, gamma', ALL_BUT_PHI0, 'quarter-turns'
    ),
    DeviceRow(
        'quarter turns + caliper prior on L',
        ('alpha0', 'beta0', 'gamma'),
        'quarter-turns',
        caliper=(('dL', CALIPER_STD_M),),
    ),
    DeviceRow('ideal device, planned postures (I-optimal)', defective=False, planned=True),
    DeviceRow(
        'caliper prior + alpha0, gamma, planned',
        ('alpha0', 'gamma'),
        caliper=(('dL', CALIPER_STD_M),),
        planned=True,
        claim='prior',
    ),
    DeviceRow(
        'quarter turns, planned: dL, alpha0, beta0, gamma',
        ALL_BUT_PHI0,
        'quarter-turns',
        planned=True,
        claim='procedure',
    ),
    DeviceRow(
        'quarter turns + caliper prior, planned',
        ('alpha0', 'beta0', 'gamma'),
        'quarter-turns',
        caliper=(('dL', CALIPER_STD_M),),
        planned=True,
    ),
)


@dataclass
class RowOutcome:
    row: DeviceRow
    device_frame_position_m: list[float] = field(default_factory=list)
    true_frame_position_m: list[float] = field(default_factory=list)
    true_frame_orientation_rad: list[float] = field(default_factory=list)
    origin_aligned_position_m: list[float] = field(
        default_factory=list
    )  # true frames, origin re-referenced
    device_errors: list[np.ndarray] = field(default_factory=list)  # identified - true, per seed
    failures: list[str] = field(default_factory=list)

    @staticmethod
    def mean(values: list[float]) -> float:
        return float(np.mean(values)) if values else float('nan')

    def device_rmse(self) -> np.ndarray:
        return (
            np.sqrt(np.mean(np.square(self.device_errors), axis=0))
            if self.device_errors
            else np.full(len(DEVICE_PARAMETER_NAMES), np.nan)
        )


def run_row(
    row: DeviceRow,
    true_params: KinematicParameters,
    defects: DeviceDefects,
    seeds,
    postures: int = 50,
    noise_um: float = 10.0,
    progress: Callable[[str], None] = lambda _: None,
) -> RowOutcome:
    """
    Run ``row`` over ``seeds``.

    Weighted by the known noise, validated on 50 fresh postures in both frames.
    """
    used = defects if row.defective else DeviceDefects()
    outcome = RowOutcome(row)
    noise = NoiseModel.from_microns(noise_um)
    for seed in seeds:
        progress(f'{row.label}, seed {seed}')
        nominal = nominal_set(2, seed=seed, exact=true_params)
        prior = caliper_prior(used, row.caliper, seed)
        if row.planned:
            measurements = simulate_planned_run(
                true_params, nominal, used, postures, noise_um, seed, row, prior
            )
        else:
            measurements = simulate_device_run(
                true_params, used, postures, noise_um, seed, row.procedure, row.fixed
            )
        options = SolverOptions(
            cost=row.cost,
            free_device=row.identify,
            noise=noise if row.weighted else None,
            device_prior=prior,
            allow_rank_deficient=row.cost == 'relative',
        )
        try:
            result = identify(nominal, measurements, options)
        except CalibrationError as error:
            outcome.failures.append(f'seed {seed}: {error.reason}')
            continue
        poses = validation_poses(true_params, 50, seed)
        in_device = pose_errors(
            device_frame_truth(true_params, used),
            result.parameters,
            device_frame_poses(poses, used),
        ).summary()
        in_truth = pose_errors(true_params, result.parameters, poses).summary()
        outcome.device_frame_position_m.append(in_device['position_mean_m'])
        outcome.true_frame_position_m.append(in_truth['position_mean_m'])
        outcome.true_frame_orientation_rad.append(in_truth['orientation_mean_rad'])
        outcome.origin_aligned_position_m.append(
            pose_errors(true_params, result.parameters, poses, align_origin=True).summary()[
                'position_mean_m'
            ]
        )
        outcome.device_errors.append(result.device.vector - used.vector)
    return outcome


@dataclass
class Claim:
    """
    One of the issue's claims on a row.

    Its error / the defect-free one of the same seeds (random postures, the baseline the issue
    measured), and / an ideal device calibrated the same way (its own plan).
    """

    text: str
    value: float  # / the ideal device with random postures
    like_for_like: float  # / the ideal device with the row's posture choice (planned or random)
    target: float = CLAIM_RATIO

    @property
    def met(self) -> bool:
        return bool(self.value <= self.target)

    @property
    def met_like_for_like(self) -> bool:
        return bool(self.like_for_like <= self.target)


def claims(outcomes: list[RowOutcome]) -> list[Claim]:
    """
    Return the issue's claims on the table.

    Caliper prior within 1.5x (device frames), procedure within 1.5x (true frames).
    """
    references = {
        o.row.planned: o.mean(o.true_frame_position_m) for o in outcomes if not o.row.defective
    }
    random_reference = references[False]
    found = []
    for outcome in outcomes:
        own = references.get(outcome.row.planned, random_reference)
        if outcome.row.claim == 'prior':
            error = outcome.mean(outcome.device_frame_position_m)
            text = (
                f'{outcome.row.label}, no procedure: position within {CLAIM_RATIO}x the '
                'defect-free one (device frames: without a procedure beta0 is a frame definition)'
            )
        elif outcome.row.claim == 'procedure':
            error = outcome.mean(outcome.true_frame_position_m)
            text = (
                f'{outcome.row.label}, no prior: position within {CLAIM_RATIO}x the defect-free '
                'one (true frames, every beta0 and phi0 effect included)'
            )
        else:
            continue
        found.append(Claim(text, error / random_reference, error / own))
    return found


def device_table(
    defects: DeviceDefects = DEFAULT_DEFECTS,
    seeds=range(10),
    postures: int = 50,
    noise_um: float = 10.0,
    true_params: KinematicParameters | None = None,
    progress: Callable[[str], None] = lambda _: None,
    rows=ROWS,
) -> list[RowOutcome]:
    """Every row of ``rows`` on the same machine, noise and seeds."""
    true_params = true_params if true_params is not None else default_parameters()
    return [
        run_row(row, true_params, defects, seeds, postures, noise_um, progress) for row in rows
    ]


@dataclass
class EfficiencySummary:
    """
    Monte Carlo of the joint estimator against its Cramer-Rao bound.

    Monte Carlo of the joint estimator against its Cramer-Rao bound (same postures, noise seeds
    vary).
    """

    seeds: int
    procedure: str
    identified: tuple[str, ...]
    crb_std: np.ndarray  # (len(identified),) device parameters
    rmse: np.ndarray  # (len(identified),)
    bias: np.ndarray  # (len(identified),)
    predicted_position_ms_m2: float  # mean squared validation position error the CRB predicts
    position_ms_m2: float  # ... and the Monte Carlo's
    failures: int = 0

    @property
    def efficiency(self) -> np.ndarray:
        """CRB variance / mean squared error per identified device parameter (1: at the bound)."""
        return self.crb_std**2 / self.rmse**2

    @property
    def pose_efficiency(self) -> float:
        return self.predicted_position_ms_m2 / self.position_ms_m2


def estimator_efficiency(
    seeds: int = 100,
    procedure: str = RECOMMENDED_PROCEDURE,
    identified: tuple[str, ...] = ALL_BUT_PHI0,
    defects: DeviceDefects = DEFAULT_DEFECTS,
    postures: int = 50,
    noise_um: float = 10.0,
    true_params: KinematicParameters | None = None,
    progress: Callable[[str], None] = lambda _: None,
) -> EfficiencySummary:
    """
    Repeat the joint problem over noise seeds.

    The joint problem (``procedure``, ``identified`` device parameters) repeated over noise seeds.

    The estimator's target is the true machine in the frames it calibrates in (the
    device's where beta0 or phi0 is not identified); the CRB is the covariance of the
    weighted solve on exact readings at that target, device parameters included.
    """
    true_params = true_params if true_params is not None else default_parameters()
    frames = DeviceDefects(
        beta0=0.0 if 'beta0' in identified else defects.beta0,
        phi0=0.0 if 'phi0' in identified else defects.phi0,
    )
    target = device_frame_truth(true_params, frames)
    exact = simulate_device_run(true_params, defects, postures, 0.0, 0, procedure)
    noise = NoiseModel.from_microns(noise_um)
    held = replace(
        defects,
        phi0=defects.phi0 if 'phi0' in identified else 0.0,
        beta0=defects.beta0 if 'beta0' in identified else 0.0,
    )
    index = [DEVICE_PARAMETER_NAMES.index(name) for name in identified]
    crb = identify(
        target, exact, SolverOptions(free_device=identified, noise=noise, device_defects=held)
    )
    crb_std = np.sqrt(np.diag(crb.covariance)[target.layout.n_parameters:][index])
    validation = device_frame_poses(validation_poses(true_params, 50, 0), frames)
    predicted = predicted_pose_errors(target, crb.covariance, validation)
    predicted_ms = float(np.mean(np.sum(predicted.position_std_m**2, axis=1)))
    rng_poses = simulate_device_run(
        true_params, defects, postures, 0.0, 0, procedure
    )  # the same postures
    errors, squared, failures = [], [], 0
    for seed in range(seeds):
        progress(f'efficiency, noise seed {seed + 1}/{seeds}')
        measurements = _with_noise(rng_poses, noise, seed)
        options = SolverOptions(free_device=identified, noise=noise)
        try:
            result = identify(nominal_set(2, seed=0, exact=target), measurements, options)
        except CalibrationError:
            failures += 1
            continue
        errors.append(result.device.vector[index] - defects.vector[index])
        sliders_truth = pose_errors(target, result.parameters, validation)
        squared.append(float(np.nanmean(sliders_truth.position_m**2)))
    error_array = np.array(errors)
    return EfficiencySummary(
        seeds,
        procedure,
        identified,
        crb_std,
        np.sqrt(np.mean(error_array**2, axis=0)),
        error_array.mean(axis=0),
        predicted_ms,
        float(np.mean(squared)),
        failures,
    )


def _with_noise(exact: Measurements, noise: NoiseModel, seed: int) -> Measurements:
    """
    Return ``exact`` readings with fresh uniform noise of ``noise``.

    ``exact`` readings with fresh uniform noise of ``noise`` (the same postures, another noise
    draw).
    """
    rng = np.random.default_rng([seed, 0xEFF])
    n = len(exact)
    actuators = exact.actuator_positions + rng.uniform(-noise.actuator_m, noise.actuator_m, (n, 6))
    angles = exact.inclinometer + rng.uniform(-noise.angle_rad, noise.angle_rad, (n, 2))
    rotary = exact.rotary + rng.uniform(-noise.angle_rad, noise.angle_rad, n)
    return Measurements(
        actuators, angles, rotary, exact.kinds, exact.link_lengths, exact.device_turn
    )


__all__ = [
    'PROCEDURES',
    'RECOMMENDED_PROCEDURE',
    'ROWS',
    'Claim',
    'DeviceRow',
    'EfficiencySummary',
    'RowOutcome',
    'caliper_prior',
    'claims',
    'device_table',
    'estimator_efficiency',
    'procedure_turns',
    'simulate_device_run',
]
