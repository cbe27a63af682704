"""
Identification: Jacobians, exact recovery, identifiability, named errors.

Analytic vs finite-difference Jacobian, exact recovery, identifiability, named errors.
"""

from hexacal_identify.core.assessment.identifiability import (
    analyze,
    column_scales,
    DEFAULT_RANK_TOLERANCE,
)
from hexacal_identify.core.errors import (
    InvalidMeasurementError,
    RankDeficientError,
    TooFewPosturesError,
)
from hexacal_identify.core.fit.baseline import absolute_residuals, finite_difference_jacobian
from hexacal_identify.core.fit.identification import (
    CONVERGED,
    identify,
    ITERATION_LIMIT,
    SolverOptions,
)
from hexacal_identify.core.fit.least_squares_run import NormalEquations
from hexacal_identify.core.fit.residuals import ChannelSigma, CostFunction, COSTS
from hexacal_identify.core.machine.device import DeviceModel
from hexacal_identify.core.machine.kinematics import forward_kinematics, pose_parameter_sensitivity
from hexacal_identify.core.machine.measurements import (
    Measurements,
    NoiseModel,
    simulate_measurements,
)
from hexacal_identify.core.machine.model import HexaParameters, nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.studies.accuracy import (
    identifiability_by_cost,
    simulate_run_measurements,
    StudyRun,
)
import numpy as np
import pytest

TRUE = table1_parameters()


def _measurements(n, seed, noise_um=0.0):
    rng = np.random.default_rng(seed)
    poses = sample_poses(TRUE, n, rng)
    return simulate_measurements(TRUE, poses, noise=NoiseModel.from_microns(noise_um), rng=rng)


@pytest.mark.parametrize('cost', COSTS)
def test_analytic_identification_jacobian_matches_finite_differences(cost):
    params = nominal_set(1, seed=1)
    measurements = simulate_run_measurements(
        StudyRun(postures=16, noise_um=5.0, seed=2, cost=cost)
    )
    function = CostFunction(cost, measurements, DeviceModel(), ChannelSigma())
    keep = np.flatnonzero(function.usable())
    function = CostFunction(cost, measurements.subset(keep), DeviceModel(), ChannelSigma())

    def solve(vector):
        fk = forward_kinematics(
            HexaParameters(vector),
            function.measurements.actuator_positions,
            function.initial_poses(),
            tolerance=1e-13,
            fit_tilt_first=True,
        )
        assert not fk.failures
        return fk.poses

    poses = solve(params.vector)
    sensitivity, _ = pose_parameter_sensitivity(params, poses)
    analytic = function.residuals(poses, sensitivity).jacobian
    numeric = finite_difference_jacobian(
        lambda v: function.residuals(solve(v), None).values, params.vector, 1e-6
    )
    np.testing.assert_allclose(analytic, numeric, atol=2e-6 * np.abs(numeric).max(), rtol=1e-4)


@pytest.mark.parametrize('cost', COSTS)
def test_factored_sensitivity_gives_the_same_jacobian_and_noise_rows(cost):
    """
    Check the factored sensitivity gives the same Jacobian and noise rows.

    CostFunction.residuals with a PoseSensitivity (rows formed from the factored dX/du) equals the
    full-array path.
    """
    from hexacal_identify.core.machine.kinematics import pose_sensitivities

    params = nominal_set(1, seed=1)
    measurements = simulate_run_measurements(
        StudyRun(postures=16, noise_um=5.0, seed=2, cost=cost)
    )
    function = CostFunction(
        cost, measurements, DeviceModel(), ChannelSigma(position_m=1e-5, angle_rad=2e-5)
    )
    fk = forward_kinematics(
        params, measurements.actuator_positions, function.initial_poses(), fit_tilt_first=True
    )
    assert not fk.failures
    sensitivity = pose_sensitivities(params, fk.poses)
    for with_device in (False, True):
        factored = function.residuals(fk.poses, sensitivity, with_device=with_device)
        full = function.residuals(fk.poses, sensitivity.wrt_parameters, with_device=with_device)
        assert factored.jacobian.shape == (len(factored.values), 54 + 5 * with_device)
        np.testing.assert_allclose(
            factored.jacobian, full.jacobian, rtol=1e-12, atol=1e-12 * np.abs(full.jacobian).max()
        )
        np.testing.assert_array_equal(factored.values, full.values)
        assert factored.noise_jacobian is not None and full.noise_jacobian is None
    without_noise = function.residuals(fk.poses, sensitivity, with_noise=False)
    assert without_noise.noise_jacobian is None
    np.testing.assert_array_equal(
        without_noise.jacobian, function.residuals(fk.poses, sensitivity).jacobian
    )


