"""
The Hexa Slide (6-PRRS, paper section 2): 54 parameters, Table 1 default, Table 2 nominal sets.

The 54 identification parameters are stored chain-major; per chain, in the row
order of Table 1: ``A0x A0y A0z Bx By Bz l ax ay`` (SI units, metres).

Conventions chosen here (each checked against Table 1):

* ``A0`` is the start point of the rail in the base frame OXYZ; ``B`` the centre
  of the spherical joint in the platform frame PX'Y'Z'; ``l`` the leg length.
* Table 1 gives the rail direction ``a`` as 1000 x its unit-vector components,
  i.e. plain unit-vector components once the table is read in metres.
* Only ``ax, ay`` are parameters (section 2.3); the rails descend inward, so
  ``az = -sqrt(1 - ax^2 - ay^2)``.  With the other sign the Table 1 machine has
  no feasible posture in the paper's workspace.

Inverse kinematics (eq. 3): for one chain, with ``d = P + R B - A0`` (the
vector A0 -> B), the slider position solves ``|d - lambda a| = l``; eq. 3 takes
the smaller root ``lambda = a.d - sqrt(l^2 - |d|^2 + (a.d)^2)``.  The leg
vector is ``e = d - lambda a`` (slider joint A -> spherical joint B) and
``w = a.e`` equals the square root in eq. 3.  Differentiating
``|d - lambda a|^2 = l^2`` gives every derivative used here in closed form:

* d lambda / d d  = e / w
* d lambda / d A0 = -e / w,  d lambda / d B = R^T e / w
* d lambda / d l  = -l / w,  d lambda / d a = -lambda e / w
"""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_msgs_py.models import HEXA_SLIDE, MODELS
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
    cross_last,
    euler_rate_axes,
    move_joint_points,
    platform_point_derivatives,
    PlatformPoints,
    pose_jacobian_rows,
    rigid_leg_motion,
)
from .stacking import ElementwiseStacking

LAYOUT = MODELS[HEXA_SLIDE]
N_CHAINS = LAYOUT.n_chains
PARAMETER_FIELDS = LAYOUT.fields
FIELDS_PER_CHAIN = len(PARAMETER_FIELDS)
N_PARAMETERS = N_CHAINS * FIELDS_PER_CHAIN

# Column offsets inside one chain's block of 9.
A0_SLICE = slice(0, 3)
B_SLICE = slice(3, 6)
L_INDEX = 6
AXY_SLICE = slice(7, 9)

# Table 1 of the paper, mm; rows in PARAMETER_FIELDS order, columns = chains 1..6.
_TABLE1_MM = np.array(
    [
        [-735.9, -841.8, -110.1, 110.2, 839.7, 729.7],
        [-552.2, -358.9, 899.1, 897.2, -355.6, -546.3],
        [261.4, 259.9, 253.4, 251.8, 256.3, 253.9],
        [-61.1, -170.8, -110.2, 109.8, 173.8, 63.7],
        [-161.7, 28.8, 137.1, 137.2, 28.8, -161.7],
        [-16.1, -16.2, -16.1, -15.8, -16.1, -16.2],
        [994.7, 994.8, 994.6, 994.7, 994.8, 994.7],
        [750.2, 749.8, 0.2, -0.2, -749.7, -750.3],
        [433.2, 432.7, -866.2, -866.3, 432.9, 432.7],
    ]
)

# Table 2 of the paper: (max, mean, sigma) of the nominal-parameter errors, mm.
TABLE2_ERROR_STATS_MM = {1: (1.8, 0.80, 0.87), 2: (2.8, 1.33, 1.45), 3: (9.2, 4.99, 5.28)}

# Table 3 of the paper: initial error, then after calibration at 5, 10, 20 um noise.
PAPER_TABLE3 = {
    'initial': {'position_m': 2.39e-3, 'orientation_rad': np.radians(0.61)},
    5: {'position_m': 3.5e-6, 'orientation_rad': np.radians(0.0024)},
    10: {'position_m': 12e-6, 'orientation_rad': np.radians(0.005)},
    20: {'position_m': 25e-6, 'orientation_rad': np.radians(0.007)},
}
# Header of the shipped default file (hexacal_identify/data/table1_exact.yaml).
TABLE1_COMMENT = 'Table 1 of Rauf, Kim, Ryu (exact machine), SI units'


