"""Identifiability of the parameters from an identification Jacobian.

The Jacobian's columns are scaled to unit norm first (parameters have different
units and sensitivities; an unscaled SVD would mostly measure that).  The
numerical rank counts singular values above ``rank_tolerance`` x the largest.
Each null direction is described in words: first by matching it against the
motions of a frame or a slider zero that leave every measurement unchanged
(the usual reasons a calibration cannot see something), else by listing the
parameters it mixes.  Column-pivoted QR orders the parameters from best to
worst determined; its last ``n - rank`` columns are those a user would fix.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .device import DEFAULT_LINK_LENGTH_M
from .model import FIELDS_PER_CHAIN, N_CHAINS, N_PARAMETERS, HexaParameters, parameter_names

DEFAULT_RANK_TOLERANCE = 1e-6


@dataclass
class NullDirection:
    """A parameter change the measurements cannot see (to first order)."""

    description: str
    coefficients: dict[str, float]  # parameter name -> component (unit-norm, scaled units)


@dataclass
class IdentifiabilityReport:
    rank: int
    n_parameters: int
    condition_number: float  # of the column-scaled Jacobian over its identifiable part
    singular_values: np.ndarray  # column-scaled, descending
    parameter_names: list[str]
    pivot_order: list[str]  # column-pivoted QR: best determined first
    null_directions: list[NullDirection] = field(default_factory=list)

    @property
    def identifiable(self) -> bool:
        return self.rank == self.n_parameters

    @property
    def unidentifiable_parameters(self) -> list[str]:
        """The parameters a user would fix to make the rest identifiable (last pivots)."""
        return self.pivot_order[self.rank:]

    def verdict(self) -> str:
        if self.identifiable:
            return (
                f"all {self.n_parameters} parameters identifiable "
                f"(rank {self.rank}, condition number {self.condition_number:.3g})"
            )
        lines = [
            f"rank {self.rank} of {self.n_parameters}: {self.n_parameters - self.rank} combination(s) "
            "of parameters cannot be identified from these measurements"
        ]
        lines += [f"  - {d.description}" for d in self.null_directions]
        lines.append("  fix e.g. " + ", ".join(self.unidentifiable_parameters) + " to identify the rest")
        return "\n".join(lines)

    def to_json(self) -> dict:
        return {
            "rank": self.rank,
            "n_parameters": self.n_parameters,
            "identifiable": self.identifiable,
            "condition_number": self.condition_number,
            "singular_values": self.singular_values.tolist(),
            "unidentifiable_combinations": [d.description for d in self.null_directions],
            "suggest_fixing": self.unidentifiable_parameters,
        }


def column_scales(jacobian: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(jacobian, axis=0)
    return np.where(norms > 0, norms, 1.0)


def analyze(
    jacobian: np.ndarray,
    names: list[str] | None = None,
    params: HexaParameters | None = None,
    free: np.ndarray | None = None,
    rank_tolerance: float = DEFAULT_RANK_TOLERANCE,
    link_length: float = DEFAULT_LINK_LENGTH_M,
) -> IdentifiabilityReport:
    """Rank, conditioning and unidentifiable combinations of a (rows x free params) Jacobian."""
    names = names if names is not None else parameter_names()[: jacobian.shape[1]]
    scales = column_scales(jacobian)
    scaled = jacobian / scales
    zero_columns = np.linalg.norm(jacobian, axis=0) == 0
    scaled[:, zero_columns] = 0.0
    # Full V when there are fewer rows than parameters, so the null space is complete.
    _, singular, vt = np.linalg.svd(scaled, full_matrices=scaled.shape[0] < scaled.shape[1])
    singular = np.concatenate([singular, np.zeros(jacobian.shape[1] - len(singular))])
    rank = int(np.sum(singular > rank_tolerance * singular[0])) if singular[0] > 0 else 0
    condition = float(singular[0] / singular[rank - 1]) if rank else float("inf")
    _, _, pivots = scipy.linalg.qr(scaled, mode="economic", pivoting=True)
    null_space = vt[rank:].T
    gauges = _gauge_directions(params, free, scales, link_length) if params is not None else []
    directions = _describe(null_space, names, gauges)
    return IdentifiabilityReport(
        rank=rank,
        n_parameters=jacobian.shape[1],
        condition_number=condition,
        singular_values=singular,
        parameter_names=list(names),
        pivot_order=[names[i] for i in pivots],
        null_directions=directions,
    )


def _gauge_directions(params: HexaParameters, free: np.ndarray | None, scales: np.ndarray,
                      link_length: float) -> list[tuple[str, np.ndarray]]:
    """Parameter changes that move a frame (or one slider's zero), in scaled free coordinates."""
    a0, b, rails = params.base_points, params.platform_points, params.rail_directions
    axis_names = "XYZ"

    def direction(d_a0=None, d_b=None, d_rail=None, chain_only=None):
        delta = np.zeros((N_CHAINS, FIELDS_PER_CHAIN))
        if d_a0 is not None:
            delta[:, 0:3] = d_a0
        if d_b is not None:
            delta[:, 3:6] = d_b
        if d_rail is not None:
            # keep a a unit vector with a_z < 0: d ax, d ay are the x, y parts of d a.
            delta[:, 7:9] = d_rail[:, :2]
        if chain_only is not None:
            mask = np.zeros(N_CHAINS, bool)
            mask[chain_only] = True
            delta[~mask] = 0.0
        vector = delta.reshape(-1)
        if free is not None:
            vector = vector[free]
        return vector * scales

    gauges = []
    # The fixed-position procedure pins the platform at [0, 0, -L]: a rotation of the base frame about
    # that point leaves it pinned, so name rotations about it as well as about O.
    fixed_point = np.array([0.0, 0.0, -link_length])
    for k, axis in enumerate(np.eye(3)):
        gauges.append(
            (
                f"a rotation of the base frame about the {axis_names[k]} axis through the fixed-position point "
                f"[0, 0, -{link_length:g}] m",
                direction(d_a0=np.cross(axis, a0 - fixed_point), d_rail=np.cross(axis, rails)),
            )
        )
    for k, axis in enumerate(np.eye(3)):
        gauges.append((f"a translation of the base frame along {axis_names[k]}", direction(d_a0=np.tile(axis, (6, 1)))))
        gauges.append(
            (
                f"a rotation of the base frame about {axis_names[k]}",
                direction(d_a0=np.cross(axis, a0), d_rail=np.cross(axis, rails)),
            )
        )
        gauges.append((f"a translation of the platform frame along {axis_names[k].lower()}'", direction(d_b=np.tile(axis, (6, 1)))))
        gauges.append((f"a rotation of the platform frame about {axis_names[k].lower()}'", direction(d_b=np.cross(axis, b))))
    for chain in range(N_CHAINS):
        gauges.append(
            (f"a shift of chain_{chain + 1}'s rail start A0 along its rail (a slider zero offset)",
             direction(d_a0=rails, chain_only=chain))
        )
    return [(name, vec) for name, vec in gauges if np.linalg.norm(vec) > 0]


def _describe(null_space: np.ndarray, names: list[str], gauges: list[tuple[str, np.ndarray]]) -> list[NullDirection]:
    if null_space.shape[1] == 0:
        return []
    described: list[NullDirection] = []
    explained = _explain_by_gauges(null_space, gauges)
    for column, text in zip(null_space.T, explained):
        order = np.argsort(-np.abs(column))
        top = [i for i in order[:6] if abs(column[i]) > 0.15 * abs(column[order[0]])]
        coefficients = {names[i]: float(column[i]) for i in top}
        if text is None:
            mix = ", ".join(f"{names[i]} ({column[i]:+.2f})" for i in top)
            text = f"parameters that move together without changing any measurement: {mix}"
        described.append(NullDirection(text, coefficients))
    return described


def _explain_by_gauges(null_space: np.ndarray, gauges: list[tuple[str, np.ndarray]]) -> list[str | None]:
    """Name each null direction after the gauge motion it coincides with, when one does."""
    texts: list[str | None] = [None] * null_space.shape[1]
    if not gauges:
        return texts
    used: set[int] = set()
    for j, column in enumerate(null_space.T):
        best, best_score = None, 0.0
        for g, (_, vector) in enumerate(gauges):
            score = abs(np.dot(column, vector)) / np.linalg.norm(vector)
            if score > best_score and g not in used:
                best, best_score = g, score
        if best is not None and best_score > 0.99:
            used.add(best)
            texts[j] = gauges[best][0]
    # A null space spanned by gauges, but not aligned with them one by one.
    if any(t is None for t in texts):
        inside = [name for name, vector in gauges if _in_span(vector, null_space)]
        for j, t in enumerate(texts):
            if t is None and inside:
                texts[j] = "a combination of: " + "; ".join(inside)
    return texts


def _in_span(vector: np.ndarray, basis: np.ndarray) -> bool:
    unit = vector / np.linalg.norm(vector)
    return float(np.linalg.norm(basis.T @ unit)) > 0.99


__all__ = ["IdentifiabilityReport", "NullDirection", "analyze", "column_scales", "N_PARAMETERS"]
