"""
Kinematics: IK at home, IK/FK round trips, analytic Jacobians vs finite differences.

IK at home, IK/FK round trips over the workspace, analytic Jacobians vs finite differences.
"""

from hexacal_identify.core.errors import InvalidMeasurementError, UnreachablePoseError
from hexacal_identify.core.machine.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    leg_geometry,
    parameter_jacobian_blocks,
    pose_jacobian,
    rotation_matrices,
)
from hexacal_identify.core.machine.model import HexaParameters, nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import acceptable_poses, sample_poses, Workspace
from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

TRUE = table1_parameters()
HOME = np.array([[0.0, 0.0, -0.75, 0.0, 0.0, 0.0]])


def test_home_slider_positions_are_about_315_mm():
    sliders = inverse_kinematics(TRUE, HOME)[0]
    assert np.all(np.abs(sliders - 0.315) < 0.02), sliders


def test_rotation_matches_eq2_composition():
    theta, psi, phi = 0.3, -0.2, 0.5
    ry = np.array(
        [[np.cos(theta), 0, np.sin(theta)], [0, 1, 0], [-np.sin(theta), 0, np.cos(theta)]]
    )
    rx = np.array([[1, 0, 0], [0, np.cos(psi), -np.sin(psi)], [0, np.sin(psi), np.cos(psi)]])
    rz = np.array([[np.cos(phi), -np.sin(phi), 0], [np.sin(phi), np.cos(phi), 0], [0, 0, 1]])
    np.testing.assert_allclose(
        rotation_matrices(np.array([[theta, psi, phi]]))[0], ry @ rx @ rz, atol=1e-15
    )


pose_strategy = st.tuples(
    st.floats(-0.4, 0.4),
    st.floats(-0.4, 0.4),
    st.floats(-0.61, 0.61),
    st.floats(-0.61, 0.61),
    st.floats(-0.61, 0.61),
)


@settings(max_examples=150, deadline=None)
@given(pose_strategy)
def test_ik_fk_round_trip_over_the_workspace(sample):
    x, y, theta, psi, phi = sample
    pose = np.array([[x, y, -np.sqrt(0.75**2 - x**2 - y**2), theta, psi, phi]])
    if not acceptable_poses(TRUE, pose, Workspace(actuator_stroke_m=(-1.0, 2.0)))[0]:
        return  # outside the usable workspace: nothing to round-trip
    sliders = inverse_kinematics(TRUE, pose)
    guess = pose.copy()
    guess[:, 3:5] = 0.0  # the device does not measure theta, psi
    result = forward_kinematics(TRUE, sliders, guess, fit_tilt_first=True)
    assert result.converged[0], result.failures
    np.testing.assert_allclose(result.poses, pose, atol=1e-9)


def test_fk_batched_recovers_many_postures():
    poses = sample_poses(TRUE, 500, np.random.default_rng(4))
    sliders = inverse_kinematics(TRUE, poses)
    start = poses + np.random.default_rng(5).normal(0, [0.005] * 3 + [0.05] * 3, poses.shape)
    result = forward_kinematics(TRUE, sliders, start)
    assert result.converged.all(), result.failures
    np.testing.assert_allclose(result.poses, poses, atol=1e-9)


def test_fk_reports_failures_by_index_and_reason():
    poses = sample_poses(TRUE, 5, np.random.default_rng(6))
    sliders = inverse_kinematics(TRUE, poses)
    sliders[2] = np.nan
    start = poses.copy()
    start[4, :3] += [
        0.3,
        0.0,
        0.0,
    ]  # expected posture 300 mm off: the solution is "another branch"
    result = forward_kinematics(TRUE, sliders, start)
    assert set(result.failures) == {2, 4}
    assert 'non-finite' in result.failures[2]
    assert 'branch' in result.failures[4]
    assert np.isnan(result.poses[[2, 4]]).all() and result.converged[[0, 1, 3]].all()


def test_unreachable_pose_is_a_named_error():
    far = np.array([[3.0, 0.0, -0.75, 0, 0, 0]])
    with pytest.raises(UnreachablePoseError) as caught:
        inverse_kinematics(TRUE, np.vstack([HOME, far]))
    assert caught.value.indices == [1]


def test_nan_pose_is_a_named_error():
    with pytest.raises(InvalidMeasurementError):
        inverse_kinematics(TRUE, np.array([[np.nan, 0, -0.75, 0, 0, 0]]))


