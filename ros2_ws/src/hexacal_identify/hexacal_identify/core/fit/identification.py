"""
Parameter identification by least squares on forward-kinematics residuals (eqs. 5-13).

scipy's ``least_squares`` (trust-region reflective, columns scaled by their norms
at the start) minimises the residuals of the chosen cost function over the free
unknowns.  Each evaluation solves forward kinematics for every posture
(warm-started from the last accepted solution); the identification Jacobian
(eq. 6) is analytic, by implicit differentiation of IK(X, u) = lambda.  At each
accepted point the Jacobian is also reduced to its normal equations (J^T J,
J^T r: n x n, n = the architecture's parameters + 5), whose eigendecomposition
serves the stop (the Gauss-Newton step from there is below ``STOP_STEP``), the
convergence verdict, the covariance and the identifiability analysis.

Beyond the paper:

* The unknowns are the architecture's kinematic parameters (its layout's
  ``n_parameters``, 54 for a Hexa Slide) followed by the 5 device defects
  (``device.DEVICE_PARAMETER_NAMES``); masks choose which are identified.
* With a known noise model the residuals are whitened per posture by the
  covariance the reading noise propagates to them (through eq. 4 and FK), so the
  fit is weighted by what each row really knows and the covariance is the
  Cramer-Rao bound of that noise.  With ``scatter_weights`` the reading noise is
  each posture's own measured scatter (``Measurements.standard_errors``, the
  standard errors of its means, raised to ``scatter_floor``): a posture whose
  channels scattered more weighs less, channel by channel.
* Postures are screened: one whose residual is far above the others' (a glitched
  reading, a wrong FK branch) is excluded and reported; a Huber or soft-L1 loss
  (iteratively reweighted) is available as well.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import functools
import time

import numpy as np
from threadpoolctl import ThreadpoolController

from .adequacy import Adequacy, assess, WhitenedResiduals
from .compliance import ComplianceModel, LOADS_TOLERANCE_M
from .identifiability import analyze, column_scales, DEFAULT_RANK_TOLERANCE, IdentifiabilityReport
from .residuals import ChannelSigma, CostFunction, COSTS, DL, N_NOISE_SOURCES, ResidualBlock
from .statics import StaticLoads
from ..architectures import Architecture, KinematicParameters
from ..errors import InvalidMeasurementError, RankDeficientError, TooFewPosturesError
from ..machine.device import (
    DEVICE_PARAMETER_NAMES,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
    N_DEVICE_PARAMETERS,
)
from ..machine.kinematics import forward_kinematics, pose_sensitivities
from ..machine.measurements import (
    MeasurementLimits,
    Measurements,
    NoiseModel,
    ScatterFloor,
    Weights,
)
from ..machine.model import parameter_names

CONVERGED = 'converged'
ITERATION_LIMIT = 'iteration-limit'
DIVERGED = 'diverged'
FLOOR_STEP_M = (
    1e-9  # a Gauss-Newton step below this (m) is at the rounding floor of FK and residuals
)
# The solve stops when the Gauss-Newton step from the accepted point is below this (m or rad):
# the unknowns are then within about this of the minimum.
STOP_STEP = 1e-10
ROBUST_LOSSES = ('huber', 'soft_l1')
MAX_ROUNDS = 20  # outer rounds: re-admitting postures, screening outliers, refitting weights
IRLS_TOLERANCE = 1e-9  # robust reweighting stops when no unknown moves more than this (m)


@functools.lru_cache(maxsize=1)
def _blas_controller() -> ThreadpoolController:
    """Built once: inspecting the loaded BLAS libraries costs about a millisecond each time."""
    # scipy brings its own OpenBLAS: loaded first, so that the one-thread limit covers it too.
    import scipy.linalg  # noqa: F401

    return ThreadpoolController()


def unknown_names(model: str, compliance: ComplianceModel | None = None) -> list[str]:
    """
    Return the names of the model's kinematic parameters followed by the 5 device defects.

    With a ``compliance`` choice its unknowns (``compliance.<name>``) follow.
    """
    names = parameter_names(model) + [f'device.{name}' for name in DEVICE_PARAMETER_NAMES]
    return names + (compliance.unknown_names if compliance is not None else [])


@dataclass(frozen=True)
class SolverOptions:
    cost: str = 'absolute'
    device: DeviceModel = DeviceModel()
    sigma: ChannelSigma = ChannelSigma()
    limits: MeasurementLimits = MeasurementLimits()
    free_parameters: tuple[bool, ...] | None = (
        None  # mask over the kinematic parameters; None = all
    )
    device_defects: DeviceDefects = DeviceDefects()  # assumed (and starting) device defects
    free_device: tuple[
        str, ...
    ] = ()  # device defects to identify, names from DEVICE_PARAMETER_NAMES
    device_prior: DevicePrior = (
        DevicePrior()
    )  # prior value +- std per device defect (identified, MAP rows)
    noise: NoiseModel | None = None  # known reading noise: whiten the residuals by it
    # Whiten by each posture's measured scatter (Measurements.standard_errors, every posture)
    # raised to scatter_floor, instead of one noise model shared by every posture.
    scatter_weights: bool = False
    scatter_floor: ScatterFloor = ScatterFloor()
    robust_loss: str | None = None  # None, 'huber' or 'soft_l1'
    outlier_threshold: float | None = (
        6.0  # a posture whose RMS residual exceeds this x the median is excluded
    )
    outlier_floor: float = (
        1e-7  # ... and exceeds this (m or rad, unweighted): below, it is rounding, not a glitch
    )
    max_iterations: int = 100  # steps taken per solve
    step_tolerance: float = 1e-12  # least_squares' xtol: a step below this x |unknowns| converges
    relative_cost_tolerance: float = (
        1e-9  # least_squares' ftol: ... or an accepted step lowers the cost by less than this
    )
    rank_tolerance: float = DEFAULT_RANK_TOLERANCE
    allow_rank_deficient: bool = (
        False  # hold the unidentifiable unknowns fixed instead of refusing
    )
    fk_tolerance: float = 1e-12
    # Branch check (section 3.3): a nominal model with Table 2's set-3 errors already moves FK
    # solutions ~70 mm from the measured position, another FK branch moves them much further.
    branch_tolerance_m: float = 0.2
    branch_tolerance_rad: float = 0.5
    # Axial compliances identified with the geometry from the static loads
    # (core/fit/compliance.py).
    compliance: ComplianceModel = ComplianceModel()

    def free_mask(self, n_parameters: int) -> np.ndarray:
        """Return the mask over the unknowns: n_parameters kinematic (the layout's) + 5 device."""
        kinematic = (
            np.ones(n_parameters, bool)
            if self.free_parameters is None
            else np.asarray(self.free_parameters, bool)
        )
        if kinematic.shape != (n_parameters,):
            raise ValueError(f'free_parameters must be a mask of {n_parameters} booleans')
        unknown = sorted(set(self.free_device) - set(DEVICE_PARAMETER_NAMES))
        if unknown:
            raise ValueError(
                f'unknown device parameter(s) {unknown}; choose from '
                f'{", ".join(DEVICE_PARAMETER_NAMES)}'
            )
        identified = set(self.free_device) | set(self.device_prior.names)
        device = np.array([name in identified for name in DEVICE_PARAMETER_NAMES])
        if self.compliance.active:
            return np.concatenate([kinematic, device, self.compliance.free()])
        return np.concatenate([kinematic, device])

    def validate(self, n_parameters: int) -> None:
        if self.cost not in COSTS:
            raise ValueError(
                f'unknown cost function {self.cost!r}; choose one of {", ".join(COSTS)}'
            )
        if self.robust_loss not in (None, *ROBUST_LOSSES):
            raise ValueError(
                f'unknown robust loss {self.robust_loss!r}; choose one of '
                f'{", ".join(ROBUST_LOSSES)}'
            )
        if self.noise is not None and not self.noise.known:
            raise ValueError('a noise model for weighting needs positive slider and angle noise')
        if self.noise is not None and self.scatter_weights:
            raise ValueError(
                "weigh by the postures' scatter or by a noise model, not both: give one"
            )
        if self.device_prior and self.weights == Weights.NONE:
            raise ValueError(
                f'a device prior ({self.device_prior.describe()}) is weighed against the data by '
                'the reading noise: give the noise model too (noise_slider_m and '
                'noise_angle_rad, --noise-um / --weighted), or postures that carry their scatter'
            )
        if self.compliance.prior and self.weights == Weights.NONE:
            raise ValueError(
                'a compliance prior is weighed against the data by the reading noise: give the '
                'noise model too (--noise-um / --weighted), or postures that carry their scatter'
            )
        self.free_mask(n_parameters)

    @property
    def weights(self) -> Weights:
        """Return what whitens the residuals: the postures' scatter, the noise model, or none."""
        if self.scatter_weights:
            return Weights.SCATTER
        return Weights.NOISE_MODEL if self.noise is not None else Weights.NONE


@dataclass
class IdentificationResult:
    parameters: KinematicParameters
    initial_parameters: KinematicParameters
    std: np.ndarray  # (n,), n = the layout's n_parameters; NaN for fixed or unidentifiable ones
    covariance: np.ndarray  # (n + 5, n + 5): kinematic then 5 device; zero rows for fixed ones
    rank: int
    condition_number: float
    iterations: int
    reason: str
    cost: str
    solve_seconds: float
    used_postures: list[int]
    rejected_postures: dict[int, str]
    rms_residual: dict[str, float]  # per channel, after, unweighted units (m, rad)
    initial_rms_residual: dict[str, float]
    residuals: np.ndarray  # final residual rows (unweighted units)
    residual_channels: np.ndarray
    residual_postures: np.ndarray  # original posture index of each row
    identifiability: IdentifiabilityReport
    poses: np.ndarray | None = field(repr=False, default=None)  # FK poses of the used postures
    device: DeviceDefects = field(default_factory=DeviceDefects)
    device_std: np.ndarray = field(default_factory=lambda: np.full(N_DEVICE_PARAMETERS, np.nan))
    free_device: tuple[str, ...] = ()
    variance_factor: float = float(
        'nan'
    )  # residual variance / expected: ~1 when the noise model fits
    weighted: bool = False  # whitened by the noise model (JSON weighted_by_noise_model)
    robust_loss: str | None = None
    held_for_identifiability: list[str] = field(default_factory=list)  # held at their start values
    # The rows whitened by the noise model, prior rows included (None without one): adequacy.py.
    whitened: WhitenedResiduals | None = field(repr=False, default=None)
    # What whitened the rows (the std, covariance and adequacy are under it), and why (one line).
    weights: str = Weights.NONE.value
    weights_note: str = ''
    # Identified axial compliances (m/N) and their std (NaN: held or unidentifiable); empty: rigid.
    compliance_mode: str = 'none'
    compliance: dict[str, float] = field(default_factory=dict)
    compliance_std: dict[str, float] = field(default_factory=dict)

    @property
    def adequacy(self) -> Adequacy:
        """Return the fit against its noise model (verdict unknown without one)."""
        return assess(self.whitened, self.rank)

    @property
    def correlation(self) -> np.ndarray:
        std = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid='ignore', divide='ignore'):
            return self.covariance / np.outer(std, std)

    def to_json(self) -> dict:
        """Return the JSON object that ``hexacal study/calibrate --json`` print."""
        from hexacal_msgs_py.parameters_file import parameters_to_chain_dict

        model = self.parameters.model
        payload = {
            'model': model,
            'parameters': parameters_to_chain_dict(self.parameters.vector, model),
            'std': parameters_to_chain_dict(np.nan_to_num(self.std, nan=-1.0), model),
            'rank': self.rank,
            'condition_number': self.condition_number,
            'solve_seconds': self.solve_seconds,
            'iterations': self.iterations,
            'reason': self.reason,
            'cost': self.cost,
            'postures_used': len(self.used_postures),
            'postures_rejected': [
                {'index': i, 'reason': r} for i, r in sorted(self.rejected_postures.items())
            ],
            'rms_residual': self.rms_residual,
            'identifiability': self.identifiability.to_json(),
            'device': {n: float(v) for n, v in zip(DEVICE_PARAMETER_NAMES, self.device.vector)},
            'device_identified': list(self.free_device),
            'device_std': {
                n: (None if not np.isfinite(s) else float(s))
                for n, s in zip(DEVICE_PARAMETER_NAMES, self.device_std)
            },
            'weighted_by_noise_model': self.weighted,
            'weights': self.weights,
            'weights_note': self.weights_note,
            'variance_factor': self.variance_factor,
            'robust_loss': self.robust_loss,
            'held_for_identifiability': self.held_for_identifiability,
        }
        if self.compliance_mode != 'none':
            payload['compliance'] = {
                'mode': self.compliance_mode,
                'unit': 'm/N',
                'values': dict(self.compliance),
                'std': {
                    name: (None if not np.isfinite(s) else float(s))
                    for name, s in self.compliance_std.items()
                },
            }
        payload['std_note'] = '-1 marks a parameter that was held fixed or is not identifiable'
        return payload


