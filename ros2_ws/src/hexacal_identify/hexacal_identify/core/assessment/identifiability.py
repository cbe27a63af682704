"""
Identifiability of the parameters from an identification Jacobian.

The Jacobian's columns are scaled to unit norm first (parameters have different
units and sensitivities; an unscaled SVD would mostly measure that).  The
numerical rank counts singular values above ``rank_tolerance`` x the largest.
Each null direction is described in words: first by matching it against the
motions of a frame, an actuator zero or the machine's scale that leave every
measurement unchanged (the usual reasons a calibration cannot see something), else by listing the
parameters it mixes.  Column-pivoted QR orders the parameters from best to
worst determined; its last ``n - rank`` columns are those a user would fix.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_LINK_LENGTH_M, DEFAULT_MOUNT, fixed_point, N_DEVICE_PARAMETERS

DEFAULT_RANK_TOLERANCE = 1e-6


@dataclass
class NullDirection:
    """A parameter change the measurements cannot see (to first order)."""

    description: str
    coefficients: dict[str, float]  # parameter name -> component (unit-norm, scaled units)
    fix: str | None = (
        None  # the unknown to hold fixed for this direction, when the explanation names one
    )


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
        """
        Return the unknowns a user would fix to make the rest identifiable.

        A device defect that a frame motion imitates is named first (fixing it is
        choosing the frame, which the device defines anyway); the rest are the last
        pivots of the column-pivoted QR.
        """
        named = [d.fix for d in self.null_directions if d.fix]
        rest = [name for name in reversed(self.pivot_order) if name not in named]
        return named + rest[: max(self.n_parameters - self.rank - len(named), 0)]

    def verdict(self) -> str:
        if self.identifiable:
            return (
                f'all {self.n_parameters} parameters identifiable '
                f'(rank {self.rank}, condition number {self.condition_number:.3g})'
            )
        lines = [
            f'rank {self.rank} of {self.n_parameters}: {self.n_parameters - self.rank} '
            'combination(s) of parameters cannot be identified from these measurements'
        ]
        lines += [f'  - {d.description}' for d in self.null_directions]
        lines.append(
            '  fix e.g. ' + ', '.join(self.unidentifiable_parameters) + ' to identify the rest'
        )
        return '\n'.join(lines)

    def to_json(self) -> dict:
        return {
            'rank': self.rank,
            'n_parameters': self.n_parameters,
            'identifiable': self.identifiable,
            'condition_number': self.condition_number,
            'singular_values': self.singular_values.tolist(),
            'unidentifiable_combinations': [d.description for d in self.null_directions],
            'suggest_fixing': self.unidentifiable_parameters,
        }


def column_scales(jacobian: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(jacobian, axis=0)
    return np.where(norms > 0, norms, 1.0)


def pivoted_qr(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return Householder QR with column pivoting: (R, pivots), R min(m, n) x n (LAPACK dgeqp3)."""
    from scipy.linalg import qr  # imported by the analysis that uses it, not at start-up

    r, pivots = qr(matrix, mode='r', pivoting=True)
    return r[: min(matrix.shape)], pivots