def _central(fun, x, h):
    return (fun(x + h) - fun(x - h)) / (2 * h[h != 0][0])


def test_pose_jacobian_matches_finite_differences():
    poses = sample_poses(TRUE, 20, np.random.default_rng(7))
    analytic = pose_jacobian(leg_geometry(TRUE, poses), poses[:, 3:6])
    for k in range(6):
        h = np.zeros(6)
        h[k] = 1e-6
        numeric = _central(lambda p: inverse_kinematics(TRUE, p), poses, h)
        np.testing.assert_allclose(analytic[:, :, k], numeric, atol=1e-8, rtol=1e-6)


def test_parameter_jacobian_matches_finite_differences():
    params = nominal_set(3, seed=1)
    poses = sample_poses(TRUE, 15, np.random.default_rng(8))
    blocks = parameter_jacobian_blocks(params, leg_geometry(params, poses))
    for chain in range(6):
        for field in range(9):
            h = np.zeros(54)
            h[chain * 9 + field] = 1e-7
            plus = inverse_kinematics(HexaParameters(params.vector + h), poses)[:, chain]
            minus = inverse_kinematics(HexaParameters(params.vector - h), poses)[:, chain]
            np.testing.assert_allclose(
                blocks[:, chain, field], (plus - minus) / 2e-7, atol=1e-7, rtol=1e-6
            )


def test_fk_internal_jacobians_match_finite_differences_and_the_public_ones():
    """
    Check FK's internal Jacobians against finite differences and the public ones.

    FK's and the sensitivities' coordinate-major path (_Legs) against IK differences and the
    LegGeometry path.
    """
    from hexacal_identify.core.architectures.hexa_slide import _ChainIK, _Chains

    params = nominal_set(2, seed=3)
    poses = sample_poses(TRUE, 12, np.random.default_rng(9))
    chains = _Chains(params)
    legs = _ChainIK(chains, poses)
    geometry = leg_geometry(params, poses)
    np.testing.assert_allclose(
        legs.actuators, inverse_kinematics(params, poses), rtol=0, atol=1e-15
    )
    jac = legs.pose_jacobian()
    np.testing.assert_allclose(jac, pose_jacobian(geometry, poses[:, 3:6]), rtol=1e-12, atol=1e-12)
    for k in range(6):
        h = np.zeros(6)
        h[k] = 1e-6
        numeric = _central(lambda p: inverse_kinematics(params, p), poses, h)
        np.testing.assert_allclose(jac[:, :, k], numeric, atol=1e-8, rtol=1e-6)
    blocks = legs.parameter_blocks(chains)
    np.testing.assert_allclose(
        blocks, parameter_jacobian_blocks(params, geometry), rtol=1e-12, atol=1e-12
    )
    for chain in range(6):
        for field in range(9):
            h = np.zeros(54)
            h[chain * 9 + field] = 1e-7
            plus = inverse_kinematics(HexaParameters(params.vector + h), poses)[:, chain]
            minus = inverse_kinematics(HexaParameters(params.vector - h), poses)[:, chain]
            np.testing.assert_allclose(
                blocks[:, chain, field], (plus - minus) / 2e-7, atol=1e-7, rtol=1e-6
            )


def test_factored_pose_sensitivity_rows_equal_the_full_array():
    from hexacal_identify.core.machine.kinematics import pose_sensitivities

    params = nominal_set(1, seed=4)
    poses = sample_poses(TRUE, 9, np.random.default_rng(10))
    sensitivity = pose_sensitivities(params, poses)
    full = sensitivity.wrt_parameters
    assert full.shape == (9, 6, 54)
    index = np.array([0, 3, 8])
    np.testing.assert_array_equal(sensitivity.rows(None, slice(5, 6), -1.0), -full[:, 5:6, :])
    np.testing.assert_allclose(
        sensitivity.rows(index, slice(0, 3), 2.5), 2.5 * full[index, :3, :], rtol=1e-15, atol=0
    )
    weights = np.random.default_rng(11).normal(size=(3, 6))
    np.testing.assert_allclose(
        sensitivity.combined(index, weights),
        np.einsum('nk,nkp->np', weights, full[index]),
        rtol=1e-12,
        atol=1e-14 * np.abs(full).max(),
    )
