"""
Build the design problem: the candidates' identification-Jacobian rows at the nominal.

Noise weighting (``noise``, on by default in ``hexacal plan``): each posture's rows
are whitened by the covariance its reading noise propagates to its residuals.
Unweighted, the indices favour postures near singularities, where dX/du is large
but so is the amplified actuator noise; weighted, M is the Fisher information and
sqrt(trace(W M^-1)) is the predicted RMS position error in metres.

Column scaling: every design is scaled by the same column scales, the RMS
per-posture column norm over the whole candidate set, so indices of different
designs compare (a design's own unit-norm scaling would give each design its own
yardstick).  O1's ranking of designs does not depend on the scaling at all.

Planning for an imperfect device (``device_columns``, ``device_prior``,
``procedure``; absolute cost).  The rows gain the columns of the device
parameters identified with the machine, the information starts from the
priors' (1 / std^2 on their columns), and every sphere candidate is offered
once per device turn of the procedure (``studies.device_procedure.PROCEDURES``:
0 / 180 deg, or 0 / 90 / 180 / 270 deg), so the plan chooses which postures
to measure in which mounting..
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .observability import full_rank, index_from_eigenvalues, INDICES, RANK_TOLERANCE
from ..architectures import KinematicParameters
from ..fit.residuals import ChannelSigma, CostFunction, COSTS
from ..machine.device import (
    DEVICE_PARAMETER_NAMES,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
    inclinometer_angles,
    STANDING,
)
from ..machine.kinematics import pose_parameter_sensitivity, pose_sensitivities
from ..machine.measurements import NoiseModel, simulate_measurements, SPHERE


@dataclass
class CandidateSet:
    """
    Candidates and their identification-Jacobian rows at the nominal parameters (column-scaled).

    For every cost but 'relative', ``rows[i]`` are posture i's rows (zero-padded to
    the same count).  For 'relative', ``rows[i]`` is posture i's phi row and
    ``difference_rows[i]`` its position (fixed) or link-length (sphere) rows,
    which enter as differences with the previous posture of the same kind.
    """

    poses: np.ndarray
    kinds: np.ndarray
    cost: str
    scales: np.ndarray  # (n,), n = the model's parameters
    rows: np.ndarray  # (N, r, n)
    difference_rows: np.ndarray | None = None  # (N, r', n), relative cost only
    # mean of dP/du^T dP/du over the sphere candidates (column-scaled): what the position error
    # weighs
    position_weight: np.ndarray | None = None
    prior_information: np.ndarray | None = (
        None  # (n, n) information of the device priors (column-scaled)
    )
    turns: np.ndarray | None = None  # (N,) device turn of each candidate, rad (None: all normal)
    device_columns: tuple[
        str, ...
    ] = ()  # device parameters after the model's, in DEVICE_PARAMETER_NAMES order

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def n_parameters(self) -> int:
        return len(self.scales)

    @property
    def relative(self) -> bool:
        return self.difference_rows is not None

    def slot_rows(
        self, candidates: np.ndarray, previous: np.ndarray, following: np.ndarray
    ) -> np.ndarray:
        """
        Return the rows each candidate adds in a plan slot between ``previous`` and ``following``.

        ``previous`` and ``following`` are design entries of the same kind; -1 = none.
        """
        candidates = np.asarray(candidates, dtype=int)
        own = self.rows[candidates]
        if not self.relative:
            return own
        previous = np.broadcast_to(previous, candidates.shape)
        following = np.broadcast_to(following, candidates.shape)
        diff = self.difference_rows
        assert diff is not None  # relative cost: set by build_candidate_set
        before = np.where(
            (previous >= 0)[:, None, None], diff[candidates] - diff[np.maximum(previous, 0)], 0.0
        )
        after = np.where(
            (following >= 0)[:, None, None], diff[np.maximum(following, 0)] - diff[candidates], 0.0
        )
        return np.concatenate([own, before, after], axis=1)

    def design_jacobian(self, design: np.ndarray) -> np.ndarray:
        """Stacked (scaled) rows of a plan, in plan order."""
        design = np.asarray(design, dtype=int)
        blocks = []
        for slot, candidate in enumerate(design):
            previous, following = kind_neighbours(self.kinds, design, slot)
            rows = self.slot_rows(np.array([candidate]), np.array([previous]), np.array([-1]))[0]
            blocks.append(rows)
        stacked = np.concatenate(blocks) if blocks else np.zeros((0, self.n_parameters))
        return stacked[np.any(stacked != 0.0, axis=1)]

    def information(self, design: np.ndarray) -> np.ndarray:
        jacobian = self.design_jacobian(design)
        return jacobian.T @ jacobian + self.start_information()

    def start_information(self) -> np.ndarray:
        """Return the information before any posture: the device priors' (zero without priors)."""
        if self.prior_information is not None:
            return self.prior_information.copy()
        return np.zeros((self.n_parameters, self.n_parameters))

    def rank(self, design: np.ndarray) -> int:
        eigenvalues = np.linalg.eigvalsh(self.information(design))
        return int(np.sum(eigenvalues > RANK_TOLERANCE * eigenvalues[-1]))

    def indices(self, design: np.ndarray) -> dict[str, float]:
        """O1..O4 of a plan (on this set's column scales)."""
        eigenvalues = np.linalg.eigvalsh(self.information(design))
        return {
            name: float(index_from_eigenvalues(eigenvalues, len(design), name))
            for name in INDICES
        }

    def predicted_position_error(self, design: np.ndarray) -> float:
        """
        sqrt(trace(W M^-1)): predicted RMS position error over the workspace, linearised.

        In metres when the rows are noise-weighted (M is then the Fisher information),
        per unit residual noise otherwise; infinite when the plan is rank deficient.
        """
        information = self.information(design)
        if not full_rank(information):
            return float('inf')
        return float(np.sqrt(np.trace(self.position_weight @ np.linalg.inv(information))))


