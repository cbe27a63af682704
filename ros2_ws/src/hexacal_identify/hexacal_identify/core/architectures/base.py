"""
The interface a kinematic architecture implements, and the parameters it owns.

An architecture is six chains between base and platform, each driven by one
actuator whose reading lambda_c is a function of the pose X and the chain's
own parameters u_c (inverse kinematics).  Everything else in the core (forward
kinematics, the identification Jacobian by implicit differentiation, every
cost function, the solver, identifiability, planning, the studies) and the
command-line front ends are written against this interface and never name an
architecture.

Adding an architecture is one module in this package and two registrations:
``hexacal_msgs_py.models.register_model(layout)`` for its contract half and
``architectures.register_architecture(instance)`` for its kinematics (the
built-in ones are registered in ``architectures/__init__.py``).  The complete
list of what a new architecture provides:

In the contract (``hexacal_msgs_py.models``, one declarative ``ModelLayout``):

* ``name`` (the ``model`` key of files, messages and plans) and ``title``;
* ``fields`` and ``field_units`` of one chain (the vector is chain-major);
* ``chain_keys``: the parameters-file keys ``chain_N.<key>``, each covering
  consecutive fields, in the order files are written;
* ``actuator_prefix`` (joint names ``<prefix>_1..6``, unique among models),
  ``actuator_description`` and ``actuator_unit`` (the SI unit of the readings:
  'm' for sliders and legs, the default, 'rad' for motors turning cranks);
* ``physical_checks``: declarative checks naming fields (``PositiveField``,
  ``UnitVectorXY``, ``FieldBelow``) that every parameters file and message must pass.

In the core (a subclass of ``Architecture`` and one of ``KinematicParameters``
whose ``architecture`` is the instance):

* class attributes ``name`` (= the layout's), ``layout`` (``MODELS[name]``),
  ``parameters_type``, ``unreachable_reason`` and ``nominal_error_stats_mm``
  (Table 2-like rows: set number -> (max, mean, RMS) mm);
* ``default_parameters()`` and ``default_workspace()``: the shipped machine and
  the postures.Workspace measurement postures are drawn from;
* ``chains(params)``: the per-chain constants of one parameter set;
* ``legs(chains, poses)``: IK for N poses with what the derivatives reuse (the
  ``Legs`` protocol) - ``sliders`` (N, 6) actuator readings, ``reachable()``,
  ``pose_jacobian()`` = d lambda / d X (N, 6, 6), ``parameter_blocks(chains)``
  = d lambda_c / d u_c (N, 6, fields per chain), ``unit_legs()``, plus
  ``subset``/``replace_rows`` for the batched Newton iteration;
* optionally ``stack_chains``/``legs_stacked``: IK of many parameter sets at once, each pose
  row on its own set (the release rehearsal's machines and candidates); the default calls
  ``legs`` once per parameter set present, an architecture overrides it vectorised;
* ``acceptable_poses`` and ``joint_cosines``: the workspace and planning limits;
* ``frame_motion`` and ``actuator_zero_shift``: frame motions and actuator zero
  offsets expressed as parameter changes (identifiability's named combinations);
* ``in_frames``: the same machine in rotated frames (the device-frame study);
* ``drawing(params, pose)``: what a visualiser draws of the machine at a pose;
* ``mechanism(params, pose)``: each chain's bodies and joints (types, anchors, axes) at a pose,
  what a physics model (hexacal_identify.physics.mjcf) builds the machine from;
* optionally (defaults below): ``vector_problem`` (the solver's own check, the
  layout's by default), ``default_machine_comment`` (header of the shipped
  default file), the texts that name the default machine in reports
  (``machine_label``, ``nominal_label``, ``truth_file_name``), notes on
  dimensionless fields (``error_table_note``, ``std_note``),
  ``default_machine_alias`` (a ``hexacal params`` choice naming the default
  machine), ``paper_accuracy`` (a published Table 3 to print beside the
  study of this machine) and ``actuator_lever_m`` (metres of travel at the
  actuator's joint per unit reading: 1 for sliders, the crank length for cranks;
  ``actuator_limit`` and ``released_margin`` size the limits by it).  The units
  of the actuators (``actuator_quantities``) come from the layout's
  ``actuator_unit``.

Poses are ``X = [x, y, z, theta, psi, phi]`` with R = R_Y(theta) R_X(psi)
R_z(phi) (eq. 2) for every architecture.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Protocol, Self, Sequence, TypeVar

from hexacal_msgs_py.models import ActuatorQuantities, ModelLayout
import numpy as np

from .common import rotation_from_trig


class ChainIK(Protocol):
    """IK of N poses x 6 chains (see the module docstring)."""

    actuators: np.ndarray  # actuator readings lambda, (N, 6)

    def reachable(self) -> np.ndarray: ...  # (N,) every chain can reach

    def pose_jacobian(self, unit: np.ndarray | None = None) -> np.ndarray: ...  # (N, 6, 6)

    def parameter_blocks(
        self, chains: Any, unit: np.ndarray | None = None
    ) -> np.ndarray: ...  # (N, 6, F)

    def unit_legs(self) -> np.ndarray: ...  # the shared factor of both Jacobians

    # Self: an architecture's legs combine only with legs of the same architecture.
    def subset(self, mask: np.ndarray) -> Self: ...

    def replace_rows(self, mask: np.ndarray, rows: Self) -> None: ...


@dataclass(frozen=True)
class StackedLegs:
    """IK of a stacked batch, pose row i on its own parameter set: what Newton needs."""

    actuators: np.ndarray  # actuator readings lambda, (N, 6)
    pose_jacobian: np.ndarray  # d lambda / d X, (N, 6, 6)
    reachable: np.ndarray  # (N,) every chain can reach


@dataclass(frozen=True)
class KinematicParameters:
    """A parameter vector of one architecture, chain-major in its layout's field order (SI)."""

    vector: np.ndarray
    architecture: ClassVar['Architecture']

    def __post_init__(self) -> None:
        layout = self.architecture.layout
        vector = np.array(self.vector, dtype=float).reshape(-1)
        if vector.shape != (layout.n_parameters,):
            raise ValueError(
                f'expected {layout.n_parameters} parameters for a {layout.name}, got {vector.size}'
            )
        if not np.all(np.isfinite(vector)):
            bad = [layout.parameter_names[i] for i in np.flatnonzero(~np.isfinite(vector))]
            raise ValueError(f'non-finite parameter(s): {", ".join(bad)}')
        problem = self.architecture.vector_problem(vector)
        if problem:
            raise ValueError(problem)
        vector.setflags(write=False)
        object.__setattr__(self, 'vector', vector)

    @property
    def model(self) -> str:
        return self.architecture.name

    @property
    def layout(self) -> ModelLayout:
        return self.architecture.layout

    @property
    def per_chain(self) -> np.ndarray:
        """(6, fields per chain) view, one row per chain."""
        return self.vector.reshape(self.layout.n_chains, self.layout.fields_per_chain)

    @property
    def base_points(self) -> np.ndarray:
        """Return the base-side joint of each chain, base frame, (6, 3) (rail start A0; UPS: A)."""
        return self.per_chain[:, 0:3]

    @property
    def platform_points(self) -> np.ndarray:
        """Platform joint centres B in the platform frame, (6, 3)."""
        return self.per_chain[:, 3:6]

    def with_vector(self, vector: np.ndarray) -> 'KinematicParameters':
        return type(self)(vector)


