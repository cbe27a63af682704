"""
One solver run: scipy's ``least_squares`` on the free unknowns, and what its Jacobian tells.

At each accepted point the Jacobian is reduced to its normal equations (``NormalEquations``),
whose eigendecomposition serves the stop (the Gauss-Newton step from there is below
``STOP_STEP``), the convergence verdict, the covariance and the identifiability analysis.
"""

from __future__ import annotations

from dataclasses import dataclass
import time

import numpy as np

from .fit_problem import FitProblem, split_unknowns
from .identification_result import CONVERGED, DIVERGED, IdentificationResult, ITERATION_LIMIT
from .residuals import ChannelSigma, ResidualBlock
from .row_weights import RowTransform
from .solver_options import unknown_names
from ..architectures import KinematicParameters
from ..assessment.adequacy import WhitenedResiduals
from ..assessment.identifiability import analyze, column_scales, IdentifiabilityReport
from ..machine.device import DEVICE_PARAMETER_NAMES, N_DEVICE_PARAMETERS
from ..machine.measurements import Weights

FLOOR_STEP_M = (
    1e-9  # a Gauss-Newton step below this (m) is at the rounding floor of FK and residuals
)
# The solve stops when the Gauss-Newton step from the accepted point is below this (m or rad):
# the unknowns are then within about this of the minimum.
STOP_STEP = 1e-10


class _FailedPostures(Exception):
    """A trial step at which a few postures' FK failed: set them aside and solve on."""

    def __init__(self, failures: dict[int, str]):
        super().__init__(f'{len(failures)} posture(s) failed forward kinematics')
        self.failures = failures


class _IterationLimit(Exception):
    """The solve formed max_iterations Jacobians without converging."""


