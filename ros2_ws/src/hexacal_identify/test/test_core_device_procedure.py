"""Device turned about its link axis, device priors (MAP rows), and the device-procedure study."""

import math

from hexacal_identify.core.errors import InvalidMeasurementError, RankDeficientError
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.fit.residuals import ChannelSigma, CostFunction
from hexacal_identify.core.machine.device import (
    device_position,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
    inclinometer_readings,
)
from hexacal_identify.core.machine.measurements import Measurements, NoiseModel
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.studies.defective_device import DEFAULT_DEFECTS
from hexacal_identify.studies.device_procedure import (
    ALL_BUT_PHI0,
    caliper_prior,
    claims,
    DeviceRow,
    estimator_efficiency,
    procedure_turns,
    PROCEDURES,
    run_row,
    simulate_device_run,
)
import numpy as np
import pytest

TRUE = table1_parameters()
READINGS = np.random.default_rng(0).uniform(-0.5, 0.5, (2, 30))
TURNS = np.tile([0.0, math.pi / 2, math.pi, 3 * math.pi / 2, 0.3], 6)


def test_a_turned_device_reads_the_rotated_direction_and_inverts_exactly():
    position = device_position(*READINGS, 0.75, DEFAULT_DEFECTS, device_turn=TURNS).position
    alpha, beta = inclinometer_readings(position, DEFAULT_DEFECTS, device_turn=TURNS)
    np.testing.assert_allclose(np.vstack([alpha, beta]), READINGS, atol=1e-14)
    # Without defects, turned by pi, the sensor reads the normal readings negated (its axes are -X,
    # -Y).
    normal = inclinometer_readings(position, DeviceDefects())
    reversed_ = inclinometer_readings(position, DeviceDefects(), device_turn=math.pi)
    np.testing.assert_allclose(np.vstack(reversed_), -np.vstack(normal), atol=1e-14)
    # With zero offsets only, the reversed reading is -true + offset: the offsets do not turn sign.
    offsets = DeviceDefects(alpha0=2e-4, beta0=-1.5e-4)
    turned = inclinometer_readings(position, offsets, device_turn=math.pi)
    np.testing.assert_allclose(turned[0], -normal[0] + 2e-4, atol=1e-14)
    np.testing.assert_allclose(turned[1], -normal[1] - 1.5e-4, atol=1e-14)


@pytest.mark.parametrize('column', range(4))
def test_turned_device_derivatives_match_finite_differences(column):
    analytic = device_position(*READINGS, 0.75, DEFAULT_DEFECTS, device_turn=TURNS).d_defects[
        :, :, column
    ]
    step = 1e-7
    up, down = DEFAULT_DEFECTS.vector.copy(), DEFAULT_DEFECTS.vector.copy()
    up[column] += step
    down[column] -= step
    numeric = (
        device_position(*READINGS, 0.75, DeviceDefects.from_vector(up), device_turn=TURNS).position
        - device_position(
            *READINGS, 0.75, DeviceDefects.from_vector(down), device_turn=TURNS
        ).position
    ) / (2 * step)
    np.testing.assert_allclose(analytic, numeric, atol=1e-8)


def test_turned_reading_derivatives_match_finite_differences():
    analytic = device_position(*READINGS, 0.75, DEFAULT_DEFECTS, device_turn=TURNS).d_readings
    step = 1e-7
    for column in range(2):
        up, down = READINGS.copy(), READINGS.copy()
        up[column] += step
        down[column] -= step
        numeric = (
            device_position(*up, 0.75, DEFAULT_DEFECTS, device_turn=TURNS).position
            - device_position(*down, 0.75, DEFAULT_DEFECTS, device_turn=TURNS).position
        ) / (2 * step)
        np.testing.assert_allclose(analytic[:, :, column], numeric, atol=1e-8)


def test_turned_rotary_reading_is_wrapped_and_unwrapped_by_the_cost():
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 12, 0.0, 3, 'quarter-turns')
    assert np.all(np.abs(measurements.rotary) <= math.pi)
    assert set(np.round(measurements.turns, 6)) == {
        round(t, 6) for t in PROCEDURES['quarter-turns']
    }
    cost = CostFunction('absolute', measurements, DeviceModel(), ChannelSigma())
    phi = cost.measured_phi(DEFAULT_DEFECTS)
    assert np.all(np.abs(phi) < math.radians(40))  # the platform's phi, not phi - turn


