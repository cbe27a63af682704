"""Kinematic parameters of the Hexa Slide manipulator (paper section 2.3, Table 1).

The 54 identification parameters are stored chain-major; per chain, in the row
order of Table 1: ``A0x A0y A0z Bx By Bz l ax ay`` (SI units, metres).

Conventions chosen here (each checked against Table 1):

* ``A0`` is the start point of the rail in the base frame OXYZ; ``B`` the centre
  of the spherical joint in the platform frame PX'Y'Z'; ``l`` the leg length.
* Table 1 gives the rail direction ``a`` as 1000 x its unit-vector components,
  i.e. plain unit-vector components once the table is read in metres.
* Only ``ax, ay`` are parameters (section 2.3); the rails descend inward, so
  ``az = -sqrt(1 - ax^2 - ay^2)``.  With the other sign the Table 1 machine has
  no feasible posture in the paper's workspace.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

N_CHAINS = 6
PARAMETER_FIELDS = ("A0x", "A0y", "A0z", "Bx", "By", "Bz", "l", "ax", "ay")
FIELDS_PER_CHAIN = len(PARAMETER_FIELDS)
N_PARAMETERS = N_CHAINS * FIELDS_PER_CHAIN

# Column offsets inside one chain's block of 9.
A0_SLICE = slice(0, 3)
B_SLICE = slice(3, 6)
L_INDEX = 6
AXY_SLICE = slice(7, 9)

# Table 1 of the paper, mm; rows in PARAMETER_FIELDS order, columns = chains 1..6.
_TABLE1_MM = np.array(
    [
        [-735.9, -841.8, -110.1, 110.2, 839.7, 729.7],
        [-552.2, -358.9, 899.1, 897.2, -355.6, -546.3],
        [261.4, 259.9, 253.4, 251.8, 256.3, 253.9],
        [-61.1, -170.8, -110.2, 109.8, 173.8, 63.7],
        [-161.7, 28.8, 137.1, 137.2, 28.8, -161.7],
        [-16.1, -16.2, -16.1, -15.8, -16.1, -16.2],
        [994.7, 994.8, 994.6, 994.7, 994.8, 994.7],
        [750.2, 749.8, 0.2, -0.2, -749.7, -750.3],
        [433.2, 432.7, -866.2, -866.3, 432.9, 432.7],
    ]
)

# Table 2 of the paper: (max, mean, sigma) of the nominal-parameter errors, mm.
TABLE2_ERROR_STATS_MM = {1: (1.8, 0.80, 0.87), 2: (2.8, 1.33, 1.45), 3: (9.2, 4.99, 5.28)}


def parameter_names() -> list[str]:
    """Names of the 54 parameters in vector order, e.g. ``chain_3.A0z``."""
    return [f"chain_{c + 1}.{f}" for c in range(N_CHAINS) for f in PARAMETER_FIELDS]


def parameter_units() -> list[str]:
    """Unit of each parameter: metres, except the rail direction components."""
    return ["1" if f in ("ax", "ay") else "m" for _ in range(N_CHAINS) for f in PARAMETER_FIELDS]


@dataclass(frozen=True)
class HexaParameters:
    """The 54 kinematic parameters; ``vector`` is chain-major (see module doc)."""

    vector: np.ndarray

    def __post_init__(self) -> None:
        vector = np.array(self.vector, dtype=float).reshape(-1)
        if vector.shape != (N_PARAMETERS,):
            raise ValueError(f"expected {N_PARAMETERS} parameters, got {vector.size}")
        if not np.all(np.isfinite(vector)):
            bad = [parameter_names()[i] for i in np.flatnonzero(~np.isfinite(vector))]
            raise ValueError(f"non-finite parameter(s): {', '.join(bad)}")
        axy = vector.reshape(N_CHAINS, FIELDS_PER_CHAIN)[:, AXY_SLICE]
        norm2 = np.sum(axy**2, axis=1)
        if np.any(norm2 >= 1.0):
            chain = int(np.argmax(norm2 >= 1.0)) + 1
            raise ValueError(
                f"chain_{chain}.a = {axy[chain - 1].tolist()} is not the x, y part of a unit vector"
            )
        vector.setflags(write=False)
        object.__setattr__(self, "vector", vector)

    @property
    def per_chain(self) -> np.ndarray:
        """(6, 9) view, one row per chain."""
        return self.vector.reshape(N_CHAINS, FIELDS_PER_CHAIN)

    @property
    def base_points(self) -> np.ndarray:
        """A0, rail start points in the base frame, (6, 3)."""
        return self.per_chain[:, A0_SLICE]

    @property
    def platform_points(self) -> np.ndarray:
        """B, spherical-joint centres in the platform frame, (6, 3)."""
        return self.per_chain[:, B_SLICE]

    @property
    def leg_lengths(self) -> np.ndarray:
        """l, (6,)."""
        return self.per_chain[:, L_INDEX]

    @property
    def rail_directions(self) -> np.ndarray:
        """a, unit rail directions (6, 3) with az = -sqrt(1 - ax^2 - ay^2): rails descend."""
        axy = self.per_chain[:, AXY_SLICE]
        az = -np.sqrt(1.0 - np.sum(axy**2, axis=1))
        return np.column_stack([axy, az])

    @classmethod
    def from_parts(
        cls, base_points: np.ndarray, platform_points: np.ndarray, leg_lengths: np.ndarray, rail_xy: np.ndarray
    ) -> "HexaParameters":
        blocks = np.column_stack(
            [np.asarray(base_points), np.asarray(platform_points), np.asarray(leg_lengths), np.asarray(rail_xy)]
        )
        return cls(blocks.reshape(-1))

    def with_vector(self, vector: np.ndarray) -> "HexaParameters":
        return HexaParameters(vector)


def table1_parameters() -> HexaParameters:
    """The paper's exact machine (Table 1), converted from mm to SI.

    Shipped as the default "exact" parameter file ``hexacal_identify/data/table1_exact.yaml``.
    Rounded to 1e-10 m so the file reads like the table (0.2614, not 0.26139999999999997).
    """
    return HexaParameters(np.round(_TABLE1_MM.T / 1000.0, 10).reshape(-1))


def error_vector_with_stats(rng: np.random.Generator, max_mm: float, mean_mm: float, sigma_mm: float) -> np.ndarray:
    """54 signed errors (m) with the statistics of one row of Table 2.

    Table 2's sigma exceeds its mean in every row, so it is read as the RMS of the
    errors (equal, up to sampling, to the standard deviation of errors of random
    sign); mean is the mean magnitude, max the largest magnitude.  One error is set
    to the maximum; the other 53 magnitudes are an affine map of seeded normal draws
    chosen so that the overall mean and RMS match exactly.  An error of "1 mm" on a
    rail-direction component is 1e-3 (Table 1's a rows are 1000 x the unit vector).
    """
    n = N_PARAMETERS
    rest = n - 1
    rest_sum = n * mean_mm - max_mm
    rest_sq = n * sigma_mm**2 - max_mm**2
    rest_mean = rest_sum / rest
    rest_std = np.sqrt(max(rest_sq / rest - rest_mean**2, 0.0))
    for _ in range(1000):
        draws = rng.standard_normal(rest)
        draws = (draws - draws.mean()) / draws.std()
        magnitudes = rest_mean + rest_std * draws
        if magnitudes.min() >= 0.0 and magnitudes.max() <= max_mm:
            break
    else:  # pragma: no cover - the Table 2 rows always succeed quickly
        raise RuntimeError("could not draw errors with the requested statistics")
    magnitudes = np.concatenate([[max_mm], magnitudes])
    rng.shuffle(magnitudes)
    signs = rng.choice([-1.0, 1.0], size=n)
    return signs * magnitudes * 1e-3


def nominal_set(set_number: int, seed: int = 0, exact: HexaParameters | None = None) -> HexaParameters:
    """Nominal parameter set 1, 2 or 3: exact + seeded errors with Table 2's statistics."""
    if set_number not in TABLE2_ERROR_STATS_MM:
        raise ValueError(f"nominal set must be 1, 2 or 3, got {set_number}")
    exact = exact if exact is not None else table1_parameters()
    rng = np.random.default_rng([seed, set_number])
    errors = error_vector_with_stats(rng, *TABLE2_ERROR_STATS_MM[set_number])
    return HexaParameters(exact.vector + errors)


def error_stats_mm(errors_m: np.ndarray) -> tuple[float, float, float]:
    """(max, mean, sigma) of parameter errors in mm, read as in Table 2."""
    magnitudes = np.abs(np.asarray(errors_m)) * 1e3
    return float(magnitudes.max()), float(magnitudes.mean()), float(np.sqrt(np.mean(magnitudes**2)))