def kind_neighbours(kinds: np.ndarray, design: np.ndarray, slot: int) -> tuple[int, int]:
    """Previous and next design entries of the same kind as design[slot] (-1 = none)."""
    kind = kinds[design[slot]]
    same_before = [c for c in design[:slot] if kinds[c] == kind]
    after = slot + 1
    same_after = [c for c in design[after:] if kinds[c] == kind]
    return (int(same_before[-1]) if same_before else -1, int(same_after[0]) if same_after else -1)


def build_candidate_set(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: np.ndarray,
    cost: str = 'absolute',
    device: DeviceModel = DeviceModel(),
    sigma: ChannelSigma = ChannelSigma(),
    noise: NoiseModel | None = None,
    device_columns: tuple[str, ...] = (),
    device_prior: DevicePrior = DevicePrior(),
    turns: np.ndarray | None = None,
) -> CandidateSet:
    """
    Return the analytic identification-Jacobian rows of every candidate.

    The rows come from pose_parameter_sensitivity and the CostFunction.

    With ``noise``, each posture's rows are whitened by the covariance the reading
    noise propagates to its residuals (actuator noise through FK, inclinometer
    noise through eq. 4, rotary noise): near a singularity a posture's rows look
    large, but so does its actuator noise, and whitening tells the two apart.
    Not for the relative cost (its rows mix two postures' noise).
    """
    if cost not in COSTS:
        raise ValueError(f'unknown cost function {cost!r}; choose one of {", ".join(COSTS)}')
    if noise is not None and cost == 'relative':
        raise ValueError('noise weighting of the plan is not available for the relative cost')
    if device_columns or device_prior or turns is not None:
        return _device_candidate_set(
            nominal, poses, kinds, cost, device, sigma, noise, device_columns, device_prior, turns
        )
    # At the nominal parameters the commanded pose is where the model puts the platform,
    # so noise-free simulated readings there are the expected measurements.
    measurements = simulate_measurements(nominal, poses, kinds, device)
    sensitivity, legs = pose_parameter_sensitivity(nominal, poses)
    own_cost = 'sphere-fixed' if cost == 'relative' else cost
    function = CostFunction(own_cost, measurements, device, sigma)
    block = function.residuals(poses, sensitivity)
    jacobian = block.jacobian
    assert jacobian is not None  # residuals() computed it from the sensitivity
    phi = block.channels == 'phi'
    if cost == 'relative':
        rows = _rows_per_posture(jacobian[phi], block.postures[phi], len(poses))
        difference = _rows_per_posture(jacobian[~phi], block.postures[~phi], len(poses))
        stacked = np.concatenate([rows, difference], axis=1)
    else:
        rows = _rows_per_posture(jacobian, block.postures, len(poses))
        difference = None
        if noise is not None:
            rows = _whiten(rows, _noise_rows(function, poses, legs, block, sigma, device), noise)
        stacked = rows
    # RMS per-posture column norm over all candidates: one yardstick for every design.
    norms = np.sqrt(np.einsum('nrk,nrk->k', stacked, stacked) / max(len(poses), 1))
    scales = np.where(norms > 0, norms, 1.0)
    # Validation postures are drawn like the sphere candidates: their mean dP/du^T dP/du weighs the
    # error.
    sphere = np.asarray(kinds) == SPHERE
    position = sensitivity[sphere if np.any(sphere) else slice(None), :3, :]
    weight = np.einsum('nik,nil->kl', position, position) / max(len(position), 1)
    return CandidateSet(
        poses,
        np.asarray(kinds).astype(str),
        cost,
        scales,
        rows / scales,
        None if difference is None else difference / scales,
        weight / np.outer(scales, scales),
    )


