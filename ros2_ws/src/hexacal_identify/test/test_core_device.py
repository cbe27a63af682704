"""
Device defects: measurement model, joint identification, identifiability, uncertainty.

The measurement model, joint identification, what is (not) identifiable, robustness, uncertainty.
"""

from hexacal_identify.core.assessment.uncertainty import monte_carlo
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.errors import RankDeficientError
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.machine.device import (
    device_position,
    DeviceDefects,
    inclinometer_readings,
    measured_position,
)
from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.studies.defective_device import (
    DEFAULT_DEFECTS,
    device_frame_poses,
    device_frame_truth,
    IDENTIFIED_WITH_EQ7,
    simulate_procedure,
)
import numpy as np
import pytest

TRUE = table1_parameters()
READINGS = np.random.default_rng(0).uniform(-0.5, 0.5, (2, 30))


def test_device_model_without_defects_is_eq4():
    position = device_position(*READINGS, 0.75).position
    np.testing.assert_allclose(position, measured_position(*READINGS, 0.75), atol=1e-15)


def test_defective_readings_invert_exactly():
    position = device_position(*READINGS, 0.75, DEFAULT_DEFECTS).position
    alpha, beta = inclinometer_readings(position, DEFAULT_DEFECTS)
    np.testing.assert_allclose(np.vstack([alpha, beta]), READINGS, atol=1e-14)


@pytest.mark.parametrize('column, name', list(enumerate(['dL', 'alpha0', 'beta0', 'gamma'])))
def test_device_derivatives_match_finite_differences(column, name):
    analytic = device_position(*READINGS, 0.75, DEFAULT_DEFECTS).d_defects[:, :, column]
    step = 1e-7
    up, down = DEFAULT_DEFECTS.vector.copy(), DEFAULT_DEFECTS.vector.copy()
    up[column] += step
    down[column] -= step
    numeric = (
        device_position(*READINGS, 0.75, DeviceDefects.from_vector(up)).position
        - device_position(*READINGS, 0.75, DeviceDefects.from_vector(down)).position
    ) / (2 * step)
    np.testing.assert_allclose(analytic, numeric, atol=1e-8)


def test_defect_string_parsing_and_errors():
    parsed = DeviceDefects.parse('dL=0.0005,alpha0=2e-4,beta0=-1.5e-4,gamma=1e-4,phi0=1e-4')
    assert parsed == DEFAULT_DEFECTS
    with pytest.raises(ValueError, match='delta'):
        DeviceDefects.parse('delta=1')
    with pytest.raises(ValueError, match='number'):
        DeviceDefects.parse('dL=abc')


@pytest.mark.parametrize('lvdt', [False, True])
def test_joint_identification_recovers_defects_and_machine_without_noise(lvdt):
    measurements = simulate_procedure(TRUE, DEFAULT_DEFECTS, 60, 20, 0.0, seed=1, lvdt=lvdt)
    result = identify(nominal_set(2), measurements, SolverOptions(free_device=IDENTIFIED_WITH_EQ7))
    assert result.reason == CONVERGED and result.rank == 57
    # With gamma != 0 a base rotation about Y imitates beta0 only to first order, so the device
    # frames (base turned by -beta0) hold the truth to ~1e-8, not to rounding.
    for name in IDENTIFIED_WITH_EQ7:
        assert getattr(result.device, name) == pytest.approx(
            getattr(DEFAULT_DEFECTS, name), abs=1e-7
        )
    truth = device_frame_truth(TRUE, DEFAULT_DEFECTS)
    poses = device_frame_poses(validation_poses(TRUE, 30, 1), DEFAULT_DEFECTS)
    assert pose_errors(truth, result.parameters, poses).summary()['position_mean_m'] < 1e-7


def test_frame_defining_defects_are_named_and_refused():
    # gamma = 0: then a base rotation about Y imitates beta0 exactly (with gamma it is only nearly
    # so).
    defects = DeviceDefects(dL=5e-4, alpha0=2e-4, beta0=-1.5e-4, phi0=1e-4)
    measurements = simulate_procedure(TRUE, defects, 60, 20, 0.0, seed=2)
    every_defect = ('dL', 'alpha0', 'beta0', 'gamma', 'phi0')
    with pytest.raises(RankDeficientError) as caught:
        identify(nominal_set(2), measurements, SolverOptions(free_device=every_defect))
    text = str(caught.value)
    assert 'beta0 cannot be told apart from a rotation of the base frame about Y' in text
    assert "phi0 cannot be told apart from a rotation of the platform frame about z'" in text
    assert set(caught.value.report.unidentifiable_parameters) == {'device.beta0', 'device.phi0'}


def test_ignoring_defects_costs_accuracy_that_joint_identification_recovers():
    measurements = simulate_procedure(TRUE, DEFAULT_DEFECTS, 60, 20, 10.0, seed=3)
    truth = device_frame_truth(TRUE, DEFAULT_DEFECTS)
    poses = device_frame_poses(validation_poses(TRUE, 50, 3), DEFAULT_DEFECTS)
    noise = NoiseModel.from_microns(10)
    ignored = identify(nominal_set(2), measurements, SolverOptions(noise=noise))
    joint = identify(
        nominal_set(2), measurements, SolverOptions(free_device=IDENTIFIED_WITH_EQ7, noise=noise)
    )
    error_ignored = pose_errors(truth, ignored.parameters, poses).summary()['position_mean_m']
    error_joint = pose_errors(truth, joint.parameters, poses).summary()['position_mean_m']
    assert error_ignored > 10 * error_joint
    assert abs(joint.device.dL - DEFAULT_DEFECTS.dL) < 4 * joint.device_std[0]


def test_glitched_postures_are_excluded_and_the_result_stays_within_the_noise():
    rng = np.random.default_rng(3)
    poses = sample_poses(TRUE, 60, rng)
    clean = simulate_measurements(TRUE, poses, noise=NoiseModel.from_microns(10), rng=rng)
    corrupted = clean.subset(np.arange(60))
    corrupted.actuator_positions[5, 2] += 0.005
    corrupted.inclinometer[17, 0] += 0.02
    corrupted.rotary[33] += 0.05
    reference = identify(nominal_set(2), clean)
    result = identify(nominal_set(2), corrupted)
    assert set(result.rejected_postures) == {5, 17, 33}
    assert all('outlier' in why for why in result.rejected_postures.values())
    assert (
        np.max(np.abs(result.parameters.vector - reference.parameters.vector) / reference.std)
        < 3.0
    )
    unscreened = identify(nominal_set(2), corrupted, SolverOptions(outlier_threshold=None))
    assert (
        np.max(np.abs(unscreened.parameters.vector - reference.parameters.vector) / reference.std)
        > 30
    )


@pytest.mark.slow
def test_covariance_predicts_the_monte_carlo_spread():
    summary = monte_carlo(seeds=60, postures=50, noise_um=10.0)
    assert 0.9 < np.median(summary.std_ratio) < 1.1
    assert (
        np.mean(np.abs(summary.std_ratio - 1) < 0.25) > 0.9
    )  # 60 seeds: ~9% sampling error per std
    assert abs(summary.pose_error_mean_m / summary.predicted_pose_error_mean_m - 1) < 0.1
    assert 0.8 < np.median(summary.efficiency) < 1.25
    assert 0.8 < summary.variance_factor_mean < 1.2