def analyze(
    jacobian: np.ndarray,
    names: list[str] | None = None,
    params: KinematicParameters | None = None,
    free: np.ndarray | None = None,
    rank_tolerance: float = DEFAULT_RANK_TOLERANCE,
    link_length: float = DEFAULT_LINK_LENGTH_M,
    mount: str = DEFAULT_MOUNT,
    gram_root: np.ndarray | None = None,
    extra_names: Sequence[str] = (),
) -> IdentifiabilityReport:
    """
    Rank, conditioning and unidentifiable combinations of a (rows x free params) Jacobian.

    ``gram_root``, if given, is an n x n F with F^T F = J^T J (the solver has it
    from its normal equations).  Everything here depends on J only through
    J^T J (column norms, singular values and V, the greedy choices of the
    column-pivoted QR), so F stands in for the tall J and nothing of J's size is
    decomposed.  Where several columns are equally good pivots (the A0z of
    different chains for a base rotation), rounding decides which one is
    suggested for fixing, with or without F.

    Without ``params`` (no architecture: no named frame motions) ``names`` is required.
    ``extra_names``: unknowns after the device defects (``compliance.<name>``), each a candidate
    explanation like a device defect (no effect, or imitated by a frame motion or a zero).
    """
    if names is None:
        if params is None:
            raise ValueError('analyze needs the parameters (params) or the column names (names)')
        names = list(params.layout.parameter_names)[: jacobian.shape[1]]
    factor = jacobian if gram_root is None else gram_root
    scales = column_scales(factor)
    scaled = factor / scales  # zero columns stay zero (their scale is 1)
    # Full V when there are fewer rows than parameters, so the null space is complete.
    _, singular, vt = np.linalg.svd(scaled, full_matrices=scaled.shape[0] < scaled.shape[1])
    singular = np.concatenate([singular, np.zeros(jacobian.shape[1] - len(singular))])
    rank = int(np.sum(singular > rank_tolerance * singular[0])) if singular[0] > 0 else 0
    condition = float(singular[0] / singular[rank - 1]) if rank else float('inf')
    _, pivots = pivoted_qr(scaled)
    null_space = vt[rank:].T
    gauges = (
        _gauge_directions(params, free, scales, link_length, mount) if params is not None else []
    )
    # The unknowns are the kinematic parameters followed by the device defects.
    n_parameters = (
        params.layout.n_parameters
        if params is not None
        else (len(free) if free is not None else len(names))
        - N_DEVICE_PARAMETERS
        - len(extra_names)
    )
    directions = _describe(
        null_space, names, gauges, _device_directions(free, scales, n_parameters, extra_names)
    )
    return IdentifiabilityReport(
        rank=rank,
        n_parameters=jacobian.shape[1],
        condition_number=condition,
        singular_values=singular,
        parameter_names=list(names),
        pivot_order=[names[i] for i in pivots],
        null_directions=directions,
    )