def _split(vector: np.ndarray, arch: Architecture) -> tuple[KinematicParameters, DeviceDefects]:
    """Split the unknown vector into the architecture's parameters and the 5 device defects."""
    n = arch.layout.n_parameters
    return arch.parameters(vector[:n]), DeviceDefects.from_vector(
        vector[n:n + N_DEVICE_PARAMETERS]
    )


class _Problem:
    """The postures in use, their cost function, and FK + residuals for an unknown vector."""

    def __init__(
        self,
        measurements: Measurements,
        used: np.ndarray,
        options: SolverOptions,
        free: np.ndarray,
        arch: Architecture,
    ):
        self.arch = arch
        self.n_parameters = arch.layout.n_parameters
        self.measurements = measurements
        self.used = np.asarray(used, dtype=int)
        self.options = options
        self.free = free
        self.cost = CostFunction(
            options.cost, measurements.subset(self.used), options.device, options.sigma
        )
        # Static loads of the used postures, held through a solver run (compliance.py).
        self.loads: StaticLoads | None = None
        self._compliant_cost: tuple[bytes, CostFunction] | None = None

    def without(self, local_indices) -> '_Problem':
        keep = np.setdiff1d(np.arange(len(self.used)), list(local_indices))
        problem = _Problem(self.measurements, self.used[keep], self.options, self.free, self.arch)
        if self.loads is not None:
            problem.loads = self.loads.subset(keep)
        return problem

    @property
    def compliance(self) -> ComplianceModel:
        return self.options.compliance

    def _offset(self) -> int:
        return self.n_parameters + N_DEVICE_PARAMETERS

    def cost_at(self, vector: np.ndarray | None) -> CostFunction:
        """Return the cost function of the readings corrected by ``vector``'s compliances."""
        if not self.compliance.active or self.loads is None or vector is None:
            return self.cost
        values = vector[self._offset():]
        key = values.tobytes()
        if self._compliant_cost is None or self._compliant_cost[0] != key:
            corrected = self.compliance.corrected(
                self.cost.measurements, self.loads, values, self.options.device.link_length
            )
            self._compliant_cost = (
                key,
                CostFunction(
                    self.options.cost, corrected, self.options.device, self.options.sigma
                ),
            )
        return self._compliant_cost[1]

    def update_loads(self, vector: np.ndarray, poses: np.ndarray) -> bool:
        """Evaluate the loads at ``poses``; return whether a deflection moved (compliance.py)."""
        moved, loads = self._loads_at(vector, poses)
        if moved:
            self.loads, self._compliant_cost = loads, None
        return moved

    def loads_moved(self, vector: np.ndarray, poses: np.ndarray) -> bool:
        """Return whether the loads at ``poses`` move a deflection from those held."""
        return self._loads_at(vector, poses)[0]

    def _loads_at(self, vector: np.ndarray, poses: np.ndarray):
        if not self.compliance.active:
            return False, None
        loads = self.compliance.loads(_split(vector, self.arch)[0], poses, self.used)
        if self.loads is None:
            return True, loads
        values = vector[self._offset():]
        old = self.compliance.deflections(self.loads, values)
        new = self.compliance.deflections(loads, values)
        moved = max(float(np.max(np.abs(a - b), initial=0.0)) for a, b in zip(old, new))
        return moved > LOADS_TOLERANCE_M, loads

    def solve_fk(
        self,
        params: KinematicParameters,
        start: np.ndarray,
        fit_tilt_first: bool = False,
        vector: np.ndarray | None = None,
    ):
        return forward_kinematics(
            params,
            self.cost_at(vector).measurements.actuator_positions,
            start,
            tolerance=self.options.fk_tolerance,
            branch_tolerance_m=self.options.branch_tolerance_m,
            branch_tolerance_rad=self.options.branch_tolerance_rad,
            fit_tilt_first=fit_tilt_first,
        )

    def expected_poses(self, defects: DeviceDefects) -> np.ndarray:
        return self.cost.initial_poses(defects)

    def residuals(self, vector: np.ndarray, poses: np.ndarray) -> ResidualBlock:
        return self.cost_at(vector).residuals(poses, None, _split(vector, self.arch)[1])

    def jacobian(self, vector: np.ndarray, poses: np.ndarray) -> ResidualBlock:
        if self.compliance.active:
            return self._compliant_jacobian(vector, poses)
        params, defects = _split(vector, self.arch)
        # The 5 device columns are only formed when a device defect is identified.
        with_device = bool(self.free[self.n_parameters:].any())
        block = self.cost.residuals(
            poses,
            pose_sensitivities(params, poses),
            defects,
            with_device=with_device,
            with_noise=False,
        )  # noise derivatives: only row_transform's block needs them
        columns = self.free if with_device else self.free[: self.n_parameters]
        if not columns.all():
            assert block.jacobian is not None  # a sensitivity was given: the rows have one
            block.jacobian = block.jacobian[:, columns]
        return block

    def _compliant_jacobian(self, vector: np.ndarray, poses: np.ndarray) -> ResidualBlock:
        """Return the rows with device columns as asked and the compliance columns after them."""
        params, defects = _split(vector, self.arch)
        n, offset = self.n_parameters, self._offset()
        with_device = bool(self.free[n:offset].any())
        assert self.loads is not None  # _run evaluates them before the solver starts
        block = self.cost_at(vector).residuals(
            poses, pose_sensitivities(params, poses), defects, with_device=True, with_noise=True
        )
        assert block.jacobian is not None
        extra = self.compliance.columns(block, self.loads, n + DL)
        kept = [self.free[:n]] + ([self.free[n:offset]] if with_device else [])
        columns = np.concatenate(kept + [self.free[offset:]])
        jacobian = block.jacobian if with_device else block.jacobian[:, :n]
        block.jacobian = np.hstack([jacobian, extra])[:, columns]
        block.noise_jacobian = None  # only row_transform's block needs them
        return block

    def with_prior(self, block: ResidualBlock, vector: np.ndarray) -> ResidualBlock:
        """Return ``block`` (weighted) plus one row (value - prior) / std per device prior."""
        block = self._with_compliance_prior(block, vector)
        prior = self.options.device_prior
        if not prior:
            return block
        unknowns = self.n_parameters + prior.indices
        values = (vector[unknowns] - prior.values) / prior.stds
        jacobian = None
        if block.jacobian is not None:
            column = (
                np.cumsum(self.free) - 1
            )  # the prior's parameters are free: their device columns exist
            jacobian = np.zeros((len(values), block.jacobian.shape[1]))
            jacobian[np.arange(len(values)), column[unknowns]] = 1.0 / prior.stds
            jacobian = np.vstack([block.jacobian, jacobian])
        channels = np.array([f'prior.{name}' for name in prior.names])
        return ResidualBlock(
            np.concatenate([block.values, values]),
            jacobian,
            np.concatenate([block.channels, channels]),
            np.concatenate([block.postures, np.full(len(values), -1)]),
        )

    def _with_compliance_prior(self, block: ResidualBlock, vector: np.ndarray) -> ResidualBlock:
        """Return ``block`` plus one row (value - prior) / std per compliance prior."""
        indices, prior_values, stds = self.compliance.prior_rows()
        if not self.compliance.active or not len(indices):
            return block
        unknowns = self._offset() + indices
        values = (vector[unknowns] - prior_values) / stds
        jacobian = None
        if block.jacobian is not None:
            column = np.cumsum(self.free) - 1
            jacobian = np.zeros((len(values), block.jacobian.shape[1]))
            free = self.free[unknowns]
            jacobian[np.flatnonzero(free), column[unknowns[free]]] = 1.0 / stds[free]
            jacobian = np.vstack([block.jacobian, jacobian])
        names = self.compliance.names
        channels = np.array([f'prior.compliance.{names[k]}' for k in indices])
        return ResidualBlock(
            np.concatenate([block.values, values]),
            jacobian,
            np.concatenate([block.channels, channels]),
            np.concatenate([block.postures, np.full(len(values), -1)]),
        )

    def row_transform(
        self, vector: np.ndarray, poses: np.ndarray, robust: bool = True
    ) -> '_RowTransform':
        """Return row weights here: noise whitening and/or robust weights (None if neither)."""
        loss = self.options.robust_loss if robust else None
        variances = self.variances()
        if variances is None and loss is None:
            return _RowTransform()
        params, defects = _split(vector, self.arch)
        raw = self.cost_at(vector).residuals(
            poses, pose_sensitivities(params, poses), defects, with_device=True
        )
        return _RowTransform(raw, variances, loss)

    def variances(self) -> np.ndarray | None:
        """
        Return the variances of the 9 readings: (9,) shared, (P, 9) per posture, or None.

        The noise model's are shared by every posture; the postures' scatter gives each used
        posture its own (standard errors raised to the floor, squared).
        """
        if self.options.scatter_weights:
            errors = self.cost.measurements.standard_errors
            assert errors is not None  # _identify_once refuses scatter weights without them
            return self.options.scatter_floor.apply(errors) ** 2
        if self.options.noise is not None:
            return self.options.noise.standard_deviations() ** 2
        return None

    def row_count(self, defects: DeviceDefects) -> int:
        return (
            len(self.cost.residuals(self.expected_poses(defects), None, defects).values)
            if len(self.used)
            else 0
        )

    def check_enough(self, set_aside: dict[int, str]) -> None:
        n_free = int(self.free.sum())
        rows = self.row_count(self.options.device_defects)
        if rows < n_free:
            raise TooFewPosturesError(
                f'{len(self.used)} usable posture(s) give {rows} residuals for {n_free} unknowns '
                f'with the {self.options.cost} cost function ({len(set_aside)} posture(s) set '
                'aside); measure more postures'
            )