def test_reversal_separates_the_zero_offsets_exactly():
    """Without noise, a half turn makes beta0 (a frame definition alone) identifiable."""
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 50, 0.0, 1, 'quarter-turns')
    result = identify(nominal_set(2), measurements, SolverOptions(free_device=ALL_BUT_PHI0))
    assert result.reason == CONVERGED
    np.testing.assert_allclose(result.device.vector[:4], DEFAULT_DEFECTS.vector[:4], atol=1e-9)
    one_mounting = simulate_device_run(TRUE, DEFAULT_DEFECTS, 50, 0.0, 1, 'none')
    with pytest.raises(RankDeficientError):
        identify(nominal_set(2), one_mounting, SolverOptions(free_device=ALL_BUT_PHI0))


def test_relative_cost_refuses_turned_postures_by_name():
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 40, 0.0, 1, 'reversal', fixed=10)
    with pytest.raises(InvalidMeasurementError, match='turned about its link'):
        identify(nominal_set(2), measurements, SolverOptions(cost='relative'))


def test_device_turns_survive_subset_and_concatenate():
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 8, 0.0, 1, 'reversal')
    np.testing.assert_array_equal(
        measurements.turns, [0, 0, 0, 0, math.pi, math.pi, math.pi, math.pi]
    )
    assert measurements.subset([0, 1]).device_turn is None  # all normal: the same as no turns
    np.testing.assert_array_equal(measurements.subset([5, 0]).turns, [math.pi, 0])
    plain = Measurements(
        measurements.actuator_positions[:2], measurements.inclinometer[:2], measurements.rotary[:2]
    )
    joined = Measurements.concatenate([plain, measurements.subset([6])])
    np.testing.assert_array_equal(joined.turns, [0, 0, math.pi])
    bad = Measurements(
        measurements.actuator_positions,
        measurements.inclinometer,
        measurements.rotary,
        device_turn=np.full(8, np.nan),
    )
    with pytest.raises(InvalidMeasurementError, match='device_turn'):
        bad.validate()


def test_device_prior_parsing_and_errors():
    prior = DevicePrior.parse('dL=5e-4:10e-6, alpha0=0:50e-6')
    assert (
        prior.names == ('dL', 'alpha0')
        and prior.get('dL') == (5e-4, 10e-6)
        and prior.get('gamma') is None
    )
    for text, message in (
        ('dL=0', 'NAME=VALUE:STD'),
        ('dL=0:-1', 'std positive'),
        ('delta=0:1', 'unknown'),
        ('dL=a:1', 'numbers'),
        ('dL=0:1,dL=0:2', 'twice'),
    ):
        with pytest.raises(ValueError, match=message):
            DevicePrior.parse(text)


def test_a_prior_needs_the_noise_model():
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 30, 10.0, 1)
    with pytest.raises(ValueError, match='reading noise'):
        identify(
            nominal_set(2),
            measurements,
            SolverOptions(device_prior=DevicePrior.parse('dL=5e-4:1e-5')),
        )


def test_prior_rows_enter_the_estimate_and_the_covariance():
    noise = NoiseModel.from_microns(10)
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 50, 10.0, 2)
    free = SolverOptions(free_device=('dL', 'alpha0', 'gamma'), noise=noise)
    without = identify(nominal_set(2, seed=2, exact=TRUE), measurements, free)
    # A very tight prior pins dL at its value; a caliper's +-10 um shrinks its std below 10 um.
    pinned = identify(
        nominal_set(2, seed=2, exact=TRUE),
        measurements,
        SolverOptions(
            free_device=('alpha0', 'gamma'),
            noise=noise,
            device_prior=DevicePrior((('dL', 4.9e-4, 1e-9),)),
        ),
    )
    assert abs(pinned.device.dL - 4.9e-4) < 1e-10
    assert pinned.device_std[0] < 1e-9
    caliper = identify(
        nominal_set(2, seed=2, exact=TRUE),
        measurements,
        SolverOptions(
            free_device=('alpha0', 'gamma'),
            noise=noise,
            device_prior=DevicePrior((('dL', 5e-4, 10e-6),)),
        ),
    )
    assert 'dL' in caliper.free_device
    assert caliper.device_std[0] < 10e-6 < without.device_std[0]
    # Posterior precision = prior precision + data precision (linear Gaussian MAP), to
    # linearisation accuracy.
    expected = 1.0 / np.sqrt(1.0 / 10e-6**2 + 1.0 / without.device_std[0] ** 2)
    assert caliper.device_std[0] == pytest.approx(expected, rel=0.05)


