"""
The Gough-Stewart platform (6-UPS): 42 parameters, six extensible legs.

Each leg joins a base joint to a platform joint.

Per chain (leg), chain-major: ``Ax Ay Az`` the base joint centre in the base
frame, ``Bx By Bz`` the platform joint centre in the platform frame, ``l0`` the
leg length at actuator reading zero (SI units, metres).  The actuator reading
lambda is the leg extension::

    |P + R B - A| = lambda + l0

so with ``d = P + R B - A`` and ``n = d / |d|`` (the unit leg direction)
inverse kinematics is ``lambda = |d| - l0`` and every derivative is closed form:

* d lambda / d d = n,  d lambda / d A = -n,  d lambda / d B = R^T n,
  d lambda / d l0 = -1.

Pose, rotation convention, device and rotary sensor are the Hexa Slide's: the
device's base joint at the base origin, the platform hanging below it (a
ceiling-mounted hexapod; ``device.mount: standing`` for an upright one).

The default machine (``default_parameters``): base joints on a 0.5 m circle in
the base plane, platform joints on a 0.2 m circle 15 mm above the platform
plane, in pairs 30 deg apart (the classic 6-6 layout), with a few millimetres
of as-built irregularity so that no symmetry hides a parameter; legs 0.60 m at
reading zero with 0.5 m of stroke (0.60-1.10 m).  Its nominal sets add errors
with Table 2's statistics (the same three rows), drawn over 42 parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_msgs_py.models import GOUGH_STEWART, MODELS
import numpy as np

from .base import (
    ACTUATED,
    ACTUATOR_BODY,
    Architecture,
    ChainMechanism,
    COMPLIANCE,
    HINGE,
    KinematicParameters,
    LEG_BODY,
    MechanismBody,
    MechanismJoint,
    PASSIVE,
    SLIDE,
    universal_joint_axes,
)
from .common import (
    condition_ok,
    move_joint_points,
    platform_point_derivatives,
    platform_point_motion,
    PlatformPoints,
    pose_jacobian_rows,
    rotation_from_trig,
)
from .stacking import ElementwiseStacking

LAYOUT = MODELS[GOUGH_STEWART]
N_CHAINS = LAYOUT.n_chains
FIELDS_PER_CHAIN = LAYOUT.fields_per_chain
N_PARAMETERS = LAYOUT.n_parameters
A_SLICE = slice(0, 3)
B_SLICE = slice(3, 6)
L0_INDEX = 6

BASE_RADIUS_M = 0.5
PLATFORM_RADIUS_M = 0.2
PLATFORM_JOINT_HEIGHT_M = 0.015
LEG_OFFSET_M = 0.60
STROKE_M = (0.0, 0.5)
# Joint angles (deg) of legs 1..6: base pairs around 0/120/240, platform pairs around 60/180/300,
# each leg joining a base joint to the nearer joint of the neighbouring platform pair.
_BASE_ANGLES_DEG = (-15.0, 15.0, 105.0, 135.0, 225.0, 255.0)
_PLATFORM_ANGLES_DEG = (-45.0, 45.0, 75.0, 165.0, 195.0, 285.0)
# As-built irregularity (mm), per leg: base x, y, z, platform x, y, z, l0.
_AS_BUILT_MM = np.array(
    [
        [1.2, -0.8, 0.5, -0.4, 0.3, 0.2, 0.7],
        [-0.9, 1.1, -0.3, 0.5, -0.2, -0.1, -0.4],
        [0.6, 0.4, 0.9, -0.3, -0.5, 0.3, 0.2],
        [-1.1, -0.6, -0.7, 0.2, 0.4, -0.2, -0.6],
        [0.8, -1.2, 0.2, -0.5, 0.1, 0.1, 0.5],
        [-0.5, 0.9, -0.6, 0.4, -0.3, -0.3, -0.3],
    ]
)


@dataclass(frozen=True)
class GoughStewartParameters(KinematicParameters):
    """The 42 kinematic parameters of a 6-UPS platform; ``vector`` is chain-major (module doc)."""

    @property
    def leg_offsets(self) -> np.ndarray:
        """l0, the leg lengths at actuator reading zero, (6,)."""
        return self.per_chain[:, L0_INDEX]

    @classmethod
    def from_parts(
        cls, base_points: np.ndarray, platform_points: np.ndarray, leg_offsets: np.ndarray
    ) -> 'GoughStewartParameters':
        blocks = np.column_stack(
            [np.asarray(base_points), np.asarray(platform_points), np.asarray(leg_offsets)]
        )
        return cls(blocks.reshape(-1))


def default_gough_stewart() -> GoughStewartParameters:
    """Return the shipped default hexapod (module doc), rounded to 1e-10 m like Table 1's file."""
    base_angles, platform_angles = np.radians(_BASE_ANGLES_DEG), np.radians(_PLATFORM_ANGLES_DEG)
    base = np.column_stack(
        [
            BASE_RADIUS_M * np.cos(base_angles),
            BASE_RADIUS_M * np.sin(base_angles),
            np.zeros(N_CHAINS),
        ]
    )
    platform = np.column_stack(
        [
            PLATFORM_RADIUS_M * np.cos(platform_angles),
            PLATFORM_RADIUS_M * np.sin(platform_angles),
            np.full(N_CHAINS, PLATFORM_JOINT_HEIGHT_M),
        ]
    )
    exact = (
        np.column_stack([base, platform, np.full(N_CHAINS, LEG_OFFSET_M)]) + _AS_BUILT_MM / 1000.0
    )
    return GoughStewartParameters(np.round(exact, 10).reshape(-1))


