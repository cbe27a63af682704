"""
The rotary hexapod (6-RUS): 66 parameters, six motors turning cranks that drive fixed-length rods.

Each chain is a motor on the base (revolute joint R, actuated), a crank of
length ``r`` turning about the motor axis, a rod of length ``l`` with a
universal (or spherical) joint U at the crank tip and a spherical joint S at
the platform.  The actuator reading lambda is the motor's angle in radians.

The parameter set (the 11 fields per chain, why they are minimal, complete and
parametrically continuous, what each cost function cannot see) and the default machine are
``rotary_hexapod_parameters``'s.

Crank direction and tip: with the motor axis ``n``, the zero reference ``h`` and ``w = n x h``
(rotary_hexapod_parameters.axis_frame) and the crank angle ``phi = lambda + alpha0``::

    c(phi) = cos phi h + sin phi w,   C = A + r c(phi),   |P + R B - C| = l

Inverse kinematics: with ``D = P + R B - A``, ``D.c(phi) = K`` where
``K = (|D|^2 + r^2 - l^2) / (2 r)``; with ``rho = |(D.h, D.w)|`` and ``beta =
atan2(D.w, D.h)`` the two crank branches are ``phi = beta + s acos(K / rho)``
(s = +1, -1); reachable iff ``rho^2 - K^2 >= 0``.  The rod vector ``E = D - r
c`` and the crank's tangent ``t = n x c`` decide the branch: on branch s,
``E.t = -s sqrt(rho^2 - K^2)``.  The shipped machine hangs its rods below its
cranks (``E.t < 0``: branch +1, ``MACHINE_BRANCH``); the two branches meet where
the rod lies in the plane of crank and motor axis (E.t = 0: among others, a
crank and its rod aligned), the singularity ``acceptable_poses`` keeps away from.

Derivatives, from ``|E|^2 = l^2`` with ``g = r E.t`` (closed form, every one):

* d lambda / d D = E / g, so d lambda / d A = -E / g, d lambda / d B = R^T E / g
* d lambda / d l = -l / g, d lambda / d r = -E.c / g, d lambda / d alpha0 = -1
* d lambda / d az = -r E.(dc / d az) / g, d lambda / d el = -r E.(dc / d el) / g
  with dc/daz = cos phi dh/daz + sin phi dw/daz and dc/del = -sin phi n.
"""

from __future__ import annotations

from hexacal_msgs_py.models import ROTARY_HEXAPOD
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
    PlatformPoints,
    pose_jacobian_rows,
    rigid_leg_motion,
)

from .rotary_hexapod_parameters import (
    A_SLICE,
    ALPHA0_INDEX,
    axis_angles,
    axis_frame,
    AZ_INDEX,
    B_SLICE,
    CRANK_M,
    default_rotary_hexapod,
    EL_INDEX,
    FIELDS_PER_CHAIN,
    L_INDEX,
    LAYOUT,
    N_CHAINS,
    R_INDEX,
    RotaryHexapodParameters,
    STROKE_RAD,
    wrap_angle,
)

# The shipped machine's crank branch (module doc): rods hanging below their cranks, E.t < 0.
MACHINE_BRANCH = 1


