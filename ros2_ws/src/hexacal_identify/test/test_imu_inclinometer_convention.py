"""
The Imu inclinometer convention reads what core/machine/device.py says.

The Imu inclinometer convention (hexacal_msgs_py.inputs) reads what core/machine/device.py says the
inclinometer reads.

An IMU fixed on the measuring link, axes along the base's at zero reading, turns with the
link. The link hangs (or stands) in a U joint at O whose base-fixed axis is Y and whose
link-fixed axis is X, so its orientation for a platform at p is built here from p alone
(not from the convention's own inverse). Its quaternion, under any heading of the IMU's
world frame, must give device.inclinometer_angles(p), and device.measured_position of
those angles must give p back, on either mount.
"""

from hexacal_identify.core.machine.device import (
    HANGING,
    inclinometer_angles,
    measured_position,
    MOUNTS,
    sphere_z,
)
from hexacal_msgs_py.inputs import (
    inclinometer_angles_to_quaternion,
    InputMapping,
    quaternion_to_inclinometer_angles,
)
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

LINK = 0.75


def link_orientation(position: np.ndarray, mount: str) -> Rotation:
    """
    Return the U-joint link turned to point from O to `position`.

    R_Y(t1) R_X(t2) (0, 0, -1 or +1) = u.
    """
    u = position / np.linalg.norm(position)
    axis = -1.0 if mount == HANGING else 1.0  # the link's direction in its own frame
    t2 = np.arcsin(
        -axis * u[1]
    )  # R_Y(t1) R_X(t2) (0, 0, s) = s (cos t2 sin t1, -sin t2, cos t2 cos t1)
    t1 = np.arctan2(axis * u[0], axis * u[2])
    rotation = Rotation.from_euler('YX', [t1, t2])  # intrinsic: R_Y(t1) R_X(t2)
    assert rotation.apply([0.0, 0.0, axis]) == pytest.approx(u, abs=1e-14)
    return rotation


@pytest.mark.parametrize('mount', MOUNTS)
def test_an_imu_on_the_link_reads_device_readings(mount):
    rng = np.random.default_rng(7)
    xy = rng.uniform(-0.3, 0.3, (100, 2))
    positions = np.column_stack([xy, sphere_z(xy, LINK, mount)])
    alphas, betas = inclinometer_angles(positions, mount)
    for position, alpha, beta in zip(positions, alphas, betas):
        heading = Rotation.from_euler('z', rng.uniform(-np.pi, np.pi))
        quaternion = (heading * link_orientation(position, mount)).as_quat()  # x, y, z, w
        read = quaternion_to_inclinometer_angles(*quaternion)
        assert read == pytest.approx((alpha, beta), abs=1e-13)
        assert measured_position(*read, LINK, mount) == pytest.approx(position, abs=1e-13)


def test_the_inverse_is_the_links_orientation():
    rng = np.random.default_rng(8)
    for alpha, beta in rng.uniform(-0.4, 0.4, (50, 2)):
        position = measured_position(alpha, beta, LINK)
        built = link_orientation(position, HANGING).as_quat()
        inverse = np.array(inclinometer_angles_to_quaternion(alpha, beta))
        assert min(np.abs(built - inverse).max(), np.abs(built + inverse).max()) < 1e-14


def test_signs_and_offsets_undo_a_sensor_mounted_otherwise():
    # An IMU turned by 180 deg about the link (Z): both axes reversed; and tilted by 10 mrad about
    # its X: it reads -alpha - 0.01 and -beta, which signs (-1, -1) and offsets (-0.01, 0) turn
    # back.
    mapping = InputMapping(
        InputMapping.default().actuator_joints,
        inclinometer_signs=(-1, -1),
        inclinometer_offsets_rad=(-0.01, 0.0),
    )
    turned = Rotation.from_euler('z', np.pi) * Rotation.from_euler(
        'x', 0.01
    )  # sensor frame in link frame
    for alpha, beta in [(0.1, -0.05), (-0.2, 0.15), (0.0, 0.0)]:
        position = measured_position(alpha, beta, LINK)
        sensor = link_orientation(position, HANGING) * turned
        raw = quaternion_to_inclinometer_angles(*sensor.as_quat())
        assert mapping.inclinometer_angles(*raw) == pytest.approx((alpha, beta), abs=1e-12)
