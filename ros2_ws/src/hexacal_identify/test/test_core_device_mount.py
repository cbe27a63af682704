"""
Device mount (#10): hanging and standing.

Hanging (eq. 4 with z < 0, unchanged) and standing (platform above O: p = -p_hanging).
"""

from hexacal_identify.core.architectures.gough_stewart import (
    default_gough_stewart,
    GoughStewartParameters,
)
from hexacal_identify.core.errors import CalibrationError
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.fit.residuals import ChannelSigma, CostFunction
from hexacal_identify.core.machine.device import (
    check_mount,
    device_position,
    DeviceDefects,
    DeviceModel,
    DeviceMountError,
    fixed_point,
    fixed_position,
    inclinometer_angles,
    inclinometer_readings,
    measured_position,
    MOUNTS,
    sphere_z,
)
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.measurements import FIXED, Measurements, SPHERE
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses, Workspace
import numpy as np
import pytest

L = 0.75
READINGS = np.random.default_rng(10).uniform(-0.5, 0.5, (2, 30))
NO_DEFECTS = DeviceDefects()
SMALL = DeviceDefects(dL=5e-4, alpha0=2e-4, beta0=-1.5e-4, gamma=1e-4, phi0=1e-4)
LARGE = DeviceDefects(
    dL=-0.01, alpha0=0.03, beta0=-0.02, gamma=0.05, phi0=0.01
)  # every term of the model matters
DEFECT_CASES = pytest.mark.parametrize(
    'defects', [NO_DEFECTS, SMALL, LARGE], ids=['ideal', 'small', 'large']
)

# Eq. 4 with the hanging sign of z, evaluated to 20 digits by hand (decimal series) at L = 0.75 m.
EQ4 = {
    (0.1, -0.2): (-0.14825760874056289778, -0.07487506248512111423, -0.73137774540136191965),
    (-0.35, 0.4): (0.27435672348525468582, 0.25717335559158851189, -0.64891467347579517483),
}


def _eq4_expression(alpha, beta, length):
    """
    Return eq. 4 as written in device.py before the mount existed.

    Eq. 4 as written in device.py before the mount existed (the hanging arithmetic, bit for bit).
    """
    return np.stack(
        [
            length * np.cos(alpha) * np.sin(beta),
            -length * np.sin(alpha),
            -length * np.cos(alpha) * np.cos(beta),
        ],
        axis=-1,
    )


# -- hanging: unchanged
# ----------------------------------------------------------------------------
def test_hanging_is_eq4_at_hand_computed_values():
    alpha, beta = np.array(list(EQ4)).T
    expected = np.array(list(EQ4.values()))
    np.testing.assert_allclose(measured_position(alpha, beta, L), expected, rtol=0, atol=2e-16)
    np.testing.assert_allclose(
        device_position(alpha, beta, L).position, expected, rtol=0, atol=2e-16
    )
    np.testing.assert_allclose(
        np.column_stack(inclinometer_angles(expected)),
        np.column_stack([alpha, beta]),
        rtol=0,
        atol=1e-15,
    )


def test_hanging_is_the_default_and_runs_the_same_arithmetic():
    assert DeviceModel().mount == 'hanging' and MOUNTS == ('hanging', 'standing')
    np.testing.assert_array_equal(measured_position(*READINGS, L), _eq4_expression(*READINGS, L))
    np.testing.assert_array_equal(
        measured_position(*READINGS, L, 'hanging'), _eq4_expression(*READINGS, L)
    )
    for defects in (NO_DEFECTS, SMALL, LARGE):
        default = device_position(*READINGS, L, defects)
        explicit = device_position(*READINGS, L, defects, 'hanging')
        through_model = DeviceModel(L).position(*READINGS, defects)
        for result in (explicit, through_model):
            np.testing.assert_array_equal(result.position, default.position)
            np.testing.assert_array_equal(result.d_defects, default.d_defects)
            np.testing.assert_array_equal(result.d_readings, default.d_readings)
        positions = default.position
        np.testing.assert_array_equal(
            np.array(inclinometer_readings(positions, defects, 'hanging')),
            np.array(inclinometer_readings(positions, defects)),
        )
    assert np.all(device_position(*READINGS, L).position[:, 2] < 0)


