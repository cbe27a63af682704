"""
Pose geometry every architecture shares.

Eq. 2's rotation and the pose Jacobian of a chain closure.

Written per coordinate ((3, N, 6) arrays, one (N, 6) array per axis; no small
einsums) because forward kinematics evaluates it several times per
identification iteration.
"""

from __future__ import annotations

import numpy as np


def rotation_from_trig(cosines: np.ndarray, sines: np.ndarray) -> np.ndarray:
    """
    Return R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2) from cos and sin of the angles.

    R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2) from cos and sin of [theta, psi, phi] (each (3, ...)).
    """
    ct, cp, cf = cosines
    st, sp, sf = sines
    st_sp, ct_sp = st * sp, ct * sp  # each used twice, as (st * sp) * sf etc. are evaluated
    rot = np.empty(cosines.shape[1:] + (3, 3))
    rot[..., 0, 0] = ct * cf + st_sp * sf
    rot[..., 0, 1] = -ct * sf + st_sp * cf
    rot[..., 0, 2] = st * cp
    rot[..., 1, 0] = cp * sf
    rot[..., 1, 1] = cp * cf
    rot[..., 1, 2] = -sp
    rot[..., 2, 0] = -st * cf + ct_sp * sf
    rot[..., 2, 1] = st * sf + ct_sp * cf
    rot[..., 2, 2] = ct * cp
    return rot


class PlatformPoints:
    """R and R B for N poses: what every chain closure starts from (coordinate-major)."""

    __slots__ = ('tilt_trig', 'rotations', 'rotated', 'offsets')

    def __init__(self, platform: np.ndarray, base: np.ndarray, poses: np.ndarray):
        """
        Platform, base: (3, 6) joint centres (platform frame, base frame); poses (N, 6).

        Or, a parameter set per pose row (a stacked batch): platform (N, 3, 6), base (3, N, 6).
        """
        angles = poses[:, 3:6].T
        cosines, sines = np.cos(angles), np.sin(angles)
        self.tilt_trig = np.empty((4, len(poses)))  # ct, st, cp, sp: (4, N)
        self.tilt_trig[0::2] = cosines[:2]
        self.tilt_trig[1::2] = sines[:2]
        self.rotations = rotation_from_trig(cosines, sines)  # (N, 3, 3)
        self.rotated = np.matmul(self.rotations, platform).transpose(1, 0, 2)  # R B, (3, N, 6)
        base = base if base.ndim == 3 else base[:, None, :]
        self.offsets = self.rotated + (poses[:, :3].T[:, :, None] - base)  # P + R B - A, (3, N, 6)


class StackedChains:
    """
    The per-chain constants of K parameter sets, gathered per pose row of a stacked batch.

    ``chains`` are K objects of one class whose slots are arrays with the chain on the last axis
    (coordinate-major (3, 6), or (6,)).  A slot is kept as (..., K, 6) and gathered for N rows
    as (..., N, 6), which an architecture's elementwise IK takes as it takes (..., 6): one call
    for every row, each on its own parameter set.  The platform joints are gathered as
    (N, 3, 6), what PlatformPoints multiplies by the (N, 3, 3) rotations.
    """

    def __init__(self, chains):
        self.kind = type(chains[0])
        self.count = len(chains)
        self.arrays = {
            name: np.stack([getattr(c, name) for c in chains],
                           axis=0 if name == 'platform' else -2)
            for name in self.kind.__slots__
        }

    def __len__(self) -> int:
        return self.count

    def rows(self, machine: np.ndarray):
        """Return constants whose row i are those of parameter set machine[i] (N,)."""
        out = object.__new__(self.kind)
        for name, value in self.arrays.items():
            setattr(out, name, value[machine] if name == 'platform' else value[..., machine, :])
        return out


def euler_rate_axes(angles: np.ndarray) -> np.ndarray:
    """
    Return the unit rotation axes (N, 3, 3) of d theta, d psi, d phi in the base frame.

    Unit axes (N, 3, 3), columns = rotation axes of d theta, d psi, d phi in the base frame.

    omega = e_Y dtheta + R_Y(theta) e_X dpsi + R_Y(theta) R_X(psi) e_z dphi.
    """
    angles = np.asarray(angles, dtype=float)
    ct, cp = np.cos(angles[:, 0]), np.cos(angles[:, 1])
    st, sp = np.sin(angles[:, 0]), np.sin(angles[:, 1])
    axes = np.zeros((len(angles), 3, 3))
    axes[:, 1, 0] = 1.0
    axes[:, 0, 1] = ct
    axes[:, 2, 1] = -st
    axes[:, 0, 2] = st * cp
    axes[:, 1, 2] = -sp
    axes[:, 2, 2] = ct * cp
    return axes


