"""The fit weighs each posture by its measured scatter (Measurements.standard_errors)."""

from dataclasses import replace

from hexacal_identify.core.assessment.adequacy import Verdict
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.errors import InvalidMeasurementError
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.weighting import choose_weights, weight_mode
from hexacal_identify.core.machine.measurements import (
    Measurements,
    NoiseModel,
    ScatterFloor,
    simulate_measurements,
    Weights,
)
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
import numpy as np
import pytest

TRUE = table1_parameters()
NOMINAL = nominal_set(2)
SEEDS = (0, 1, 2)
BASE_STD = 1e-6  # 1 um / 1 urad standard error of a quiet posture's values
NOISY_FACTOR = 10.0  # a third of the postures scatter ten times more


def _scattered(seed: int, count: int = 60) -> Measurements:
    """Return postures whose values carry Gaussian errors of their own (recorded) std."""
    rng = np.random.default_rng([seed, 19])
    exact = simulate_measurements(TRUE, sample_poses(TRUE, count, rng))
    sigma = np.full((count, 9), BASE_STD)
    sigma[rng.permutation(count)[: count // 3]] *= NOISY_FACTOR
    errors = rng.normal(size=(count, 9)) * sigma
    return Measurements(
        exact.actuator_positions + errors[:, :6],
        exact.inclinometer + errors[:, 6:8],
        exact.rotary + errors[:, 8],
        exact.kinds,
        standard_errors=sigma,
    )


def _position_error_m(result) -> float:
    validation = validation_poses(TRUE, 50, 0)
    return pose_errors(TRUE, result.parameters, validation).summary()['position_mean_m']


@pytest.fixture(scope='module')
def fits():
    """Unweighted and scatter-weighted fits of the same postures, per seed."""
    out = {}
    for seed in SEEDS:
        measured = _scattered(seed)
        out[seed] = (
            measured,
            identify(NOMINAL, measured),
            identify(NOMINAL, measured, SolverOptions(scatter_weights=True)),
        )
    return out


def test_weighing_by_scatter_beats_unweighted(fits):
    for seed, (_, unweighted, weighted) in fits.items():
        plain, scatter = _position_error_m(unweighted), _position_error_m(weighted)
        # Measured: about 14-19 um unweighted, about 2 um weighed by the scatter.
        assert scatter < 0.3 * plain, (seed, plain, scatter)
        assert weighted.weights == Weights.SCATTER and not weighted.weighted
        assert unweighted.weights == Weights.NONE


def test_the_variance_factor_is_one_when_the_scatter_is_right(fits):
    factors = []
    for _, _, weighted in fits.values():
        adequacy = weighted.adequacy
        assert adequacy.verdict == Verdict.PASS, adequacy.reason
        assert adequacy.variance_factor == pytest.approx(weighted.variance_factor, rel=1e-9)
        factors.append(weighted.variance_factor)
    assert 0.8 < np.mean(factors) < 1.2
    # The std are the Cramer-Rao bound of the scatter: finite for an identifiable fit.
    assert np.all(np.isfinite(fits[0][2].std)) and np.all(fits[0][2].std > 0)


def test_a_posture_biased_twenty_standard_errors_fails_the_verdict():
    # Screening off: it would set a gross posture aside (the other way the fit says so); here
    # the verdict itself must see a posture 20 standard errors off on one channel.
    options = SolverOptions(scatter_weights=True, outlier_threshold=None)
    for seed in SEEDS:
        measured = _scattered(seed, count=30)
        assert identify(NOMINAL, measured, options).adequacy.verdict == Verdict.PASS
        biased = measured.subset(np.arange(len(measured)))
        biased.actuator_positions[7, 2] += 20.0 * biased.standard_errors[7, 2]
        adequacy = identify(NOMINAL, biased, options).adequacy
        assert adequacy.verdict == Verdict.FAIL, (seed, adequacy.reason)
        assert adequacy.worst_postures[0].name == '7'


def test_zero_standard_errors_are_floored():
    measured = _scattered(0, count=30)
    zero = replace(measured, standard_errors=np.zeros((30, 9)))
    result = identify(NOMINAL, zero, SolverOptions(scatter_weights=True))
    assert result.reason == 'converged'
    assert np.all(np.isfinite(result.parameters.vector)) and np.all(np.isfinite(result.std))
    floor = ScatterFloor()
    at_floor = replace(measured, standard_errors=np.tile(floor.standard_deviations(), (30, 1)))
    same = identify(NOMINAL, at_floor, SolverOptions(scatter_weights=True))
    np.testing.assert_array_equal(result.parameters.vector, same.parameters.vector)
    # The zeros were raised to the floor, channel by channel.
    assert floor.apply(np.zeros((1, 9))).tolist() == [floor.standard_deviations().tolist()]
    with pytest.raises(ValueError, match='positive'):
        ScatterFloor(actuator_m=0.0)


@pytest.mark.parametrize('cost', ['absolute', 'relative'])
def test_uniform_scatter_weighs_as_the_noise_model(cost):
    # The per-posture whitening (own and partner rows of the relative cost) is the shared one's
    # algebra: the same standard deviations give the same fit.
    noise = NoiseModel.from_microns(5.0)
    rng = np.random.default_rng(3)
    poses = np.vstack([sample_poses(TRUE, 40, rng), sample_poses(TRUE, 12, rng, 'fixed')])
    kinds = np.array(['sphere'] * 40 + ['fixed'] * 12)
    measured = simulate_measurements(TRUE, poses, kinds, noise=noise, rng=rng)
    measured.standard_errors = np.tile(noise.standard_deviations(), (len(measured), 1))
    # The relative cost cannot see one base rotation (rank 53): hold it, as a user would.
    common = SolverOptions(cost=cost, allow_rank_deficient=True)
    by_noise = identify(NOMINAL, measured, replace(common, noise=noise))
    by_scatter = identify(NOMINAL, measured, replace(common, scatter_weights=True))
    np.testing.assert_allclose(
        by_scatter.parameters.vector, by_noise.parameters.vector, rtol=0, atol=1e-10
    )
    np.testing.assert_allclose(by_scatter.std, by_noise.std, rtol=1e-6)
    assert by_scatter.variance_factor == pytest.approx(by_noise.variance_factor, rel=1e-6)
    assert by_noise.weighted and by_noise.weights == Weights.NOISE_MODEL
    assert by_noise.to_json()['weights'] == 'noise_model'


def test_scatter_weights_need_every_postures_scatter_and_one_weighting():
    measured = _scattered(0, count=30)
    without = replace(measured, standard_errors=None)
    with pytest.raises(InvalidMeasurementError, match='standard errors of every posture'):
        identify(NOMINAL, without, SolverOptions(scatter_weights=True))
    both = SolverOptions(scatter_weights=True, noise=NoiseModel.from_microns(1.0))
    with pytest.raises(ValueError, match='not both'):
        identify(NOMINAL, measured, both)


def test_measurements_carry_their_standard_errors():
    measured = _scattered(0, count=10)
    part = measured.subset([2, 5])
    np.testing.assert_array_equal(part.standard_errors, measured.standard_errors[[2, 5]])
    whole = Measurements.concatenate([part, measured.subset([1])])
    assert whole.standard_errors.shape == (3, 9)
    mixed = Measurements.concatenate([part, replace(measured.subset([1]), standard_errors=None)])
    assert mixed.standard_errors is None  # known for every posture, or not at all
    negative = measured.subset(np.arange(10))
    negative.standard_errors[4, 7] = -1e-6
    with pytest.raises(InvalidMeasurementError, match=r'negative standard error.*\[4\]'):
        negative.validate()
    wrong = replace(measured, standard_errors=np.ones((10, 8)))
    with pytest.raises(InvalidMeasurementError, match='standard_errors must be'):
        wrong.validate()
    nan = measured.subset(np.arange(10))
    nan.standard_errors[3, 0] = np.nan
    with pytest.raises(InvalidMeasurementError, match=r'non-finite standard_errors.*\[3\]'):
        nan.validate()


def test_the_weights_modes():
    noise = NoiseModel.from_microns(10.0)
    assert choose_weights('auto', 5, 5, noise).weights == Weights.SCATTER
    assert choose_weights('auto', 5, 5, None).weights == Weights.SCATTER
    partial = choose_weights('auto', 3, 5, noise)
    assert partial.weights == Weights.NOISE_MODEL
    assert partial.note.startswith('2 of 5 postures carry no scatter')
    assert choose_weights('auto', 0, 5, None).weights == Weights.NONE
    assert choose_weights('noise-model', 5, 5, noise).weights == Weights.NOISE_MODEL
    assert choose_weights('none', 5, 5, noise).weights == Weights.NONE
    with pytest.raises(InvalidMeasurementError, match='1 of 5 postures carry no scatter'):
        choose_weights('scatter', 4, 5, noise)
    with pytest.raises(ValueError, match='needs the noise model'):
        choose_weights('noise-model', 5, 5, None)
    assert weight_mode('noise_model') == 'noise-model'
    with pytest.raises(ValueError, match='weights must be one of'):
        weight_mode('loud')
