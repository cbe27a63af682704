"""
Passive-actuator kinematics and the LVDT link on both machine models (issue #18).

The passive solve reproduces a known pose and the released actuator's reading, its analytic
Jacobian matches finite differences, a pose with no solution near the start is a named error;
the LVDT extension is |P| - L of the six actuators' forward kinematics.
"""

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.errors import InvalidMeasurementError
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.lvdt import (
    extension_gains,
    extension_sensitivity,
    lvdt_extensions,
)
from hexacal_identify.core.modes.passive_actuator import (
    passive_system,
    PassiveSolveError,
    release_conditions,
    solve_passive,
)
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')


def _machine(model: str, count: int = 30, seed: int = 7):
    params = default_parameters(model)
    workspace = params.architecture.default_workspace()
    rng = np.random.default_rng(seed)
    poses = np.array(sample_poses(params, count, rng, 'sphere', workspace))
    return params, poses, workspace.link_length


@pytest.mark.parametrize('model', MODELS)
def test_dropping_one_actuator_and_solving_gives_back_the_pose_and_its_reading(model):
    params, poses, length = _machine(model)
    actuators = inverse_kinematics(params, poses)
    released = np.argmin(release_conditions(params, poses, length), axis=1)
    rows = np.arange(len(poses))
    commanded = actuators.copy()
    commanded[rows, released] = np.nan  # not commanded: the solve must not need it
    start = poses + np.random.default_rng(1).normal(0.0, 2e-3, poses.shape)  # a mm-level guess
    solved = solve_passive(params, commanded, released, start, length)
    solved.raise_if_failed()
    assert np.all(solved.converged)
    assert np.max(np.abs(solved.poses[:, :3] - poses[:, :3])) < 1e-10  # m
    assert np.max(np.abs(solved.poses[:, 3:] - poses[:, 3:])) < 1e-10 / length  # rad
    np.testing.assert_allclose(solved.released_positions, actuators[rows, released], atol=1e-10)
    np.testing.assert_allclose(solved.actuators, actuators, atol=1e-10)


@pytest.mark.parametrize('model', MODELS)
def test_every_released_chain_of_a_well_conditioned_posture_solves(model):
    params, poses, length = _machine(model, count=5)
    conditions = release_conditions(params, poses, length)
    pose = poses[int(np.argmin(np.max(conditions, axis=1)))]  # every release fine here
    actuators = inverse_kinematics(params, pose[None])
    solved = solve_passive(
        params, np.repeat(actuators, 6, axis=0), np.arange(6), np.tile(pose + 1e-3, (6, 1)), length
    )
    assert np.all(solved.converged), solved.failures
    assert np.max(np.abs(solved.poses - pose)) < 1e-10 / length
    np.testing.assert_allclose(solved.released_positions, actuators[0], atol=1e-10)


@pytest.mark.parametrize('model', MODELS)
@pytest.mark.parametrize('released', [0, 3, 5])
def test_the_analytic_jacobian_matches_finite_differences(model, released):
    params, poses, length = _machine(model, count=4)
    commanded = inverse_kinematics(params, poses) + 1e-3  # away from the solution too
    residual, jacobian, _ = passive_system(params, poses, commanded, released, length)
    step = 1e-6
    numeric = np.empty_like(jacobian)
    for k in range(6):
        delta = np.zeros(6)
        delta[k] = step
        plus = passive_system(params, poses + delta, commanded, released, length)[0]
        minus = passive_system(params, poses - delta, commanded, released, length)[0]
        numeric[:, :, k] = (plus - minus) / (2 * step)
    np.testing.assert_allclose(jacobian, numeric, atol=1e-8)
    # Row `released` is the sphere: |P| - L, whatever was commanded there.
    np.testing.assert_allclose(
        residual[:, released], np.linalg.norm(poses[:, :3], axis=1) - length, atol=1e-15
    )


@pytest.mark.parametrize('model', MODELS)
def test_release_conditions_are_those_of_the_six_by_six_systems(model):
    params, poses, length = _machine(model, count=3)
    conditions = release_conditions(params, poses, length)
    for released in range(6):
        jacobian = passive_system(params, poses, np.zeros((3, 6)), released, length)[1]
        jacobian[:, :, 3:] /= length
        np.testing.assert_allclose(conditions[:, released], np.linalg.cond(jacobian), rtol=1e-9)


def test_no_solution_near_the_start_is_a_named_error():
    params, poses, length = _machine('gough_stewart', count=2)
    commanded = inverse_kinematics(params, poses)
    # A link 30 cm longer than the one the five actuators were set for: nothing near the start.
    solved = solve_passive(params, commanded, 2, poses, length + 0.3)
    assert not np.any(solved.converged) and np.all(np.isnan(solved.poses))
    with pytest.raises(PassiveSolveError, match='passive-actuator solve failed for 2 posture'):
        solved.raise_if_failed()
    assert 'near the start' in next(iter(solved.failures.values()))
    with pytest.raises(InvalidMeasurementError, match='chain index 0..5'):
        solve_passive(params, commanded, 6, poses, length)


def test_a_start_on_the_other_side_of_o_is_refused():
    params, poses, length = _machine('hexa_slide', count=1)
    commanded = inverse_kinematics(params, poses)
    solved = solve_passive(params, commanded, 0, poses, length, mount='standing')
    assert not solved.converged[0] and 'another assembly mode' in solved.failures[0]


@pytest.mark.parametrize('model', MODELS)
def test_the_lvdt_extension_is_the_distance_off_the_sphere(model):
    params, poses, length = _machine(model, count=6)
    extension = np.linspace(-4e-3, 4e-3, 6)
    off = poses.copy()
    off[:, :3] *= ((length + extension) / length)[:, None]
    predicted = lvdt_extensions(params, inverse_kinematics(params, off), poses, length)
    np.testing.assert_allclose(predicted, extension, atol=1e-11)
    # de / d lambda against finite differences of the forward kinematics.
    actuators = inverse_kinematics(params, poses)
    step = 1e-6
    numeric = np.stack(
        [
            (
                lvdt_extensions(params, actuators + step * np.eye(6)[k], poses, length)
                - lvdt_extensions(params, actuators - step * np.eye(6)[k], poses, length)
            )
            / (2 * step)
            for k in range(6)
        ],
        axis=1,
    )
    sensitivity = extension_sensitivity(params, poses)
    np.testing.assert_allclose(sensitivity, numeric, atol=1e-7)
    np.testing.assert_allclose(extension_gains(params, poses), np.abs(sensitivity).sum(axis=1))