class _Chains:
    """Per-chain constants, coordinate-major ((3, 6) arrays, row = x, y, z)."""

    __slots__ = (
        'base',
        'platform',
        'axes',
        'zero_refs',
        'quarter_refs',
        'd_zero_ref_daz',
        'd_quarter_ref_daz',
        'rods',
        'rods_squared',
        'cranks',
        'crank_zeros',
    )

    def __init__(self, params: RotaryHexapodParameters):
        per_chain = params.per_chain
        self.base = np.ascontiguousarray(per_chain[:, A_SLICE].T)
        self.platform = np.ascontiguousarray(per_chain[:, B_SLICE].T)
        n, h, w, dh, dw = axis_frame(per_chain[:, AZ_INDEX], per_chain[:, EL_INDEX])
        self.axes = np.ascontiguousarray(n.T)
        self.zero_refs = np.ascontiguousarray(h.T)
        self.quarter_refs = np.ascontiguousarray(w.T)
        self.d_zero_ref_daz = np.ascontiguousarray(dh.T)
        self.d_quarter_ref_daz = np.ascontiguousarray(dw.T)
        self.rods = per_chain[:, L_INDEX].copy()
        self.rods_squared = self.rods**2
        self.cranks = per_chain[:, R_INDEX].copy()
        self.crank_zeros = per_chain[:, ALPHA0_INDEX].copy()


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return a . b of coordinate-major vectors ((3, ...) each; b may be (3, 6))."""
    if b.ndim == 2:
        b = b[:, None, :]
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class _ChainIK:
    """
    Crank angles of N postures x 6 chains on one branch, coordinate-major ((3, N, 6)).

    Keeps what both Jacobians reuse: the rod vectors E (crank tip -> platform joint), the crank
    directions c, cos and sin of phi and g = r E.t.
    """

    __slots__ = (
        'tilt_trig',
        'rotations',
        'rotated',
        'actuators',
        'rods',
        'crank_dirs',
        'cos_phi',
        'sin_phi',
        'leverage',
        'discriminant',
    )

    def __init__(
        self,
        chains: _Chains,
        poses: np.ndarray,
        branch: int = MACHINE_BRANCH,
        reading_centre: float = 0.0,
    ):
        points = PlatformPoints(chains.platform, chains.base, poses)
        self.tilt_trig, self.rotations, self.rotated = (
            points.tilt_trig,
            points.rotations,
            points.rotated,
        )
        d = points.offsets  # A -> platform joint
        d_h = _dot(d, chains.zero_refs)
        d_w = _dot(d, chains.quarter_refs)
        k = (_dot(d, d) + chains.cranks**2 - chains.rods_squared) / (2.0 * chains.cranks)
        rho_squared = d_h * d_h + d_w * d_w
        self.discriminant = rho_squared - k * k
        with np.errstate(divide='ignore', invalid='ignore'):
            ratio = np.clip(k / np.sqrt(rho_squared), -1.0, 1.0)
        phi = np.arctan2(d_w, d_h) + branch * np.arccos(np.nan_to_num(ratio))
        self.cos_phi, self.sin_phi = np.cos(phi), np.sin(phi)
        self.crank_dirs = (
            self.cos_phi * chains.zero_refs[:, None, :]
            + self.sin_phi * chains.quarter_refs[:, None, :]
        )
        self.rods = d - chains.cranks * self.crank_dirs
        tangent = (
            self.cos_phi * chains.quarter_refs[:, None, :]
            - self.sin_phi * chains.zero_refs[:, None, :]
        )  # n x c
        self.leverage = chains.cranks * _dot(self.rods, tangent)  # g = r E.t
        self.actuators = reading_centre + wrap_angle(phi - chains.crank_zeros - reading_centre)

    def subset(self, mask: np.ndarray) -> '_ChainIK':
        out = object.__new__(_ChainIK)
        out.tilt_trig, out.rotations = self.tilt_trig[:, mask], self.rotations[mask]
        out.rotated, out.rods = self.rotated[:, mask], self.rods[:, mask]
        out.crank_dirs = self.crank_dirs[:, mask]
        for name in ('actuators', 'cos_phi', 'sin_phi', 'leverage', 'discriminant'):
            setattr(out, name, getattr(self, name)[mask])
        return out

    def replace_rows(self, mask: np.ndarray, rows: '_ChainIK') -> None:
        for name in ('rotations', 'actuators', 'cos_phi', 'sin_phi', 'leverage', 'discriminant'):
            getattr(self, name)[mask] = getattr(rows, name)
        for name in ('tilt_trig', 'rotated', 'rods', 'crank_dirs'):
            getattr(self, name)[:, mask] = getattr(rows, name)

    def reachable(self) -> np.ndarray:
        return np.all(self.discriminant >= 0.0, axis=1)

    def unit_legs(self) -> np.ndarray:
        """Return E / g, (3, N, 6): d lambda / d(P + R B) (inf/NaN at a singular chain)."""
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.rods / self.leverage

    def pose_jacobian(self, unit: np.ndarray | None = None) -> np.ndarray:
        """Return d lambda / d X, (N, 6, 6): rows (E / g, (R B x E / g) on the Euler-rate axes)."""
        unit = self.unit_legs() if unit is None else unit
        return pose_jacobian_rows(self.rotated, unit, self.tilt_trig)

    def parameter_blocks(self, chains: _Chains, unit: np.ndarray | None = None) -> np.ndarray:
        """Return d lambda_c / d u_c, (N, 6, 11), in field order (module doc)."""
        unit = self.unit_legs() if unit is None else unit
        blocks = np.empty(unit.shape[1:] + (FIELDS_PER_CHAIN,))
        blocks[..., A_SLICE] = -unit.transpose(1, 2, 0)
        blocks[..., B_SLICE] = platform_point_derivatives(self.rotations, unit)
        with np.errstate(divide='ignore', invalid='ignore'):
            blocks[..., L_INDEX] = -chains.rods / self.leverage
        blocks[..., R_INDEX] = -_dot(unit, self.crank_dirs)
        d_crank_daz = (
            self.cos_phi * chains.d_zero_ref_daz[:, None, :]
            + self.sin_phi * chains.d_quarter_ref_daz[:, None, :]
        )
        blocks[..., AZ_INDEX] = -chains.cranks * _dot(unit, d_crank_daz)
        # dc/del = -sin phi n (dh/del = 0, dw/del = -n).
        blocks[..., EL_INDEX] = chains.cranks * self.sin_phi * _dot(unit, chains.axes)
        blocks[..., ALPHA0_INDEX] = -1.0
        return blocks


def crank_ik(
    params: RotaryHexapodParameters, poses: np.ndarray, branch: int = MACHINE_BRANCH
) -> _ChainIK:
    """Return the IK of ``poses`` (N, 6) on crank branch ``branch`` (+1 the machine's, or -1)."""
    arch = RotaryHexapod(branch)
    return arch.legs(arch.chains(params), np.atleast_2d(np.asarray(poses, dtype=float)))


class RotaryHexapod(Architecture[RotaryHexapodParameters]):
    """6-RUS: a motor turning a crank, a fixed-length rod, a spherical platform joint."""

    name = ROTARY_HEXAPOD
    layout = LAYOUT
    unreachable_reason = 'a rod cannot reach its crank circle'
    parameters_type = RotaryHexapodParameters
    # Table 2's rows; on the three angles "1 mm" is 1 mrad.
    nominal_error_stats_mm = {1: (1.8, 0.80, 0.87), 2: (2.8, 1.33, 1.45), 3: (9.2, 4.99, 5.28)}
    error_table_note = ' (axis_az, axis_el, alpha0: mrad)'
    # Travel at the crank tip per rad of reading: limits sized for sliders, in rad.
    actuator_lever_m = CRANK_M
    std_note = ' (angles: urad)'

    def __init__(self, branch: int = MACHINE_BRANCH, reading_centre: float | None = None):
        """
        Set the crank branch the IK takes (the shipped machine's by default) and its readings.

        Readings are wrapped into [reading_centre - pi, reading_centre + pi), the half turn either
        side of where the cranks work, so that no reading jumps by a turn inside the workspace:
        0 on the machine's branch (cranks about their zero), pi by default on the other one (the
        default machine's cranks point the other way there).
        """
        if branch not in (1, -1):
            raise ValueError(f'a crank branch is +1 or -1, got {branch!r}')
        self.branch = branch
        if reading_centre is None:
            reading_centre = 0.0 if branch == MACHINE_BRANCH else float(np.pi)
        self.reading_centre = reading_centre

    def default_machine_comment(self, params: KinematicParameters) -> str:
        """Return the header of the shipped default file."""
        low, high = self.default_workspace().actuator_stroke_m
        chains = params.per_chain
        base_radius = float(np.mean(np.hypot(chains[:, 0], chains[:, 1])))
        platform_radius = float(np.mean(np.hypot(chains[:, 3], chains[:, 4])))
        return (
            f'Default {LAYOUT.title} of hexacal (SI units: m, rad): motor axes on a '
            f'{base_radius:.2f} m circle,\n'
            f'{float(np.mean(chains[:, R_INDEX])):.2f} m cranks, rods '
            f'{chains[:, L_INDEX].min():.3f}-{chains[:, L_INDEX].max():.3f} m, platform '
            f'joints on a {platform_radius:.2f} m circle,\n'
            'with mm/mrad-level as-built irregularity.\n'
            f'Crank angle limits ({low:g}, {high:g}) rad of the actuator reading lambda.\n'
            f'Written by `hexacal params default --model {self.name}`.'
        )

    def default_parameters(self) -> RotaryHexapodParameters:
        return default_rotary_hexapod()

    def default_workspace(self):
        from ..machine.postures import Workspace

        return Workspace(
            xy_range_m=0.2,
            rotation_range_rad=float(np.radians(20.0)),
            actuator_stroke_m=STROKE_RAD,
        )

    def chains(self, params: RotaryHexapodParameters) -> _Chains:
        return _Chains(params)

    def legs(self, chains: _Chains, poses: np.ndarray) -> _ChainIK:
        return _ChainIK(chains, poses, self.branch, self.reading_centre)

    def acceptable_poses(
        self, params: RotaryHexapodParameters, poses: np.ndarray, workspace
    ) -> np.ndarray:
        legs = self.legs(_Chains(params), np.asarray(poses, dtype=float))
        low, high = workspace.actuator_stroke_m
        ok = np.all(legs.discriminant > 0.0, axis=1)
        ok &= np.all((legs.actuators >= low) & (legs.actuators <= high), axis=1)
        # Away from the branch boundary (rod in the plane of crank and axis) and with the platform
        # joints inside their range: min_joint_cosine reads as the least joint-angle cosine.
        crank_cos, platform_cos = self._cosines(legs, params)
        ok &= np.all(crank_cos > workspace.min_joint_cosine, axis=1)
        ok &= np.all(platform_cos > workspace.min_joint_cosine, axis=1)
        conditioned = np.zeros(len(poses), bool)
        if np.any(ok):
            conditioned[ok] = condition_ok(
                legs.subset(ok).pose_jacobian(), workspace.link_length, workspace.max_condition
            )
        return ok & conditioned

    def _cosines(
        self, legs: _ChainIK, params: RotaryHexapodParameters
    ) -> tuple[np.ndarray, np.ndarray]:
        rods = params.rod_lengths
        # Crank side: the rod's angle from the crank's tangent on the machine's side (1: the rod
        # pulls square to the crank; 0: the branch boundary, e.g. crank and rod aligned).
        crank_cos = -self.branch * legs.leverage / (params.crank_lengths * rods)
        # Platform side: the rod's angle from the platform normal, for either mount.
        normal = legs.rotations[:, :, 2]
        platform_cos = np.abs(
            legs.rods[0] * normal[:, 0:1] + legs.rods[1] * normal[:, 1:2]
            + legs.rods[2] * normal[:, 2:3]
        ) / rods
        return crank_cos, platform_cos

    def joint_cosines(
        self, params: RotaryHexapodParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        legs = self.legs(_Chains(params), np.asarray(poses, dtype=float))
        return self._cosines(legs, params)

    def frame_motion(
        self,
        params: RotaryHexapodParameters,
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
        if base_rotation is not None:
            # The motor axes and the crank zeros turn with the base: dn = w x n in angles, and
            # alpha0 takes up the turn of h about n that the new angles' reference does not.
            per_chain = params.per_chain
            elevation = per_chain[:, EL_INDEX]
            n, h, w, _, _ = axis_frame(per_chain[:, AZ_INDEX], elevation)
            omega = np.asarray(base_rotation, dtype=float)
            dn = np.cross(omega, n)
            d_az = np.sum(dn * h, axis=1) / np.cos(elevation)
            delta[:, AZ_INDEX] += d_az
            delta[:, EL_INDEX] += np.sum(dn * w, axis=1)
            delta[:, ALPHA0_INDEX] += (
                np.sum(np.cross(omega, h) * w, axis=1) - np.sin(elevation) * d_az
            )
        return delta.reshape(-1)

    def actuator_zero_shift(
        self, params: RotaryHexapodParameters, chain: int
    ) -> tuple[str, np.ndarray]:
        delta = np.zeros((N_CHAINS, FIELDS_PER_CHAIN))
        delta[chain, ALPHA0_INDEX] = 1.0
        return (
            f"chain_{chain + 1}'s crank zero angle alpha0 (a motor encoder zero offset)",
            delta.reshape(-1),
        )

    def in_frames(
        self,
        params: RotaryHexapodParameters,
        base_rotation: np.ndarray,
        platform_rotation: np.ndarray,
    ) -> RotaryHexapodParameters:
        per_chain = params.per_chain
        _, h, _, _, _ = axis_frame(per_chain[:, AZ_INDEX], per_chain[:, EL_INDEX])
        axes = params.axis_directions @ base_rotation.T
        turned_h = h @ base_rotation.T
        azimuth, elevation = axis_angles(axes)
        _, new_h, new_w, _, _ = axis_frame(azimuth, elevation)
        # The physical crank at reading zero turns with the base: re-measure its zero from new h.
        offset = np.arctan2(np.sum(turned_h * new_w, axis=1), np.sum(turned_h * new_h, axis=1))
        return RotaryHexapodParameters.from_parts(
            params.base_points @ base_rotation.T,
            params.platform_points @ platform_rotation.T,
            params.rod_lengths,
            params.crank_lengths,
            axes,
            wrap_angle(params.crank_zeros + offset),
        )

    def actuator_mass_motion(
        self, params: RotaryHexapodParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the cranks' motion (Base): the crank's middle A + (r / 2) c turns about n.

        Per unit reading it moves (r / 2) n x c; with the pose through d lambda / d X.
        """
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        legs = self.legs(_Chains(params), poses)
        cranks = legs.crank_dirs.transpose(1, 2, 0)  # (N, 6, 3)
        tangents = np.cross(params.axis_directions[None], cranks)  # n x c
        with_reading = 0.5 * params.crank_lengths[None, :, None] * tangents
        jacobian = np.asarray(legs.pose_jacobian())
        return with_reading, with_reading[..., None] * jacobian[:, :, None, :]

    def leg_mass_motion(
        self, params: RotaryHexapodParameters, poses: np.ndarray, com_fraction: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the rods' motion (Base): a rigid rod from the crank's tip C to B.

        Its base-side share rides on the tip, which moves r n x c per unit reading: on a
        released crank the rod and the link hold its moment, not the motor (common.py
        rigid_leg_motion).
        """
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        legs = self.legs(_Chains(params), poses)
        cranks = legs.crank_dirs.transpose(1, 2, 0)  # (N, 6, 3)
        tips = params.crank_lengths[None, :, None] * np.cross(params.axis_directions[None], cranks)
        rods = legs.rods.transpose(1, 2, 0)
        return rigid_leg_motion(
            tips, rods / np.linalg.norm(rods, axis=2)[..., None],
            np.asarray(legs.pose_jacobian()), legs.rotated.transpose(1, 2, 0), poses[:, 3:6],
            com_fraction,
        )

    def mechanism(
        self, params: RotaryHexapodParameters, pose: np.ndarray
    ) -> tuple[ChainMechanism, ...]:
        """
        Return the 6-RUS chains at ``pose``: crank, universal joint, rod, spherical joint.

        Per chain: a ``crank`` body on a hinge about the motor axis n through A (the actuator,
        its value the crank reading lambda: the crank points along c(lambda + alpha0) at every
        value, so the hinge's zero is the crank zero alpha0), a ``rod`` body on the crank tip's
        universal joint (two hinges at C = A + r c: the first normal to the motor axis and the
        rod, the second normal to the rod and the first; rods hang across horizontal motor axes,
        so the joint is far from its own singularity) and the rod's axial spring (a slide along
        the rod), ending at the platform's spherical joint B.
        """
        pose_row = np.asarray(pose, dtype=float).reshape(1, 6)
        legs = self.legs(_Chains(params), pose_row)
        if not legs.reachable()[0]:
            raise ValueError(
                f'pose {pose_row[0].tolist()} is unreachable: {self.unreachable_reason}'
            )
        readings = legs.actuators[0]
        base, axes = params.base_points, params.axis_directions
        tips = base + params.crank_lengths[:, None] * legs.crank_dirs[:, 0, :].T
        rods = legs.rods[:, 0, :].T  # crank tip -> platform joint
        chains = []
        for c in range(N_CHAINS):
            tip, rod = tips[c], rods[c]
            joint = tip + rod
            first, second = universal_joint_axes(axes[c], rod)
            rod_unit = rod / np.linalg.norm(rod)
            chains.append(
                ChainMechanism(
                    bodies=(
                        MechanismBody(
                            'crank',
                            ACTUATOR_BODY,
                            (MechanismJoint(HINGE, ACTUATED, base[c].copy(), axes[c].copy()),),
                            np.array([base[c], tip]),
                        ),
                        MechanismBody(
                            'rod',
                            LEG_BODY,
                            (
                                MechanismJoint(HINGE, PASSIVE, tip.copy(), first),
                                MechanismJoint(HINGE, PASSIVE, tip.copy(), second),
                                MechanismJoint(SLIDE, COMPLIANCE, tip.copy(), rod_unit),
                            ),
                            np.array([tip, joint]),
                        ),
                    ),
                    platform_joint=joint,
                    actuator=float(readings[c]),
                )
            )
        return tuple(chains)

    def drawing(
        self,
        params: RotaryHexapodParameters,
        pose: np.ndarray,
        actuators: np.ndarray | None = None,
    ) -> dict[str, np.ndarray]:
        """
        Return Base.drawing plus the chains.

        ``base_joints`` the motor axis points A, ``motor_axes`` (6, 2, 3) a short segment of
        each motor axis centred on A, ``cranks`` (6, 2, 3) A -> crank tip, ``crank_tips`` (6, 3)
        and ``rods`` (6, 2, 3) crank tip -> platform joint.  The cranks follow ``actuators``
        when given (else IK of ``pose``); the rods join the tips to the pose's platform joints.
        """
        drawn = super().drawing(params, pose, actuators)
        if actuators is None:
            pose_row = np.asarray(pose, dtype=float).reshape(1, 6)
            readings = self.legs(_Chains(params), pose_row).actuators[0]
        else:
            readings = np.asarray(actuators, dtype=float).reshape(N_CHAINS)
        base = params.base_points
        tips = base + params.crank_lengths[:, None] * params.crank_directions(readings)
        half_axis = 0.25 * params.crank_lengths[:, None] * params.axis_directions
        drawn.update(
            base_joints=base.copy(),
            motor_axes=np.stack([base - half_axis, base + half_axis], axis=1),
            cranks=np.stack([base, tips], axis=1),
            crank_tips=tips,
            rods=np.stack([tips, drawn['platform_joints']], axis=1),
        )
        return drawn


ARCHITECTURE = RotaryHexapod()
RotaryHexapodParameters.architecture = ARCHITECTURE

__all__ = [
    'ARCHITECTURE',
    'MACHINE_BRANCH',
    'RotaryHexapod',
    'RotaryHexapodParameters',
    'axis_angles',
    'axis_frame',
    'crank_ik',
    'default_rotary_hexapod',
]