def test_hanging_fixed_point_and_sphere_are_below_the_base_joint():
    np.testing.assert_array_equal(fixed_point(L), [0.0, 0.0, -L])
    np.testing.assert_array_equal(DeviceModel(L).fixed_point, [0.0, 0.0, -L])
    np.testing.assert_array_equal(fixed_position(L).position, [[0.0, 0.0, -L]])
    xy = np.random.default_rng(1).uniform(-0.4, 0.4, (20, 2))
    np.testing.assert_array_equal(sphere_z(xy, L), -np.sqrt(L**2 - np.sum(xy**2, axis=1)))


# -- standing: the convention
# ------------------------------------------------------------------------
def test_standing_formula_is_the_hanging_one_negated():
    alpha, beta = READINGS
    expected = np.column_stack(
        [-L * np.cos(alpha) * np.sin(beta), L * np.sin(alpha), L * np.cos(alpha) * np.cos(beta)]
    )
    np.testing.assert_allclose(
        measured_position(alpha, beta, L, 'standing'), expected, rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(
        device_position(alpha, beta, L, mount='standing').position, expected, rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(
        -np.array(list(EQ4.values())),
        measured_position(*np.array(list(EQ4)).T, L, 'standing'),
        rtol=0,
        atol=2e-16,
    )
    for defects in (NO_DEFECTS, LARGE):
        hanging = device_position(alpha, beta, L, defects)
        standing = DeviceModel(L, 'standing').position(alpha, beta, defects)
        np.testing.assert_array_equal(standing.position, -hanging.position)
        np.testing.assert_array_equal(standing.d_defects, -hanging.d_defects)
        np.testing.assert_array_equal(standing.d_readings, -hanging.d_readings)
        assert np.all(standing.position[:, 2] > 0)


def test_standing_signs_follow_the_rigid_link_through_its_joint():
    """
    Check that a standing link swings opposite to a hanging one.

    A reading that swings a hanging link's lower end to +x (+y) swings an upright link's upper end
    to -x (-y).

    The inclinometer sits upright on the link either way; a reading is one orientation R of the
    link (the U joint at O allows the same ones whichever way the link leaves it): the platform end
    is R (0, 0, -L)
    hanging and R (0, 0, +L) standing.
    """
    small = 0.05
    assert (
        measured_position(0.0, small, L)[0] > 0
        and measured_position(0.0, small, L, 'standing')[0] < 0
    )
    assert (
        measured_position(-small, 0.0, L)[1] > 0
        and measured_position(-small, 0.0, L, 'standing')[1] < 0
    )
    rng = np.random.default_rng(2)
    for q1, q2 in rng.uniform(
        -0.6, 0.6, (20, 2)
    ):  # a U joint: about base Y, then about the link's X
        c1, s1, c2, s2 = np.cos(q1), np.sin(q1), np.cos(q2), np.sin(q2)
        rotation = np.array([[c1, 0, s1], [0, 1, 0], [-s1, 0, c1]]) @ np.array(
            [[1, 0, 0], [0, c2, -s2], [0, s2, c2]]
        )
        down_end, up_end = rotation @ [0.0, 0.0, -L], rotation @ [0.0, 0.0, L]
        for defects in (NO_DEFECTS, LARGE):
            hanging = np.array(inclinometer_readings(down_end, defects, 'hanging'))
            standing = np.array(inclinometer_readings(up_end, defects, 'standing'))
            np.testing.assert_array_equal(standing, hanging)


def test_standing_fixed_point_is_above_the_base_joint():
    np.testing.assert_array_equal(fixed_point(L, 'standing'), [0.0, 0.0, L])
    model = DeviceModel(L, 'standing')
    np.testing.assert_array_equal(model.fixed_point, [0.0, 0.0, L])
    np.testing.assert_allclose(
        model.fixed_position().position, [[0.0, 0.0, L]], rtol=0, atol=1e-16
    )
    for defects in (SMALL, LARGE):  # where the defective inclinometer reads zero
        where = model.fixed_position(defects).position
        assert where[0, 2] > 0 and np.linalg.norm(where) == pytest.approx(
            L + defects.dL, abs=1e-15
        )
        np.testing.assert_allclose(
            np.array(model.readings(where, defects)).ravel(), [0.0, 0.0], atol=1e-15
        )
    xy = np.random.default_rng(3).uniform(-0.4, 0.4, (20, 2))
    z = model.sphere_z(xy)
    assert np.all(z > 0)
    np.testing.assert_array_equal(z, -sphere_z(xy, L))
    np.testing.assert_allclose(
        np.linalg.norm(np.column_stack([xy, z]), axis=1), L, rtol=0, atol=1e-15
    )


@DEFECT_CASES
def test_standing_readings_position_readings_round_trip(defects):
    position = device_position(*READINGS, L, defects, 'standing').position
    assert np.all(position[:, 2] > 0)
    np.testing.assert_allclose(
        np.linalg.norm(position, axis=1), L + defects.dL, rtol=0, atol=1e-15
    )
    back = np.array(inclinometer_readings(position, defects, 'standing'))
    np.testing.assert_allclose(back, READINGS, rtol=0, atol=1e-14)


@DEFECT_CASES
def test_standing_position_readings_position_round_trip(defects):
    rng = np.random.default_rng(4)
    xy = rng.uniform(-0.4, 0.4, (30, 2))
    length = L + defects.dL
    position = np.column_stack([xy, sphere_z(xy, length, 'standing')])
    model = DeviceModel(L, 'standing')
    alpha, beta = model.readings(position, defects)
    np.testing.assert_allclose(
        model.position(alpha, beta, defects).position, position, rtol=0, atol=1e-15
    )
    if defects == NO_DEFECTS:
        np.testing.assert_allclose(
            measured_position(*model.angles(position), L, 'standing'), position, rtol=0, atol=1e-15
        )


@pytest.mark.parametrize('mount', MOUNTS)
@pytest.mark.parametrize('column, name', list(enumerate(['dL', 'alpha0', 'beta0', 'gamma'])))
def test_position_derivatives_wrt_defects_match_finite_differences(mount, column, name):
    for defects in (SMALL, LARGE):
        analytic = device_position(*READINGS, L, defects, mount).d_defects[:, :, column]
        step = 1e-6
        up, down = defects.vector.copy(), defects.vector.copy()
        up[column] += step
        down[column] -= step
        numeric = (
            device_position(*READINGS, L, DeviceDefects.from_vector(up), mount).position
            - device_position(*READINGS, L, DeviceDefects.from_vector(down), mount).position
        ) / (2 * step)
        np.testing.assert_allclose(analytic, numeric, rtol=0, atol=1e-9)


@pytest.mark.parametrize('mount', MOUNTS)
def test_position_derivatives_wrt_readings_match_finite_differences(mount):
    step = 1e-6
    for defects in (NO_DEFECTS, SMALL, LARGE):
        analytic = device_position(*READINGS, L, defects, mount).d_readings
        for column in range(2):
            up, down = READINGS.copy(), READINGS.copy()
            up[column] += step
            down[column] -= step
            numeric = (
                device_position(*up, L, defects, mount).position
                - device_position(*down, L, defects, mount).position
            ) / (2 * step)
            np.testing.assert_allclose(analytic[:, :, column], numeric, rtol=0, atol=1e-9)


# -- bad names
# -----------------------------------------------------------------------------------------
@pytest.mark.parametrize('bad', ['upright', 'Standing', '', None, 1])
def test_unknown_mount_is_a_named_value_error(bad):
    with pytest.raises(
        ValueError, match='device mount must be one of hanging, standing'
    ) as caught:
        DeviceModel(mount=bad)
    assert isinstance(caught.value, DeviceMountError) and isinstance(
        caught.value, CalibrationError
    )
    assert repr(bad) in str(caught.value)
    for call in (
        lambda: check_mount(bad),
        lambda: measured_position(0.1, 0.2, L, bad),
        lambda: device_position(0.1, 0.2, L, NO_DEFECTS, bad),
        lambda: inclinometer_readings([0.0, 0.0, -L], NO_DEFECTS, bad),
        lambda: inclinometer_angles([0.0, 0.0, -L], bad),
        lambda: fixed_point(L, bad),
        lambda: fixed_position(L, NO_DEFECTS, bad),
        lambda: sphere_z(np.zeros((1, 2)), L, bad),
    ):
        with pytest.raises(DeviceMountError, match='hanging, standing'):
            call()


# -- the cost functions on an upright machine
# -----------------------------------------------------------
MIRROR = np.diag([1.0, 1.0, -1.0])  # z -> -z: the default hexapod reflected into an upright one


def _upright_machine() -> GoughStewartParameters:
    hanging = default_gough_stewart()
    return GoughStewartParameters.from_parts(
        hanging.base_points @ MIRROR, hanging.platform_points @ MIRROR, hanging.leg_offsets
    )


def _upright_poses(
    n_sphere: int, n_fixed: int, seed: int, length: float
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return poses of the default (hanging) machine reflected.

    (x, y, -z, -theta, -psi, phi), leg lengths kept.
    """
    hanging = default_gough_stewart()
    workspace = hanging.architecture.default_workspace()
    workspace = Workspace(
        length,
        workspace.xy_range_m,
        workspace.rotation_range_rad,
        workspace.actuator_stroke_m,
        workspace.max_condition,
        workspace.min_joint_cosine,
    )
    rng = np.random.default_rng(seed)
    poses = np.concatenate(
        [
            sample_poses(hanging, n_sphere, rng, SPHERE, workspace),
            sample_poses(hanging, n_fixed, rng, FIXED, workspace),
        ]
    )
    poses[:, [2, 3, 4]] *= -1.0
    return poses, np.array([SPHERE] * n_sphere + [FIXED] * n_fixed)


def _standing_measurements(params, poses, kinds, defects: DeviceDefects) -> Measurements:
    """
    Simulate readings of a standing device (no noise).

    Readings of a standing device (no noise); fixed postures sit where the defective inclinometer
    reads zero.
    """
    model = DeviceModel(L, 'standing')
    poses = poses.copy()
    poses[kinds == FIXED, :3] = model.fixed_position(defects).position[0]
    alpha, beta = model.readings(poses[:, :3], defects)
    return Measurements(
        inverse_kinematics(params, poses),
        np.column_stack([alpha, beta]),
        poses[:, 5] + defects.phi0,
        kinds,
    ), poses


def test_upright_machine_keeps_its_leg_lengths():
    poses, _ = _upright_poses(10, 2, 5, L)
    hanging_poses = poses.copy()
    hanging_poses[:, [2, 3, 4]] *= -1.0
    np.testing.assert_allclose(
        inverse_kinematics(_upright_machine(), poses),
        inverse_kinematics(default_gough_stewart(), hanging_poses),
        rtol=0,
        atol=1e-14,
    )


@pytest.mark.parametrize('cost', ['absolute', 'fixed', 'sphere-fixed'])
def test_standing_costs_vanish_at_the_true_poses_and_their_device_columns_are_exact(cost):
    params = _upright_machine()
    true_length = L + LARGE.dL
    poses, kinds = _upright_poses(12, 4, 6, true_length)
    measurements, poses = _standing_measurements(params, poses, kinds, LARGE)
    assert np.all(poses[:, 2] > 0)
    function = CostFunction(cost, measurements, DeviceModel(L, 'standing'), ChannelSigma())
    used = np.flatnonzero(function.usable())  # eq. 10 alone: the fixed postures only
    measurements, poses = measurements.subset(used), poses[used]
    function = CostFunction(cost, measurements, DeviceModel(L, 'standing'), ChannelSigma())
    n = len(params.vector)
    block = function.residuals(poses, np.zeros((len(poses), 6, n)), LARGE, with_device=True)
    np.testing.assert_allclose(block.values, 0.0, rtol=0, atol=1e-15)
    hanging = CostFunction(cost, measurements, DeviceModel(L), ChannelSigma()).residuals(
        poses, None, LARGE
    )
    assert (
        np.max(np.abs(hanging.values)) > L
    )  # the hanging reading of the same device is the point mirrored
    step = 1e-6
    for column in range(5):
        up, down = LARGE.vector.copy(), LARGE.vector.copy()
        up[column] += step
        down[column] -= step
        numeric = (
            function.residuals(poses, None, DeviceDefects.from_vector(up)).values
            - function.residuals(poses, None, DeviceDefects.from_vector(down)).values
        ) / (2 * step)
        np.testing.assert_allclose(block.jacobian[:, n + column], numeric, rtol=0, atol=1e-9)


def test_standing_initial_poses_are_the_measured_positions():
    params = _upright_machine()
    poses, kinds = _upright_poses(8, 3, 7, L + SMALL.dL)
    measurements, poses = _standing_measurements(params, poses, kinds, SMALL)
    function = CostFunction(
        'sphere-fixed', measurements, DeviceModel(L, 'standing'), ChannelSigma()
    )
    start = function.initial_poses(SMALL)
    np.testing.assert_allclose(start[:, :3], poses[:, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(start[:, 5], poses[:, 5], rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    'cost, defects, free',
    [
        ('absolute', NO_DEFECTS, ()),
        ('sphere-fixed', NO_DEFECTS, ()),
        # beta0 and phi0 are frame definitions (device.py's module doc): zero here so the frames
        # are the true ones.
        ('absolute', DeviceDefects(dL=5e-4, alpha0=2e-4, gamma=1e-4), ('dL', 'alpha0', 'gamma')),
    ],
    ids=['absolute', 'sphere-fixed', 'absolute-with-defects'],
)
def test_noise_free_identification_of_an_upright_hexapod_with_a_standing_device(
    cost, defects, free
):
    true = _upright_machine()
    poses, kinds = _upright_poses(30, 10, 8, L + defects.dL)
    measurements, _ = _standing_measurements(true, poses, kinds, defects)
    result = identify(
        nominal_set(2, exact=true),
        measurements,
        SolverOptions(cost=cost, device=DeviceModel(L, 'standing'), free_device=free),
    )
    assert result.reason == CONVERGED and result.rank == len(true.vector) + len(free)
    assert np.max(np.abs(result.parameters.vector - true.vector)) < 1e-9
    for name in free:
        assert getattr(result.device, name) == pytest.approx(getattr(defects, name), abs=1e-10)


def test_simulated_readings_follow_the_device_mount():
    from hexacal_identify.core.machine.measurements import simulate_measurements

    params = _upright_machine()
    poses, kinds = _upright_poses(8, 2, 9, L + SMALL.dL)
    expected, poses = _standing_measurements(params, poses, kinds, SMALL)
    simulated = simulate_measurements(
        params, poses, kinds, DeviceModel(L, 'standing'), defects=SMALL
    )
    np.testing.assert_array_equal(simulated.inclinometer, expected.inclinometer)
    hanging = simulate_measurements(params, poses, kinds, DeviceModel(L), defects=SMALL)
    np.testing.assert_array_equal(
        hanging.inclinometer,
        np.column_stack(inclinometer_readings(poses[:, :3], SMALL, 'hanging')),
    )
