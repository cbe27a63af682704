"""
The pose <-> geometry_msgs/Pose convention (poses.py).

Eq. 2's rotation as a quaternion and back.
"""

import math

from geometry_msgs.msg import Pose, PoseStamped
from hexacal_msgs_py import poses
from hexacal_msgs_py.errors import InvalidReadingError
import numpy as np
import pytest

WORKSPACE_ANGLE = math.radians(35.0)  # the Hexa Slide's rotation range; the hexapod's is 20 deg


def eq2(theta: float, psi: float, phi: float) -> np.ndarray:
    """R = R_Y(theta) R_X(psi) R_z(phi), written out from the elementary rotations."""
    ct, st, cp, sp, cf, sf = (
        math.cos(theta),
        math.sin(theta),
        math.cos(psi),
        math.sin(psi),
        math.cos(phi),
        math.sin(phi),
    )
    r_y = np.array([[ct, 0, st], [0, 1, 0], [-st, 0, ct]])
    r_x = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    r_z = np.array([[cf, -sf, 0], [sf, cf, 0], [0, 0, 1]])
    return r_y @ r_x @ r_z


def workspace_poses(n: int = 500, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    position = rng.uniform(-0.5, 0.5, (n, 3))
    tilt = rng.uniform(-WORKSPACE_ANGLE, WORKSPACE_ANGLE, (n, 2))
    phi = rng.uniform(-math.pi, math.pi, (n, 1))  # any turn about the platform's own axis
    return np.hstack([position, tilt, phi])


def test_quaternion_is_eq2_rotation():
    # The core's rotation_matrices is checked against this same convention in
    # hexacal_identify/test/test_pose_convention.py (the contract imports nothing of the core).
    angles = workspace_poses()[:, 3:]
    for theta, psi, phi in angles:
        q = poses.quaternion_from_angles(theta, psi, phi)
        assert abs(math.fsum(c * c for c in q) - 1.0) < 1e-15 and q[3] >= 0.0
        rotation = np.array(poses.rotation_from_quaternion(q))
        assert np.allclose(rotation, eq2(theta, psi, phi), atol=1e-14, rtol=0)


def test_round_trip_over_the_workspace():
    for pose in workspace_poses():
        position, quaternion = poses.pose_to_position_quaternion(pose)
        back = np.array(poses.pose_from_position_quaternion(position, quaternion))
        assert np.array_equal(back[:3], pose[:3])
        assert np.allclose(back[3:], pose[3:], atol=1e-14, rtol=0)


def test_elementary_rotations():
    angle = 0.3
    s, c = math.sin(angle / 2), math.cos(angle / 2)
    assert np.allclose(poses.quaternion_from_angles(angle, 0, 0), (0, s, 0, c))  # theta: about Y
    assert np.allclose(poses.quaternion_from_angles(0, angle, 0), (s, 0, 0, c))  # psi: about X
    assert np.allclose(poses.quaternion_from_angles(0, 0, angle), (0, 0, s, c))  # phi: about z
    assert poses.quaternion_from_angles(0, 0, 0) == (0.0, 0.0, 0.0, 1.0)


def test_phi_of_half_a_turn_and_beyond_reads_back_in_range():
    q = poses.quaternion_from_angles(0.1, -0.2, 3.5)  # w >= 0 whatever the angle
    assert q[3] >= 0.0
    theta, psi, phi = poses.angles_from_quaternion(q)
    assert np.allclose((theta, psi, phi), (0.1, -0.2, 3.5 - 2 * math.pi))


def test_messages_round_trip():
    pose = (0.12, -0.03, -0.71, 0.2, -0.1, 1.3)
    message = poses.fill_pose_message(PoseStamped(), pose)
    assert isinstance(message, PoseStamped)
    assert (message.pose.position.x, message.pose.position.y, message.pose.position.z) == pose[:3]
    assert np.allclose(poses.pose_from_message(message), pose, atol=1e-14)
    bare = poses.fill_pose_message(Pose(), pose)
    assert np.allclose(poses.pose_from_message(bare), pose, atol=1e-14)
    # A quaternion a little off unit length (float32 publishers) is normalised.
    bare.orientation.w *= 1.0 + 1e-4
    assert np.allclose(poses.pose_from_message(bare), pose, atol=1e-3)


@pytest.mark.parametrize(
    'quaternion, words',
    [
        ((0.0, 0.0, 0.0, 0.0), 'all zeros'),
        ((0.0, 0.0, 0.0, 2.0), 'norm 2'),
        ((math.nan, 0.0, 0.0, 1.0), 'non-finite'),
        ((0.0, 0.0, 1.0), 'expected 4'),
    ],
)
def test_bad_quaternions_are_refused(quaternion, words):
    with pytest.raises(InvalidReadingError, match=words):
        poses.pose_from_position_quaternion((0.0, 0.0, 0.0), quaternion)


def test_message_defaults_and_a_zero_orientation():
    assert poses.pose_from_message(PoseStamped()) == (0.0,) * 6  # the default orientation is w = 1
    message = PoseStamped()
    message.pose.orientation.w = 0.0
    with pytest.raises(InvalidReadingError, match='not an orientation'):
        poses.pose_from_message(message)


def test_bad_poses_are_refused():
    with pytest.raises(InvalidReadingError, match='expected 6'):
        poses.pose_to_position_quaternion((0.0, 0.0, 0.0))
    with pytest.raises(InvalidReadingError, match='non-finite'):
        poses.pose_to_position_quaternion((0.0, 0.0, math.inf, 0.0, 0.0, 0.0))
    with pytest.raises(InvalidReadingError, match='non-finite'):
        poses.pose_from_position_quaternion((0.0, math.nan, 0.0), (0.0, 0.0, 0.0, 1.0))