def _gauge_directions(
    params: KinematicParameters,
    free: np.ndarray | None,
    scales: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> list[tuple[str, np.ndarray]]:
    """
    Parameter changes that move a frame (or one actuator's zero), in scaled free coordinates.

    The architecture says what each motion does to its parameters (``frame_motion``,
    ``actuator_zero_shift``); the names are the same for every architecture.
    """
    arch = params.architecture
    axis_names = 'XYZ'

    def direction(delta: np.ndarray) -> np.ndarray:
        vector = delta
        if free is not None:
            vector = np.concatenate([vector, np.zeros(len(free) - len(vector))])[free]
        return vector * scales

    gauges = []
    # The fixed-position procedure pins the platform at [0, 0, -L] ([0, 0, +L] standing): a
    # rotation of the base frame about that point leaves it pinned, so name rotations about it as
    # well as about O.
    fixed = fixed_point(link_length, mount)
    for k, axis in enumerate(np.eye(3)):
        gauges.append(
            (
                f'a rotation of the base frame about the {axis_names[k]} axis through the '
                f'fixed-position point [0, 0, {fixed[2]:g}] m',
                direction(
                    arch.frame_motion(
                        params, base_rotation=axis, base_translation=-np.cross(axis, fixed)
                    )
                ),
            )
        )
    for k, axis in enumerate(np.eye(3)):
        gauges.append(
            (
                f'a translation of the base frame along {axis_names[k]}',
                direction(arch.frame_motion(params, base_translation=axis)),
            )
        )
        gauges.append(
            (
                f'a rotation of the base frame about {axis_names[k]}',
                direction(arch.frame_motion(params, base_rotation=axis)),
            )
        )
        gauges.append(
            (
                f"a translation of the platform frame along {axis_names[k].lower()}'",
                direction(arch.frame_motion(params, platform_translation=axis)),
            )
        )
        gauges.append(
            (
                f"a rotation of the platform frame about {axis_names[k].lower()}'",
                direction(arch.frame_motion(params, platform_rotation=axis)),
            )
        )
    for chain in range(params.layout.n_chains):
        name, delta = arch.actuator_zero_shift(params, chain)
        gauges.append((name, direction(delta)))
    # Every length of the machine times (1 + e) about O: the poses scale, the angles do not.  A
    # machine whose actuators read angles (a rotary hexapod) reads the same, and a cost that sees
    # only differences of |P| (eq. 12) and of positions (eq. 13) cannot see its size.
    lengths = np.array([unit == 'm' for unit in params.layout.parameter_units])
    gauges.append(
        (
            'a scaling of the machine about the base origin (every length, the angles kept)',
            direction(params.vector * lengths),
        )
    )
    return [(name, vec) for name, vec in gauges if np.linalg.norm(vec) > 0]


def _device_directions(
    free: np.ndarray | None,
    scales: np.ndarray,
    n_parameters: int,
    extra_names: Sequence[str] = (),
) -> list[tuple[str, np.ndarray, str]]:
    """
    Return (label, unit change, name to fix) of each identified device defect and extra unknown.

    Unit changes are in scaled free coordinates.
    """
    from ..machine.device import DEVICE_PARAMETER_NAMES

    if free is None or len(free) <= n_parameters:
        return []
    labelled = [(f"the device's {name}", f'device.{name}') for name in DEVICE_PARAMETER_NAMES]
    labelled += [(f'the axial {name.replace(".", " of ")}', name) for name in extra_names]
    directions = []
    for k, (label, name) in enumerate(labelled):
        if n_parameters + k >= len(free):
            break
        vector = np.zeros(len(free))
        vector[n_parameters + k] = 1.0
        vector = vector[free] * scales
        if np.linalg.norm(vector) > 0:
            directions.append((label, vector, name))
    return directions


def _describe(
    null_space: np.ndarray,
    names: list[str],
    gauges: list[tuple[str, np.ndarray]],
    device: Sequence[tuple[str, np.ndarray, str]] = (),
) -> list[NullDirection]:
    """Describe each null dimension: a named explanation if one fits, else the mixed parameters."""
    if null_space.shape[1] == 0:
        return []
    explained = _explanations(null_space, gauges, list(device))
    described = [
        NullDirection(text, _top_coefficients(vector, names), fix)
        for text, vector, fix in explained
    ]
    # Whatever the named motions do not cover: list the parameters of the remaining null
    # directions.
    if explained:
        covered, _ = np.linalg.qr(np.column_stack([vector for _, vector, _ in explained]))
        rest = null_space - covered @ (covered.T @ null_space)
        u, singular, _ = np.linalg.svd(rest, full_matrices=False)
        rest_basis = u[:, singular > 1e-6][:, : null_space.shape[1] - len(explained)]
    else:
        rest_basis = null_space
    for column in rest_basis.T:
        coefficients = _top_coefficients(column, names)
        mix = ', '.join(f'{name} ({value:+.2f})' for name, value in coefficients.items())
        described.append(
            NullDirection(
                f'parameters that move together without changing any measurement: {mix}',
                coefficients,
            )
        )
    return described


def _top_coefficients(vector: np.ndarray, names: list[str]) -> dict[str, float]:
    order = np.argsort(-np.abs(vector))
    return {
        names[i]: float(vector[i])
        for i in order[:6]
        if abs(vector[i]) > 0.15 * abs(vector[order[0]])
    }


def _explanations(
    null_space: np.ndarray,
    gauges: list[tuple[str, np.ndarray]],
    device: list[tuple[str, np.ndarray, str]],
) -> list[tuple[str, np.ndarray, str | None]]:
    """
    Named motions that lie in the null space, most specific first, none repeating another.

    Candidates: a frame motion alone; a device defect alone (no effect at all);
    a device defect together with a frame motion (the motion imitates the
    defect, e.g. an inclinometer offset and a base rotation).  A candidate
    explains a null direction when some vector of its span lies in the null
    space (largest principal cosine > 0.999).
    """
    candidates: list[tuple[str, list[np.ndarray], str | None]] = [
        (name, [vector], None) for name, vector in gauges
    ]
    candidates += [
        (f'{label} has no effect on these measurements', [vector], name)
        for label, vector, name in device
    ]
    candidates += [
        (f'{label} cannot be told apart from {g_name}', [d_vector, g_vector], d_name)
        for label, d_vector, d_name in device
        for g_name, g_vector in gauges
    ]
    found: list[tuple[str, np.ndarray, str | None]] = []
    for text, vectors, fix in candidates:
        basis, _ = np.linalg.qr(np.column_stack(vectors))
        _, cosines, vt = np.linalg.svd(null_space.T @ basis)
        if cosines[0] < 0.999:
            continue
        member = basis @ vt[0]
        if found:
            previous, _ = np.linalg.qr(np.column_stack([v for _, v, _ in found]))
            if np.linalg.norm(previous.T @ member) > 0.99:
                continue  # already explained
        found.append((text, member, fix))
        if len(found) == null_space.shape[1]:
            break
    return found


__all__ = ['IdentifiabilityReport', 'NullDirection', 'analyze', 'column_scales']
