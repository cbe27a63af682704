"""
Row weights of one solver run: whitening by the reading noise, then robust (IRLS) weights.

A posture's rows share its reading noise through eq. 4 and FK: ``Whitener`` whitens them by
the covariance it gives them (a noise model shared by every posture, or each posture's own
measured scatter); ``RowTransform`` applies it and a Huber or soft-L1 weight per row.
"""

from __future__ import annotations

import numpy as np

from .residuals import ResidualBlock
from ..errors import InvalidMeasurementError


class RowTransform:
    """Fixed row weighting for one LM run: whitening by the reading noise, then robust weights."""

    def __init__(
        self,
        block: ResidualBlock | None = None,
        variances: np.ndarray | None = None,
        robust_loss: str | None = None,
    ):
        self.whitener = (
            Whitener(block, variances) if (variances is not None and block is not None) else None
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


class Whitener:
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
