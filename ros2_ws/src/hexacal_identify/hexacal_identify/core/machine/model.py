"""
Kinematic parameters: the generic parts and the Hexa Slide's names.

The generic parts (nominal sets, error statistics), and the Hexa Slide's names.

The architectures own their parameters (``architectures/hexa_slide.py``,
``architectures/gough_stewart.py``); this module keeps the names the Hexa Slide
has always been imported by (``HexaParameters``, ``table1_parameters``,
``N_PARAMETERS`` = 54, ...) and the nominal-set generator every architecture shares.
"""

from __future__ import annotations

import numpy as np

from ..architectures import architecture, KinematicParameters
from ..architectures.hexa_slide import (  # noqa: F401  (the Hexa Slide's long-standing names)
    A0_SLICE,
    AXY_SLICE,
    B_SLICE,
    FIELDS_PER_CHAIN,
    HexaParameters,
    L_INDEX,
    N_CHAINS,
    N_PARAMETERS,
    PARAMETER_FIELDS,
    table1_parameters,
    TABLE2_ERROR_STATS_MM,
)


def parameter_names(model: str | None = None) -> list[str]:
    """
    Return the names of the parameters in vector order.

    E.g. ``chain_3.A0z``; ``model`` None is the default model.
    """
    return list(architecture(model).layout.parameter_names)


def parameter_units(model: str | None = None) -> list[str]:
    """
    Return the unit of each parameter.

    Metres, except the Hexa Slide's rail direction components ('1').
    """
    return list(architecture(model).layout.parameter_units)


def error_vector_with_stats(
    rng: np.random.Generator, max_mm: float, mean_mm: float, sigma_mm: float, n: int
) -> np.ndarray:
    """
    Draw n signed errors (m) with the statistics of one row of Table 2.

    Table 2's sigma exceeds its mean in every row, so it is read as the RMS of the
    errors (equal, up to sampling, to the standard deviation of errors of random
    sign); mean is the mean magnitude, max the largest magnitude.  One error is set
    to the maximum; the other n - 1 magnitudes are an affine map of seeded normal draws
    chosen so that the overall mean and RMS match exactly.  An error of "1 mm" on a
    rail-direction component is 1e-3 (Table 1's a rows are 1000 x the unit vector).
    """
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
        raise RuntimeError('could not draw errors with the requested statistics')
    magnitudes = np.concatenate([[max_mm], magnitudes])
    rng.shuffle(magnitudes)
    signs = rng.choice([-1.0, 1.0], size=n)
    return signs * magnitudes * 1e-3


def nominal_set(
    set_number: int,
    seed: int = 0,
    exact: KinematicParameters | None = None,
    model: str | None = None,
) -> KinematicParameters:
    """
    Return nominal parameter set 1, 2 or 3.

    Exact + seeded errors with the architecture's Table 2-like statistics.

    ``exact`` defaults to the default machine of ``model`` (default: the Table 1 Hexa Slide).
    """
    arch = exact.architecture if exact is not None else architecture(model)
    stats = arch.nominal_error_stats_mm
    if set_number not in stats:
        raise ValueError(f'nominal set must be one of {sorted(stats)}, got {set_number}')
    exact = exact if exact is not None else arch.default_parameters()
    rng = np.random.default_rng([seed, set_number])
    errors = error_vector_with_stats(rng, *stats[set_number], n=arch.layout.n_parameters)
    return exact.with_vector(exact.vector + errors)


def error_stats_mm(errors_m: np.ndarray) -> tuple[float, float, float]:
    """(max, mean, sigma) of parameter errors in mm, read as in Table 2."""
    magnitudes = np.abs(np.asarray(errors_m)) * 1e3
    return (
        float(magnitudes.max()),
        float(magnitudes.mean()),
        float(np.sqrt(np.mean(magnitudes**2))),
    )
