"""Parameter identification by Levenberg-Marquardt on forward-kinematics residuals (eqs. 5-13).

Each iteration solves forward kinematics for every posture (warm-started from
the previous solution), forms the residuals of the chosen cost function and the
identification Jacobian (eq. 6) analytically by implicit differentiation of
IK(X, u) = lambda, and takes a damped Gauss-Newton step ``du`` (eq. 5) in
column-scaled coordinates.  The SVD of the scaled Jacobian is reused for every
damping value tried in an iteration.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from .device import DeviceModel
from .errors import InvalidMeasurementError, RankDeficientError, TooFewPosturesError
from .identifiability import DEFAULT_RANK_TOLERANCE, IdentifiabilityReport, analyze, column_scales
from .kinematics import forward_kinematics, pose_parameter_sensitivity
from .measurements import MeasurementLimits, Measurements
from .model import N_PARAMETERS, HexaParameters, parameter_names
from .residuals import COSTS, ChannelSigma, CostFunction, ResidualBlock

CONVERGED = "converged"
ITERATION_LIMIT = "iteration-limit"
DIVERGED = "diverged"
FLOOR_STEP_M = 1e-9  # a Gauss-Newton step below this (m) is at the rounding floor of FK and residuals


@dataclass(frozen=True)
class SolverOptions:
    cost: str = "absolute"
    device: DeviceModel = DeviceModel()
    sigma: ChannelSigma = ChannelSigma()
    limits: MeasurementLimits = MeasurementLimits()
    free_parameters: tuple[bool, ...] | None = None  # mask over the 54; None = all
    max_iterations: int = 100
    step_tolerance: float = 1e-12  # converged when max |du| (m or unit-vector component) is below
    relative_cost_tolerance: float = 1e-9  # ... or an accepted step lowers the cost by less than this
    rank_tolerance: float = DEFAULT_RANK_TOLERANCE
    allow_rank_deficient: bool = False  # solve in the identifiable subspace instead of refusing
    fk_tolerance: float = 1e-12
    # Branch check (section 3.3): a nominal model with Table 2's set-3 errors already moves FK
    # solutions ~70 mm from the measured position, another FK branch moves them much further.
    branch_tolerance_m: float = 0.2
    branch_tolerance_rad: float = 0.5

    def free_mask(self) -> np.ndarray:
        if self.free_parameters is None:
            return np.ones(N_PARAMETERS, bool)
        mask = np.asarray(self.free_parameters, bool)
        if mask.shape != (N_PARAMETERS,):
            raise ValueError(f"free_parameters must be a mask of {N_PARAMETERS} booleans")
        return mask


@dataclass
class IdentificationResult:
    parameters: HexaParameters
    initial_parameters: HexaParameters
    std: np.ndarray  # (54,), NaN for fixed or unidentifiable parameters
    covariance: np.ndarray  # (54, 54) in parameter units; zero rows for fixed ones
    rank: int
    condition_number: float
    iterations: int
    reason: str
    cost: str
    solve_seconds: float
    used_postures: list[int]
    rejected_postures: dict[int, str]
    rms_residual: dict[str, float]  # per channel, after
    initial_rms_residual: dict[str, float]
    residuals: np.ndarray  # final residual rows (unweighted units)
    residual_channels: np.ndarray
    residual_postures: np.ndarray  # original posture index of each row
    identifiability: IdentifiabilityReport
    poses: np.ndarray = field(repr=False, default=None)  # FK poses of the used postures

    @property
    def correlation(self) -> np.ndarray:
        std = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.covariance / np.outer(std, std)

    def to_json(self) -> dict:
        """The JSON object printed by ``hexacal study --json`` and ``hexacal calibrate --json``."""
        from hexacal_msgs_py.parameters_file import parameters_to_chain_dict

        return {
            "parameters": parameters_to_chain_dict(self.parameters.vector),
            "std": parameters_to_chain_dict(np.nan_to_num(self.std, nan=-1.0)),
            "rank": self.rank,
            "condition_number": self.condition_number,
            "solve_seconds": self.solve_seconds,
            "iterations": self.iterations,
            "reason": self.reason,
            "cost": self.cost,
            "postures_used": len(self.used_postures),
            "postures_rejected": [{"index": i, "reason": r} for i, r in sorted(self.rejected_postures.items())],
            "rms_residual": self.rms_residual,
            "identifiability": self.identifiability.to_json(),
        }


class _Problem:
    """The postures in use, their cost function, and FK + residuals for a parameter vector."""

    def __init__(self, measurements: Measurements, used: np.ndarray, options: SolverOptions, free: np.ndarray):
        self.measurements = measurements
        self.used = np.asarray(used, dtype=int)
        self.options = options
        self.free = free
        self.cost = CostFunction(options.cost, measurements.subset(self.used), options.device, options.sigma)

    def without(self, local_indices: list[int]) -> "_Problem":
        keep = np.setdiff1d(np.arange(len(self.used)), local_indices)
        return _Problem(self.measurements, self.used[keep], self.options, self.free)

    def solve_fk(self, params: HexaParameters, start: np.ndarray, fit_tilt_first: bool = False):
        return forward_kinematics(
            params,
            self.cost.measurements.slider_positions,
            start,
            tolerance=self.options.fk_tolerance,
            branch_tolerance_m=self.options.branch_tolerance_m,
            branch_tolerance_rad=self.options.branch_tolerance_rad,
            fit_tilt_first=fit_tilt_first,
        )

    def expected_poses(self) -> np.ndarray:
        return self.cost.initial_poses()

    def residuals(self, poses: np.ndarray) -> ResidualBlock:
        return self.cost.residuals(poses, None)

    def jacobian(self, params: HexaParameters, poses: np.ndarray) -> ResidualBlock:
        sensitivity, _ = pose_parameter_sensitivity(params, poses)
        return self.cost.residuals(poses, sensitivity[:, :, self.free])

    def row_count(self) -> int:
        return len(self.residuals(self.expected_poses()).values) if len(self.used) else 0

    def check_enough(self, set_aside: dict[int, str]) -> None:
        n_free = int(self.free.sum())
        rows = self.row_count()
        if rows < n_free:
            raise TooFewPosturesError(
                f"{len(self.used)} usable posture(s) give {rows} residuals for {n_free} parameters "
                f"with the {self.options.cost} cost function ({len(set_aside)} posture(s) set aside); "
                "measure more postures"
            )


def identify(nominal: HexaParameters, measurements: Measurements, options: SolverOptions = SolverOptions()) -> IdentificationResult:
    """Identify the parameters from measured postures, starting from ``nominal``.

    Postures whose forward kinematics fails (with the nominal parameters, or at
    a trial step near a singularity of the current model) are set aside; once
    the parameters have converged they are tried again and, where FK now
    succeeds, the solve continues with them: a poor nominal model does not cost
    postures.  Raises InvalidMeasurementError, TooFewPosturesError or
    RankDeficientError (each with a ``reason``); otherwise returns a result
    whose ``reason`` is 'converged', 'iteration-limit' or 'diverged'.
    """
    started = time.perf_counter()
    if options.cost not in COSTS:
        raise ValueError(f"unknown cost function {options.cost!r}; choose one of {', '.join(COSTS)}")
    measurements.validate(options.limits)
    free = options.free_mask()
    usable = CostFunction(options.cost, measurements, options.device, options.sigma).usable()
    unused = {int(i): f"not used by the {options.cost} cost function" for i in np.flatnonzero(~usable)}
    # Small dense problems run fastest on one BLAS thread; more threads only add contention.
    with threadpool_limits(limits=1, user_api="blas"):
        problem, poses, set_aside = _admit(nominal, _Problem(measurements, np.flatnonzero(usable), options, free),
                                           "with the nominal parameters")
        problem.check_enough({**unused, **set_aside})
        solver = _LevenbergMarquardt(problem, nominal, poses)
        initial_block = solver.initial_block
        iterations = 0
        for _ in range(3):
            solver.run()
            iterations += solver.iterations
            set_aside.update(solver.dropped)
            if not set_aside or solver.reason != CONVERGED:
                break
            retry = _Problem(measurements, np.array(sorted(set_aside)), options, free)
            readmitted, readmitted_poses, set_aside = _admit(solver.params, retry, "with the identified parameters")
            if not len(readmitted.used):
                break
            merged = np.concatenate([solver.problem.used, readmitted.used])
            order = np.argsort(merged)
            all_poses = np.concatenate([solver.poses, readmitted_poses])[order]
            solver = _LevenbergMarquardt(_Problem(measurements, merged[order], options, free), solver.params, all_poses)
        solver.iterations, solver.initial_block = iterations, initial_block
        result = solver.result(nominal, {**unused, **set_aside}, started)
    if not result.identifiability.identifiable and not options.allow_rank_deficient:
        # Identifiable at the start but not at the solution: the apparent information came from the
        # nominal model's errors, not from the data. Refuse rather than return a number that means nothing.
        raise RankDeficientError(
            "at the identified parameters the measurements do not determine every parameter: "
            + result.identifiability.verdict(), result.identifiability,
        )
    return result


def _admit(params: HexaParameters, problem: _Problem, context: str):
    """FK from the expected postures; keep those that converge, set the others aside with the reason."""
    fk = problem.solve_fk(params, problem.expected_poses(), fit_tilt_first=True)
    failed = sorted(fk.failures)
    set_aside = {int(problem.used[i]): f"forward kinematics {context}: {fk.failures[i]}" for i in failed}
    return problem.without(failed), fk.poses[fk.converged], set_aside


class _LevenbergMarquardt:
    """Damped Gauss-Newton in column-scaled coordinates; the cost never increases."""

    def __init__(self, problem: _Problem, start: HexaParameters, poses: np.ndarray):
        self.problem = problem
        self.options = problem.options
        self.free = problem.free
        self.params = start
        self.poses = poses
        self.block = problem.jacobian(start, poses)
        self.initial_block = self.block
        self.scales = column_scales(self.block.jacobian)
        self.iterations = 0
        self.reason = ITERATION_LIMIT
        self.dropped: dict[int, str] = {}

    def analyze(self) -> IdentifiabilityReport:
        return analyze(self.block.jacobian, self.free_names(), self.params, self.free, self.options.rank_tolerance,
                       self.options.device.link_length)

    def free_names(self) -> list[str]:
        return [n for n, f in zip(parameter_names(), self.free) if f]

    def _check_rank(self, singular: np.ndarray) -> None:
        rank = int(np.sum(singular > self.options.rank_tolerance * singular[0]))
        if rank < len(singular) and not self.options.allow_rank_deficient:
            report = self.analyze()
            raise RankDeficientError(
                "the measurements do not determine every parameter: " + report.verdict(), report
            )

    def run(self) -> None:
        cost = float(self.block.values @ self.block.values)
        damping = 1e-9
        self.iterations = 0
        while self.iterations < self.options.max_iterations:
            self.iterations += 1
            s, vt, projected = _scaled_svd(self.block, self.scales)
            if self.iterations == 1:
                self._check_rank(s)
            keep = s > self.options.rank_tolerance * s[0]
            gauss_newton = self._step(0.0, s, keep, vt, projected)
            # The full Gauss-Newton step would lower the cost by |U_k^T r|^2: when that is negligible
            # (or the step itself is), the minimum is reached to working precision.
            predicted_decrease = float(projected[keep] @ projected[keep])
            if (np.max(np.abs(gauss_newton)) < self.options.step_tolerance
                    or predicted_decrease <= self.options.relative_cost_tolerance * cost):
                self.reason = CONVERGED
                return
            # FK stops at fk_tolerance, so the cost is only known to ~1e-9 of itself: below that, a step
            # that fails to lower it says nothing about the model.
            at_floor = np.max(np.abs(gauss_newton)) < FLOOR_STEP_M or predicted_decrease < 1e-6 * cost
            trial = None
            while damping < 1e12:
                trial = self._try(self._step(damping, s, keep, vt, projected))
                if isinstance(trial, dict) or (trial is not None and trial[2] < cost):
                    break
                trial = None
                if at_floor:
                    break  # a sub-nanometre step that does not lower the cost: rounding error, done
                damping *= 10.0
            if isinstance(trial, dict):
                self._drop(trial)
                cost = float(self.block.values @ self.block.values)
                continue
            if trial is None:
                # No step lowers the cost: converged at the floor of rounding error if the Gauss-Newton
                # step is negligible, otherwise the model cannot follow the data from here.
                self.reason = CONVERGED if at_floor else DIVERGED
                return
            self.params, self.poses, trial_cost = trial
            self.block = self.problem.jacobian(self.params, self.poses)
            decrease, cost = cost - trial_cost, trial_cost
            damping = max(damping / 10.0, 1e-12)
            if decrease <= self.options.relative_cost_tolerance * cost:
                self.reason = CONVERGED
                return

    def _step(self, damping, s, keep, vt, projected) -> np.ndarray:
        """LM step for one damping value (zero along unidentifiable directions)."""
        factor = np.where(keep, s / (s**2 + damping * s[0] ** 2), 0.0)
        step = np.zeros(N_PARAMETERS)
        step[self.free] = -(vt.T @ (factor * projected)) / self.scales
        return step

    def _try(self, step: np.ndarray):
        """(params, poses, cost) of a trial step; None if it fails; {index: why} for a few FK failures."""
        try:
            params = HexaParameters(self.params.vector + step)
        except ValueError:  # the step left the valid parameter set (|a_xy| >= 1)
            return None
        fk = self.problem.solve_fk(params, self.poses)
        if fk.failures:
            # A few postures whose FK breaks down (near a singularity of the model) are set aside;
            # many failing at once means the step is too long.
            few = len(fk.failures) <= max(1, len(self.poses) // 20)
            return dict(fk.failures) if few else None
        values = self.problem.residuals(fk.poses).values
        return params, fk.poses, float(values @ values)

    def _drop(self, failures: dict[int, str]) -> None:
        local = sorted(failures)
        for i in local:
            self.dropped[int(self.problem.used[i])] = (
                f"forward kinematics failed during identification: {failures[i]}"
            )
        keep = np.setdiff1d(np.arange(len(self.poses)), local)
        self.problem = self.problem.without(local)
        self.problem.check_enough(self.dropped)
        self.poses = self.poses[keep]
        self.block = self.problem.jacobian(self.params, self.poses)

    def result(self, nominal: HexaParameters, rejected: dict[int, str], started: float) -> IdentificationResult:
        used = self.problem.used
        report = self.analyze()
        covariance = _covariance(self.block, self.scales, self.free, self.options.rank_tolerance)
        std = np.sqrt(np.diag(covariance))
        std[~self.free] = np.nan
        std[np.isinf(std)] = np.nan
        sigma = self.options.sigma
        return IdentificationResult(
            parameters=self.params,
            initial_parameters=nominal,
            std=std,
            covariance=np.nan_to_num(covariance, nan=0.0, posinf=0.0),
            rank=report.rank,
            condition_number=report.condition_number,
            iterations=self.iterations,
            reason=self.reason,
            cost=self.options.cost,
            solve_seconds=time.perf_counter() - started,
            used_postures=[int(i) for i in used],
            rejected_postures=rejected,
            rms_residual=_rms_by_channel(self.block, sigma),
            initial_rms_residual=_rms_by_channel(self.initial_block, sigma),
            residuals=_unweighted(self.block, sigma),
            residual_channels=self.block.channels,
            residual_postures=used[self.block.postures],
            identifiability=report,
            poses=self.poses,
        )


def _scaled_svd(block: ResidualBlock, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Singular values, V^T and U^T r of the column-scaled Jacobian, via QR first (J is tall)."""
    q, r = np.linalg.qr(block.jacobian / scales)
    u_r, s, vt = np.linalg.svd(r)
    return s, vt, u_r.T @ (q.T @ block.values)