@dataclass(frozen=True)
class HexaParameters(KinematicParameters):
    """The 54 kinematic parameters; ``vector`` is chain-major (see module doc)."""

    @property
    def leg_lengths(self) -> np.ndarray:
        """l, (6,)."""
        return self.per_chain[:, L_INDEX]

    @property
    def rail_directions(self) -> np.ndarray:
        """Return the unit rail directions a (6, 3), az = -sqrt(1 - ax^2 - ay^2): rails descend."""
        axy = self.per_chain[:, AXY_SLICE]
        az = -np.sqrt(1.0 - np.sum(axy**2, axis=1))
        return np.column_stack([axy, az])

    @classmethod
    def from_parts(
        cls,
        base_points: np.ndarray,
        platform_points: np.ndarray,
        leg_lengths: np.ndarray,
        rail_xy: np.ndarray,
    ) -> 'HexaParameters':
        blocks = np.column_stack(
            [
                np.asarray(base_points),
                np.asarray(platform_points),
                np.asarray(leg_lengths),
                np.asarray(rail_xy),
            ]
        )
        return cls(blocks.reshape(-1))


def table1_parameters() -> HexaParameters:
    """
    Return the paper's exact machine (Table 1), converted from mm to SI.

    Shipped as the default "exact" parameter file ``hexacal_identify/data/table1_exact.yaml``.
    Rounded to 1e-10 m so the file reads like the table (0.2614, not 0.26139999999999997).
    """
    return HexaParameters(np.round(_TABLE1_MM.T / 1000.0, 10).reshape(-1))


# -- inverse kinematics, coordinate-major (FK and the identification Jacobian)
# ---------------------


class _Chains:
    """
    One parameter set's per-chain constants, coordinate-major ((3, 6) arrays: row = x, y, z).

    Or those of a stacked batch's rows (common.StackedChains): (3, N, 6), platform (N, 3, 6).
    """

    __slots__ = ('base', 'platform', 'rails', 'lengths', 'lengths_squared', 'rail_z_slope')

    def __init__(self, params: HexaParameters):
        per_chain = params.per_chain
        self.base = np.ascontiguousarray(per_chain[:, 0:3].T)
        self.platform = np.ascontiguousarray(per_chain[:, 3:6].T)
        self.rails = np.ascontiguousarray(params.rail_directions.T)
        self.lengths = per_chain[:, 6].copy()
        self.lengths_squared = self.lengths**2
        # a_z = -sqrt(1 - ax^2 - ay^2) => d a_z / d a_x = -a_x / a_z (and likewise for y): (2, 6).
        self.rail_z_slope = -self.rails[:2] / self.rails[2]