class _RowTransform:
    """Fixed row weighting for one LM run: whitening by the reading noise, then robust weights."""

    def __init__(
        self,
        block: ResidualBlock | None = None,
        variances: np.ndarray | None = None,
        robust_loss: str | None = None,
    ):
        self.whitener = (
            _Whitener(block, variances) if (variances is not None and block is not None) else None
        )
        self.robust = None
        if robust_loss is not None and block is not None:
            values = self.whitener.apply_values(block.values) if self.whitener else block.values
            self.robust = _robust_weights(values, robust_loss)

    def values(self, block: ResidualBlock) -> np.ndarray:
        values = self.whitener.apply_values(block.values) if self.whitener else block.values
        return values * self.robust if self.robust is not None else values

    def apply(self, block: ResidualBlock) -> ResidualBlock:
        assert block.jacobian is not None  # only blocks with a Jacobian are weighted whole
        jacobian = self.whitener.apply_matrix(block.jacobian) if self.whitener else block.jacobian
        if self.robust is not None:
            jacobian = jacobian * self.robust[:, None]
        return ResidualBlock(self.values(block), jacobian, block.channels, block.postures)


def _row_variances(g: np.ndarray, variances: np.ndarray, postures: np.ndarray) -> np.ndarray:
    """
    Return each row's variance g diag(v) g^T from its noise derivatives g (R, 9).

    v is the (9,) variances every posture shares, or row r's posture's own
    (``variances[postures[r]]`` of (P, 9)).  Each case keeps its own einsum: the
    shared one's results stay bit-for-bit those of earlier releases.
    """
    if variances.ndim == 1:
        return np.einsum('rk,k,rk->r', g, variances, g)
    return np.einsum('rk,rk,rk->r', g, variances[postures], g)