class _Chains:
    """
    Per-chain constants, coordinate-major ((3, 6) arrays).

    Or those of a stacked batch's rows (common.StackedChains): (3, N, 6), platform (N, 3, 6).
    """

    __slots__ = ('base', 'platform', 'offsets')

    def __init__(self, params: GoughStewartParameters):
        per_chain = params.per_chain
        self.base = np.ascontiguousarray(per_chain[:, A_SLICE].T)
        self.platform = np.ascontiguousarray(per_chain[:, B_SLICE].T)
        self.offsets = per_chain[:, L0_INDEX].copy()


class _ChainIK:
    """IK lambda = |P + R B - A| - l0 for N postures x 6 legs, coordinate-major ((3, N, 6))."""

    __slots__ = ('tilt_trig', 'rotations', 'rotated', 'actuators', 'legs', 'lengths')

    def __init__(self, chains: _Chains, poses: np.ndarray):
        points = PlatformPoints(chains.platform, chains.base, poses)
        self.tilt_trig, self.rotations, self.rotated = (
            points.tilt_trig,
            points.rotations,
            points.rotated,
        )
        d = points.offsets  # A -> B
        self.legs = d
        self.lengths = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        self.actuators = self.lengths - chains.offsets

    def subset(self, mask: np.ndarray) -> '_ChainIK':
        out = object.__new__(_ChainIK)
        out.tilt_trig, out.rotations = self.tilt_trig[:, mask], self.rotations[mask]
        out.rotated, out.legs = self.rotated[:, mask], self.legs[:, mask]
        out.actuators, out.lengths = self.actuators[mask], self.lengths[mask]
        return out

    def replace_rows(self, mask: np.ndarray, rows: '_ChainIK') -> None:
        for name in ('rotations', 'actuators', 'lengths'):
            getattr(self, name)[mask] = getattr(rows, name)
        self.tilt_trig[:, mask] = rows.tilt_trig
        self.rotated[:, mask] = rows.rotated
        self.legs[:, mask] = rows.legs

    def reachable(self) -> np.ndarray:
        # A leg of zero length has no direction; any other length is reachable (the stroke is a
        # workspace limit, checked where postures are chosen, not a kinematic one).
        return np.all(self.lengths > 0.0, axis=1)

    def unit_legs(self) -> np.ndarray:
        """Return n = d / |d|, (3, N, 6)."""
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.legs / self.lengths

    def pose_jacobian(self, unit: np.ndarray | None = None) -> np.ndarray:
        """Return d lambda / d X, (N, 6, 6): rows (n, (R B x n) on the Euler-rate axes)."""
        unit = self.unit_legs() if unit is None else unit
        return pose_jacobian_rows(self.rotated, unit, self.tilt_trig)

    def parameter_blocks(self, chains: _Chains, unit: np.ndarray | None = None) -> np.ndarray:
        """Return d lambda_c / d u_c, (N, 6, 7): -n, R^T n, -1."""
        unit = self.unit_legs() if unit is None else unit
        blocks = np.empty(unit.shape[1:] + (FIELDS_PER_CHAIN,))
        blocks[..., 0:3] = -unit.transpose(1, 2, 0)
        blocks[..., 3:6] = platform_point_derivatives(self.rotations, unit)
        blocks[..., 6] = -1.0
        return blocks