def test_paper_style_residuals_equal_the_batched_ones():
    params = nominal_set(1, seed=0)
    measurements = _measurements(10, 3, noise_um=5)
    function = CostFunction('absolute', measurements, DeviceModel(), ChannelSigma())
    fk = forward_kinematics(
        params, measurements.actuator_positions, function.initial_poses(), fit_tilt_first=True
    )
    batched = function.residuals(fk.poses, None).values.reshape(2, -1)  # [phi rows], [x y z rows]
    per_posture = absolute_residuals(params.vector, measurements).reshape(-1, 4)
    np.testing.assert_allclose(per_posture[:, 3], batched[0][:10], atol=1e-10)
    np.testing.assert_allclose(
        per_posture[:, :3].reshape(-1), batched[0][10:].tolist() + batched[1].tolist(), atol=1e-10
    )


@pytest.mark.parametrize('number', [1, 2, 3])
def test_exact_parameters_recovered_without_noise(number):
    result = identify(nominal_set(number, seed=0), _measurements(25, 10 + number))
    assert result.reason == CONVERGED
    assert result.rank == 54
    assert np.max(np.abs(result.parameters.vector - TRUE.vector)) < 1e-9
    assert len(result.used_postures) == 25, result.rejected_postures


def test_iteration_limit_is_reported_with_the_iterations_taken():
    measurements = _measurements(25, 11)
    # Without the outlier screen: a solve stopped short would set postures aside and run again.
    options = SolverOptions(max_iterations=2, outlier_threshold=None)
    result = identify(nominal_set(1, seed=0), measurements, options)
    assert result.reason == ITERATION_LIMIT
    assert result.iterations == 2
    # Stopped short of the truth, it is still nearer than the start.
    error = np.max(np.abs(result.parameters.vector - TRUE.vector))
    assert 1e-9 < error < np.max(np.abs(nominal_set(1, seed=0).vector - TRUE.vector))
    full = identify(nominal_set(1, seed=0), measurements)
    assert full.reason == CONVERGED and full.iterations > 2


def test_eq7_has_full_rank_and_the_other_costs_are_reported_honestly():
    rows = {row.cost: row.report for row in identifiability_by_cost()}
    assert rows['absolute'].rank == 54 and rows['sphere-fixed'].rank == 54
    # eq. 8 alone cannot see a base rotation about the vertical Y axis of eq. 2 (absorbed by
    # theta).
    assert rows['sphere'].rank == 53
    assert 'rotation of the base frame about Y' in rows['sphere'].null_directions[0].description
    assert rows['fixed'].rank == 53 and rows['relative'].rank == 53


def test_noisy_identification_is_within_its_own_uncertainty():
    result = identify(nominal_set(2, seed=0), _measurements(50, 21, noise_um=10))
    assert result.reason == CONVERGED
    normalized = np.abs(result.parameters.vector - TRUE.vector) / result.std
    assert np.median(normalized) < 2.0 and np.max(normalized) < 6.0
    assert 5e-6 < result.rms_residual['x'] < 2e-5  # ~ the noise, in m
    assert set(result.to_json()) >= {
        'parameters',
        'std',
        'rank',
        'condition_number',
        'solve_seconds',
        'iterations',
        'reason',
    }


def test_nan_reading_is_a_named_error_naming_the_posture():
    measurements = _measurements(30, 4)
    measurements.inclinometer[7, 1] = np.nan
    with pytest.raises(InvalidMeasurementError, match=r'\[7\]') as caught:
        identify(nominal_set(1), measurements)
    assert caught.value.reason == 'invalid-measurement'


def test_out_of_range_inclinometer_angle_is_rejected():
    measurements = _measurements(30, 4)
    measurements.inclinometer[3, 0] = 2.0
    with pytest.raises(InvalidMeasurementError, match='range'):
        identify(nominal_set(1), measurements)


def test_too_few_postures_is_a_named_error():
    with pytest.raises(TooFewPosturesError, match='13 usable posture'):
        identify(nominal_set(1), _measurements(13, 5))  # 52 residuals < 54 parameters


def test_rank_deficient_problem_is_refused_with_the_combination_named():
    measurements = _measurements(40, 6)
    with pytest.raises(RankDeficientError) as caught:
        identify(nominal_set(1), measurements, SolverOptions(cost='sphere'))
    assert caught.value.reason == 'rank-deficient'
    assert 'rotation of the base frame about Y' in str(caught.value)
    allowed = identify(
        nominal_set(1), measurements, SolverOptions(cost='sphere', allow_rank_deficient=True)
    )
    assert allowed.rank == 53 and np.isnan(allowed.std).any()