def _group_covariances(g: np.ndarray, variances: np.ndarray, postures: np.ndarray) -> np.ndarray:
    """Return the (P, k, k) covariances of groups of k rows, g (P, k, 9); see _row_variances."""
    if variances.ndim == 1:
        return np.einsum('pik,k,pjk->pij', g, variances, g)
    return np.einsum('pik,pk,pjk->pij', g, variances[postures], g)


class _Whitener:
    """
    Per-posture inverse Cholesky factors of the covariance that reading noise gives the rows.

    Rows of one posture (phi and position, or phi and link length) share its
    slider noise through FK, so they are whitened together; rows of the relative
    cost pair two postures and are scaled by their own standard deviation (the
    correlation between consecutive differences is left out).  ``variances``: of
    the 9 readings, (9,) shared by every posture (a noise model) or (P, 9) per
    posture of the problem (its measured scatter), indexed by the rows' postures.
    """

    def __init__(self, block: ResidualBlock, variances: np.ndarray):
        if block.noise_jacobian is None:
            raise InvalidMeasurementError("noise weighting needs the rows' noise derivatives")
        paired = (
            block.partners >= 0
            if block.partners is not None
            else np.zeros(len(block.values), bool)
        )
        self.scales = np.ones(len(block.values))
        if np.any(paired):
            # Rows get partners together with their partners' noise derivatives (residuals.py).
            assert block.partner_noise_jacobian is not None and block.partners is not None
            own = _row_variances(
                block.noise_jacobian[paired], variances, block.postures[paired]
            )
            partner = _row_variances(
                block.partner_noise_jacobian[paired], variances, block.partners[paired]
            )
            self.scales[paired] = 1.0 / np.sqrt(own + partner)
        self.groups: list[
            tuple[np.ndarray, np.ndarray]
        ] = []  # (row indices (P, k), inverse factors (P, k, k))
        single = np.flatnonzero(~paired)
        postures = block.postures[single]
        order = np.argsort(postures, kind='stable')
        single, postures = single[order], postures[order]
        _, starts, counts = np.unique(postures, return_index=True, return_counts=True)
        for size in np.unique(counts):
            rows = np.stack([single[s:s + size] for s, c in zip(starts, counts) if c == size])
            g = block.noise_jacobian[rows]  # (P, k, 9)
            covariance = _group_covariances(g, variances, block.postures[rows[:, 0]])
            covariance += np.eye(size) * 1e-30  # rows with no noise at all would be singular
            self.groups.append((rows, np.linalg.inv(np.linalg.cholesky(covariance))))

    def apply_values(self, values: np.ndarray) -> np.ndarray:
        out = values * self.scales
        for rows, factor in self.groups:
            out[rows] = np.einsum('pij,pj->pi', factor, values[rows])
        return out

    def apply_matrix(self, matrix: np.ndarray) -> np.ndarray:
        out = matrix * self.scales[:, None]
        for rows, factor in self.groups:
            out[rows] = np.einsum('pij,pjc->pic', factor, matrix[rows])
        return out


