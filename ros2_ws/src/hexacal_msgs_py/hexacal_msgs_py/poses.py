"""
Platform pose <-> geometry_msgs/Pose convention (ROS-free: the standard library only).

hexacal's pose is ``X = [x, y, z, theta, psi, phi]`` (eq. 1): the position of
the platform frame's origin P in the base frame (m) and three angles (rad)
with

    R = R_Y(theta) R_X(psi) R_z(phi)                                   (eq. 2)

psi about the base X axis, theta about the base Y axis, phi about the
platform's own z axis; R maps platform-frame vectors to the base frame.

On ``hexacal/platform_pose`` and ``hexacal/target_pose``
(``geometry_msgs/msg/PoseStamped``, ``header.frame_id`` = the base frame) the
same pose is written the ROS way (REP 103: SI units, right-handed frames):

* ``pose.position`` = (x, y, z) in m, P in the base frame;
* ``pose.orientation`` = the unit quaternion (x, y, z, w) of the same R, i.e.
  the platform frame's orientation in the base frame (what a TF
  base -> platform would carry): q = q_Y(theta) * q_X(psi) * q_z(phi)
  (Hamilton product, q_A(a) = (axis sin(a/2), cos(a/2))), written with
  w >= 0.

Back from a message: R from the quaternion, then

    psi = asin(-R[1][2]),  theta = atan2(R[0][2], R[2][2]),  phi = atan2(R[1][0], R[1][1])

which inverts eq. 2 for |psi| < 90 deg (every hexacal workspace: the
platform is never tilted by a right angle about X), with theta and phi in
(-180, 180] deg.  A message's quaternion must be a unit quaternion to within
``QUATERNION_NORM_TOLERANCE`` (it is normalised): an all-zero orientation (a
hand-filled message that forgot w; the message default is w = 1, the identity)
is refused rather than read as some rotation.

The message functions read and write the fields of any object shaped like
``geometry_msgs/msg/Pose`` (or ``PoseStamped``: its ``pose``) without
importing it.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Any

from hexacal_msgs_py.errors import InvalidReadingError

POSE_FIELDS = ('x', 'y', 'z', 'theta', 'psi', 'phi')  # m, m, m, rad, rad, rad
QUATERNION_NORM_TOLERANCE = 1e-3  # |q| may differ from 1 by this much (then it is normalised)

Quaternion = tuple[float, float, float, float]  # (x, y, z, w), ROS order
Matrix = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _product(a: Quaternion, b: Quaternion) -> Quaternion:
    """Hamilton product a * b of quaternions in (x, y, z, w) order."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def quaternion_from_angles(theta: float, psi: float, phi: float) -> Quaternion:
    """
    Return the unit quaternion (x, y, z, w) of R (eq. 2).

    Unit quaternion (x, y, z, w), w >= 0, of R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2).
    """
    about_y = (0.0, math.sin(theta / 2.0), 0.0, math.cos(theta / 2.0))
    about_x = (math.sin(psi / 2.0), 0.0, 0.0, math.cos(psi / 2.0))
    about_z = (0.0, 0.0, math.sin(phi / 2.0), math.cos(phi / 2.0))
    q = _product(_product(about_y, about_x), about_z)
    return tuple(-c for c in q) if q[3] < 0.0 else q  # type: ignore[return-value]


def rotation_from_quaternion(quaternion: Sequence[float]) -> Matrix:
    """
    Return the rotation matrix of a unit quaternion (x, y, z, w).

    The rotation matrix (rows) of a unit quaternion (x, y, z, w), checked and normalised.
    """
    x, y, z, w = _unit(quaternion)
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        (2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        (2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)),
    )


def angles_from_rotation(rotation: Sequence[Sequence[float]]) -> tuple[float, float, float]:
    """(theta, psi, phi) of R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2), for |psi| < 90 deg."""
    psi = math.asin(max(-1.0, min(1.0, -rotation[1][2])))
    theta = math.atan2(rotation[0][2], rotation[2][2])
    phi = math.atan2(rotation[1][0], rotation[1][1])
    return theta, psi, phi


def angles_from_quaternion(quaternion: Sequence[float]) -> tuple[float, float, float]:
    """
    Return (theta, psi, phi) of a unit quaternion (x, y, z, w).

    InvalidReadingError if it is not one.
    """
    return angles_from_rotation(rotation_from_quaternion(quaternion))


def pose_to_position_quaternion(
    pose: Sequence[float],
) -> tuple[tuple[float, float, float], Quaternion]:
    """[x, y, z, theta, psi, phi] -> ((x, y, z), (qx, qy, qz, qw))."""
    values = _finite(pose, 6, 'pose [x, y, z, theta, psi, phi]')
    return (values[0], values[1], values[2]), quaternion_from_angles(
        values[3], values[4], values[5]
    )


def pose_from_position_quaternion(
    position: Sequence[float], quaternion: Sequence[float]
) -> tuple[float, ...]:
    """
    Return [x, y, z, theta, psi, phi] of a position and quaternion.

    ((x, y, z), (qx, qy, qz, qw)) -> [x, y, z, theta, psi, phi] (InvalidReadingError naming a
    problem).
    """
    x, y, z = _finite(position, 3, 'position')
    return (x, y, z, *angles_from_quaternion(quaternion))


def pose_from_message(message: Any) -> tuple[float, ...]:
    """[x, y, z, theta, psi, phi] of a geometry_msgs Pose or PoseStamped."""
    pose: Any = getattr(message, 'pose', message)  # a Pose, duck-typed: no message import
    p, q = pose.position, pose.orientation
    return pose_from_position_quaternion((p.x, p.y, p.z), (q.x, q.y, q.z, q.w))


def fill_pose_message(message: Any, pose: Sequence[float]) -> Any:
    """
    Write [x, y, z, theta, psi, phi] into a geometry_msgs Pose.

    Write [x, y, z, theta, psi, phi] into a geometry_msgs Pose (or a PoseStamped's pose); returns
    it.
    """
    target: Any = getattr(message, 'pose', message)
    (x, y, z), (qx, qy, qz, qw) = pose_to_position_quaternion(pose)
    target.position.x, target.position.y, target.position.z = x, y, z
    target.orientation.x, target.orientation.y = qx, qy
    target.orientation.z, target.orientation.w = qz, qw
    return message


def _finite(values: Sequence[float], size: int, what: str) -> tuple[float, ...]:
    try:
        numbers = tuple(float(v) for v in values)
    except (TypeError, ValueError) as error:
        raise InvalidReadingError(f'{what}: not numbers ({error})') from None
    if len(numbers) != size:
        raise InvalidReadingError(f'{what}: expected {size} values, got {len(numbers)}')
    if not all(math.isfinite(v) for v in numbers):
        raise InvalidReadingError(f'{what}: non-finite value in {list(numbers)}')
    return numbers


def _unit(quaternion: Sequence[float]) -> Quaternion:
    x, y, z, w = _finite(quaternion, 4, 'orientation quaternion (x, y, z, w)')
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise InvalidReadingError(
            f'orientation quaternion (x, y, z, w) = ({x:g}, {y:g}, {z:g}, {w:g}) has norm '
            f'{norm:g}, not 1: not an orientation'
            + (' (all zeros; the identity is w = 1)' if norm == 0.0 else '')
        )
    return x / norm, y / norm, z / norm, w / norm
