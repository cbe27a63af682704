"""
The accuracy of each measuring mode (``hexacal study --measuring-mode M``).

Each mode's procedure is simulated on the TRUE machine with targets computed by a model, the
NOMINAL one at first (as the executor does), then calibrated with the core and judged against
the truth on fresh validation poses:

* ``passive_actuator``: per posture the released actuator chosen on the nominal plan
  (core/modes/released_actuator.py); the five others stand exactly at their setpoints; the platform
  and the released actuator are where the link puts them (core/modes/passive_actuator.py,
  ``solve_passive`` on the true machine); the released encoder reads where it went.
* ``lvdt``: the six stand at their setpoints; the platform is the true forward kinematics of
  the six; the link length L_m = |P| is read with the LVDT's noise and used per posture in
  eq. 4 (``Measurements.link_lengths``); its extension |P| - L is checked against the stroke.
* ``compliant``: the six commanded against the rigid link; equally stiff servos put the
  platform on the true sphere (core/modes/compliant.py, the simulated driver's model); the encoders
  read where the actuators stand; the force is the servo stiffness times the deviation.

A posture the procedure cannot measure on the true machine is skipped and counted
(``failed_postures``), as an executor would have to: in ``passive_actuator`` the five nominal
setpoints and the link may have no assembly near the planned pose (a fold of the passive system
the nominal model does not see), in ``lvdt`` the forward kinematics may fail.  The readings
carry the study's uniform noise.  With refinement (core/walk_refine/refinement.py) the
remaining targets come from an intermediate calibration once the postures measured so far give
one of full rank; the deviations before (nominal targets) and after (refined targets) are
reported apart.  SI units throughout (um only for display, by the CLI).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from typing import Callable

from hexacal_msgs_py.measuring_modes import (
    DEFAULT_LVDT_STROKE_M,
    measuring_mode,
    MeasuringMode,
)
import numpy as np

from ..core.architectures import default_parameters, KinematicParameters
from ..core.assessment.validation import pose_errors, PoseErrors, validation_poses
from ..core.errors import CalibrationError
from ..core.fit.identification import IdentificationResult, identify, SolverOptions
from ..core.machine.device import DeviceModel
from ..core.machine.kinematics import forward_kinematics, inverse_kinematics
from ..core.machine.measurements import Measurements, NoiseModel, simulate_measurements, SPHERE
from ..core.machine.model import nominal_set
from ..core.machine.postures import sample_poses, Workspace
from ..core.modes.compliant import device_constrained_pose
from ..core.modes.passive_actuator import solve_passive
from ..core.modes.released_actuator import choose_released_actuators
from ..core.walk_refine.refinement import (
    full_rank_postures,
    RefinedWalk,
    refinement_checkpoints,
    walk_refined,
)

DEFAULT_SERVO_STIFFNESS_N_PER_M = 2e6  # a stiff position loop: 1 mm of strain is 2 kN
DEFAULT_LVDT_NOISE_M = 1e-6  # uniform half-width of the LVDT's reading


@dataclass(frozen=True)
class ModeStudyRun:
    """One simulated measuring campaign in one mode, then its calibration (module doc)."""

    mode: str = MeasuringMode.PASSIVE_ACTUATOR.value
    true_params: KinematicParameters = field(default_factory=default_parameters)
    nominal_params: KinematicParameters | None = None  # None: nominal set ``nominal_set_number``
    nominal_set_number: int = 2
    postures: int = 50
    noise_um: float = 10.0
    lvdt_noise_m: float = DEFAULT_LVDT_NOISE_M
    lvdt_stroke_m: float = DEFAULT_LVDT_STROKE_M
    servo_stiffness_n_per_m: float = DEFAULT_SERVO_STIFFNESS_N_PER_M
    seed: int = 0
    cost: str = 'absolute'
    validation_postures: int = 50
    refine: bool = True
    first_calibration: int | None = None  # postures before the first re-calibration; None: auto
    device: DeviceModel = DeviceModel()

    def __post_init__(self) -> None:
        measuring_mode(self.mode)  # ValueError naming the modes
        if self.postures < 1:
            raise ValueError(f'postures must be positive, got {self.postures}')
        if self.first_calibration is not None and self.first_calibration < 1:
            raise ValueError(
                f'the first calibration needs at least 1 posture, got {self.first_calibration}'
            )
        if not (math.isfinite(self.lvdt_stroke_m) and self.lvdt_stroke_m > 0):
            raise ValueError(f'the LVDT stroke must be positive, got {self.lvdt_stroke_m} m')
        if not (math.isfinite(self.servo_stiffness_n_per_m) and self.servo_stiffness_n_per_m > 0):
            raise ValueError(
                f'the servo stiffness must be positive, got {self.servo_stiffness_n_per_m} N/m'
            )

    def nominal(self) -> KinematicParameters:
        """Return the starting model: ``nominal_params``, else the Table 2 set of the seed."""
        if self.nominal_params is not None:
            return self.nominal_params
        return nominal_set(self.nominal_set_number, seed=self.seed, exact=self.true_params)

    @property
    def workspace(self) -> Workspace:
        """Return the architecture's workspace on the device's link sphere."""
        base = self.true_params.architecture.default_workspace()
        return replace(base, link_length=self.device.link_length, mount=self.device.mount)

    def checkpoints(self) -> tuple[int, ...]:
        """Return the posture counts after which the walk re-calibrates (none without refine)."""
        if not self.refine:
            return ()
        first = self.first_calibration
        if first is None:
            first = full_rank_postures(self.true_params.layout.n_parameters)
        return refinement_checkpoints(self.postures, first)


@dataclass
class ModeBatch:
    """
    What the machine did and read at a batch of postures (k of them).

    ``deviation_m`` the largest |true position - setpoint| of a commanded actuator at rest;
    ``extension_m`` the LVDT link's |P| - L (lvdt, else None); ``released_offset_m`` the
    released actuator's |reading - the model's prediction| (passive_actuator, else None);
    ``true_poses`` where the platform stood (NaN rows where the procedure failed: no pose
    closes the five commanded legs and the link, or no forward kinematics); ``measured`` (k,)
    the postures measured (``measurements`` and ``exact`` hold those rows only; the per-posture
    figures are NaN elsewhere); ``exact`` the noise-free readings; ``released``
    the released chain per posture (passive_actuator, else None).
    """

    measurements: Measurements
    exact: Measurements
    true_poses: np.ndarray
    setpoints: np.ndarray
    measured: np.ndarray
    deviation_m: np.ndarray
    extension_m: np.ndarray | None = None
    released_offset_m: np.ndarray | None = None
    released: np.ndarray | None = None  # (k,) the released chain, 0-based (passive_actuator)


def _readings(
    run: ModeStudyRun, true_poses: np.ndarray, rng: np.random.Generator, lvdt: bool
) -> tuple[Measurements, Measurements]:
    """Return the (noisy, exact) readings at the true poses: encoders, inclinometer, rotary."""
    noise = NoiseModel.from_microns(run.noise_um)
    exact = simulate_measurements(run.true_params, true_poses, SPHERE, run.device)
    noisy = simulate_measurements(run.true_params, true_poses, SPHERE, run.device, noise, rng)
    if lvdt:
        length = np.linalg.norm(true_poses[:, :3], axis=1)
        exact.link_lengths = length.copy()
        noisy.link_lengths = length + rng.uniform(-run.lvdt_noise_m, run.lvdt_noise_m, len(length))
    return noisy, exact


def measuring_function(
    run: ModeStudyRun, planned: np.ndarray, released: np.ndarray | None, rng: np.random.Generator
) -> Callable[[np.ndarray, np.ndarray], ModeBatch]:
    """Return ``measure(indices, setpoints)``: the true machine in the run's mode (module doc)."""
    truth, length, mount = run.true_params, run.device.link_length, run.device.mount
    mode = measuring_mode(run.mode)

    def measure(indices: np.ndarray, setpoints: np.ndarray) -> ModeBatch:
        start = planned[indices]
        extension = offset = chosen = None
        if mode is MeasuringMode.PASSIVE_ACTUATOR:
            assert released is not None
            chosen = released[indices]
            solution = solve_passive(truth, setpoints, chosen, start, length, mount)
            poses, measured = solution.poses, solution.converged
            predicted = setpoints[np.arange(len(chosen)), chosen]
            offset = np.abs(solution.released_positions - predicted)
        elif mode is MeasuringMode.LVDT:
            solved = forward_kinematics(truth, setpoints, start)
            poses, measured = solved.poses, solved.converged
            extension = np.linalg.norm(poses[:, :3], axis=1) - length
        else:
            poses = np.array(
                [
                    device_constrained_pose(truth, target, near, length, mount)[0]
                    for target, near in zip(setpoints, start)
                ]
            )
            measured = np.ones(len(indices), bool)
        noisy, exact = _readings(run, poses[measured], rng, mode is MeasuringMode.LVDT)
        deviation = np.full(len(indices), np.nan)
        commanded = np.abs(exact.actuator_positions - setpoints[measured])
        if chosen is not None:
            commanded[np.arange(len(commanded)), chosen[measured]] = 0.0  # not commanded
        deviation[measured] = commanded.max(axis=1, initial=0.0)
        return ModeBatch(
            noisy, exact, poses, setpoints, measured, deviation, extension, offset, chosen
        )

    return measure


