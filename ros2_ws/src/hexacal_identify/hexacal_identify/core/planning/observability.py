"""
Score a design: the observability indices of its identification Jacobian.

Observability indices (Sun & Hollerbach 2008; sigma = singular values of the
column-scaled identification Jacobian, n parameters, m = postures):

* O1 = (sigma_1 ... sigma_n)^(1/n) / sqrt(m)  (Borm & Menq; D-optimal, the default)
* O2 = sigma_min / sigma_max                  (inverse condition number, Driels & Pathre)
* O3 = sigma_min                              (Nahvi & Hollerbach)
* O4 = sigma_min^2 / sigma_max                (noise amplification index, Nahvi & Hollerbach)

and, beyond them, I (I-optimal): the least predicted mean squared position error
over the workspace, trace(W M^-1), with M = J^T J the information of the plan and
W the mean of dP/du^T dP/du over the sphere candidates (drawn like validation
postures).  It targets what a calibration is judged by; ``hexacal study --plan``
measures it against O1.
"""

from __future__ import annotations

import numpy as np

INDICES = ('O1', 'O2', 'O3', 'O4')
PREDICTION = 'I'  # I-optimal: least predicted mean squared position error over the workspace
CRITERIA = INDICES + (PREDICTION,)
# Eigenvalue of M (= sigma^2) relative to the largest: below counts as missing.
RANK_TOLERANCE = 1e-9


def observability_indices(singular_values: np.ndarray, n_postures: int) -> dict[str, float]:
    """O1..O4 from the singular values of a column-scaled identification Jacobian (module doc)."""
    sigma = np.sort(np.asarray(singular_values, dtype=float))[::-1]
    largest, smallest = float(sigma[0]), float(sigma[-1])
    if smallest <= 0.0:
        return {'O1': 0.0, 'O2': 0.0, 'O3': 0.0, 'O4': 0.0}
    return {
        'O1': float(np.exp(np.mean(np.log(sigma))) / np.sqrt(n_postures)),
        'O2': smallest / largest,
        'O3': smallest,
        'O4': smallest**2 / largest,
    }


def observability_index(
    jacobian: np.ndarray, n_postures: int, index: str = 'O1', scales: np.ndarray | None = None
) -> float:
    """
    Return one index of a Jacobian (rows x n parameters).

    ``scales`` None = unit-norm columns (as identifiability.analyze).
    """
    if index not in INDICES:
        raise ValueError(
            f'unknown observability index {index!r}; choose one of {", ".join(INDICES)}'
        )
    if scales is None:
        norms = np.linalg.norm(jacobian, axis=0)
        scales = np.where(norms > 0, norms, 1.0)
    singular = np.linalg.svd(jacobian / scales, compute_uv=False)
    singular = np.concatenate([singular, np.zeros(jacobian.shape[1] - len(singular))])
    return observability_indices(singular, n_postures)[index]


def index_from_eigenvalues(eigenvalues: np.ndarray, n_postures: int, index: str) -> np.ndarray:
    """Index of information matrices from their eigenvalues (..., n), ascending."""
    sigma = np.sqrt(np.maximum(eigenvalues, 0.0))
    smallest, largest = sigma[..., 0], sigma[..., -1]
    deficient = eigenvalues[..., 0] <= RANK_TOLERANCE * eigenvalues[..., -1]
    if index == 'O1':
        with np.errstate(divide='ignore'):
            value = np.exp(np.mean(np.log(sigma), axis=-1)) / np.sqrt(n_postures)
    elif index == 'O2':
        value = smallest / largest
    elif index == 'O3':
        value = smallest
    else:
        value = smallest**2 / largest
    return np.where(deficient, 0.0, value)


def check_index(index: str) -> None:
    if index not in CRITERIA:
        raise ValueError(
            f'unknown observability index {index!r}; choose one of {", ".join(CRITERIA)}'
        )


def full_rank(information: np.ndarray) -> bool:
    """Return whether an information matrix has full rank (RANK_TOLERANCE)."""
    eigenvalues = np.linalg.eigvalsh(information)
    return bool(eigenvalues[0] > RANK_TOLERANCE * eigenvalues[-1])
