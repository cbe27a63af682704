"""
Stacked inverse kinematics for architectures whose per-chain constants stack row by row.

`ElementwiseStacking` gives an architecture the batched IK of the release rehearsal
(`Architecture.stack_chains` / `legs_stacked`: pose i on machine i) in one call of its own chain
IK over `common.StackedChains`, instead of the base class's loop over machines.
"""

from __future__ import annotations

from typing import Any, ClassVar, Sequence

import numpy as np

from .base import StackedLegs
from .common import StackedChains


class ElementwiseStacking:
    """Mixin (before Architecture): `chain_ik(chains, poses)` evaluated for stacked rows."""

    chain_ik: ClassVar[Any]  # the architecture's ChainIK class, elementwise over its constants

    def stack_chains(self, chains: Sequence[Any]) -> StackedChains:
        """Stack the per-chain constants of several machines."""
        return StackedChains(chains)

    def legs_stacked(
        self, stacked: StackedChains, machine: np.ndarray, poses: np.ndarray
    ) -> StackedLegs:
        """Return the IK of row i on parameter set machine[i]: one elementwise call for all."""
        return self.legs_of_rows(self.stacked_rows(stacked, machine), poses)

    def stacked_rows(self, stacked: StackedChains, machine: np.ndarray) -> Any:
        """Return the per-chain constants of rows ``machine`` (N,), gathered."""
        return stacked.rows(np.asarray(machine, dtype=int))

    def legs_of_rows(self, rows: Any, poses: np.ndarray) -> StackedLegs:
        """Return the IK of each gathered row at its pose: one elementwise call."""
        legs = self.chain_ik(rows, np.asarray(poses, dtype=float))
        return StackedLegs(legs.actuators, legs.pose_jacobian(), legs.reachable())