def calibrate(run: ModeStudyRun, measurements: Measurements) -> IdentificationResult:
    """Identify the machine from the nominal model and `measurements` (the usual calibration)."""
    options = SolverOptions(cost=run.cost, device=run.device)
    return identify(run.nominal(), measurements, options)


def _batches_measurements(batches: list[ModeBatch]) -> Measurements:
    return Measurements.concatenate([batch.measurements for batch in batches])


def _intermediate(run: ModeStudyRun, batches: list[ModeBatch]) -> KinematicParameters | None:
    """Return a full-rank calibration of the postures so far, or None (not yet identifiable)."""
    try:
        return calibrate(run, _batches_measurements(batches)).parameters
    except CalibrationError:  # not of full rank yet (or no convergence): keep the current model
        return None


@dataclass
class ModeOutcome:
    """One mode's campaign: the walk, the final calibration and its accuracy (SI units)."""

    run: ModeStudyRun
    walk: RefinedWalk
    result: IdentificationResult
    after: PoseErrors
    released_travel_m: float | None  # the released actuators' largest range along a move

    def _per_posture(self, name: str) -> np.ndarray | None:
        values = [getattr(batch, name) for batch in self.walk.batches]
        return None if values[0] is None else np.concatenate(values)

    def _largest(self, name: str, refined: bool | None = None) -> float | None:
        values = self._per_posture(name)
        if values is None:
            return None
        if refined is not None:
            values = values[self.walk.refined == refined]
        values = values[np.isfinite(values)]
        return float(np.max(np.abs(values))) if values.size else None

    @property
    def failed_postures(self) -> int:
        """Return how many postures the procedure could not measure (module doc)."""
        return int(sum(np.sum(~batch.measured) for batch in self.walk.batches))

    def figures(self, refined: bool | None = None) -> dict:
        """
        Return the largest deviation, extension, force and released offset, in SI.

        ``refined`` None: every posture; False: those on the starting model's targets; True:
        those on refined targets (None values where there are none).
        """
        mode = measuring_mode(self.run.mode)
        deviation = self._largest('deviation_m', refined)
        extension = self._largest('extension_m', refined)
        force = None
        if mode is MeasuringMode.COMPLIANT and deviation is not None:
            force = self.run.servo_stiffness_n_per_m * deviation
        return {
            'postures': int(np.sum(self.walk.refined == refined)) if refined is not None
            else len(self.walk.stages),
            'max_actuator_deviation_m': deviation,
            'max_link_extension_m': extension,
            'max_force_n': force,
            'max_released_offset_m': self._largest('released_offset_m', refined),
        }

    def _outside_stroke(self) -> int | None:
        """Return how many postures stretched the LVDT link beyond its stroke (lvdt, else None)."""
        extensions = self._per_posture('extension_m')
        if extensions is None:
            return None
        return int(np.sum(np.abs(extensions[np.isfinite(extensions)]) > self.run.lvdt_stroke_m))

    def to_json(self) -> dict:
        """Return the outcome as JSON-safe builtins, snake_case SI keys."""
        summary = self.after.summary()
        overall = self.figures()
        mode = measuring_mode(self.run.mode)
        extension = overall['max_link_extension_m']
        out = {
            'measuring_mode': mode.value,
            'postures': overall['postures'],
            **{key: value for key, value in overall.items() if key != 'postures'},
            'failed_postures': self.failed_postures,
            'released_travel_max_m': self.released_travel_m,
            'lvdt_stroke_m': self.run.lvdt_stroke_m if mode is MeasuringMode.LVDT else None,
            'lvdt_postures_outside_stroke': self._outside_stroke(),
            'lvdt_inside_stroke': (
                bool(extension is not None and abs(extension) <= self.run.lvdt_stroke_m)
                if mode is MeasuringMode.LVDT else None
            ),
            'servo_stiffness_n_per_m': (
                self.run.servo_stiffness_n_per_m if mode is MeasuringMode.COMPLIANT else None
            ),
            'pose_error_mean_m': summary['position_mean_m'],
            'pose_error_max_m': summary['position_max_m'],
            'orientation_error_mean_rad': summary['orientation_mean_rad'],
            'orientation_error_max_rad': summary['orientation_max_rad'],
            'rms_residual': self.result.rms_residual,
            'rank': self.result.rank,
            'reason': self.result.reason,
            'refine': self.run.refine,
            'calibrated_at': list(self.walk.calibrated_at),
            'before_refinement': self.figures(False),
            'after_refinement': self.figures(True),
            'noise_um': self.run.noise_um,
            'seed': self.run.seed,
            'validation_postures': self.run.validation_postures,
        }
        return out