class _ChainIK:
    """
    Solve eq. 3 for N postures x 6 chains, coordinate-major.

    Vectors are (3, N, 6), one (N, 6) array per axis.

    The arithmetic is written out per coordinate (no small-dimension einsums): FK
    evaluates this several times per identification iteration.
    """

    __slots__ = (
        'tilt_trig',
        'rotations',
        'rotated',
        'actuators',
        'legs',
        'rail_dot',
        'discriminant',
    )

    def __init__(self, chains: _Chains, poses: np.ndarray):
        points = PlatformPoints(chains.platform, chains.base, poses)
        self.tilt_trig, self.rotations, rotated = (
            points.tilt_trig,
            points.rotations,
            points.rotated,
        )
        d = points.offsets  # A0 -> B
        rails = chains.rails
        d0, d1, d2 = d
        a_dot_d = rails[0] * d0 + rails[1] * d1 + rails[2] * d2
        discriminant = chains.lengths_squared - (d0 * d0 + d1 * d1 + d2 * d2) + a_dot_d * a_dot_d
        root = np.sqrt(np.maximum(discriminant, 0.0))
        sliders = a_dot_d - root
        self.rotated = rotated
        self.actuators = sliders
        # (3, 6) constants of one parameter set, or (3, N, 6) of a stacked batch (StackedChains).
        self.legs = d - sliders * (rails if rails.ndim == 3 else rails[:, None, :])
        self.rail_dot = root
        self.discriminant = discriminant

    def subset(self, mask: np.ndarray) -> '_ChainIK':
        out = object.__new__(_ChainIK)
        out.tilt_trig, out.rotations = self.tilt_trig[:, mask], self.rotations[mask]
        out.rotated, out.legs = self.rotated[:, mask], self.legs[:, mask]
        out.actuators, out.rail_dot, out.discriminant = (
            self.actuators[mask],
            self.rail_dot[mask],
            self.discriminant[mask],
        )
        return out

    def replace_rows(self, mask: np.ndarray, rows: '_ChainIK') -> None:
        for name in ('rotations', 'actuators', 'rail_dot', 'discriminant'):
            getattr(self, name)[mask] = getattr(rows, name)
        self.tilt_trig[:, mask] = rows.tilt_trig
        self.rotated[:, mask] = rows.rotated
        self.legs[:, mask] = rows.legs

    def reachable(self) -> np.ndarray:
        return (self.discriminant >= 0.0).all(axis=1)

    def unit_legs(self) -> np.ndarray:
        """Return e / w, (3, N, 6) (inf/NaN at a singular leg, which FK flags)."""
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.legs / self.rail_dot

    def pose_jacobian(self, unit: np.ndarray | None = None) -> np.ndarray:
        """J_inv = d lambda / d X, (N, 6 chains, 6 pose coordinates); see ``pose_jacobian``."""
        unit = self.unit_legs() if unit is None else unit
        return pose_jacobian_rows(self.rotated, unit, self.tilt_trig)

    def parameter_blocks(self, chains: _Chains, unit: np.ndarray | None = None) -> np.ndarray:
        """Return d lambda_c / d u_c, (N, 6, 9); see ``parameter_jacobian_blocks``."""
        unit = self.unit_legs() if unit is None else unit
        blocks = np.empty(unit.shape[1:] + (FIELDS_PER_CHAIN,))
        blocks[..., 0:3] = -unit.transpose(1, 2, 0)
        blocks[..., 3:6] = platform_point_derivatives(self.rotations, unit)
        blocks[..., 6] = -chains.lengths / self.rail_dot
        d_rail = -self.actuators * unit  # d lambda / d a (full vector), (3, N, 6)
        blocks[..., 7] = d_rail[0] + d_rail[2] * chains.rail_z_slope[0]
        blocks[..., 8] = d_rail[1] + d_rail[2] * chains.rail_z_slope[1]
        return blocks

    def as_geometry(self) -> 'LegGeometry':
        return LegGeometry(
            self.rotations,
            self.rotated.transpose(1, 2, 0),
            self.actuators,
            self.legs.transpose(1, 2, 0),
            self.rail_dot,
            self.discriminant,
        )


# -- the same, posture-major: the reference path (tests, workspace checks, the baseline) ----------


@dataclass
class LegGeometry:
    """Everything IK computes for N postures x 6 chains, reused by the Jacobians."""

    rotations: np.ndarray  # (N, 3, 3)
    rotated_platform_points: np.ndarray  # R B, (N, 6, 3)
    actuator_positions: np.ndarray  # lambda, (N, 6)
    leg_vectors: np.ndarray  # e = B - A, (N, 6, 3)
    rail_leg_dot: np.ndarray  # w = a.e, (N, 6); zero at a singular leg
    discriminant: np.ndarray  # l^2 - |d|^2 + (a.d)^2, (N, 6); negative = unreachable


def leg_geometry(params: HexaParameters, poses: np.ndarray) -> LegGeometry:
    """Eq. 3 for every chain and posture, keeping the intermediate vectors."""
    return _ChainIK(_Chains(params), np.asarray(poses, dtype=float)).as_geometry()


def subset_geometry(geometry: LegGeometry, mask: np.ndarray) -> LegGeometry:
    return LegGeometry(*(getattr(geometry, f)[mask] for f in LegGeometry.__dataclass_fields__))


