"""core/machine/angle_conventions.py: R_Y(theta) R_X(psi) R_z(phi) <-> Rz(C) Ry(B) Rx(A)."""

from hexacal_identify.core.machine.angle_conventions import (
    angles_from_rpy,
    hexacal_rotations,
    linuxcnc_from_pose,
    pose_from_linuxcnc,
    rpy_from_angles,
    rpy_rotations,
)
from hexacal_identify.core.machine.kinematics import rotation_matrices
import numpy as np


def _elementary(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {
        'x': np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        'y': np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        'z': np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


def test_rotations_are_the_products_they_name():
    rng = np.random.default_rng(1)
    for theta, psi, phi in rng.uniform(-np.pi, np.pi, (20, 3)):
        expected = _elementary('y', theta) @ _elementary('x', psi) @ _elementary('z', phi)
        np.testing.assert_allclose(hexacal_rotations([[theta, psi, phi]])[0], expected, atol=1e-15)
        np.testing.assert_allclose(
            rotation_matrices([[theta, psi, phi]])[0], expected, atol=1e-15
        )
    for a, b, c in rng.uniform(-np.pi, np.pi, (20, 3)):
        expected = _elementary('z', c) @ _elementary('y', b) @ _elementary('x', a)
        np.testing.assert_allclose(rpy_rotations([[a, b, c]])[0], expected, atol=1e-15)


def test_both_conventions_give_the_same_rotation():
    angles = np.random.default_rng(2).uniform(-np.pi, np.pi, (2000, 3))
    rpy = rpy_from_angles(angles)
    np.testing.assert_allclose(rpy_rotations(rpy), hexacal_rotations(angles), rtol=0, atol=1e-12)
    back = angles_from_rpy(angles)
    np.testing.assert_allclose(hexacal_rotations(back), rpy_rotations(angles), rtol=0, atol=1e-12)


def test_round_trips_inside_the_principal_ranges():
    rng = np.random.default_rng(3)
    angles = np.column_stack(
        [
            rng.uniform(-np.pi, np.pi, 2000),
            rng.uniform(-np.radians(85), np.radians(85), 2000),
            rng.uniform(-np.pi, np.pi, 2000),
        ]
    )
    np.testing.assert_allclose(angles_from_rpy(rpy_from_angles(angles)), angles, atol=1e-12)
    np.testing.assert_allclose(rpy_from_angles(angles_from_rpy(angles)), angles, atol=1e-12)


def test_tilts_without_a_turn_are_the_same_numbers_and_a_turn_with_a_tilt_is_not():
    for hexacal, rpy in (([0.3, 0, 0], [0, 0.3, 0]), ([0, 0.3, 0], [0.3, 0, 0])):
        np.testing.assert_allclose(rpy_from_angles([hexacal])[0], rpy, atol=1e-15)
    np.testing.assert_allclose(rpy_from_angles([[0.3, 0.2, 0.0]])[0], [0.2, 0.3, 0.0], atol=1e-15)
    np.testing.assert_allclose(rpy_from_angles([[0, 0, 0.3]])[0], [0, 0, 0.3], atol=1e-15)
    assert not np.allclose(rpy_from_angles([[0.3, 0.0, 0.2]])[0], [0.0, 0.3, 0.2], atol=1e-3)


def test_gimbal_lock_keeps_the_rotation():
    for angles in ([0.4, np.pi / 2, 0.3], [-1.0, -np.pi / 2, 0.7]):
        rpy = rpy_from_angles([angles])
        np.testing.assert_allclose(rpy_rotations(rpy), hexacal_rotations([angles]), atol=1e-12)
    for rpy in ([0.4, np.pi / 2, 0.3], [-1.0, -np.pi / 2, 0.7]):
        back = angles_from_rpy([rpy])
        np.testing.assert_allclose(hexacal_rotations(back), rpy_rotations([rpy]), atol=1e-12)


def test_pose_conversion_scales_lengths_and_uses_degrees():
    pose = np.array([0.01, -0.02, -0.75, 0.1, -0.2, 0.3])
    values = linuxcnc_from_pose(pose, 1e3)
    np.testing.assert_allclose(values[:3], [10.0, -20.0, -750.0])
    np.testing.assert_allclose(values[3:], np.degrees(rpy_from_angles([pose[3:]])[0]))
    np.testing.assert_allclose(pose_from_linuxcnc(values, 1e3), pose, atol=1e-15)
    batch = np.vstack([pose, pose * 0.5])
    assert linuxcnc_from_pose(batch).shape == (2, 6)
    np.testing.assert_allclose(pose_from_linuxcnc(linuxcnc_from_pose(batch)), batch, atol=1e-15)