def _robust_weights(values: np.ndarray, loss: str) -> np.ndarray:
    """Return square roots of IRLS weights; the scale is a MAD estimate of the inlier spread."""
    # Kept by hand: least_squares' losses take a fixed f_scale, this re-estimates it each round.
    scale = 1.4826 * np.median(np.abs(values)) + 1e-300
    if loss == 'huber':
        z = np.abs(values) / (1.345 * scale)
        weights = np.where(z <= 1.0, 1.0, 1.0 / np.maximum(z, 1e-300))
    else:
        z = values / scale
        weights = 1.0 / np.sqrt(1.0 + z**2)
    return np.sqrt(weights)


def _identify_once(
    nominal: KinematicParameters, measurements: Measurements, options: SolverOptions
) -> IdentificationResult:
    """
    Identify the parameters (and chosen device defects) from measured postures.

    The solve starts from ``nominal``.  Postures whose forward kinematics fails (with the nominal
    parameters, or at a trial step near a singularity of the current model) are set aside; once the
    parameters have converged they are tried again and, where FK now succeeds, the solve continues
    with them.  Postures whose residual stands out (``outlier_threshold``) are excluded and
    reported.  Raises InvalidMeasurementError, TooFewPosturesError or RankDeficientError (each with
    a ``reason``); otherwise returns a result whose ``reason`` is 'converged', 'iteration-limit' or
    'diverged'.
    """
    started = time.perf_counter()
    n_parameters = nominal.layout.n_parameters
    options.validate(n_parameters)
    measurements.validate(options.limits, nominal.layout.actuator_unit)
    if options.scatter_weights and measurements.standard_errors is None:
        raise InvalidMeasurementError(
            "weighing by the postures' scatter needs the standard errors of every posture; "
            'these postures carry none: weigh by a noise model, or not at all'
        )
    free = options.free_mask(n_parameters)
    options.compliance.validate(options.cost, len(measurements))
    start = np.concatenate([nominal.vector, options.device_defects.vector])
    if options.compliance.active:
        start = np.concatenate([start, options.compliance.start()])
    start[n_parameters + options.device_prior.indices] = (
        options.device_prior.values
    )  # start at the prior
    cost = CostFunction(options.cost, measurements, options.device, options.sigma)
    missing = cost.missing_postures()
    if missing is not None:
        raise TooFewPosturesError(missing)
    usable = cost.usable()
    unused = {
        int(i): f'not used by the {options.cost} cost function' for i in np.flatnonzero(~usable)
    }
    # Small dense problems run fastest on one BLAS thread; more threads only add contention.
    with _blas_controller().limit(limits=1, user_api='blas'):
        problem, poses, set_aside = _admit(
            start,
            _Problem(measurements, np.flatnonzero(usable), options, free, nominal.architecture),
            'with the nominal parameters',
        )
        problem.check_enough({**unused, **set_aside})
        solver = _run(problem, start, poses, options)
        initial_block, iterations = solver.initial_block, solver.iterations
        previous = start
        for round_number in range(MAX_ROUNDS):
            set_aside.update(solver.dropped)
            problem, vector, poses = solver.problem, solver.vector, solver.poses
            changed = False
            if solver.reason == CONVERGED:
                problem, poses, changed = _readmit(problem, vector, poses, set_aside, options)
            outliers = _outliers(problem, vector, poses, options)
            if outliers:
                set_aside.update(outliers)
                outlying = np.isin(problem.used, list(outliers))
                problem, poses = problem.without(np.flatnonzero(outlying)), poses[~outlying]
                problem.check_enough({**unused, **set_aside})
                changed = True
            # Noise weights depend on the poses: refit them once at the solution. Robust weights
            # depend on the residuals: iterate (IRLS) until the solution stops moving.
            moved = float(np.max(np.abs(vector - previous)))
            reweight = (round_number == 0 and options.weights != Weights.NONE) or (
                options.robust_loss is not None and moved > IRLS_TOLERANCE
            )
            # Compliances: the loads were held through the run; run again while they move.
            reweight = reweight or problem.loads_moved(vector, poses)
            if not changed and not reweight:
                break
            previous = vector
            solver = _run(problem, vector, poses, options)
            iterations += solver.iterations
        solver.iterations, solver.initial_block = iterations, initial_block
        result = solver.result(nominal, {**unused, **set_aside}, started)
    if not result.identifiability.identifiable and not options.allow_rank_deficient:
        # Identifiable at the start but not at the solution: the apparent information came from the
        # nominal model's errors, not from the data. Refuse rather than return a number that means
        # nothing.
        raise RankDeficientError(
            'at the identified parameters the measurements do not determine every parameter: '
            + result.identifiability.verdict(),
            result.identifiability,
        )
    return result


