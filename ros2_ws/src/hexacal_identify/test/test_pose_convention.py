"""
The contract's pose <-> quaternion convention is the core's eq. 2 rotation.

The contract's pose <-> quaternion convention (hexacal_msgs_py.poses) is the core's eq. 2 rotation.
"""

import math

from hexacal_identify.core.machine.kinematics import rotation_matrices
from hexacal_msgs_py import poses
import numpy as np


def test_contract_quaternions_are_the_core_rotation_matrices():
    rng = np.random.default_rng(3)
    tilt = rng.uniform(-math.radians(35.0), math.radians(35.0), (500, 2))
    angles = np.hstack([tilt, rng.uniform(-math.pi, math.pi, (500, 1))])
    for (theta, psi, phi), expected in zip(angles, rotation_matrices(angles)):
        rotation = np.array(
            poses.rotation_from_quaternion(poses.quaternion_from_angles(theta, psi, phi))
        )
        assert np.allclose(rotation, expected, atol=1e-14, rtol=0)
        back = poses.angles_from_quaternion(poses.quaternion_from_angles(theta, psi, phi))
        assert np.allclose(back, (theta, psi, phi), atol=1e-12)