class GoughStewart(ElementwiseStacking, Architecture[GoughStewartParameters]):
    """6-UPS: universal joint on the base, prismatic leg, spherical joint on the platform."""

    name = GOUGH_STEWART
    layout = LAYOUT
    unreachable_reason = 'a leg of zero length'
    parameters_type = GoughStewartParameters
    chain_ik = _ChainIK  # stacked rows too (ElementwiseStacking)
    nominal_error_stats_mm = {1: (1.8, 0.80, 0.87), 2: (2.8, 1.33, 1.45), 3: (9.2, 4.99, 5.28)}

    def default_machine_comment(self, params: KinematicParameters) -> str:
        """Return the header of the shipped default file (what hexacal_identify/data/ ships)."""
        low, high = self.default_workspace().actuator_stroke_m
        chains = params.per_chain
        base_radius = float(np.mean(np.hypot(chains[:, 0], chains[:, 1])))
        platform_radius = float(np.mean(np.hypot(chains[:, 3], chains[:, 4])))
        offsets = chains[:, L0_INDEX]
        return (
            f'Default {LAYOUT.title} of hexacal (SI units): base joints on a '
            f'{base_radius:.2f} m circle,\n'
            f'platform joints on a {platform_radius:.2f} m circle, with mm-level as-built '
            'irregularity.\n'
            f'Stroke limits ({low:g}, {high:g}) m of the actuator reading lambda; l0 '
            f'{offsets.min():.4f}-{offsets.max():.4f} m, so legs '
            f'{offsets.min() + low:.2f}-{offsets.max() + high:.2f} m.\n'
            f'Written by `hexacal params default --model {self.name}`.'
        )

    def default_parameters(self) -> GoughStewartParameters:
        return default_gough_stewart()

    def default_workspace(self):
        from ..machine.postures import Workspace

        return Workspace(
            xy_range_m=0.25, rotation_range_rad=float(np.radians(20.0)), actuator_stroke_m=STROKE_M
        )

    def chains(self, params: GoughStewartParameters) -> _Chains:
        return _Chains(params)

    def legs(self, chains: _Chains, poses: np.ndarray) -> _ChainIK:
        return _ChainIK(chains, poses)

    def acceptable_poses(
        self, params: GoughStewartParameters, poses: np.ndarray, workspace
    ) -> np.ndarray:
        legs = _ChainIK(_Chains(params), np.asarray(poses, dtype=float))
        low, high = workspace.actuator_stroke_m
        ok = legs.reachable() & np.all((legs.actuators >= low) & (legs.actuators <= high), axis=1)
        # Joints away from their limits (min_joint_cosine reads as the least joint-angle
        # cosine).
        base_cos, platform_cos = self._cosines(legs)
        ok &= np.all(base_cos > workspace.min_joint_cosine, axis=1)
        ok &= np.all(platform_cos > workspace.min_joint_cosine, axis=1)
        conditioned = np.zeros(len(poses), bool)
        if np.any(ok):
            conditioned[ok] = condition_ok(
                legs.subset(ok).pose_jacobian(), workspace.link_length, workspace.max_condition
            )
        return ok & conditioned

    @staticmethod
    def _cosines(legs: _ChainIK) -> tuple[np.ndarray, np.ndarray]:
        unit = legs.unit_legs()  # (3, N, 6), A -> B
        # The joints' neutral axes are normal to the base and platform planes, pointing along the
        # legs: down from a ceiling-mounted base, up from an upright one; |cos| serves both mounts.
        base_cos = np.abs(unit[2])
        normal = legs.rotations[:, :, 2]  # z' in the base frame, (N, 3)
        platform_cos = np.abs(
            unit[0] * normal[:, 0:1] + unit[1] * normal[:, 1:2] + unit[2] * normal[:, 2:3]
        )
        return base_cos, platform_cos

    def joint_cosines(
        self, params: GoughStewartParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        return self._cosines(_ChainIK(_Chains(params), np.asarray(poses, dtype=float)))

    def frame_motion(
        self,
        params: GoughStewartParameters,
        base_translation=None,
        base_rotation=None,
        platform_translation=None,
        platform_rotation=None,
    ) -> np.ndarray:
        delta = np.zeros((N_CHAINS, FIELDS_PER_CHAIN))
        move_joint_points(
            delta,
            params.base_points,
            params.platform_points,
            base_translation,
            base_rotation,
            platform_translation,
            platform_rotation,
        )
        return delta.reshape(-1)

    def actuator_zero_shift(
        self, params: GoughStewartParameters, chain: int
    ) -> tuple[str, np.ndarray]:
        delta = np.zeros((N_CHAINS, FIELDS_PER_CHAIN))
        delta[chain, L0_INDEX] = 1.0
        return f"chain_{chain + 1}'s leg offset l0 (a leg-length zero offset)", delta.reshape(-1)

    def in_frames(
        self,
        params: GoughStewartParameters,
        base_rotation: np.ndarray,
        platform_rotation: np.ndarray,
    ) -> GoughStewartParameters:
        return GoughStewartParameters.from_parts(
            params.base_points @ base_rotation.T,
            params.platform_points @ platform_rotation.T,
            params.leg_offsets,
        )

    def actuator_mass_motion(
        self, params: GoughStewartParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the extending rods' motion (Base): a rigid rod hanging from the platform joint.

        The rod's middle lies d = (|B - A| - l0) / 2 before B along the leg's unit u (as
        ``mechanism`` places it), on the platform side of the leg's spring: the pose held, it
        does not move with the reading.  With the pose, the rigid rod (d fixed) follows B and
        turns with u: d(B - d u) = (I - (d / |B - A|) (I - u u^T)) dB.
        """
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        points = PlatformPoints(params.platform_points.T, params.base_points.T, poses)
        legs = points.offsets.transpose(1, 2, 0)  # B - A, (N, 6, 3)
        lengths = np.linalg.norm(legs, axis=2)
        units = legs / lengths[..., None]
        half_rods = 0.5 * (lengths - np.minimum(params.leg_offsets, lengths))
        ratio = (half_rods / lengths)[..., None, None]
        transverse = np.eye(3) - units[..., :, None] * units[..., None, :]
        carry = np.eye(3) - ratio * transverse  # (N, 6, 3, 3)
        joints = platform_point_motion(points.rotated.transpose(1, 2, 0), poses[:, 3:6])
        return np.zeros_like(legs), carry @ joints

    def leg_mass_motion(
        self, params: GoughStewartParameters, poses: np.ndarray, com_fraction: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the housings' motion (Base): a rigid housing hanging on the base's joint.

        The leg's mass is its housing (``mechanism``'s cylinder), on the base side of the
        actuated slide: it turns with the leg but does not extend with it, so its weight is not
        a two-force member's.  Its centre lies a = f |B - A| from A along u (f the
        ``com_fraction``): with the pose, d(A + a u) = (a / |B - A|) (I - u u^T) dB (its axial
        weight goes to the base, through a released drive too); with the pose held it lies on
        the platform side of the leg's spring, which giving moves it by -u per unit reading.
        """
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        points = PlatformPoints(params.platform_points.T, params.base_points.T, poses)
        legs = points.offsets.transpose(1, 2, 0)  # B - A, (N, 6, 3)
        units = legs / np.linalg.norm(legs, axis=2)[..., None]
        transverse = np.eye(3) - units[..., :, None] * units[..., None, :]
        joints = platform_point_motion(points.rotated.transpose(1, 2, 0), poses[:, 3:6])
        return -units, com_fraction * transverse @ joints

    def mechanism(
        self, params: GoughStewartParameters, pose: np.ndarray
    ) -> tuple[ChainMechanism, ...]:
        """
        Return the 6-UPS chains at ``pose``: universal joint, prismatic leg, spherical joint.

        Per chain: a ``cylinder`` body (the leg's housing, carrying the leg mass) on the base's
        universal joint at A (the first hinge normal to the base normal z and the leg, the second
        normal to the leg and the first) and the leg's axial spring (a slide along the leg: the
        housing and screw between the joint centre and the encoder), and a ``rod`` body on the
        actuated slide along the leg (its value the extension lambda = |B - A| - l0) ending at
        the platform's spherical joint B.
        """
        pose = np.asarray(pose, dtype=float).reshape(6)
        rotation = rotation_from_trig(np.cos(pose[3:6]), np.sin(pose[3:6]))
        joints = pose[:3] + params.platform_points @ rotation.T
        chains = []
        for c in range(N_CHAINS):
            base, joint = params.base_points[c], joints[c]
            leg = joint - base
            length = float(np.linalg.norm(leg))
            unit = leg / length
            first, second = universal_joint_axes(np.array([0.0, 0.0, 1.0]), leg)
            rod_start = base + min(params.leg_offsets[c], length) * unit
            chains.append(
                ChainMechanism(
                    bodies=(
                        MechanismBody(
                            'cylinder',
                            LEG_BODY,
                            (
                                MechanismJoint(HINGE, PASSIVE, base.copy(), first),
                                MechanismJoint(HINGE, PASSIVE, base.copy(), second),
                                MechanismJoint(SLIDE, COMPLIANCE, base.copy(), unit),
                            ),
                            np.array([base, joint]),
                        ),
                        MechanismBody(
                            'rod',
                            ACTUATOR_BODY,
                            (MechanismJoint(SLIDE, ACTUATED, rod_start, unit),),
                            np.array([rod_start, joint]),
                        ),
                    ),
                    platform_joint=joint,
                    actuator=length - float(params.leg_offsets[c]),
                )
            )
        return tuple(chains)

    def drawing(
        self, params: GoughStewartParameters, pose: np.ndarray, actuators: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """
        Return Base.drawing plus the legs.

        ``base_joints`` A, ``legs`` (6, 2, 3) A -> platform joint, and ``cylinders`` (6, 2, 3),
        the part of each leg from A as long as the leg at reading zero (l0), the rest being the
        extended rod (the pose decides the drawing; ``actuators`` are not needed).
        """
        drawn = super().drawing(params, pose, actuators)
        base, joints = params.base_points, drawn['platform_joints']
        legs = joints - base
        lengths = np.linalg.norm(legs, axis=1)
        with np.errstate(divide='ignore', invalid='ignore'):
            housing = np.where(
                lengths[:, None] > 0,
                legs * (np.minimum(params.leg_offsets, lengths) / lengths)[:, None],
                0.0,
            )
        drawn.update(
            base_joints=base.copy(),
            legs=np.stack([base, joints], axis=1),
            cylinders=np.stack([base, base + housing], axis=1),
        )
        return drawn


ARCHITECTURE = GoughStewart()
GoughStewartParameters.architecture = ARCHITECTURE