# The parameter class of one architecture: its methods take only its own parameter sets.
P = TypeVar('P', bound=KinematicParameters)


SLIDE = 'slide'  # a prismatic joint: translation along its axis
HINGE = 'hinge'  # a revolute joint: rotation about its axis through its anchor
ACTUATED = 'actuated'  # the joint the actuator drives and its encoder reads (value = lambda)
COMPLIANCE = 'compliance'  # the chain's axial spring between encoder and joint centres
PASSIVE = 'passive'  # a passive joint of the chain
ACTUATOR_BODY = 'actuator'  # a body carrying the actuator's moving mass
LEG_BODY = 'leg'  # a body carrying the leg's mass


@dataclass(frozen=True)
class MechanismJoint:
    """
    One joint of a chain at a pose (base frame, m): ``kind`` SLIDE or HINGE, ``role``.

    ``role`` is ACTUATED (its value is the actuator reading lambda at the pose), COMPLIANCE
    (an axial spring, zero at the pose; a physics model omits it for a rigid chain) or PASSIVE.
    Joints of one body apply in their order, each after the previous ones.
    """

    kind: str
    role: str
    anchor: np.ndarray  # (3,) a point on the axis
    axis: np.ndarray  # (3,) unit vector


@dataclass(frozen=True)
class MechanismBody:
    """
    One moving body of a chain at a pose: its joints to the previous body and its extent.

    ``carries`` says whose mass it holds (ACTUATOR_BODY: the actuator's moving mass at the
    middle of ``segment``; LEG_BODY: the leg's mass at its centre-of-mass fraction along
    ``segment`` from its start); ``segment`` (2, 3) start and end, base frame, m.
    """

    name: str
    carries: str
    joints: tuple[MechanismJoint, ...]
    segment: np.ndarray