def identify(
    nominal: KinematicParameters,
    measurements: Measurements,
    options: SolverOptions = SolverOptions(),
) -> IdentificationResult:
    """
    Identify the parameters (and chosen device defects) from measured postures.

    The solve starts from ``nominal``.  See ``_identify_once`` for the procedure.  With
    ``allow_rank_deficient`` a problem found rank-deficient is solved again from the start with the
    unknowns the analysis names held at their start values (fixing the gauge: a minimum-norm step
    would still drift along the unseen directions); the result reports them in
    ``held_for_identifiability`` and its identifiability analysis covers everything that was asked
    for.
    """
    result = _identify_once(nominal, measurements, options)
    if result.identifiability.identifiable or not options.allow_rank_deficient:
        return result
    held = result.identifiability.unidentifiable_parameters
    n = nominal.layout.n_parameters
    compliance = options.compliance
    free = options.free_mask(n) & ~np.isin(unknown_names(nominal.model, compliance), held)
    offset = n + N_DEVICE_PARAMETERS
    reduced = replace(
        options,
        free_parameters=tuple(bool(f) for f in free[:n]),
        free_device=tuple(name for name, f in zip(DEVICE_PARAMETER_NAMES, free[n:offset]) if f),
        compliance=replace(
            compliance,
            held=tuple(
                name for name, f in zip(compliance.names, free[offset:]) if not f
            ),
        ),
    )
    again = _identify_once(nominal, measurements, reduced)
    again.identifiability, again.rank = result.identifiability, result.rank
    again.held_for_identifiability = held
    again.std[np.isin(parameter_names(nominal.model), held)] = np.nan
    for name in again.compliance_std:
        if compliance.unknown_names and f'compliance.{name}' in held:
            again.compliance_std[name] = float('nan')
    return again