def test_fixing_a_parameter_makes_the_sphere_cost_identifiable():
    measurements = _measurements(40, 6)
    free = np.ones(54, bool)
    free[4 * 9 + 2] = False  # chain_5.A0z known: removes the base rotation about Y
    start = HexaParameters(np.where(free, nominal_set(1).vector, TRUE.vector))
    result = identify(
        start, measurements, SolverOptions(cost='sphere', free_parameters=tuple(free))
    )
    assert result.rank == 53 and result.reason == CONVERGED
    assert np.max(np.abs(result.parameters.vector - TRUE.vector)) < 1e-9


def test_measurements_with_inconsistent_lengths_are_rejected():
    measurements = Measurements(np.zeros((3, 6)) + 0.3, np.zeros((2, 2)), np.zeros(3))
    with pytest.raises(InvalidMeasurementError, match='inconsistent lengths'):
        measurements.validate()


def _svd_reference(jacobian, values, scales, rank_tolerance, damping):
    """
    Return what the solver computed before the normal equations.

    QR + SVD of the tall column-scaled Jacobian.
    """
    q, r = np.linalg.qr(jacobian / scales)
    u_r, s, vt = np.linalg.svd(r)
    projected = u_r.T @ (q.T @ values)
    keep = s > rank_tolerance * s[0]
    factor = np.where(keep, s / (s**2 + damping * s[0] ** 2), 0.0)
    step = -(vt.T @ (factor * projected))
    inverse = (vt[keep].T / s[keep] ** 2) @ vt[keep]
    return step, float(projected[keep] @ projected[keep]), inverse, keep


def _scaled_problem(cost):
    measurements = simulate_run_measurements(
        StudyRun(postures=30, noise_um=10.0, seed=4, cost=cost)
    )
    function = CostFunction(cost, measurements, DeviceModel(), ChannelSigma())
    function = CostFunction(
        cost, measurements.subset(np.flatnonzero(function.usable())), DeviceModel(), ChannelSigma()
    )
    params = nominal_set(2, seed=0)
    fk = forward_kinematics(
        params,
        function.measurements.actuator_positions,
        function.initial_poses(),
        fit_tilt_first=True,
    )
    assert not fk.failures
    block = function.residuals(fk.poses, pose_parameter_sensitivity(params, fk.poses)[0])
    return block, column_scales(block.jacobian)


@pytest.mark.parametrize(
    'cost', ['absolute', 'sphere']
)  # full rank, and rank 53 (base rotation about Y)
def test_normal_equations_give_the_steps_and_covariance_of_the_tall_svd(cost):
    block, scales = _scaled_problem(cost)
    normal = NormalEquations.of(block, scales, DEFAULT_RANK_TOLERANCE)
    # J^T J squares the condition number (~2e3-5e3 here): ~1e-8 relative agreement is what rounding
    # allows.
    tolerance = 1e-7
    for damping in (0.0, 1e-6, 1e-3, 1.0):
        step, decrease, inverse, keep = _svd_reference(
            block.jacobian, block.values, scales, DEFAULT_RANK_TOLERANCE, damping
        )
        np.testing.assert_array_equal(normal.keep, keep)
        np.testing.assert_allclose(
            normal.scaled_step(damping), step, rtol=0, atol=tolerance * np.abs(step).max()
        )
    np.testing.assert_allclose(normal.predicted_decrease(), decrease, rtol=tolerance)
    np.testing.assert_allclose(
        normal.scaled_inverse(), inverse, rtol=0, atol=tolerance * np.abs(inverse).max()
    )
    assert normal.rank == (54 if cost == 'absolute' else 53)


@pytest.mark.parametrize('cost', ['absolute', 'sphere'])
def test_identifiability_from_the_gram_root_matches_the_tall_jacobian(cost):
    block, scales = _scaled_problem(cost)
    normal = NormalEquations.of(block, scales, DEFAULT_RANK_TOLERANCE)
    params = nominal_set(2, seed=0)
    tall = analyze(block.jacobian, params=params)
    small = analyze(block.jacobian, params=params, gram_root=normal.square_root() * scales)
    assert (
        small.rank == tall.rank
        and small.verdict().splitlines()[:2] == tall.verdict().splitlines()[:2]
    )
    assert [d.description for d in small.null_directions] == [
        d.description for d in tall.null_directions
    ]
    identified = slice(0, tall.rank)
    np.testing.assert_allclose(
        small.singular_values[identified], tall.singular_values[identified], rtol=1e-8
    )
    np.testing.assert_allclose(small.condition_number, tall.condition_number, rtol=1e-8)
