"""
Identifiability.pivoted_qr (scipy.linalg.qr with pivoting) and the rank analysis built on it.

The pivots decide which parameters a refusal suggests fixing: the factorization
must reproduce the matrix, order the columns by decreasing remaining norm, and
the analysis must find the ranks each cost function is known to have (the
sphere, fixed and relative costs cannot see a translation of the frame: rank 53
of 54).
"""

from hexacal_identify.core.assessment.identifiability import pivoted_qr
from hexacal_identify.core.errors import RankDeficientError
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.residuals import COSTS
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.studies.accuracy import (
    identifiability_by_cost,
    simulate_run_measurements,
    StudyRun,
)
import numpy as np
import pytest


@pytest.mark.parametrize('shape', [(1, 1), (1, 5), (5, 1), (7, 3), (3, 7), (59, 59), (200, 54)])
def test_factorization_reproduces_the_matrix(shape):
    rng = np.random.default_rng(sum(shape))
    matrix = rng.standard_normal(shape) * rng.uniform(0.01, 100.0, shape[1])
    r, pivots = pivoted_qr(matrix)
    k = min(shape)
    assert r.shape == (k, shape[1])
    assert sorted(pivots) == list(range(shape[1]))
    np.testing.assert_array_equal(np.tril(r, -1), 0.0)
    permuted = matrix[:, pivots]
    # R^T R = (A P)^T (A P): Q is orthogonal.
    scale = np.abs(matrix).max() ** 2
    np.testing.assert_allclose(r.T @ r, permuted.T @ permuted, atol=1e-9 * scale)
    diagonal = np.abs(np.diag(r))
    assert np.all(diagonal[1:] <= diagonal[:-1] * (1 + 1e-12))
    # The first pivot is the column of largest norm.
    assert pivots[0] == int(np.argmax(np.linalg.norm(matrix, axis=0)))


def test_rank_deficient_matrix_puts_the_dependent_column_last():
    rng = np.random.default_rng(3)
    matrix = rng.standard_normal((20, 4))
    matrix = np.column_stack([matrix, matrix[:, 1] + matrix[:, 2]])
    r, pivots = pivoted_qr(matrix)
    assert abs(r[4, 4]) < 1e-12 * abs(r[0, 0])
    assert abs(r[3, 3]) > 1e-3 * abs(r[0, 0])
    assert pivots[4] in (1, 2, 4)  # one of the three that depend on each other


def test_identifiability_by_cost_finds_the_known_ranks():
    ours = identifiability_by_cost(postures=30)
    assert {row.cost: row.report.rank for row in ours} == {
        'absolute': 54,
        'sphere': 53,
        'fixed': 53,
        'sphere-fixed': 54,
        'relative': 53,
    }
    for row in ours:
        if row.report.rank == 53:
            assert len(row.report.unidentifiable_parameters) == 1, row.cost


def _identify_report(cost, free_device=()):
    measurements = simulate_run_measurements(
        StudyRun(postures=40, noise_um=10.0, seed=4, cost=cost)
    )
    options = SolverOptions(cost=cost, free_device=free_device)
    try:
        return identify(nominal_set(2, seed=0), measurements, options).identifiability
    except RankDeficientError as error:
        return error.report


@pytest.mark.parametrize('cost', COSTS)
def test_identification_refusals_name_what_to_fix(cost):
    report = _identify_report(cost)
    if cost in ('sphere', 'fixed', 'relative'):
        assert report.rank == 53 and report.unidentifiable_parameters
        assert 'fix e.g.' in report.verdict()
    else:
        assert report.rank == 54 and not report.unidentifiable_parameters
