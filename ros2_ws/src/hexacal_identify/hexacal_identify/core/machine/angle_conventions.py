"""
hexacal's pose angles and the roll-pitch-yaw angles of LinuxCNC (genhexkins) and ROS.

hexacal writes a platform orientation as ``R = R_Y(theta) R_X(psi) R_z(phi)``
(eq. 2): theta about the base Y axis, psi about the base X axis, phi about the
platform's own z axis.  LinuxCNC's genhexkins builds the same matrix from the
A, B, C words (degrees) as ``R = Rz(C) Ry(B) Rx(A)``: roll A about the base X
axis, then pitch B about the base Y axis, then yaw C about the base Z axis
(fixed axes; ROS's roll-pitch-yaw is the same product).  Both describe the
platform frame in the base frame, so a pose converts by its angles alone.

Without a turn about z the numbers are the same (phi = C = 0: theta = B,
psi = A, both products being R_Y R_X), and so is a turn about z alone
(phi = C).  They differ when a turn about z comes with a tilt: hexacal turns
the platform about its own, tilted z axis, genhexkins about the base Z axis
before tilting.  Each set is unique with its middle angle inside
(-90, 90) deg and the others in (-180, 180] deg; at a middle angle of +-90 deg
(gimbal lock) only a sum or difference of the outer angles is defined, and
this module sets the last one (phi, or C) to zero.
"""

from __future__ import annotations

import numpy as np

from ..architectures.common import rotation_from_trig

# cos(middle angle) below this is a gimbal lock: the outer angles are no longer separable.
_GIMBAL_COS = 1e-12

__all__ = [
    'angles_from_rpy',
    'hexacal_rotations',
    'linuxcnc_from_pose',
    'pose_from_linuxcnc',
    'rpy_from_angles',
    'rpy_rotations',
]


def hexacal_rotations(angles: np.ndarray) -> np.ndarray:
    """Return R = R_Y(theta) R_X(psi) R_z(phi) (N, 3, 3) of angles (N, 3) [theta, psi, phi]."""
    angles = np.atleast_2d(np.asarray(angles, dtype=float))
    return rotation_from_trig(np.cos(angles.T), np.sin(angles.T))


def rpy_rotations(rpy: np.ndarray) -> np.ndarray:
    """Return R = Rz(c) Ry(b) Rx(a) (N, 3, 3) of angles (N, 3) [a, b, c] (rad)."""
    rpy = np.atleast_2d(np.asarray(rpy, dtype=float))
    ca, cb, cc = np.cos(rpy.T)
    sa, sb, sc = np.sin(rpy.T)
    rot = np.empty(rpy.shape[:-1] + (3, 3))
    rot[..., 0, 0] = cc * cb
    rot[..., 0, 1] = cc * sb * sa - sc * ca
    rot[..., 0, 2] = cc * sb * ca + sc * sa
    rot[..., 1, 0] = sc * cb
    rot[..., 1, 1] = sc * sb * sa + cc * ca
    rot[..., 1, 2] = sc * sb * ca - cc * sa
    rot[..., 2, 0] = -sb
    rot[..., 2, 1] = cb * sa
    rot[..., 2, 2] = cb * ca
    return rot


def rpy_from_angles(angles: np.ndarray) -> np.ndarray:
    """Return [a, b, c] (N, 3) (rad) with Rz(c) Ry(b) Rx(a) = R_Y(theta) R_X(psi) R_z(phi)."""
    rot = hexacal_rotations(angles)
    cos_b = np.hypot(rot[:, 0, 0], rot[:, 1, 0])
    b = np.arctan2(-rot[:, 2, 0], cos_b)
    locked = cos_b < _GIMBAL_COS
    # Away from the lock: a from the last row, c from the first column.  At the lock (c = 0),
    # R = Ry(b) Rx(a), whose second row is [0, cos a, -sin a].
    a = np.where(
        locked,
        np.arctan2(-rot[:, 1, 2], rot[:, 1, 1]),
        np.arctan2(rot[:, 2, 1], rot[:, 2, 2]),
    )
    c = np.where(locked, 0.0, np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
    return np.column_stack([a, b, c])


def angles_from_rpy(rpy: np.ndarray) -> np.ndarray:
    """Return [theta, psi, phi] (N, 3) (rad) with R_Y(theta) R_X(psi) R_z(phi) = Rz Ry Rx(rpy)."""
    rot = rpy_rotations(rpy)
    cos_psi = np.hypot(rot[:, 1, 0], rot[:, 1, 1])
    psi = np.arctan2(-rot[:, 1, 2], cos_psi)
    locked = cos_psi < _GIMBAL_COS
    # Away from the lock: theta from the last column, phi from the second row.  At the lock
    # (phi = 0), R = R_Y(theta) R_X(psi), whose first column is [cos theta, 0, -sin theta].
    theta = np.where(
        locked,
        np.arctan2(-rot[:, 2, 0], rot[:, 0, 0]),
        np.arctan2(rot[:, 0, 2], rot[:, 2, 2]),
    )
    phi = np.where(locked, 0.0, np.arctan2(rot[:, 1, 0], rot[:, 1, 1]))
    return np.column_stack([theta, psi, phi])


def linuxcnc_from_pose(pose: np.ndarray, length_scale: float = 1.0) -> np.ndarray:
    """
    Return LinuxCNC's X Y Z A B C of hexacal poses.

    Poses (N, 6) or (6,) [x, y, z (m), theta, psi, phi (rad)] -> the same shape of
    [X, Y, Z (m x length_scale, e.g. 1e3 for mm), A, B, C (deg)].
    """
    poses = np.asarray(pose, dtype=float)
    flat = np.atleast_2d(poses)
    out = np.column_stack(
        [flat[:, :3] * length_scale, np.degrees(rpy_from_angles(flat[:, 3:6]))]
    )
    return out.reshape(poses.shape)


def pose_from_linuxcnc(values: np.ndarray, length_scale: float = 1.0) -> np.ndarray:
    """
    Return hexacal poses of LinuxCNC's X Y Z A B C.

    The inverse of ``linuxcnc_from_pose``: (N, 6) or (6,) [X, Y, Z (m x length_scale),
    A, B, C (deg)] -> [x, y, z (m), theta, psi, phi (rad)].
    """
    values = np.asarray(values, dtype=float)
    flat = np.atleast_2d(values)
    out = np.column_stack(
        [flat[:, :3] / length_scale, angles_from_rpy(np.radians(flat[:, 3:6]))]
    )
    return out.reshape(values.shape)