def _run(
    problem: '_Problem', vector: np.ndarray, poses: np.ndarray, options: SolverOptions
) -> '_LeastSquares':
    if problem.update_loads(vector, poses):  # compliances: loads held through the run
        # The corrected readings changed with the loads: start from their own FK poses.
        fk = problem.solve_fk(_split(vector, problem.arch)[0], poses, vector=vector)
        poses = np.where(fk.converged[:, None], fk.poses, poses)
    solver = _LeastSquares(problem, vector, poses, problem.row_transform(vector, poses))
    solver.run()
    return solver


def _admit(vector: np.ndarray, problem: '_Problem', context: str):
    """Solve FK from the expected postures; keep those that converge, set the others aside."""
    params, defects = _split(vector, problem.arch)
    fk = problem.solve_fk(
        params, problem.expected_poses(defects), fit_tilt_first=True, vector=vector
    )
    failed = sorted(fk.failures)
    set_aside = {
        int(problem.used[i]): f'forward kinematics {context}: {fk.failures[i]}' for i in failed
    }
    return problem.without(failed), fk.poses[fk.converged], set_aside


def _readmit(
    problem: '_Problem',
    vector: np.ndarray,
    poses: np.ndarray,
    set_aside: dict[int, str],
    options: SolverOptions,
) -> tuple['_Problem', np.ndarray, bool]:
    """Retry set-aside FK failures with the identified parameters; keep those that now pass."""
    retry_indices = np.array(
        sorted(i for i, why in set_aside.items() if why.startswith('forward kinematics'))
    )
    if retry_indices.size == 0:
        return problem, poses, False
    retry = _Problem(problem.measurements, retry_indices, options, problem.free, problem.arch)
    readmitted, readmitted_poses, still = _admit(vector, retry, 'with the identified parameters')
    for index in retry_indices:
        set_aside.pop(int(index), None)
    set_aside.update(still)
    if not len(readmitted.used):
        return problem, poses, False
    merged = np.concatenate([problem.used, readmitted.used])
    order = np.argsort(merged)
    merged_poses = np.concatenate([poses, readmitted_poses])[order]
    return (
        _Problem(problem.measurements, merged[order], options, problem.free, problem.arch),
        merged_poses,
        True,
    )