def _device_candidate_set(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: np.ndarray,
    cost: str,
    device: DeviceModel,
    sigma: ChannelSigma,
    noise: NoiseModel | None,
    device_columns: tuple[str, ...],
    device_prior: DevicePrior,
    turns: np.ndarray | None,
) -> CandidateSet:
    """Return candidates with device columns, priors and turns (module doc): absolute-cost rows."""
    if cost != 'absolute':
        raise ValueError(
            'planning for device parameters or device turns needs the absolute cost (eq. 7), '
            f'got {cost}'
        )
    if device_prior and noise is None:
        raise ValueError(
            'a device prior is weighed against the reading noise: plan with the noise model'
        )
    columns = tuple(
        name
        for name in DEVICE_PARAMETER_NAMES
        if name in set(device_columns) | set(device_prior.names)
    )
    measurements = simulate_measurements(nominal, poses, kinds, device, device_turn=turns)
    sensitivity = pose_sensitivities(nominal, poses)
    function = CostFunction(cost, measurements, device, sigma)
    block = function.residuals(poses, sensitivity, DeviceDefects(), with_device=True)
    assert block.jacobian is not None  # residuals() computed it from the sensitivities
    n = nominal.layout.n_parameters
    keep = np.concatenate([np.ones(n, bool), np.isin(DEVICE_PARAMETER_NAMES, columns)])
    rows = _rows_per_posture(block.jacobian[:, keep], block.postures, len(poses))
    if noise is not None:
        assert block.noise_jacobian is not None  # residuals() computes it with the device
        rows = _whiten(
            rows, _rows_per_posture(block.noise_jacobian, block.postures, len(poses)), noise
        )
    norms = np.sqrt(np.einsum('nrk,nrk->k', rows, rows) / max(len(poses), 1))
    scales = np.where(norms > 0, norms, 1.0)
    sphere = np.asarray(kinds) == SPHERE
    position = sensitivity.wrt_parameters[sphere if np.any(sphere) else slice(None), :3, :]
    weight = np.zeros((len(scales), len(scales)))
    weight[:n, :n] = np.einsum('nik,nil->kl', position, position) / max(len(position), 1)
    prior = np.zeros_like(weight)
    for name, _, std in device_prior.entries:
        column = n + columns.index(name)
        prior[column, column] = 1.0 / std**2
    scale_square = np.outer(scales, scales)
    return CandidateSet(
        poses,
        np.asarray(kinds).astype(str),
        cost,
        scales,
        rows / scales,
        None,
        weight / scale_square,
        prior / scale_square if device_prior else None,
        None if turns is None else np.asarray(turns, dtype=float),
        columns,
    )