def test_a_prior_makes_a_frame_defining_defect_identifiable():
    noise = NoiseModel.from_microns(10)
    measurements = simulate_device_run(TRUE, DEFAULT_DEFECTS, 40, 10.0, 4)
    result = identify(
        nominal_set(2, seed=4, exact=TRUE),
        measurements,
        SolverOptions(
            free_device=('dL', 'alpha0', 'gamma'),
            noise=noise,
            device_prior=DevicePrior((('beta0', -1.5e-4, 20e-6),)),
        ),
    )
    assert result.identifiability.identifiable
    assert abs(result.device.beta0 + 1.5e-4) < 3 * 20e-6
    assert result.device_std[2] <= 20e-6 * 1.0001


def test_procedure_turns_share_the_postures_out_in_blocks():
    assert procedure_turns('none', 10) is None
    np.testing.assert_array_equal(procedure_turns('reversal', 5), [0, 0, 0, math.pi, math.pi])
    assert len(set(procedure_turns('quarter-turns', 50))) == 4
    with pytest.raises(ValueError, match='unknown procedure'):
        procedure_turns('spin', 4)


def test_caliper_prior_reads_the_truth_with_its_own_error():
    priors = [
        caliper_prior(DEFAULT_DEFECTS, (('dL', 10e-6),), seed).get('dL') for seed in range(200)
    ]
    values = np.array([value for value, _ in priors])
    assert all(std == 10e-6 for _, std in priors)
    assert abs(values.mean() - 5e-4) < 3e-6 and 7e-6 < values.std() < 13e-6


@pytest.mark.slow
def test_quarter_turns_bring_the_true_frame_error_down_and_claims_are_judged():
    seeds = range(3)
    reference = run_row(DeviceRow('ideal', defective=False), TRUE, DEFAULT_DEFECTS, seeds)
    one_mounting = run_row(
        DeviceRow('joint', ('dL', 'alpha0', 'gamma')), TRUE, DEFAULT_DEFECTS, seeds
    )
    turned = run_row(
        DeviceRow(
            'turns', ALL_BUT_PHI0, 'quarter-turns', caliper=(('dL', 10e-6),), claim='procedure'
        ),
        TRUE,
        DEFAULT_DEFECTS,
        seeds,
    )
    assert not turned.failures and len(turned.true_frame_position_m) == 3
    # One mounting leaves the base frame tilted by beta0 (~110 um over the workspace); the turns
    # remove it.
    assert turned.mean(turned.true_frame_position_m) < 0.3 * one_mounting.mean(
        one_mounting.true_frame_position_m
    )
    assert turned.device_rmse()[2] < 10e-6  # beta0 identified
    (claim,) = claims([reference, one_mounting, turned])
    assert claim.value == pytest.approx(
        turned.mean(turned.true_frame_position_m) / reference.mean(reference.true_frame_position_m)
    )
    assert claim.met == (claim.value <= 1.5)


@pytest.mark.slow
def test_efficiency_summary_compares_the_monte_carlo_with_the_bound():
    summary = estimator_efficiency(seeds=8, identified=ALL_BUT_PHI0)
    assert summary.identified == ALL_BUT_PHI0 and summary.failures == 0
    assert np.all(summary.crb_std > 0) and np.all(summary.rmse > 0)
    # 8 seeds: a loose check that the estimator is near its bound, not a measurement of it.
    assert np.all((summary.efficiency > 0.2) & (summary.efficiency < 5))
    assert 0.2 < summary.pose_efficiency < 5