def run_mode(run: ModeStudyRun) -> ModeOutcome:
    """Simulate `run`'s campaign (refined when asked), calibrate it, validate on fresh poses."""
    nominal = run.nominal()
    rng = np.random.default_rng([run.seed, 0x5EED])
    planned = sample_poses(nominal, run.postures, rng, SPHERE, run.workspace)
    released, travel = None, None
    if measuring_mode(run.mode) is MeasuringMode.PASSIVE_ACTUATOR:
        choice = choose_released_actuators(
            nominal,
            planned,
            run.device.link_length,
            run.workspace.actuator_stroke_m,
            mount=run.device.mount,
        )
        released, travel = choice.released, float(np.max(choice.released_travel))
    walk = walk_refined(
        run.postures,
        nominal,
        lambda model, indices: inverse_kinematics(model, planned[indices]),
        measuring_function(run, planned, released, rng),
        lambda batches: _intermediate(run, batches),
        run.checkpoints(),
    )
    result = calibrate(run, _batches_measurements(walk.batches))
    validation = validation_poses(
        run.true_params, run.validation_postures, run.seed, run.workspace
    )
    after = pose_errors(run.true_params, result.parameters, validation)
    return ModeOutcome(run, walk, result, after, travel)


def selected_modes(name: str) -> tuple[str, ...]:
    """Return the modes named by ``--measuring-mode`` (``all``: the three, compliant last)."""
    if name == 'all':
        return (
            MeasuringMode.PASSIVE_ACTUATOR.value,
            MeasuringMode.LVDT.value,
            MeasuringMode.COMPLIANT.value,
        )
    return (measuring_mode(name).value,)


__all__ = [
    'DEFAULT_LVDT_NOISE_M',
    'DEFAULT_SERVO_STIFFNESS_N_PER_M',
    'ModeBatch',
    'ModeOutcome',
    'ModeStudyRun',
    'calibrate',
    'measuring_function',
    'run_mode',
    'selected_modes',
]