def _noise_rows(
    function: CostFunction,
    poses: np.ndarray,
    legs,
    block,
    sigma: ChannelSigma,
    device: DeviceModel,
) -> np.ndarray:
    """
    Return d residual / d readings (rows, 9).

    The readings are the 6 actuators, alpha, beta, phi, in the order of ``block``'s rows.
    """
    actuator_sensitivity = np.linalg.inv(legs.pose_jacobian())  # dX / d lambda
    wrt_actuators = function.residuals(poses, actuator_sensitivity).jacobian
    assert wrt_actuators is not None  # computed from the sensitivity given
    wrt_readings = np.zeros((len(block.channels), 3))
    is_phi = block.channels == 'phi'
    wrt_readings[is_phi, 2] = 1.0 / sigma.angle_rad  # r = phi_m - phi_c
    measured_xyz = np.isin(block.channels, ('x', 'y', 'z')) & (function.cost == 'absolute')
    if np.any(measured_xyz):  # eq. 4: the measured position moves with alpha and beta
        alpha, beta = inclinometer_angles(poses[:, :3], device.mount)
        # eq. 4's derivatives; a standing link's end is p = -p_hanging(alpha, beta) (device.py)
        length = -device.link_length if device.mount == STANDING else device.link_length
        d_alpha = np.column_stack(
            [
                -length * np.sin(alpha) * np.sin(beta),
                -length * np.cos(alpha),
                length * np.sin(alpha) * np.cos(beta),
            ]
        )
        d_beta = np.column_stack(
            [
                length * np.cos(alpha) * np.cos(beta),
                np.zeros_like(alpha),
                length * np.cos(alpha) * np.sin(beta),
            ]
        )
        axis = np.searchsorted(['x', 'y', 'z'], block.channels[measured_xyz])
        posture = block.postures[measured_xyz]
        wrt_readings[measured_xyz, 0] = d_alpha[posture, axis] / sigma.position_m
        wrt_readings[measured_xyz, 1] = d_beta[posture, axis] / sigma.position_m
    return _rows_per_posture(
        np.column_stack([wrt_actuators, wrt_readings]), block.postures, len(poses)
    )


def _whiten(rows: np.ndarray, noise_rows: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """Return L^-1 rows per posture, L L^T the residual covariance (padding: unit variance)."""
    actuators = noise_rows.shape[2] - 3  # the readings: one per actuator, then alpha, beta, phi
    std = np.array([noise.actuator_m] * actuators + [noise.angle_rad] * 3) / np.sqrt(
        3.0
    )  # +-a uniform
    weighted = noise_rows * std
    covariance = weighted @ weighted.transpose(0, 2, 1)
    padding = ~np.any(rows != 0.0, axis=2) & ~np.any(noise_rows != 0.0, axis=2)
    covariance += np.einsum('nr,rs->nrs', padding.astype(float), np.eye(rows.shape[1]))
    return np.linalg.solve(np.linalg.cholesky(covariance), rows)


def _rows_per_posture(jacobian: np.ndarray, postures: np.ndarray, n: int) -> np.ndarray:
    """Scatter Jacobian rows into (n, max rows per posture, columns), zero-padded."""
    order = np.argsort(postures, kind='stable')
    postures = postures[order]
    counts = np.bincount(postures, minlength=n)
    width = int(counts.max()) if len(counts) else 0
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    position = np.arange(len(postures)) - starts[postures]
    out = np.zeros((n, max(width, 1), jacobian.shape[1]))
    out[postures, position] = jacobian[order]
    return out