def cross_last(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """
    Return a x b over the last axis.

    Np.cross's products, without its per-call axis handling (FK calls this often).
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def pose_jacobian_rows(rotated: np.ndarray, unit: np.ndarray, tilt_trig: np.ndarray) -> np.ndarray:
    """
    Return d lambda / d X (N, 6, 6) of chains whose d lambda = unit . d(P + R B).

    Position columns: unit.  Angle column k: axis_k . ((R B) x unit), since
    d(R B) = axis_k x R B for a rate about axis_k; the axes of d theta, d psi,
    d phi are e_Y, (ct, 0, -st), (st cp, -sp, ct cp) (euler_rate_axes).
    """
    rb = rotated
    with np.errstate(invalid='ignore'):
        mx = rb[1] * unit[2] - rb[2] * unit[1]  # (R B) x unit, per coordinate
        my = rb[2] * unit[0] - rb[0] * unit[2]
        mz = rb[0] * unit[1] - rb[1] * unit[0]
        ct, st, cp, sp = tilt_trig[:, :, None]
        jac = np.empty(unit.shape[1:] + (6,))
        jac[:, :, 0:3] = unit.transpose(1, 2, 0)
        jac[:, :, 3] = my
        jac[:, :, 4] = ct * mx - st * mz
        jac[:, :, 5] = (st * cp) * mx - sp * my + (ct * cp) * mz
    return jac


def platform_point_derivatives(rotations: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """R^T unit, (N, 6, 3): d lambda / d B of chains whose d lambda = unit . d(R B)."""
    return np.matmul(rotations.transpose(0, 2, 1), unit.transpose(1, 0, 2)).transpose(0, 2, 1)


def platform_point_motion(rotated: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """
    Return d(P + R B) / d X (N, 6, 3, 6) of the platform joints R B (N, 6, 3) at Euler ``angles``.

    Position columns: the identity; angle column k: axis_k x R B (euler_rate_axes).
    """
    axes = euler_rate_axes(angles)  # (N, 3, 3), columns
    motion = np.zeros(rotated.shape + (6,))
    motion[..., :3] = np.eye(3)
    motion[..., 3:] = np.cross(
        axes.transpose(0, 2, 1)[:, None, :, :], rotated[:, :, None, :]
    ).transpose(0, 1, 3, 2)
    return motion


def rigid_leg_motion(
    tips: np.ndarray,
    units: np.ndarray,
    jacobian: np.ndarray,
    rotated: np.ndarray,
    angles: np.ndarray,
    com_fraction: float,
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return how a rigid leg's centre of mass moves (Architecture.leg_mass_motion).

    The leg of fixed length runs from a base-side joint that moves by ``tips`` (N, 6, 3) per
    unit reading (a slider, a crank's tip) to the platform joint R B (``rotated``, N, 6, 3),
    along ``units`` (N, 6, 3); its centre S + f (B - S) moves with the pose as f dB + (1 - f)
    tip d lambda (``jacobian`` d lambda / d X, N, 6, 6).  With the pose held the leg, on the
    platform side of its spring at S, turns about B: (1 - f) (I - u u^T) tip per unit reading.
    """
    across = tips - np.einsum('nci,nci->nc', units, tips)[..., None] * units
    joints = platform_point_motion(rotated, angles)
    base_side = tips[..., None] * jacobian[:, :, None, :]
    return (1.0 - com_fraction) * across, com_fraction * joints + (1.0 - com_fraction) * base_side


def condition_ok(jac: np.ndarray, link_length: float, max_condition: float) -> np.ndarray:
    """Return the mask of pose Jacobians conditioned below max_condition (angles scaled by L)."""
    jac = jac.copy()
    jac[:, :, 3:] /= link_length  # angles -> lengths, so the condition number is unit-free
    return np.linalg.cond(jac) < max_condition


def move_joint_points(
    delta: np.ndarray,
    base_points: np.ndarray,
    platform_points: np.ndarray,
    base_translation=None,
    base_rotation=None,
    platform_translation=None,
    platform_rotation=None,
) -> None:
    """
    Add to ``delta`` (6, fields) the first-order change of the joint points of a frame motion.

    Every architecture keeps the base-side points in fields 0:3 and the platform points in 3:6
    (KinematicParameters.base_points / platform_points); a point p moves by t + w x p.
    """
    if base_translation is not None:
        delta[:, 0:3] += np.asarray(base_translation)
    if base_rotation is not None:
        delta[:, 0:3] += np.cross(base_rotation, base_points)
    if platform_translation is not None:
        delta[:, 3:6] += np.asarray(platform_translation)
    if platform_rotation is not None:
        delta[:, 3:6] += np.cross(platform_rotation, platform_points)
