"""
The postures in use and what a solve evaluates on them: FK, residuals, Jacobian, prior rows.

The unknown vector is the architecture's kinematic parameters, the 5 device defects, then the
compliances when they are identified (``split_unknowns``).  ``FitProblem`` holds the postures
one solver run uses and their static loads (compliance.py).
"""

from __future__ import annotations

import numpy as np

from .compliance import ComplianceModel, LOADS_TOLERANCE_M
from .residuals import CostFunction, DL, ResidualBlock
from .row_weights import RowTransform
from .solver_options import SolverOptions
from .statics import StaticLoads
from ..architectures import Architecture, KinematicParameters
from ..errors import TooFewPosturesError
from ..machine.device import DeviceDefects, N_DEVICE_PARAMETERS
from ..machine.kinematics import forward_kinematics, pose_sensitivities
from ..machine.measurements import Measurements


def split_unknowns(
    vector: np.ndarray, arch: Architecture
) -> tuple[KinematicParameters, DeviceDefects]:
    """Split the unknown vector into the architecture's parameters and the 5 device defects."""
    n = arch.layout.n_parameters
    return arch.parameters(vector[:n]), DeviceDefects.from_vector(
        vector[n:n + N_DEVICE_PARAMETERS]
    )


class FitProblem:
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
        # Static loads of the used postures, held through a solver run (compliance.py), and the
        # parameters and poses they were evaluated at: where the loads move with the
        # compliances (the compliant mode's sharing) they are evaluated there at each vector's.
        self.loads: StaticLoads | None = None
        self._load_basis: tuple[KinematicParameters, np.ndarray] | None = None
        self._compliant_cost: tuple[bytes, CostFunction, StaticLoads] | None = None

    def without(self, local_indices) -> 'FitProblem':
        keep = np.setdiff1d(np.arange(len(self.used)), list(local_indices))
        problem = FitProblem(
            self.measurements, self.used[keep], self.options, self.free, self.arch
        )
        if self.loads is not None:
            problem.loads = self.loads.subset(keep)
        if self._load_basis is not None:
            problem._load_basis = (self._load_basis[0], self._load_basis[1][keep])
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
            loads = self._held_loads(values)
            corrected = self.compliance.corrected(
                self.cost.measurements, loads, values, self.options.device.link_length
            )
            self._compliant_cost = (
                key,
                CostFunction(
                    self.options.cost, corrected, self.options.device, self.options.sigma
                ),
                loads,
            )
        return self._compliant_cost[1]

    def _held_loads(self, values: np.ndarray) -> StaticLoads:
        """Return the held loads, at the compliances ``values`` where they move with them."""
        assert self.loads is not None
        if self._load_basis is None or not self.compliance.shares_by_values:
            return self.loads
        params, poses = self._load_basis
        return self.compliance.loads(params, poses, self.used, values)

    def update_loads(self, vector: np.ndarray, poses: np.ndarray) -> bool:
        """Evaluate the loads at ``poses``; return whether a deflection moved (compliance.py)."""
        moved, loads = self._loads_at(vector, poses)
        if moved:
            self.loads, self._compliant_cost = loads, None
            self._load_basis = (split_unknowns(vector, self.arch)[0], np.array(poses))
        return moved

    def loads_moved(self, vector: np.ndarray, poses: np.ndarray) -> bool:
        """Return whether the loads at ``poses`` move a deflection from those held."""
        return self._loads_at(vector, poses)[0]

    def _loads_at(self, vector: np.ndarray, poses: np.ndarray):
        if not self.compliance.active:
            return False, None
        values = vector[self._offset():]
        loads = self.compliance.loads(
            split_unknowns(vector, self.arch)[0], poses, self.used, values
        )
        if self.loads is None:
            return True, loads
        old = self.compliance.deflections(self._held_loads(values), values)
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
        return self.cost_at(vector).residuals(poses, None, split_unknowns(vector, self.arch)[1])

    def jacobian(self, vector: np.ndarray, poses: np.ndarray) -> ResidualBlock:
        if self.compliance.active:
            return self._compliant_jacobian(vector, poses)
        params, defects = split_unknowns(vector, self.arch)
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
        params, defects = split_unknowns(vector, self.arch)
        n, offset = self.n_parameters, self._offset()
        with_device = bool(self.free[n:offset].any())
        assert self.loads is not None  # _run evaluates them before the solver starts
        block = self.cost_at(vector).residuals(
            poses, pose_sensitivities(params, poses), defects, with_device=True, with_noise=True
        )
        assert block.jacobian is not None and self._compliant_cost is not None
        values = vector[offset:]
        loads = self._compliant_cost[2]  # at these compliances: cost_at evaluated them
        moving = None
        if self.compliance.shares_by_values and self._load_basis is not None:
            moving = (values, *self.compliance.load_sensitivities(loads, values))
        extra = self.compliance.columns(block, loads, n + DL, moving)
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
    ) -> 'RowTransform':
        """Return row weights here: noise whitening and/or robust weights (None if neither)."""
        loss = self.options.robust_loss if robust else None
        variances = self.variances()
        if variances is None and loss is None:
            return RowTransform()
        params, defects = split_unknowns(vector, self.arch)
        raw = self.cost_at(vector).residuals(
            poses, pose_sensitivities(params, poses), defects, with_device=True
        )
        if variances is not None and self.compliance.weighs_friction:
            # The released actuator's friction: one more noise source of each posture.
            derivative, variance = self.compliance.friction_noise(
                params, poses, self.used, raw, vector[self._offset():], self.n_parameters + DL
            )
            assert raw.noise_jacobian is not None
            raw.noise_jacobian = np.column_stack([raw.noise_jacobian, derivative])
            extra = np.full(variances.shape[:-1] + (1,), variance)
            variances = np.concatenate([variances, extra], axis=-1)
        return RowTransform(raw, variances, loss)

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