@dataclass(frozen=True)
class ChainMechanism:
    """
    One chain at a pose: bodies from the base (the first is a child of the base) outward.

    The last body ends at ``platform_joint``, the spherical joint centre (base frame) that
    joins it to the platform; ``actuator`` is the reading lambda at the pose.
    """

    bodies: tuple[MechanismBody, ...]
    platform_joint: np.ndarray
    actuator: float


def universal_joint_axes(first_link: np.ndarray, leg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the two axes of a universal joint joining a body to a leg (unit vectors).

    The first axis is normal to ``first_link`` (a rail, or the base normal) and the leg, the
    second normal to the first and the leg: the leg then turns freely about both but not about
    itself.
    """
    leg_unit = leg / np.linalg.norm(leg)
    first = np.cross(first_link, leg_unit)
    if np.linalg.norm(first) < 1e-9:  # a leg along the first link: any normal serves
        first = np.cross(leg_unit, [1.0, 0.0, 0.0] if abs(leg_unit[0]) < 0.9 else [0.0, 1.0, 0.0])
    first = first / np.linalg.norm(first)
    second = np.cross(leg_unit, first)
    return first, second / np.linalg.norm(second)


class Architecture(ABC, Generic[P]):
    """One kinematic architecture (see the module docstring)."""

    name: ClassVar[str]
    layout: ClassVar[ModelLayout]
    parameters_type: ClassVar[type[KinematicParameters]]
    unreachable_reason: ClassVar[str]  # what makes IK fail, for the error message
    # Table 2-like nominal error sets: set number -> (max, mean, RMS) of the errors, mm.
    nominal_error_stats_mm: ClassVar[dict[int, tuple[float, float, float]]]
    # Presentation of the default machine and of dimensionless fields (reports, file headers).
    error_table_note: ClassVar[str] = ''  # after the title of a table of parameter errors in mm
    std_note: ClassVar[str] = ''  # after the largest standard deviation in um
    default_machine_alias: ClassVar[str | None] = None  # a `hexacal params` choice for it
    # A published accuracy table of this machine (Table 3-like), printed beside its study.
    paper_accuracy: ClassVar[dict[Any, dict[str, float]] | None] = None
    # Metres of travel at the actuator's joint per unit of its reading: 1 for sliders and legs,
    # the crank length (m/rad) for actuators that turn.  What turns the limits sized for
    # sliders (margins and tolerances in m, stiffness in N/m, force in N) into this actuator's
    # unit (``actuator_limit``), so that no consumer asks which model it drives.
    actuator_lever_m: ClassVar[float] = 1.0

    @property
    def actuator_quantities(self) -> ActuatorQuantities:
        """
        Return the units of this architecture's actuators: the layout's ``actuator_unit``.

        Linear (m, force, mm shown) or rotary (rad, torque, deg shown): what every consumer
        outside the architecture's module reads instead of assuming a slider in metres.
        """
        return self.layout.actuator_quantities

    def actuator_limit(self, value: float, dimension: str = 'length') -> float:
        """
        Return a limit sized for sliders in this architecture's actuator unit.

        ``dimension``: 'length' (m -> m or rad: a margin, a tolerance, a following error),
        'force' (N -> N or N m) or 'stiffness' (N/m -> N/m or N m/rad); through
        ``actuator_lever_m``, so a slider's limits come back unchanged.
        """
        lever = self.actuator_lever_m
        scale = {'length': 1.0 / lever, 'force': lever, 'stiffness': lever * lever}
        if dimension not in scale:
            raise ValueError(f'dimension must be one of {sorted(scale)}, got {dimension!r}')
        return float(value) * scale[dimension]

    @property
    def released_margin(self) -> float:
        """
        Return the margin a released actuator keeps from its stroke ends, in its unit.

        5 mm of travel at the actuator's joint (m for sliders, rad for cranks): the true
        machine's departure from the nominal (up to 4 mm on the demo's sliders) and more.
        """
        return self.actuator_limit(0.005)

    @property
    def machine_label(self) -> str:
        """Return how reports name the default machine ("the default <name> machine")."""
        return f'the default {self.name} machine'

    @property
    def nominal_label(self) -> str:
        """Return how reports name the default machine plus nominal errors."""
        return f'{self.machine_label} + errors with Table 2-like statistics'

    @property
    def truth_file_name(self) -> str:
        """Return the file name of the simulated true machine (``hexacal demo``)."""
        return f'true_{self.name}.yaml'

    def default_machine_comment(self, params: P) -> str:
        """Return the header comment of the shipped default-machine file of this architecture."""
        return f'Default {self.layout.title} of hexacal (SI units).'

    def vector_problem(self, vector: np.ndarray) -> str | None:
        """Why `vector` is not a parameter set of this architecture (None: it is)."""
        return self.layout.physical_problem(vector)

    def parameters(self, vector: np.ndarray) -> KinematicParameters:
        return self.parameters_type(vector)

    @abstractmethod
    def default_parameters(self) -> P:
        """Return the shipped default machine (the "exact" parameters of studies and driver)."""

    @abstractmethod
    def default_workspace(self) -> Any:
        """Return the postures.Workspace postures are drawn from on the default machine."""

    @abstractmethod
    def chains(self, params: P) -> Any:
        """Per-chain constants of one parameter set, reused by every ``legs`` call."""

    @abstractmethod
    def legs(self, chains: Any, poses: np.ndarray) -> ChainIK:
        """IK for poses (N, 6) with the intermediates both Jacobians reuse."""

    def stack_chains(self, chains: Sequence[Any]) -> Any:
        """
        Return the per-chain constants of K parameter sets (each ``chains``) for ``legs_stacked``.

        The default keeps them as they are; an architecture that overrides ``legs_stacked`` lays
        them out as its vectorised IK needs.
        """
        return tuple(chains)

    def legs_stacked(self, stacked: Any, machine: np.ndarray, poses: np.ndarray) -> StackedLegs:
        """
        Return the IK of row i at ``poses[i]`` (N, 6) on parameter set ``machine[i]`` (N,).

        ``stacked`` is what ``stack_chains`` returned.  The default calls ``legs`` once per
        parameter set present in ``machine``; an architecture whose IK is elementwise over its
        chains overrides it with one call for every row (the release rehearsal evaluates many
        machines and candidates at a time, and the per-call overhead is what costs there).
        """
        machine = np.asarray(machine, dtype=int)
        poses = np.asarray(poses, dtype=float)
        present = np.unique(machine)
        if present.size == 1:
            legs = self.legs(stacked[present[0]], poses)
            return StackedLegs(legs.actuators, legs.pose_jacobian(), legs.reachable())
        n, chains = len(poses), self.layout.n_chains
        actuators, jacobian = np.empty((n, chains)), np.empty((n, chains, 6))
        reachable = np.empty(n, bool)
        for k in present:
            rows = machine == k
            legs = self.legs(stacked[k], poses[rows])
            actuators[rows] = legs.actuators
            jacobian[rows] = legs.pose_jacobian()
            reachable[rows] = legs.reachable()
        return StackedLegs(actuators, jacobian, reachable)

    def stacked_rows(self, stacked: Any, machine: np.ndarray) -> Any:
        """
        Return the rows ``machine`` (N,) of a stack, gathered once for many ``legs_of_rows``.

        A Newton iteration evaluates the same rows at new poses every step: an architecture
        that gathers per-row constants in ``legs_stacked`` gathers them here once instead.
        """
        return stacked, np.asarray(machine, dtype=int)

    def legs_of_rows(self, rows: Any, poses: np.ndarray) -> StackedLegs:
        """Return ``legs_stacked`` of the rows ``stacked_rows`` returned, at ``poses`` (N, 6)."""
        stacked, machine = rows
        return self.legs_stacked(stacked, machine, poses)

    @abstractmethod
    def acceptable_poses(
        self, params: P, poses: np.ndarray, workspace: Any
    ) -> np.ndarray:
        """
        Return the mask of acceptable poses (postures.Workspace's limits).

        Acceptable: reachable, inside the actuator stroke, away from singular legs and well
        conditioned.
        """

    @abstractmethod
    def joint_cosines(
        self, params: P, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return cosines of the base- and platform-side passive joint angles, each (N, 6)."""

    @abstractmethod
    def frame_motion(
        self,
        params: P,
        base_translation=None,
        base_rotation=None,
        platform_translation=None,
        platform_rotation=None,
    ) -> np.ndarray:
        """
        Return the first-order parameter change (vector) of a frame motion.

        The change re-expresses the machine in a base frame moved by (translation, small rotation
        vector) and a platform frame moved likewise: the measurements cannot see it.  Arguments
        are 3-vectors (None: no motion); rotations about the frame origins.
        """

    @abstractmethod
    def actuator_zero_shift(
        self, params: P, chain: int
    ) -> tuple[str, np.ndarray]:
        """Return (description, parameter change) of an actuator zero offset (chain 0-based)."""

    @abstractmethod
    def in_frames(
        self, params: P, base_rotation: np.ndarray, platform_rotation: np.ndarray
    ) -> P:
        """
        Return the same machine in rotated frames (exact, not first order).

        The base frame is rotated by base_rotation^T and the platform frame by
        platform_rotation^T about their origins: points p -> rotation @ p.
        """

    def actuator_mass_motion(
        self, params: P, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return how each actuator's moving part's centre of mass moves at ``poses`` (N, 6).

        The moving part is the ACTUATOR_BODY of ``mechanism`` (its mass at the middle of its
        segment, as a physics model places it), a rigid body.  Returns ``with_reading`` (N, 6,
        3), its motion per unit reading with the pose held (the chain's axial spring giving;
        zero for a part on the platform side of the spring), and ``with_pose`` (N, 6, 3, 6),
        d centre / d X of the rigid chain: what the statics' virtual work needs of the weight
        of the actuators' moving parts.  An architecture without it has no moving-mass statics.
        """
        raise NotImplementedError(
            f"{self.name} does not describe how its actuators' moving parts move"
        )

    def leg_mass_motion(
        self, params: P, poses: np.ndarray, com_fraction: float
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """
        Return how each leg's centre of mass moves at ``poses`` (N, 6), or None.

        None (this default): the leg is a rigid member of fixed length between a joint fixed
        on the base and the platform joint, a two-force member whose weight the statics lumps
        at its ends by ``com_fraction`` (the base-side share on the base).  Any other leg (one
        on a slider or a crank's tip, whose base-side share moves with the reading; a mass
        that does not extend with the actuator, such as a cylinder's housing) returns
        ``with_reading`` (N, 6, 3) and ``with_pose`` (N, 6, 3, 6) as ``actuator_mass_motion``
        does, for the leg mass placed as ``mechanism`` places it.
        """
        return None

    def mechanism(self, params: P, pose: np.ndarray) -> tuple[ChainMechanism, ...]:
        """
        Return each chain's bodies and joints at ``pose`` (6,): what a physics model builds.

        Every chain ends at its platform joint centre (a spherical joint: the physics model
        joins it to the platform there).  An architecture without one cannot be simulated.
        """
        raise NotImplementedError(f'{self.name} does not describe its mechanism')

    @abstractmethod
    def drawing(
        self, params: P, pose: np.ndarray, actuators: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """
        Return the machine at ``pose`` (6,) as named point sets and segments (base frame, m).

        A (k, 3) array is a set of points (joint centres), a (k, 2, 3) array k segments (start,
        end). ``actuators`` are the readings lambda (6,) at that pose (None: IK of ``pose``).
        Every architecture draws ``base_joints`` (6, 3), ``platform_joints`` (6, 3) = P + R B,
        ``platform`` (6, 2, 3), the outline through the platform joints, and ``device_link`` (1, 2,
        3), base origin O to P; this body gives the last three, and each architecture adds its
        chains (``rails``, ``sliders``, ``legs``, ...).
        """
        pose = np.asarray(pose, dtype=float).reshape(6)
        rotation = rotation_from_trig(np.cos(pose[3:6]), np.sin(pose[3:6]))
        joints = pose[:3] + params.platform_points @ rotation.T
        # Outline in the order of the joints' angles about their centroid on the platform.
        local = params.platform_points - params.platform_points.mean(axis=0)
        order = np.argsort(np.arctan2(local[:, 1], local[:, 0]))
        outline = np.stack([joints[order], joints[np.roll(order, -1)]], axis=1)
        return {
            'platform_joints': joints,
            'platform': outline,
            'device_link': np.array([[np.zeros(3), pose[:3]]]),
        }
