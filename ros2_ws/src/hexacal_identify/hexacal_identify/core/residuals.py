"""Cost functions of the paper (eqs. 7, 8, 10, 12, 13): residuals and their Jacobians.

Every residual is written ``r(u)`` with Jacobian ``dr/du``; the solver takes the
Gauss-Newton step ``du = -J^+ r``.  Computed quantities come from forward
kinematics with parameters u; dX/du comes from implicit differentiation
(``kinematics.pose_parameter_sensitivity``), never from finite differences.

Cost functions (``COSTS``):

* ``absolute``      eq. 7, every posture: [x_m - x_c, y_m - y_c, z_m - z_c, phi_m - phi_c],
                    with the measured position from the inclinometer (eq. 4).
* ``sphere``        eq. 8, every posture: [L - |P_c|, phi_m - phi_c] (fixed postures lie
                    on the sphere too).
* ``fixed``         eq. 10, fixed-position postures only: [0 - x_c, 0 - y_c, -L - z_c, phi_m - phi_c].
* ``sphere-fixed``  eq. 8 on sphere postures and eq. 10 on fixed-position postures.
* ``relative``      eq. 12 on sphere postures: |P_c^j| - |P_c^k|, and eq. 13 on fixed
                    postures: P_c^j - P_c^k, each for consecutive postures (j = k + 1)
                    of the same kind, plus phi_m - phi_c on every posture.  Differences
                    cancel a link-length or inclinometer offset; the paper leaves the
                    pairing open, consecutive pairs are the choice made here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .device import DeviceModel, measured_position
from .measurements import FIXED, SPHERE, Measurements

COSTS = ("absolute", "sphere", "fixed", "sphere-fixed", "relative")
COST_EQUATIONS = {
    "absolute": "eq. 7",
    "sphere": "eq. 8",
    "fixed": "eq. 10",
    "sphere-fixed": "eqs. 8 + 10",
    "relative": "eqs. 12 + 13",
}


@dataclass(frozen=True)
class ChannelSigma:
    """Noise scale per channel; residual rows are divided by it (1 = unweighted, as the paper)."""

    position_m: float = 1.0
    angle_rad: float = 1.0


@dataclass
class ResidualBlock:
    """Rows of one kind: residual values, Jacobian rows and the channel each row belongs to."""

    values: np.ndarray
    jacobian: np.ndarray | None
    channels: np.ndarray
    postures: np.ndarray  # posture index (into the used set) of each row


class CostFunction:
    """Residuals of one cost function over a fixed set of measured postures."""

    def __init__(self, cost: str, measurements: Measurements, device: DeviceModel, sigma: ChannelSigma):
        if cost not in COSTS:
            raise ValueError(f"unknown cost function {cost!r}; choose one of {', '.join(COSTS)}")
        self.cost = cost
        self.measurements = measurements
        self.link_length = device.link_length
        self.sigma = sigma
        alpha, beta = measurements.inclinometer.T
        self.measured_positions = measured_position(alpha, beta, self.link_length)
        self.fixed_position = np.array([0.0, 0.0, -self.link_length])
        self.is_fixed = measurements.kinds == FIXED
        self.is_sphere = measurements.kinds == SPHERE

    def usable(self) -> np.ndarray:
        """Mask of postures this cost function uses."""
        if self.cost == "fixed":
            return self.is_fixed.copy()
        return np.ones(len(self.measurements), bool)

    def initial_poses(self) -> np.ndarray:
        """Expected postures: measured position and phi, theta = psi = 0 (the FK start and branch reference)."""
        n = len(self.measurements)
        position = np.where(self.is_fixed[:, None], self.fixed_position, self.measured_positions)
        return np.column_stack([position, np.zeros((n, 2)), self.measurements.rotary])

    def residuals(self, poses: np.ndarray, sensitivity: np.ndarray | None) -> ResidualBlock:
        """Stacked residuals (and Jacobian rows when ``sensitivity`` = dX/du is given)."""
        blocks = [self._phi_block(poses, sensitivity)]
        if self.cost == "absolute":
            blocks.append(self._position_block(np.arange(len(poses)), self.measured_positions, poses, sensitivity))
        elif self.cost == "fixed":
            blocks.append(self._fixed_block(poses, sensitivity, np.ones(len(poses), bool)))
        elif self.cost == "sphere":
            blocks.append(self._length_block(poses, sensitivity, np.ones(len(poses), bool)))
        elif self.cost == "sphere-fixed":
            blocks.append(self._length_block(poses, sensitivity, self.is_sphere))
            blocks.append(self._fixed_block(poses, sensitivity, self.is_fixed))
        else:
            blocks.append(self._relative_length_block(poses, sensitivity))
            blocks.append(self._relative_position_block(poses, sensitivity))
        return _stack(blocks)

    # -- blocks -----------------------------------------------------------------
    def _phi_block(self, poses, sensitivity):
        index = np.arange(len(poses))
        values = (self.measurements.rotary - poses[:, 5]) / self.sigma.angle_rad
        jac = None if sensitivity is None else -sensitivity[:, 5, :] / self.sigma.angle_rad
        return ResidualBlock(values, jac, np.full(len(index), "phi"), index)

    def _position_block(self, index, targets, poses, sensitivity):
        values = ((targets[index] - poses[index, :3]) / self.sigma.position_m).reshape(-1)
        jac = None
        if sensitivity is not None:
            jac = (-sensitivity[index, :3, :] / self.sigma.position_m).reshape(-1, sensitivity.shape[2])
        channels = np.tile(np.array(["x", "y", "z"]), len(index))
        return ResidualBlock(values, jac, channels, np.repeat(index, 3))

    def _fixed_block(self, poses, sensitivity, mask):
        index = np.flatnonzero(mask)
        targets = np.broadcast_to(self.fixed_position, poses.shape[:1] + (3,))
        return self._position_block(index, targets, poses, sensitivity)

    def _lengths(self, poses, sensitivity, index):
        position = poses[index, :3]
        length = np.linalg.norm(position, axis=1)
        jac = None
        if sensitivity is not None:
            jac = np.einsum("ni,nik->nk", position / length[:, None], sensitivity[index, :3, :])
        return length, jac

    def _length_block(self, poses, sensitivity, mask):
        index = np.flatnonzero(mask)
        length, jac = self._lengths(poses, sensitivity, index)
        values = (self.link_length - length) / self.sigma.position_m
        jac = None if jac is None else -jac / self.sigma.position_m
        return ResidualBlock(values, jac, np.full(len(index), "link_length"), index)

    def _relative_length_block(self, poses, sensitivity):
        index = np.flatnonzero(self.is_sphere)
        length, jac = self._lengths(poses, sensitivity, index)
        values = np.diff(length) / self.sigma.position_m
        jac = None if jac is None else np.diff(jac, axis=0) / self.sigma.position_m
        return ResidualBlock(values, jac, np.full(len(values), "link_length_difference"), index[1:])

    def _relative_position_block(self, poses, sensitivity):
        index = np.flatnonzero(self.is_fixed)
        values = (np.diff(poses[index, :3], axis=0) / self.sigma.position_m).reshape(-1)
        jac = None
        if sensitivity is not None:
            diff = np.diff(sensitivity[index, :3, :], axis=0) / self.sigma.position_m
            jac = diff.reshape(-1, sensitivity.shape[2])
        pairs = max(len(index) - 1, 0)
        channels = np.tile(np.array(["x_difference", "y_difference", "z_difference"]), pairs)
        return ResidualBlock(values, jac, channels, np.repeat(index[1:], 3))


def _stack(blocks: list[ResidualBlock]) -> ResidualBlock:
    values = np.concatenate([b.values for b in blocks])
    channels = np.concatenate([b.channels for b in blocks])
    postures = np.concatenate([b.postures for b in blocks])
    if blocks[0].jacobian is None:
        return ResidualBlock(values, None, channels, postures)
    width = blocks[0].jacobian.shape[1]
    jac = np.concatenate([b.jacobian.reshape(-1, width) for b in blocks])
    return ResidualBlock(values, jac, channels, postures)
