"""
Property tests of the Gough-Stewart platform through the generic core and the study.

Property tests of the Gough-Stewart platform (6-UPS, 42 parameters) through the generic core and
the study.

IK/FK round trip over its workspace; analytic vs finite-difference d lambda / d X,
d lambda / d u and identification Jacobian; noise-free recovery from every
nominal set; the rank table of every cost function; its parameters file; the
paper-style baseline, the device frames and the uncertainty on it; and
``hexacal study --model gough_stewart --json``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys

from hexacal_identify.core.architectures import architecture, default_parameters
from hexacal_identify.core.assessment.uncertainty import predicted_pose_errors
from hexacal_identify.core.fit.baseline import absolute_residuals
from hexacal_identify.core.fit.identification import CONVERGED
from hexacal_identify.core.fit.residuals import ChannelSigma, CostFunction
from hexacal_identify.core.machine.device import DeviceDefects, DeviceModel
from hexacal_identify.core.machine.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    pose_sensitivities,
)
from hexacal_identify.core.machine.measurements import FIXED, simulate_measurements, SPHERE
from hexacal_identify.core.machine.model import error_stats_mm, nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.studies.accuracy import identifiability_by_cost, run_calibration, StudyRun
from hexacal_identify.studies.defective_device import device_frame_poses, device_frame_truth
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
import numpy as np
import pytest

MODEL = 'gough_stewart'
ARCH = architecture(MODEL)
TRUE = default_parameters(MODEL)
WORKSPACE = ARCH.default_workspace()
N = 42


def _poses(n: int, seed: int, kind: str = SPHERE) -> np.ndarray:
    return sample_poses(TRUE, n, np.random.default_rng(seed), kind, WORKSPACE)


def test_the_default_machine_is_a_42_parameter_gough_stewart():
    assert TRUE.model == MODEL and TRUE.layout.n_parameters == N and TRUE.vector.shape == (N,)
    assert TRUE.layout.actuator_names == tuple(f'leg_{i}' for i in range(1, 7))
    # Realistic size: base joints ~0.5 m and platform joints ~0.2 m from the axis.
    assert np.allclose(np.linalg.norm(TRUE.base_points[:, :2], axis=1), 0.5, atol=3e-3)
    assert np.allclose(np.linalg.norm(TRUE.platform_points[:, :2], axis=1), 0.2, atol=3e-3)


def test_ik_fk_round_trip_over_the_workspace():
    poses = np.concatenate([_poses(300, 1), _poses(100, 2, FIXED)])
    legs = inverse_kinematics(TRUE, poses)
    low, high = WORKSPACE.actuator_stroke_m
    assert np.all((legs >= low) & (legs <= high)), 'sample_poses keeps every leg inside its stroke'
    lengths = legs + TRUE.per_chain[:, 6]
    assert 0.55 < lengths.min() and lengths.max() < 1.15  # legs ~0.6-1.1 m
    rng = np.random.default_rng(3)
    start = poses + np.concatenate(
        [rng.uniform(-5e-3, 5e-3, (len(poses), 3)), rng.uniform(-0.02, 0.02, (len(poses), 3))],
        axis=1,
    )
    fk = forward_kinematics(TRUE, legs, start)
    assert np.all(fk.converged), fk.failures
    assert np.max(np.abs(fk.poses - poses)) < 1e-9
    assert np.max(np.abs(inverse_kinematics(TRUE, fk.poses) - legs)) < 1e-12


def _sliders(params, poses):
    return ARCH.legs(ARCH.chains(params), poses).actuators


def test_pose_jacobian_matches_finite_differences():
    poses = _poses(30, 4)
    analytic = ARCH.legs(ARCH.chains(TRUE), poses).pose_jacobian()
    assert analytic.shape == (30, 6, 6)
    step = 1e-6
    for k in range(6):
        delta = np.zeros(6)
        delta[k] = step
        numeric = (_sliders(TRUE, poses + delta) - _sliders(TRUE, poses - delta)) / (2 * step)
        np.testing.assert_allclose(analytic[:, :, k], numeric, rtol=0, atol=1e-8)


def test_parameter_blocks_match_finite_differences_and_are_block_diagonal():
    poses = _poses(30, 5)
    chains = ARCH.chains(TRUE)
    blocks = ARCH.legs(chains, poses).parameter_blocks(chains)
    assert blocks.shape == (30, 6, 7)
    step = 1e-6
    for index in range(N):
        chain, field = divmod(index, 7)
        delta = np.zeros(N)
        delta[index] = step
        numeric = (
            _sliders(TRUE.with_vector(TRUE.vector + delta), poses)
            - _sliders(TRUE.with_vector(TRUE.vector - delta), poses)
        ) / (2 * step)
        np.testing.assert_allclose(numeric[:, chain], blocks[:, chain, field], rtol=0, atol=1e-8)
        others = np.delete(numeric, chain, axis=1)
        assert np.max(np.abs(others)) < 1e-12, "a chain's parameter moves only its own actuator"
    np.testing.assert_array_equal(blocks[:, :, 6], -1.0)  # d lambda / d l0


def test_identification_jacobian_matches_forward_kinematics_finite_differences():
    poses = _poses(12, 6)
    legs = inverse_kinematics(TRUE, poses)
    sensitivity = pose_sensitivities(TRUE, poses)
    analytic = sensitivity.wrt_parameters
    assert analytic.shape == (12, 6, N)
    step = 1e-6

    def fk(params, readings):
        result = forward_kinematics(params, readings, poses)
        assert np.all(result.converged)
        return result.poses

    for index in range(N):
        delta = np.zeros(N)
        delta[index] = step
        numeric = (
            fk(TRUE.with_vector(TRUE.vector + delta), legs)
            - fk(TRUE.with_vector(TRUE.vector - delta), legs)
        ) / (2 * step)
        np.testing.assert_allclose(analytic[:, :, index], numeric, rtol=0, atol=1e-7)
    for chain in range(6):
        delta = np.zeros(6)
        delta[chain] = step
        numeric = (fk(TRUE, legs + delta) - fk(TRUE, legs - delta)) / (2 * step)
        np.testing.assert_allclose(
            sensitivity.wrt_actuators[:, :, chain], numeric, rtol=0, atol=1e-7
        )


@pytest.mark.parametrize('number', [1, 2, 3])
def test_noise_free_recovery_from_every_nominal_set(number):
    run = StudyRun(true_params=TRUE, nominal_set_number=number, postures=25, noise_um=0.0, seed=0)
    initial = run.nominal().vector - TRUE.vector
    # The nominal set has the architecture's Table 2-like statistics.
    np.testing.assert_allclose(
        error_stats_mm(initial), ARCH.nominal_error_stats_mm[number], atol=5e-3
    )
    outcome = run_calibration(run)
    assert outcome.result.reason == CONVERGED
    assert outcome.result.rank == N and outcome.result.parameters.model == MODEL
    assert np.max(np.abs(outcome.final_parameter_errors)) < 1e-9
    assert outcome.after.summary()['position_mean_m'] < 1e-9
    assert outcome.before.summary()['position_mean_m'] > 1e-3


def test_rank_table_of_every_cost_function():
    rows = {row.cost: row.report for row in identifiability_by_cost(model=MODEL)}
    assert set(rows) == {'absolute', 'sphere', 'fixed', 'sphere-fixed', 'relative'}
    for cost in ('absolute', 'sphere-fixed'):
        assert rows[cost].n_parameters == N and rows[cost].rank == N and rows[cost].identifiable, (
            cost
        )
    # Without an absolute position in every posture, a base rotation about the vertical Y axis of
    # eq. 2 is invisible (about the base origin for eqs. 8 and 12 + 13, about the fixed point for
    # eq. 10).
    for cost in ('sphere', 'fixed', 'relative'):
        report = rows[cost]
        assert report.rank == N - 1 and len(report.null_directions) == 1, cost
        assert re.search(
            r'rotation of the base frame about (the )?Y', report.null_directions[0].description
        ), cost


def test_the_study_defaults_to_the_models_machine_and_workspace():
    assert identifiability_by_cost(model=MODEL)[0].report.n_parameters == N
    run = StudyRun(true_params=TRUE)
    assert run.model == MODEL and run.resolved_workspace == WORKSPACE
    assert StudyRun().model == 'hexa_slide'
    with pytest.raises(ValueError, match='same model'):
        StudyRun(true_params=TRUE, nominal_params=nominal_set(2))


def test_parameters_file_round_trip_and_foreign_keys(tmp_path):
    path = tmp_path / 'gs.yaml'
    save_parameters(path, TRUE.vector, model=MODEL)
    assert 'model: gough_stewart' in path.read_text()
    contents = read_parameters_file(path)
    assert contents.model == MODEL
    np.testing.assert_array_equal(contents.vector, TRUE.vector)
    bad = tmp_path / 'gs_a0.yaml'
    bad.write_text(
        path.read_text().replace(
            '    chain_3.l0:', '    chain_3.A0: [0.0, 0.0, 0.0]\n    chain_3.l0:'
        )
    )
    with pytest.raises(ParameterFileError, match=r'gs_a0\.yaml.*chain_3\.A0.*gough_stewart'):
        read_parameters_file(bad)


def test_paper_style_baseline_residuals_equal_the_batched_ones():
    params = nominal_set(1, seed=0, exact=TRUE)
    poses = _poses(8, 7)
    measurements = simulate_measurements(TRUE, poses)
    function = CostFunction('absolute', measurements, DeviceModel(), ChannelSigma())
    fk = forward_kinematics(
        params, measurements.actuator_positions, function.initial_poses(), fit_tilt_first=True
    )
    batched = function.residuals(fk.poses, None).values.reshape(2, -1)  # [phi rows], [x y z rows]
    per_posture = absolute_residuals(params.vector, measurements, model=MODEL).reshape(-1, 4)
    assert np.all(np.isfinite(per_posture)) and np.max(np.abs(per_posture)) > 1e-4
    np.testing.assert_allclose(per_posture[:, 3], batched[0][:8], atol=1e-10)
    np.testing.assert_allclose(
        per_posture[:, :3].reshape(-1), batched[0][8:].tolist() + batched[1].tolist(), atol=1e-10
    )


def test_device_frames_reproduce_the_defective_readings():
    """
    Check the frame-defining defects equal the same machine in the device's frames.

    The frame-defining defects (beta0, phi0) equal the same machine in the device's frames (device
    study).
    """
    defects = DeviceDefects(beta0=-1.5e-4, phi0=1e-4)
    poses = _poses(20, 8)
    defective = simulate_measurements(TRUE, poses, defects=defects)
    in_frames = simulate_measurements(
        device_frame_truth(TRUE, defects), device_frame_poses(poses, defects)
    )
    assert device_frame_truth(TRUE, defects).model == MODEL
    np.testing.assert_allclose(
        in_frames.actuator_positions, defective.actuator_positions, rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(in_frames.inclinometer, defective.inclinometer, rtol=0, atol=1e-12)
    np.testing.assert_allclose(in_frames.rotary, defective.rotary, rtol=0, atol=1e-15)
    assert np.max(np.abs(device_frame_truth(TRUE, defects).vector - TRUE.vector)) > 1e-5


def test_predicted_pose_errors_use_the_models_parameters():
    run = StudyRun(true_params=TRUE, postures=40, noise_um=10.0, seed=1, weighted=True)
    outcome = run_calibration(run)
    assert outcome.result.covariance.shape == (N + 5, N + 5)
    poses = _poses(10, 9)
    predicted = predicted_pose_errors(TRUE, outcome.result.covariance, poses, samples=500)
    assert predicted.position_mean_m.shape == (10,) and predicted.position_std_m.shape == (10, 3)
    # Same order as the measured error after a +-10 um calibration.
    measured = outcome.after.summary()['position_mean_m']
    assert 0.2 * measured < predicted.position_mean_m.mean() < 5 * measured


def _hexacal(*args):
    return subprocess.run(
        [sys.executable, '-m', 'hexacal_identify.cli', *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
    )


def _check_gough_stewart_payload(payload):
    assert payload['model'] == MODEL
    for key in ('parameters', 'std'):
        chains = payload[key]
        assert sorted(chains) == [f'chain_{i}' for i in range(1, 7)]
        count = 0
        for chain in chains.values():
            assert sorted(chain) == ['A', 'B', 'l0']
            assert len(chain['A']) == 3 and len(chain['B']) == 3 and isinstance(chain['l0'], float)
            count += 7
        assert count == N
    assert payload['identifiability']['n_parameters'] == N and payload['rank'] == N


@pytest.mark.slow
def test_study_json_on_the_default_gough_stewart():
    done = _hexacal(
        'study', '--model', MODEL, '--json', '--postures', '30', '--noise-um', '10', '--seed', '1'
    )
    assert done.returncode == 0, done.stderr
    payload = json.loads(done.stdout)
    _check_gough_stewart_payload(payload)
    validation = payload['validation']
    assert validation['after']['position_mean_m'] < 1e-4 < validation['before']['position_mean_m']


@pytest.mark.slow
def test_study_takes_the_model_from_the_files_and_refuses_a_mismatch(tmp_path):
    truth, nominal, hexa = (
        tmp_path / 'gs_true.yaml',
        tmp_path / 'gs_nominal.yaml',
        tmp_path / 'hexa.yaml',
    )
    save_parameters(truth, TRUE.vector, model=MODEL)
    save_parameters(nominal, nominal_set(1, seed=4, exact=TRUE).vector, model=MODEL)
    save_parameters(hexa, nominal_set(1, seed=4).vector)
    done = _hexacal(
        'study',
        '--json',
        '--true-params',
        truth,
        '--nominal-params',
        nominal,
        '--postures',
        '30',
        '--noise-um',
        '0',
    )
    assert done.returncode == 0, done.stderr
    payload = json.loads(done.stdout)
    _check_gough_stewart_payload(payload)
    assert payload['parameter_error_max_m']['after'] < 1e-9
    for args in (
        ('--true-params', truth, '--nominal-params', hexa),
        ('--model', 'hexa_slide', '--true-params', truth),
    ):
        done = _hexacal('study', '--json', *args)
        assert done.returncode == 2 and done.stdout == ''
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and 'models disagree' in lines[0] and 'gough_stewart' in lines[0]
        assert 'hexa_slide' in lines[0]