class LeastSquaresRun:
    """
    scipy's least_squares (trust-region reflective) on the free unknowns, columns scaled.

    FK is warm-started from the last accepted poses; a trial at which a few postures' FK
    fails sets them aside and restarts from the accepted point.
    """

    def __init__(
        self,
        problem: FitProblem,
        start: np.ndarray,
        poses: np.ndarray,
        transform: RowTransform | None = None,
    ):
        self.problem = problem
        self.options = problem.options
        self.free = problem.free
        self.transform = transform or RowTransform()
        self.vector = np.array(start, dtype=float)
        self.poses = poses
        self._set_block(problem.jacobian(self.vector, poses), first=True)
        self.initial_block = self.raw_block
        self.iterations = 0
        self.evaluations = 0
        self.reason = ITERATION_LIMIT
        self.dropped: dict[int, str] = {}
        self._trial: tuple[bytes, np.ndarray] | None = None  # the last trial's (x, FK poses)

    @property
    def params(self) -> KinematicParameters:
        return split_unknowns(self.vector, self.problem.arch)[0]

    def free_names(self) -> list[str]:
        names = unknown_names(self.problem.arch.name, self.options.compliance)
        return [n for n, f in zip(names, self.free) if f]

    def _set_block(self, raw_block: ResidualBlock, first: bool = False) -> None:
        """Take residuals and Jacobian (unweighted) here; reduce them to normal equations."""
        self.raw_block = raw_block
        self.block = self.problem.with_prior(self.transform.apply(raw_block), self.vector)
        assert self.block.jacobian is not None  # problem.jacobian's rows, plus the prior's
        if first:  # columns are scaled by their norms at the start of the run, fixed for the run
            self.scales = column_scales(self.block.jacobian)
        self.normal = NormalEquations.of(self.block, self.scales, self.options.rank_tolerance)

    def analyze(self) -> IdentifiabilityReport:
        # The normal equations already hold J^T J: its n x n square root spares analyze() a tall
        # SVD.
        assert self.block.jacobian is not None  # _set_block keeps only blocks with one
        return analyze(
            self.block.jacobian,
            self.free_names(),
            self.params,
            self.free,
            self.options.rank_tolerance,
            self.options.device.link_length,
            self.options.device.mount,
            gram_root=self.normal.square_root() * self.scales,
            extra_names=self.options.compliance.unknown_names,
        )

    def run(self) -> None:
        from scipy.optimize import least_squares  # ~0.2 s: imported by the solve alone

        self.iterations = 1  # the Jacobian at the start
        while True:
            if self._at_minimum():
                self.reason = CONVERGED
                return
            try:
                solution = least_squares(
                    self._values,
                    self.vector[self.free],
                    jac=self._jacobian,
                    method='trf',
                    x_scale=1.0 / self.scales,
                    ftol=self.options.relative_cost_tolerance,
                    xtol=self.options.step_tolerance,
                    gtol=None,
                    max_nfev=20 * self.options.max_iterations,
                    callback=self._stop_when_converged,
                )
            except _FailedPostures as failed:
                self._drop(failed.failures)
                continue
            except _IterationLimit:
                self.reason = ITERATION_LIMIT
                return
            break
        if solution.status == 0:
            self.reason = ITERATION_LIMIT
            return
        # Stopped by the callback, or no step lowers the cost any more: converged if the
        # Gauss-Newton step from here is negligible (at the rounding floor of FK, which stops at
        # fk_tolerance), otherwise the model cannot follow the data from here.
        at_floor = self._negligible(
            max(self.options.step_tolerance, FLOOR_STEP_M),
            max(self.options.relative_cost_tolerance, 1e-6),
        )
        self.reason = CONVERGED if at_floor else DIVERGED

    def _negligible(self, step_tolerance: float, relative_cost_tolerance: float) -> bool:
        """Whether the full Gauss-Newton step from the accepted point is negligible."""
        gauss_newton = np.max(np.abs(self.normal.scaled_step(0.0) / self.scales), initial=0.0)
        predicted = self.normal.predicted_decrease()
        return bool(
            gauss_newton < step_tolerance
            or predicted <= relative_cost_tolerance * self.normal.squared_norm
        )

    def _at_minimum(self) -> bool:
        """Whether the Gauss-Newton step from the accepted point is below STOP_STEP."""
        return self._negligible(max(self.options.step_tolerance, STOP_STEP), 0.0)

    def _stop_when_converged(self, intermediate_result) -> None:
        """Stop least_squares at the minimum (its own tests stop it at the rounding floor)."""
        if self._at_minimum():
            raise StopIteration

    def _values(self, free_vector: np.ndarray) -> np.ndarray:
        """Return the weighted residual rows at a trial (inf where the step left the model)."""
        self.evaluations += 1
        vector = self.vector.copy()
        vector[self.free] = free_vector
        if np.array_equal(vector, self.vector):
            return self.block.values
        rows = len(self.block.values)
        try:
            params, _ = split_unknowns(vector, self.problem.arch)
        except ValueError:  # the step left the valid parameter set (|a_xy| >= 1, absurd defects)
            return np.full(rows, np.inf)
        fk = self.problem.solve_fk(params, self.poses, vector=vector)
        if fk.failures:
            # A few postures whose FK breaks down (near a singularity of the model) are set aside;
            # many failing at once means the step is too long: least_squares shortens it.
            if len(fk.failures) <= max(1, len(self.poses) // 20):
                raise _FailedPostures(dict(fk.failures))
            return np.full(rows, np.inf)
        self._trial = (vector.tobytes(), fk.poses)
        block = self.problem.residuals(vector, fk.poses)
        return self.problem.with_prior(
            ResidualBlock(self.transform.values(block), None, block.channels, block.postures),
            vector,
        ).values

    def _jacobian(self, free_vector: np.ndarray) -> np.ndarray:
        """Accept a point (least_squares asks for its Jacobian only at accepted points)."""
        vector = self.vector.copy()
        vector[self.free] = free_vector
        if not np.array_equal(vector, self.vector):
            if self._trial is not None and self._trial[0] == vector.tobytes():
                poses = self._trial[1]
            else:
                params = split_unknowns(vector, self.problem.arch)[0]
                poses = self.problem.solve_fk(params, self.poses, vector=vector).poses
            self.vector, self.poses = vector, poses
            self._set_block(self.problem.jacobian(self.vector, self.poses))
            # As before: a pass per step taken, plus the one that finds no step worth taking.
            if self.iterations >= self.options.max_iterations:
                raise _IterationLimit
            self.iterations += 1
        assert self.block.jacobian is not None  # _set_block keeps only blocks with one
        return self.block.jacobian

    def _drop(self, failures: dict[int, str]) -> None:
        local = sorted(failures)
        for i in local:
            self.dropped[int(self.problem.used[i])] = (
                f'forward kinematics failed during identification: {failures[i]}'
            )
        keep = np.setdiff1d(np.arange(len(self.poses)), local)
        self.problem = self.problem.without(local)
        self.problem.check_enough(self.dropped)
        self.poses = self.poses[keep]
        # Whitening/robust weights were per row of the old posture set: refit them on the new one.
        self.transform = self.problem.row_transform(self.vector, self.poses)
        self._set_block(self.problem.jacobian(self.vector, self.poses))

    def result(
        self, nominal: KinematicParameters, rejected: dict[int, str], started: float
    ) -> IdentificationResult:
        used = self.problem.used
        report = self.analyze()
        whitened = self.transform.whitener is not None
        weights = self.options.weights if whitened else Weights.NONE
        covariance, variance_factor = parameter_covariance(
            self.normal, len(self.block.values), self.scales, self.free, known_noise=whitened
        )
        std_all = np.sqrt(np.diag(covariance))
        std_all[~self.free] = np.nan
        std_all[np.isinf(std_all)] = np.nan
        params, defects = split_unknowns(self.vector, self.problem.arch)
        n = self.problem.n_parameters
        sigma = self.options.sigma
        compliance = self.options.compliance
        offset = n + N_DEVICE_PARAMETERS
        return IdentificationResult(
            parameters=params,
            initial_parameters=nominal,
            std=std_all[:n],
            covariance=np.nan_to_num(covariance, nan=0.0, posinf=0.0),
            rank=report.rank,
            condition_number=report.condition_number,
            iterations=self.iterations,
            reason=self.reason,
            cost=self.options.cost,
            solve_seconds=time.perf_counter() - started,
            used_postures=[int(i) for i in used],
            rejected_postures=rejected,
            rms_residual=_rms_by_channel(self.raw_block, sigma),
            initial_rms_residual=_rms_by_channel(self.initial_block, sigma),
            residuals=_unweighted(self.raw_block, sigma),
            residual_channels=self.raw_block.channels,
            residual_postures=used[self.raw_block.postures],
            identifiability=report,
            poses=self.poses,
            device=defects,
            device_std=std_all[n:offset],
            free_device=tuple(
                name for name, f in zip(DEVICE_PARAMETER_NAMES, self.free[n:offset]) if f
            ),
            variance_factor=variance_factor,
            weighted=weights == Weights.NOISE_MODEL,
            robust_loss=self.options.robust_loss,
            whitened=self._whitened() if whitened else None,
            weights=weights.value,
            compliance_mode=compliance.mode,
            compliance={k: float(v) for k, v in zip(compliance.names, self.vector[offset:])},
            compliance_std={k: float(v) for k, v in zip(compliance.names, std_all[offset:])},
        )

    def _whitened(self) -> WhitenedResiduals:
        """Return the final rows whitened by the reading noise alone (no robust weights)."""
        assert self.transform.whitener is not None  # only called for a weighted fit
        raw = self.raw_block
        block = self.problem.with_prior(
            ResidualBlock(
                self.transform.whitener.apply_values(raw.values), None, raw.channels, raw.postures
            ),
            self.vector,
        )
        local = block.postures
        postures = np.where(local >= 0, self.problem.used[np.maximum(local, 0)], -1)
        return WhitenedResiduals(block.values, block.channels, postures)


@dataclass(frozen=True)
class NormalEquations:
    """
    Column-scaled normal equations of one Jacobian: J_s^T J_s = V diag(lam) V^T, J_s^T r and |r|^2.

    J_s = J / scales.  lam are the squared singular values of J_s and V its right
    singular vectors, so everything the SVD of the tall J_s gave is here at n x n
    cost: with g = J_s^T r, U^T r = V^T g / sqrt(lam).  Forming J^T J squares the
    condition number (~1e3-1e4 for the column-scaled problems here, so ~1e-9
    relative error in the smallest lam); directions with lam <= tol^2 lam_max are
    unidentifiable exactly where s <= tol s_max was before.
    """

    eigenvalues: np.ndarray  # lam, descending, negative rounding clipped to 0
    eigenvectors: np.ndarray  # V, (n, n), columns in the order of lam
    gradient: np.ndarray  # J_s^T r
    squared_norm: float  # |r|^2
    keep: np.ndarray  # identifiable directions: lam > tol^2 lam_max

    @classmethod
    def of(
        cls, block: ResidualBlock, scales: np.ndarray, rank_tolerance: float
    ) -> 'NormalEquations':
        jacobian = block.jacobian
        assert jacobian is not None  # normal equations are formed from a Jacobian
        gram = (jacobian.T @ jacobian) / np.outer(scales, scales)  # numpy uses BLAS syrk for J^T J
        eigenvalues, eigenvectors = np.linalg.eigh(gram)
        eigenvalues, eigenvectors = np.maximum(eigenvalues[::-1], 0.0), eigenvectors[:, ::-1]
        keep = eigenvalues > rank_tolerance**2 * eigenvalues[0]
        return cls(
            eigenvalues,
            eigenvectors,
            (jacobian.T @ block.values) / scales,
            float(block.values @ block.values),
            keep,
        )

    @property
    def rank(self) -> int:
        return int(self.keep.sum())

    def _projected_gradient(self) -> np.ndarray:
        """V^T g over the identifiable directions (zero elsewhere)."""
        return np.where(self.keep, self.eigenvectors.T @ self.gradient, 0.0)

    def scaled_step(self, damping: float) -> np.ndarray:
        """Return -(J_s^T J_s + damping lam_max I)^+ g on the identifiable subspace (0: GN)."""
        denominator = np.where(self.keep, self.eigenvalues + damping * self.eigenvalues[0], 1.0)
        return -self.eigenvectors @ (self._projected_gradient() / denominator)

    def predicted_decrease(self) -> float:
        """|U_k^T r|^2: how much the full Gauss-Newton step would lower |r|^2."""
        projected = self._projected_gradient()
        return float(np.sum(projected**2 / np.where(self.keep, self.eigenvalues, 1.0)))

    def scaled_inverse(self) -> np.ndarray:
        """(J_s^T J_s)^+ over the identifiable subspace."""
        kept = self.eigenvectors[:, self.keep]
        return (kept / self.eigenvalues[self.keep]) @ kept.T

    def square_root(self) -> np.ndarray:
        """F (n x n) with F^T F = J_s^T J_s: stands in for J_s wherever only J_s^T J_s matters."""
        return np.sqrt(self.eigenvalues)[:, None] * self.eigenvectors.T


def parameter_covariance(
    normal: NormalEquations,
    rows: int,
    scales: np.ndarray,
    free: np.ndarray,
    known_noise: bool = False,
) -> tuple[np.ndarray, float]:
    """
    Parameter covariance over the identifiable subspace, and the variance factor s^2.

    s^2 = |r|^2 / (rows - rank).  With rows whitened by a known noise model the
    covariance is (J^T J)^-1 itself (the Cramer-Rao bound of that noise) and s^2
    should be ~1; otherwise it is s^2 (J^T J)^-1.  Parameters touched by an
    unidentifiable direction get an infinite variance (std NaN in the result).
    """
    variance = normal.squared_norm / max(rows - normal.rank, 1)
    factor = 1.0 if known_noise else variance
    covariance = np.zeros((len(free), len(free)))
    covariance[np.ix_(free, free)] = factor * normal.scaled_inverse() / np.outer(scales, scales)
    if normal.rank < len(normal.eigenvalues):
        weak = np.flatnonzero(np.any(np.abs(normal.eigenvectors[:, ~normal.keep]) > 1e-6, axis=1))
        free_index = np.flatnonzero(free)
        covariance[free_index[weak], free_index[weak]] = np.inf
    return covariance, variance


def _unweighted(block: ResidualBlock, sigma: ChannelSigma) -> np.ndarray:
    angular = np.char.startswith(block.channels.astype(str), 'phi')
    return block.values * np.where(angular, sigma.angle_rad, sigma.position_m)


def _rms_by_channel(block: ResidualBlock, sigma: ChannelSigma) -> dict[str, float]:
    values = _unweighted(block, sigma)
    return {
        str(channel): float(np.sqrt(np.mean(values[block.channels == channel] ** 2)))
        for channel in dict.fromkeys(block.channels.tolist())
    }