def _covariance(block: ResidualBlock, scales: np.ndarray, free: np.ndarray, rank_tolerance: float) -> np.ndarray:
    """s^2 (J^T J)^-1 over the identifiable subspace, s^2 = |r|^2 / (rows - rank).

    Parameters touched by an unidentifiable direction get an infinite variance
    (std NaN in the result): the data say nothing about them.
    """
    s, vt, _ = _scaled_svd(block, scales)
    keep = s > rank_tolerance * s[0]
    rank = int(keep.sum())
    variance = float(block.values @ block.values) / max(len(block.values) - rank, 1)
    scaled_cov = variance * ((vt[keep].T / s[keep] ** 2) @ vt[keep]) / np.outer(scales, scales)
    covariance = np.zeros((N_PARAMETERS, N_PARAMETERS))
    covariance[np.ix_(free, free)] = scaled_cov
    if rank < len(s):
        weak = np.flatnonzero(np.any(np.abs(vt[~keep]) > 1e-6, axis=0))
        free_index = np.flatnonzero(free)
        covariance[free_index[weak], free_index[weak]] = np.inf
    return covariance


def _unweighted(block: ResidualBlock, sigma: ChannelSigma) -> np.ndarray:
    angular = np.char.startswith(block.channels.astype(str), "phi")
    return block.values * np.where(angular, sigma.angle_rad, sigma.position_m)


def _rms_by_channel(block: ResidualBlock, sigma: ChannelSigma) -> dict[str, float]:
    values = _unweighted(block, sigma)
    return {
        str(channel): float(np.sqrt(np.mean(values[block.channels == channel] ** 2)))
        for channel in dict.fromkeys(block.channels.tolist())
    }


__all__ = [
    "CONVERGED",
    "DIVERGED",
    "ITERATION_LIMIT",
    "IdentificationResult",
    "InvalidMeasurementError",
    "SolverOptions",
    "identify",
]
