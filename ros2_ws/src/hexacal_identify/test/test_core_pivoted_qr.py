"""
Identifiability.pivoted_qr (numpy) against scipy.linalg.qr(pivoting=True), which it replaces.

The identifiability analysis no longer imports scipy (#12 item 2: ~0.2 s of every
`hexacal calibrate`).  Its pivots decide which parameters a refusal suggests
fixing, and on unit-norm columns the first pivot is decided by the last bit
of the column norms: so the pivots must be scipy's exactly, on random matrices
and on real identification problems, including the rank-deficient ones (the
sphere, fixed and relative costs are rank 53 of 54).
"""

from hexacal_identify.core import identifiability
from hexacal_identify.core.errors import RankDeficientError
from hexacal_identify.core.identifiability import pivoted_qr
from hexacal_identify.core.identification import identify, SolverOptions
from hexacal_identify.core.model import nominal_set
from hexacal_identify.core.residuals import COSTS
from hexacal_identify.studies.accuracy import (
    identifiability_by_cost,
    simulate_run_measurements,
    StudyRun,
)
import numpy as np
import pytest

scipy_linalg = pytest.importorskip('scipy.linalg')


def scipy_pivoted_qr(matrix):
    r, pivots = scipy_linalg.qr(matrix, mode='r', pivoting=True)
    return r[: min(matrix.shape)], pivots


def assert_same_factorization(matrix, steps=None):
    """
    Assert the same pivots and the same |R|.

    Same pivots (the first ``steps`` of them; all by default) and the same |R|.
    """
    expected_r, expected_pivots = scipy_pivoted_qr(matrix)
    r, pivots = pivoted_qr(matrix)
    steps = min(matrix.shape) if steps is None else steps
    assert r.shape == expected_r.shape
    np.testing.assert_array_equal(pivots[:steps], expected_pivots[:steps])
    scale = max(abs(expected_r[0, 0]), 1.0) if expected_r.size else 1.0
    np.testing.assert_allclose(
        np.abs(np.diag(r))[:steps],
        np.abs(np.diag(expected_r))[:steps],
        rtol=1e-10,
        atol=1e-12 * scale,
    )
    if steps == min(matrix.shape) and np.array_equal(pivots, expected_pivots):
        np.testing.assert_allclose(np.abs(r), np.abs(expected_r), rtol=0, atol=1e-10 * scale)
        np.testing.assert_array_equal(np.tril(r, -1), 0.0)


@pytest.mark.parametrize(
    'shape',
    [
        (1, 1),
        (1, 5),
        (5, 1),
        (7, 3),
        (3, 7),
        (54, 54),
        (59, 59),
        (200, 54),
        (9, 9),
        (16, 12),
        (17, 12),
    ],
)
def test_random_matrices_match_scipy(shape):
    rng = np.random.default_rng(sum(shape))
    for _ in range(20):
        matrix = rng.standard_normal(shape) * rng.uniform(0.01, 100.0, shape[1])
        assert_same_factorization(matrix)


def test_random_unit_norm_columns_match_scipy():
    """
    Check columns of norm 1 to within rounding.

    Columns of norm 1 to within rounding (as the scaled Jacobian's): the last bit of the norms
    decides.
    """
    rng = np.random.default_rng(7)
    for _ in range(200):
        m, n = rng.integers(1, 70, size=2)
        matrix = rng.standard_normal((m, n))
        matrix /= np.linalg.norm(matrix, axis=0)
        assert_same_factorization(matrix)


def test_random_rank_deficient_matrices_match_scipy_up_to_the_rank():
    """
    Check rank-deficient matrices: the pivots agree where the rank is.

    Beyond the rank the remaining columns are rounding noise: the pivots agree where the rank is.
    """
    rng = np.random.default_rng(3)
    for _ in range(200):
        m, n = rng.integers(2, 70, size=2)
        rank = int(rng.integers(1, min(m, n) + 1))
        matrix = rng.standard_normal((m, rank)) @ rng.standard_normal((rank, n))
        assert_same_factorization(matrix, steps=rank)


def test_zero_and_repeated_columns():
    matrix = np.zeros((6, 5))
    assert_same_factorization(matrix)
    matrix[:, 2] = 1.0
    matrix[:, 4] = 1.0  # a tie: the first index wins
    r, pivots = pivoted_qr(matrix)
    assert pivots[0] == 2
    assert_same_factorization(matrix, steps=1)


class _Both:
    """
    Stand in for pivoted_qr, recording whether scipy agrees.

    Stands in for pivoted_qr: returns ours, records whether scipy agrees on each matrix analyzed.
    """

    def __init__(self):
        self.matrices = []

    def __call__(self, matrix):
        self.matrices.append(np.array(matrix))
        return pivoted_qr(matrix)


def _report_text(report):
    return report.to_json(), report.pivot_order, report.unidentifiable_parameters, report.verdict()


def test_identifiability_by_cost_matches_scipy(monkeypatch):
    """
    Check the study's analysis of the tall Jacobian of each cost against scipy.

    The study's analysis of the tall Jacobian of each cost (rank 53 for sphere, fixed and
    relative).
    """
    both = _Both()
    monkeypatch.setattr(identifiability, 'pivoted_qr', both)
    ours = identifiability_by_cost(postures=30)
    assert {row.cost: row.report.rank for row in ours} == {
        'absolute': 54,
        'sphere': 53,
        'fixed': 53,
        'sphere-fixed': 54,
        'relative': 53,
    }
    for matrix in both.matrices:
        assert_same_factorization(matrix)
    monkeypatch.setattr(identifiability, 'pivoted_qr', scipy_pivoted_qr)
    theirs = identifiability_by_cost(postures=30)
    for a, b in zip(ours, theirs):
        assert _report_text(a.report) == _report_text(b.report), a.cost


def _identify_report(cost, free_device=()):
    measurements = simulate_run_measurements(
        StudyRun(postures=40, noise_um=10.0, seed=4, cost=cost)
    )
    options = SolverOptions(cost=cost, free_device=free_device)
    try:
        return identify(nominal_set(2, seed=0), measurements, options).identifiability
    except RankDeficientError as error:
        return error.report


@pytest.mark.parametrize(
    'cost, free_device',
    [(cost, ()) for cost in COSTS]
    + [('relative', ('phi0',)), ('absolute', ('dL', 'alpha0', 'gamma'))],
)
def test_identification_refusals_match_scipy(monkeypatch, cost, free_device):
    """
    Check the solver's rank analysis against scipy.

    The solver's analysis (on the square root of J^T J): same rank, combinations and suggestions.
    """
    both = _Both()
    monkeypatch.setattr(identifiability, 'pivoted_qr', both)
    ours = _identify_report(cost, free_device)
    assert both.matrices
    for matrix in both.matrices:
        assert_same_factorization(matrix)
    monkeypatch.setattr(identifiability, 'pivoted_qr', scipy_pivoted_qr)
    assert _report_text(ours) == _report_text(_identify_report(cost, free_device))
    if cost in ('sphere', 'fixed', 'relative'):
        assert ours.rank == 53 and ours.unidentifiable_parameters
