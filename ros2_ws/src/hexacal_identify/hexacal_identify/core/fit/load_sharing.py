"""
The compliant mode's static load, shared by stiffness, and its derivatives by the compliances.

With all six drives powered and the link fixed, seven members hold the platform's six
coordinates: how they share the weight depends on how stiff each is (statics.py's module doc
gives the system).  Chain c yields ``1 / k_c = d_c + c_c r_c^2`` in its actuator's unit (the
servo's ``d_c = 1 / kp_c`` in series with the leg's compliance c_c referred to the actuator by
r_c = d lambda_c / d leg length), the link ``c_L``.  The fit identifies c_c and c_L: the loads
move with them, and their derivatives (``SharedLoads.sensitivities``) complete the compliance
columns of the Jacobian.

The system is scaled by a stiffness s per posture (its entries of order one); the loads do not
depend on s, so their derivatives hold s fixed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LoadSharing:
    """
    How stiff the chains and the link are where all six drives hold the platform (compliant).

    ``drive_compliance`` (6,): 1 / kp of each servo in its actuator's unit (m/N, rad/(N m));
    ``chain_compliance`` (6,): each leg's axial compliance between encoder and joint centres
    (m/N, along the leg); ``link_compliance``: the measuring link's (m/N).  Negative values (an
    estimate on its way) count as rigid.
    """

    drive_compliance: np.ndarray
    chain_compliance: np.ndarray
    link_compliance: float = 0.0

    @classmethod
    def of(
        cls, drive_stiffness, chain_compliance=0.0, link_compliance: float = 0.0
    ) -> 'LoadSharing':
        """Return the sharing of drives of gain ``drive_stiffness`` (6 values or one)."""
        stiffness = np.broadcast_to(np.asarray(drive_stiffness, dtype=float), (6,))
        if not np.all(np.isfinite(stiffness) & (stiffness > 0)):
            raise ValueError(f'drive stiffness must be 6 values > 0, got {drive_stiffness!r}')
        chains = np.broadcast_to(np.asarray(chain_compliance, dtype=float), (6,))
        return cls(1.0 / stiffness, np.maximum(chains, 0.0), max(float(link_compliance), 0.0))


@dataclass
class SharedLoads:
    """The solved system of N postures: thrusts (N, 6), the link's tension (N,), and its parts."""

    thrust: np.ndarray
    tension: np.ndarray
    jacobian: np.ndarray  # (N, 6, 6) d lambda / d X
    system: np.ndarray  # (N, 7, 7)
    stiffness: np.ndarray  # (N, 6) k_c / s
    scale: np.ndarray  # (N, 1) s
    leg_factor: np.ndarray  # (N, 6) r_c
    unborne: np.ndarray  # (N, 6) w_c: the weight between drive and spring

    def sensitivities(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Return d reading_loads / d (c_1..c_6, c_L), (N, 6, 7), and d tension / d them, (N, 7).

        A chain's compliance c_k adds S^-1 [J_k^T b_k; 0] to [s y; T], b_k = k_k r_k^2
        (tau_k - w_k), and -b_k to its own thrust; the link's adds -S^-1 [0; s T].
        """
        n = len(self.thrust)
        squared = self.leg_factor**2
        bend = self.stiffness * self.scale * squared * (self.thrust - self.unborne)  # b (N, 6)
        right = np.zeros((n, 7, 7))
        right[:, :6, :6] = np.swapaxes(self.jacobian * bend[..., None], 1, 2)
        right[:, 6, 6] = -self.scale[:, 0] * self.tension
        moved = np.linalg.solve(self.system, right)  # (N, 7 state, 7 compliances)
        thrust = self.stiffness[..., None] * (self.jacobian @ moved[:, :6, :])
        chains = np.arange(6)
        thrust[:, chains, chains] -= bend
        return thrust * squared[..., None], moved[:, 6, :]


def share_by_stiffness(
    jacobian: np.ndarray,
    link_row: np.ndarray,
    gradient: np.ndarray,
    leg_factor: np.ndarray,
    unborne: np.ndarray,
    sharing: LoadSharing | None,
) -> SharedLoads:
    """Return the compliant mode's loads (statics.py's module doc; None: equal and rigid)."""
    n = len(gradient)
    if sharing is None:  # equal drives, rigid link: the rule before the stiffnesses were known
        stiffness, scale, link = np.ones((n, 6)), np.ones((n, 1)), np.zeros(n)
        offset = np.zeros((n, 6))
    else:
        leg = sharing.chain_compliance * leg_factor**2  # the leg's compliance at the actuator
        compliance = sharing.drive_compliance + leg
        scale = 1.0 / compliance.mean(axis=1, keepdims=True)
        stiffness = 1.0 / (compliance * scale)
        link = sharing.link_compliance * scale[:, 0]
        offset = leg * scale * unborne
    system = np.zeros((n, 7, 7))
    weighted = jacobian if sharing is None else stiffness[..., None] * jacobian
    system[:, :6, :6] = np.swapaxes(jacobian, 1, 2) @ weighted
    system[:, :6, 6] = -link_row
    system[:, 6, :6] = link_row
    system[:, 6, 6] = link
    right = np.zeros((n, 7))
    right[:, :6] = gradient - np.einsum('ncx,nc->nx', jacobian, stiffness * offset)
    solution = np.linalg.solve(system, right[..., None])[..., 0]
    thrust = stiffness * (np.einsum('ncx,nx->nc', jacobian, solution[:, :6]) + offset)
    return SharedLoads(
        thrust, solution[:, 6], jacobian, system, stiffness, scale, leg_factor, unborne
    )


__all__ = ['LoadSharing', 'SharedLoads', 'share_by_stiffness']