def pose_jacobian(geometry: LegGeometry, angles: np.ndarray) -> np.ndarray:
    """
    J_inv = d lambda / d X, (N, 6 chains, 6 pose coordinates).

    Position columns: e / w.  Angle column k: axis_k . (R B x e) / w, since
    d(R B) = axis_k x R B for a rate about axis_k.
    """
    with np.errstate(
        divide='ignore', invalid='ignore'
    ):  # w = 0 only where a leg cannot reach: flagged by FK
        unit = geometry.leg_vectors / geometry.rail_leg_dot[..., None]
        moment = cross_last(geometry.rotated_platform_points, unit)
        return np.concatenate([unit, np.matmul(moment, euler_rate_axes(angles))], axis=2)


def parameter_jacobian_blocks(params: HexaParameters, geometry: LegGeometry) -> np.ndarray:
    """
    Return d lambda_c / d u_c for each chain's own 9 parameters, (N, 6, 9).

    lambda_c depends only on chain c's parameters, so the full (N, 6, 54)
    matrix is block diagonal; these are its blocks, in PARAMETER_FIELDS order.
    """
    legs, w = geometry.leg_vectors, geometry.rail_leg_dot
    unit = legs / w[..., None]
    blocks = np.empty(legs.shape[:2] + (FIELDS_PER_CHAIN,))
    blocks[..., 0:3] = -unit
    blocks[..., 3:6] = np.matmul(unit, geometry.rotations)  # R^T e / w, as rows: (e/w)^T R
    blocks[..., 6] = -params.leg_lengths[None] / w
    # a_z = -sqrt(1 - ax^2 - ay^2) => d a_z / d a_x = -a_x / a_z (and likewise for y).
    rails = params.rail_directions
    dz_dxy = -rails[:, :2] / rails[:, 2:3]
    d_rail = -geometry.actuator_positions[..., None] * unit  # d lambda / d a (full vector)
    blocks[..., 7:9] = d_rail[..., :2] + d_rail[..., 2:3] * dz_dxy[None]
    return blocks


def rail_xy_slice(chain: int) -> slice:
    """Vector slice of chain's (ax, ay) components (chain counted from 0)."""
    start = chain * FIELDS_PER_CHAIN
    return slice(start + AXY_SLICE.start, start + AXY_SLICE.stop)