def _outliers(
    problem: '_Problem', vector: np.ndarray, poses: np.ndarray, options: SolverOptions
) -> dict[int, str]:
    """Return postures whose residual stands far above the others' (glitch or wrong FK branch)."""
    if options.outlier_threshold is None or len(poses) < 3:
        return {}
    block = problem.residuals(vector, poses)
    whitened = options.weights != Weights.NONE
    values = block.values
    if whitened:
        values = problem.row_transform(vector, poses, robust=False).values(block)
    count = np.bincount(block.postures, minlength=len(poses))
    rms = np.sqrt(
        np.bincount(block.postures, weights=values**2, minlength=len(poses)) / np.maximum(count, 1)
    )
    typical = np.median(rms) + 1e-300
    if whitened:
        typical = max(
            typical, 1.0
        )  # whitened rows are ~1 by construction; exact data must not make 1e-12 "big"
    floor = 0.0 if whitened else options.outlier_floor
    flagged = np.flatnonzero((rms > options.outlier_threshold * typical) & (rms > floor))
    return {
        int(problem.used[i]): (
            f"outlier: residual {rms[i] / typical:.0f} x the median posture's "
            '(glitched reading or wrong forward-kinematics branch)'
        )
        for i in flagged
    }


class _FailedPostures(Exception):
    """A trial step at which a few postures' FK failed: set them aside and solve on."""

    def __init__(self, failures: dict[int, str]):
        super().__init__(f'{len(failures)} posture(s) failed forward kinematics')
        self.failures = failures


class _IterationLimit(Exception):
    """The solve formed max_iterations Jacobians without converging."""


class _LeastSquares:
    """
    scipy's least_squares (trust-region reflective) on the free unknowns, columns scaled.

    FK is warm-started from the last accepted poses; a trial at which a few postures' FK
    fails sets them aside and restarts from the accepted point.
    """

    def __init__(
        self,
        problem: _Problem,
        start: np.ndarray,
        poses: np.ndarray,
        transform: _RowTransform | None = None,
    ):
        self.problem = problem
        self.options = problem.options
        self.free = problem.free
        self.transform = transform or _RowTransform()
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
        return _split(self.vector, self.problem.arch)[0]

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
        self.normal = _NormalEquations.of(self.block, self.scales, self.options.rank_tolerance)

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
            params, _ = _split(vector, self.problem.arch)
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
                params = _split(vector, self.problem.arch)[0]
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
        covariance, variance_factor = _covariance(
            self.normal, len(self.block.values), self.scales, self.free, known_noise=whitened
        )
        std_all = np.sqrt(np.diag(covariance))
        std_all[~self.free] = np.nan
        std_all[np.isinf(std_all)] = np.nan
        params, defects = _split(self.vector, self.problem.arch)
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
class _NormalEquations:
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
    ) -> '_NormalEquations':
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


def _covariance(
    normal: _NormalEquations,
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


__all__ = [
    'CONVERGED',
    'DIVERGED',
    'ITERATION_LIMIT',
    'N_NOISE_SOURCES',
    'IdentificationResult',
    'InvalidMeasurementError',
    'SolverOptions',
    'identify',
    'unknown_names',
]