def test_planning_with_device_columns_priors_and_turns():
    from hexacal_identify.core.planning.planner import Plan, plan_postures, PREDICTION

    nominal = nominal_set(2, seed=0, exact=TRUE)
    noise = NoiseModel.from_microns(10)
    plain = plan_postures(nominal, 30, index=PREDICTION, n_candidates=200, seed=1, noise=noise)
    assert (
        plain.plan.device_turns is None
        and plain.candidates.n_parameters == TRUE.layout.n_parameters
    )
    turned = plan_postures(
        nominal,
        30,
        index=PREDICTION,
        n_candidates=200,
        seed=1,
        noise=noise,
        device_columns=ALL_BUT_PHI0,
        device_turns=PROCEDURES['quarter-turns'],
    )
    assert turned.candidates.n_parameters == TRUE.layout.n_parameters + 4
    assert len(turned.candidates) == 800  # every candidate in every mounting
    assert (
        turned.rank == TRUE.layout.n_parameters + 4
    )  # beta0 identifiable: the plan uses several mountings
    turns = turned.plan.turns
    assert len(set(np.round(turns, 9))) >= 2
    assert np.all(np.diff(turns) >= 0)  # grouped by mounting: one remount per turn
    with_prior = plan_postures(
        nominal,
        30,
        index=PREDICTION,
        n_candidates=200,
        seed=1,
        noise=noise,
        device_columns=('alpha0', 'gamma'),
        device_prior=DevicePrior((('dL', 0.0, 1e-5),)),
    )
    assert with_prior.candidates.device_columns == ('dL', 'alpha0', 'gamma')
    scale = with_prior.candidates.scales[TRUE.layout.n_parameters]
    assert with_prior.candidates.start_information()[
        TRUE.layout.n_parameters, TRUE.layout.n_parameters
    ] == pytest.approx(1 / (1e-5 * scale) ** 2)
    # The plan file carries the turns; plans without turns keep their format and fingerprint.
    text = turned.plan.to_text()
    assert 'device_turn: 3.14159' in text
    assert 'device_turn' not in plain.plan.to_text()
    assert (
        plain.plan.fingerprint()
        == Plan(plain.plan.name, 0.75, plain.plan.poses, plain.plan.kinds).fingerprint()
    )
    with pytest.raises(ValueError, match='absolute cost'):
        plan_postures(
            nominal, 30, n_candidates=200, cost='sphere', noise=None, device_columns=('dL',)
        )


def test_plan_files_round_trip_device_turns(tmp_path):
    from hexacal_identify.core.planning.planner import Plan

    poses = np.tile([0.1, 0.0, -0.74, 0.0, 0.0, 0.0], (3, 1))
    plan = Plan(
        'turned', 0.75, poses, np.full(3, 'sphere'), device_turns=[0.0, math.pi, math.pi / 2]
    )
    loaded = Plan.load(plan.save(tmp_path / 'plan.yaml'))
    np.testing.assert_array_equal(loaded.turns, [0.0, math.pi, math.pi / 2])
    assert (
        loaded.fingerprint()
        == plan.fingerprint()
        != Plan('plain', 0.75, poses, np.full(3, 'sphere')).fingerprint()
    )
    with pytest.raises(ValueError, match='device_turn'):
        Plan('bad', 0.75, poses, np.full(3, 'sphere'), device_turns=[0.0, np.nan, 0.0])


def test_planned_rows_simulate_the_plan_on_the_true_sphere():
    from hexacal_identify.studies.device_procedure import ROWS, simulate_planned_run

    row = next(r for r in ROWS if r.planned and r.procedure == 'quarter-turns' and not r.caliper)
    nominal = nominal_set(2, seed=0, exact=TRUE)
    measurements = simulate_planned_run(
        TRUE, nominal, DEFAULT_DEFECTS, 20, 0.0, 0, row, DevicePrior()
    )
    assert len(measurements) == 20 and measurements.device_turn is not None
    result = identify(nominal, measurements, SolverOptions(free_device=ALL_BUT_PHI0))
    # Exact readings on the true sphere of L + dL: the device parameters come back exactly.
    np.testing.assert_allclose(result.device.vector[:4], DEFAULT_DEFECTS.vector[:4], atol=1e-9)