class HexaSlide(ElementwiseStacking, Architecture[HexaParameters]):
    """6-PRRS: a slider on an inclined rail, a fixed-length leg, a spherical platform joint."""

    name = HEXA_SLIDE
    layout = LAYOUT
    unreachable_reason = 'a leg is shorter than its distance to the rail'
    parameters_type = HexaParameters
    chain_ik = _ChainIK  # stacked rows too (ElementwiseStacking)
    nominal_error_stats_mm = TABLE2_ERROR_STATS_MM
    # The rail components are dimensionless: "1 mm" of them is 1e-3, as Table 1 prints them.
    error_table_note = ' (a: unit-vector components x 1000, as in Table 1)'
    std_note = ' (rail components x1e-6)'
    default_machine_alias = 'table1'
    # The paper's numbers belong to the machine it studied: printed beside this model's study only.
    paper_accuracy = PAPER_TABLE3

    @property
    def machine_label(self) -> str:
        """Return 'Table 1': the default machine is the paper's."""
        return 'Table 1'

    @property
    def nominal_label(self) -> str:
        """Return 'Table 1 + Table 2 errors'."""
        return 'Table 1 + Table 2 errors'

    @property
    def truth_file_name(self) -> str:
        """Return 'true_table1.yaml'."""
        return 'true_table1.yaml'

    def default_machine_comment(self, params: KinematicParameters) -> str:
        """Return the header of table1_exact.yaml."""
        return TABLE1_COMMENT

    def vector_problem(self, vector: np.ndarray) -> str | None:
        # Only the rail direction must be the x, y part of a unit vector (the solver may try any
        # l).
        axy = vector.reshape(N_CHAINS, FIELDS_PER_CHAIN)[:, AXY_SLICE]
        norm2 = np.sum(axy**2, axis=1)
        if np.any(norm2 >= 1.0):
            chain = int(np.argmax(norm2 >= 1.0)) + 1
            return (
                f'chain_{chain}.a = {axy[chain - 1].tolist()} is not the x, y part of a unit '
                'vector'
            )
        return None

    def default_parameters(self) -> HexaParameters:
        return table1_parameters()

    def default_workspace(self):
        from ..machine.postures import Workspace

        return Workspace()

    def chains(self, params: HexaParameters) -> _Chains:
        return _Chains(params)

    def legs(self, chains: _Chains, poses: np.ndarray) -> _ChainIK:
        return _ChainIK(chains, poses)

    def acceptable_poses(self, params: HexaParameters, poses: np.ndarray, workspace) -> np.ndarray:
        geometry = leg_geometry(params, poses)
        reachable = np.all(geometry.discriminant > 0.0, axis=1)
        low, high = workspace.actuator_stroke_m
        in_stroke = np.all(
            (geometry.actuator_positions >= low) & (geometry.actuator_positions <= high), axis=1
        )
        away_from_rail = np.all(
            geometry.rail_leg_dot > workspace.min_joint_cosine * params.leg_lengths, axis=1
        )
        ok = reachable & in_stroke & away_from_rail
        conditioned = np.zeros(len(poses), bool)
        if np.any(ok):
            jac = pose_jacobian(subset_geometry(geometry, ok), poses[ok, 3:6])
            jac[:, :, 3:] /= (
                workspace.link_length
            )  # angles -> lengths, so the condition number is unit-free
            conditioned[ok] = np.linalg.cond(jac) < workspace.max_condition
        return ok & conditioned

    def joint_cosines(
        self, params: HexaParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        # U joint at the slider: angle between leg and rail; S joint: between leg and the platform
        # normal.
        geometry = leg_geometry(params, poses)
        with np.errstate(invalid='ignore'):
            leg_direction = geometry.leg_vectors / np.linalg.norm(
                geometry.leg_vectors, axis=2, keepdims=True
            )
        u_cos = np.einsum('nci,ci->nc', leg_direction, params.rail_directions)
        platform_normal = geometry.rotations[:, :, 2]  # z' in the base frame
        s_cos = np.einsum('nci,ni->nc', -leg_direction, platform_normal)
        return u_cos, s_cos

    def frame_motion(
        self,
        params: HexaParameters,
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
            # the rails turn with the base; keep a a unit vector with a_z < 0: d ax, d ay are the
            # x, y parts of d a.
            delta[:, AXY_SLICE] += np.cross(base_rotation, params.rail_directions)[:, :2]
        return delta.reshape(-1)

    def actuator_zero_shift(self, params: HexaParameters, chain: int) -> tuple[str, np.ndarray]:
        delta = np.zeros((N_CHAINS, FIELDS_PER_CHAIN))
        delta[chain, A0_SLICE] = params.rail_directions[chain]
        return (
            f"a shift of chain_{chain + 1}'s rail start A0 along its rail (a slider zero offset)",
            delta.reshape(-1),
        )

    def in_frames(
        self, params: HexaParameters, base_rotation: np.ndarray, platform_rotation: np.ndarray
    ) -> HexaParameters:
        rails = params.rail_directions @ base_rotation.T
        return HexaParameters.from_parts(
            params.base_points @ base_rotation.T,
            params.platform_points @ platform_rotation.T,
            params.leg_lengths,
            rails[:, :2],
        )

    def actuator_mass_motion(
        self, params: HexaParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the sliders' motion (Base): the rail a per unit reading, a d lambda / d X."""
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        jacobian = np.asarray(self.legs(self.chains(params), poses).pose_jacobian())
        rails = params.rail_directions
        with_reading = np.broadcast_to(rails, (len(poses),) + rails.shape).copy()
        return with_reading, with_reading[..., None] * jacobian[:, :, None, :]

    def leg_mass_motion(
        self, params: HexaParameters, poses: np.ndarray, com_fraction: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the legs' motion (Base): a rigid leg between the slider and the platform joint.

        Its centre S + f (B - S) (f the ``com_fraction``) moves with the pose as f dB + (1 - f)
        a d lambda: the base-side share rides on the slider, so along a released slider's rail
        it is held by the leg and the link, not by the guides.  With the pose held the leg (on
        the platform side of its spring at the slider) turns about B: (1 - f) (I - u u^T) a per
        unit reading.
        """
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        geometry = leg_geometry(params, poses)
        rails = np.broadcast_to(params.rail_directions, geometry.leg_vectors.shape)
        units = geometry.leg_vectors / np.linalg.norm(geometry.leg_vectors, axis=2)[..., None]
        return rigid_leg_motion(
            rails, units, pose_jacobian(geometry, poses[:, 3:6]),
            geometry.rotated_platform_points, poses[:, 3:6], com_fraction,
        )

    def mechanism(self, params: HexaParameters, pose: np.ndarray) -> tuple[ChainMechanism, ...]:
        """
        Return the 6-PRRS chains at ``pose``: slider, universal joint, leg, spherical joint.

        Per chain: a ``slider`` body on a slide joint along the rail a through A0 (the actuator,
        its value the slider position lambda), a ``leg`` body on the slider's universal joint (two
        hinges at A = A0 + lambda a: the first normal to the rail and the leg, the second normal to
        the leg and the first) and the leg's axial spring (a slide along the leg), ending at the
        platform's spherical joint B.
        """
        pose = np.asarray(pose, dtype=float).reshape(6)
        geometry = leg_geometry(params, pose[None])
        sliders = geometry.actuator_positions[0]
        rails = params.rail_directions
        chains = []
        for c in range(N_CHAINS):
            slider = params.base_points[c] + sliders[c] * rails[c]
            leg = geometry.leg_vectors[0, c]
            joint = slider + leg
            first, second = universal_joint_axes(rails[c], leg)
            leg_unit = leg / np.linalg.norm(leg)
            chains.append(
                ChainMechanism(
                    bodies=(
                        MechanismBody(
                            'slider',
                            ACTUATOR_BODY,
                            (MechanismJoint(SLIDE, ACTUATED, slider, rails[c].copy()),),
                            np.array([slider, slider]),
                        ),
                        MechanismBody(
                            'leg',
                            LEG_BODY,
                            (
                                MechanismJoint(HINGE, PASSIVE, slider, first),
                                MechanismJoint(HINGE, PASSIVE, slider, second),
                                MechanismJoint(SLIDE, COMPLIANCE, slider, leg_unit),
                            ),
                            np.array([slider, joint]),
                        ),
                    ),
                    platform_joint=joint,
                    actuator=float(sliders[c]),
                )
            )
        return tuple(chains)

    def drawing(
        self, params: HexaParameters, pose: np.ndarray, actuators: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """
        Return Base.drawing plus the chains.

        ``base_joints`` the rail starts A0, ``rails`` (6, 2, 3) over the default workspace's
        stroke (extended to reach the slider), ``sliders`` A0 + lambda a and ``legs`` (6, 2, 3)
        slider -> platform joint.
        """
        drawn = super().drawing(params, pose, actuators)
        if actuators is None:
            sliders = leg_geometry(
                params, np.asarray(pose, dtype=float).reshape(1, 6)
            ).actuator_positions[0]
        else:
            sliders = np.asarray(actuators, dtype=float).reshape(N_CHAINS)
        rails, starts = params.rail_directions, params.base_points
        low, high = self.default_workspace().actuator_stroke_m
        rail_ends = np.column_stack([np.minimum(low, sliders), np.maximum(high, sliders)])
        slider_points = starts + sliders[:, None] * rails
        drawn.update(
            base_joints=starts.copy(),
            rails=starts[:, None, :] + rail_ends[:, :, None] * rails[:, None, :],
            sliders=slider_points,
            legs=np.stack([slider_points, drawn['platform_joints']], axis=1),
        )
        return drawn


ARCHITECTURE = HexaSlide()
HexaParameters.architecture = ARCHITECTURE
