"""
Static loads of the chains and of the measuring link from the weights, batched over postures.

The weights a user can know (``MassModel``: gravity, the platform's and a payload's
mass and centre of mass in the platform frame, each leg's and the link's mass with
the fraction of the way from its base-side end to its platform-side end at which
its centre of mass lies) load the chains and the link at every posture.  Each leg
and the link are two-force members: their weight is lumped at their ends by
``com_fraction`` (the platform-side share ``com_fraction * mass`` rides on the
platform, at the leg's platform joint and at the link's platform end P; the
base-side share is carried by the base).  A leg whose weight that lumping does not place
(``Architecture.leg_mass_motion``) adds the gradient of its true potential less the lumped
share's (``leg_weight_loads``): a Gough-Stewart cylinder's housing turns with the leg but
does not extend, so its axial weight goes to the base through its joint, not through a
released drive to the platform and the link, and lies on the leg's spring with the drive's
thrust; a Hexa Slide leg's (a rotary hexapod rod's) base-side share rides on its slider
(crank tip), and along a released rail (about a released motor's axis) only the leg and the
link hold it.

Statics by virtual work on the pose coordinates X (any architecture): the weights'
potential U(X) has the generalised gradient

    G = dU/dX = [-M g, -E^T ((R h) x g)]

(M the platform-side mass, h its first moment in the platform frame, E the
Euler-rate axes of ``euler_rate_axes``), and the actuator thrusts tau (along
+lambda, N) and the link's tension T hold it:

    J^T tau - T j_L = G,     J = d lambda / d X,  j_L = d|P| / d X = [P / |P|, 0, 0, 0]

(the link runs from the device's base joint O at the base origin to the platform
frame origin P on either mount, core/machine/device.py).  The measuring mode says who
carries the load:

* ``passive_actuator``: the five commanded chains and the link (six unknowns,
  six equations); the released chain carries nothing.
* ``lvdt``: the six chains; the telescopic link carries only its spring, taken
  as zero (an LVDT's return spring is a few newtons).
* ``compliant``: six position loops and the link share the load by their
  stiffness (``LoadSharing``): chain c yields ``k_c = 1 / (1 / kp_c + c_c r_c^2)`` in its
  actuator's unit (the servo's gain in series with the leg's compliance referred to the
  actuator), the link ``c_L``.  With the platform displaced by -y from where the setpoints put
  it, tau = K (J y + c_c r_c^2 w_c) (w_c below: the weight the leg's spring does not carry)
  and the link's stretch -j_L y = c_L T, so

      [J^T K J, -j_L^T; j_L, c_L] [y; T] = [G - J^T K c r^2 w; 0].

  Without a ``LoadSharing`` the six loops are equally stiff and the link axially rigid (the
  platform moves on the link's sphere, j_L y = 0).  The link's share depends on the ratio:
  on the shipped Hexa Slide (kp 1e8 N/m, legs 5e7 N/m, link 1e7 N/m) the rigid link's rule
  gave it 207 +- 101 N more than the MuJoCo machine carries, the stiffness rule 13 +- 1 N
  (of which about 7 N is the link's own weight at its platform joint, where MuJoCo reads it).
  Only the weights are modelled: the force of setpoints the machine cannot reach on the
  sphere is what the compliant mode's refinement removes, not a load this model knows.

The actuators' moving parts (``actuator_moving_mass`` each: a slider, an extending rod, a
crank, placed and moved as ``Architecture.actuator_mass_motion`` says) add the gradient of
their potential U_a(X) to G: the drives and the link hold it with the rest, so tau is the
drive's thrust (zero for the released chain).  A part that moves with the reading at a held
pose (on the base side of the leg's spring: a slider, a crank) has its weight along its
motion, w_c = dU_a / d lambda_c at a held pose, held by the drive and not by the leg: the
leg's force below is (tau_c - w_c) r_c, and the released chain's leg carries its part's
weight, -w_c r_c.  A part on the platform side of the spring (a rod) loads the leg only
through tau.

Each chain's force is carried along its leg: ``r_c = |d lambda_c / d P|`` is how
far the actuator moves per unit of leg length at a fixed pose (1 for a prismatic
leg, 1 / |e . rail| for a slider), the leg's axial force is ``F_c = tau_c r_c``
(signed as the thrust), and a leg of axial compliance c_c between the encoder
and its joint centres shifts the reading by ``c_c F_c r_c`` (``reading_loads``):
the encoder reads lambda_joint + c_c F_c r_c.  A compliance that sits along the
actuator (a ball screw) enters the same way, referred to the leg at each posture.
The link of axial compliance c_L is ``L + c_L T`` long (eq. 4's position).

A released actuator that stops by stiction holds a force its friction bounds: the loads per
newton of it (``released_force_loads``) are what the fit weighs it by (compliance.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from hexacal_msgs_py.measuring_modes import MeasuringMode
from hexacal_msgs_py.physical_file import PhysicalDescription, read_physical_file
import numpy as np

from .load_sharing import LoadSharing, share_by_stiffness, SharedLoads
from ..architectures import KinematicParameters
from ..architectures.common import euler_rate_axes, platform_point_motion, rotation_from_trig
from ..errors import InvalidMeasurementError

STANDARD_GRAVITY = (0.0, 0.0, -9.80665)


@dataclass(frozen=True)
class MassModel:
    """What loads the machine: gravity, masses (kg) and centres of mass (m, SI)."""

    gravity: tuple[float, float, float] = STANDARD_GRAVITY  # base frame, m/s^2
    platform_mass: float = 0.0
    platform_com: tuple[float, float, float] = (0.0, 0.0, 0.0)  # platform frame
    payload_mass: float = 0.0
    payload_com: tuple[float, float, float] = (0.0, 0.0, 0.0)  # platform frame
    leg_mass: float = 0.0  # each of the six legs
    leg_com_fraction: float = 0.5  # from the base-side joint (0) to the platform joint (1)
    link_mass: float = 0.0  # the measuring link
    link_com_fraction: float = 0.5  # from O (0) to the platform end P (1)
    actuator_moving_mass: float = 0.0  # each actuator's moving part (slider, rod, crank)

    def __post_init__(self) -> None:
        for name in ('gravity', 'platform_com', 'payload_com'):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(f'{name} must be 3 finite numbers, got {getattr(self, name)!r}')
            object.__setattr__(self, name, tuple(float(v) for v in value))
        for name in (
            'platform_mass', 'payload_mass', 'leg_mass', 'link_mass', 'actuator_moving_mass'
        ):
            mass = float(getattr(self, name))
            if not np.isfinite(mass) or mass < 0:
                raise ValueError(f'{name} must be a mass >= 0 kg, got {mass!r}')
        for name in ('leg_com_fraction', 'link_com_fraction'):
            fraction = float(getattr(self, name))
            if not 0.0 <= fraction <= 1.0:
                raise ValueError(f'{name} must lie in [0, 1], got {fraction!r}')

    def platform_side(self, params: KinematicParameters) -> tuple[float, np.ndarray]:
        """Return the mass M (kg) the platform carries and its first moment h (kg m, platform)."""
        legs = self.leg_com_fraction * self.leg_mass
        link = self.link_com_fraction * self.link_mass  # at P, the platform frame origin
        mass = self.platform_mass + self.payload_mass + 6 * legs + link
        moment = (
            self.platform_mass * np.asarray(self.platform_com)
            + self.payload_mass * np.asarray(self.payload_com)
            + legs * params.platform_points.sum(axis=0)
        )
        return mass, moment

    @classmethod
    def from_mapping(cls, data: dict) -> 'MassModel':
        """
        Read the keys of a physical description (``hexacal-physical/1``'s names).

        ``gravity``, ``platform {mass, com}``, ``payload {mass, com}``, ``legs {mass,
        com_fraction}``, ``link {mass, com_fraction}``, ``actuators {moving_mass}`` (0 when
        missing: a file of the mass keys only reads as before); other keys are left to their
        readers.
        """
        if not isinstance(data, dict):
            raise ValueError('a physical description is a mapping of sections')

        def section(name: str) -> dict:
            value = data.get(name) or {}
            if not isinstance(value, dict):
                raise ValueError(f'section {name!r} must be a mapping, got {value!r}')
            return value

        platform, payload = section('platform'), section('payload')
        legs, link = section('legs'), section('link')
        actuators = section('actuators')
        return cls(
            gravity=tuple(data.get('gravity', STANDARD_GRAVITY)),
            platform_mass=float(platform.get('mass', 0.0)),
            platform_com=tuple(platform.get('com', (0.0, 0.0, 0.0))),
            payload_mass=float(payload.get('mass', 0.0)),
            payload_com=tuple(payload.get('com', (0.0, 0.0, 0.0))),
            leg_mass=float(legs.get('mass', 0.0)),
            leg_com_fraction=float(legs.get('com_fraction', 0.5)),
            link_mass=float(link.get('mass', 0.0)),
            link_com_fraction=float(link.get('com_fraction', 0.5)),
            actuator_moving_mass=float(actuators.get('moving_mass', 0.0)),
        )

    @classmethod
    def from_physical(cls, physical: PhysicalDescription) -> 'MassModel':
        """Return the masses and gravity of a physical description (the contract's reader)."""
        return cls(
            gravity=physical.gravity,
            platform_mass=physical.platform_mass,
            platform_com=physical.platform_com,
            payload_mass=physical.payload_mass,
            payload_com=physical.payload_com,
            leg_mass=physical.leg_mass,
            leg_com_fraction=physical.leg_com_fraction,
            link_mass=physical.link_mass,
            link_com_fraction=physical.link_com_fraction,
            actuator_moving_mass=physical.actuator_moving_mass,
        )

    @classmethod
    def load(cls, path: Path | str) -> 'MassModel':
        """
        Read the mass model from a physical description YAML file.

        A complete ``hexacal-physical/1`` file (it names its ``model``) is read by the contract's
        reader (hexacal_msgs_py.physical_file), so a missing key takes the model's shipped default
        as the MuJoCo machine and the MJCF export take it; a file of the mass keys only is read
        as ``from_mapping`` reads it (missing masses are 0).
        """
        import yaml

        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as error:
            raise ValueError(f'cannot read the physical description {path}: {error}') from error
        if isinstance(data, dict) and 'model' in data:
            return cls.from_physical(read_physical_file(path))
        try:
            return cls.from_mapping(data)
        except (TypeError, ValueError) as error:
            raise ValueError(f'{path}: {error}') from error


def physical_weights(physical_file: str, model: str) -> tuple[MassModel, str]:
    """
    Return the weights of `physical_file` and where they come from, for the nodes' parameter.

    '' : the model's shipped physical description.  ValueError when the file cannot be read.
    """
    if physical_file:
        return MassModel.load(physical_file), physical_file
    from hexacal_msgs_py.physical_file import default_physical

    return MassModel.from_physical(default_physical(model)), physical_source('', model)


def physical_source(physical_file: str, model: str) -> str:
    """Return how a physical description is named in messages ('' : the shipped one)."""
    return physical_file or f'the shipped {model} physical description'


def actuator_weight_loads(
    params: KinematicParameters, poses: np.ndarray, masses: MassModel
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the actuators' moving parts' weight as generalised forces (module doc).

    ``pose`` (N, 6): d U_a / d X of their potential U_a = -m g . p_c summed over the chains,
    what the drives and the link hold with the platform's load; ``reading`` (N, 6): d U_a /
    d lambda_c with the pose held, the part of a chain's drive force its leg does not carry.
    """
    with_reading, with_pose = params.architecture.actuator_mass_motion(params, poses)
    weight = masses.actuator_moving_mass * np.asarray(masses.gravity)
    pose = -np.einsum('ncix,i->nx', with_pose, weight)
    reading = -np.einsum('nci,i->nc', with_reading, weight)
    return pose, reading


def leg_weight_loads(
    params: KinematicParameters, poses: np.ndarray, masses: MassModel
) -> tuple[np.ndarray, np.ndarray] | None:
    """
    Return what the legs' weight adds to the two-force members' lumping, or None (module doc).

    None when the legs are weightless or the architecture's legs are two-force members
    (``Architecture.leg_mass_motion``).  Otherwise ``pose`` (N, 6): the legs' d U_l / d X less
    the lumped platform-side share's (which ``weight_gradient`` holds); ``reading`` (N, 6):
    d U_l / d lambda_c with the pose held, the part of a chain's drive force its spring does
    not carry.
    """
    if masses.leg_mass <= 0.0:
        return None
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    motion = params.architecture.leg_mass_motion(params, poses, masses.leg_com_fraction)
    if motion is None:
        return None
    with_reading, with_pose = motion
    rotation = rotation_from_trig(np.cos(poses[:, 3:6].T), np.sin(poses[:, 3:6].T))
    lumped = masses.leg_com_fraction * platform_point_motion(
        np.einsum('nij,cj->nci', rotation, params.platform_points), poses[:, 3:6]
    )
    weight = masses.leg_mass * np.asarray(masses.gravity)
    pose = -np.einsum('ncix,i->nx', with_pose - lumped, weight)
    reading = -np.einsum('nci,i->nc', with_reading, weight)
    return pose, reading


@dataclass
class StaticLoads:
    """Static loads at N postures (N, SI)."""

    thrust: np.ndarray  # (N, 6) actuator thrust along +lambda holding the load
    chains: np.ndarray  # (N, 6) axial force of each leg, signed as the thrust
    link: np.ndarray  # (N,) tension of the measuring link
    reading_loads: np.ndarray  # (N, 6) reading shift per unit axial compliance, N
    # compliant: the solved system the loads came from, for their derivatives (load_sharing.py)
    shared: SharedLoads | None = None

    def subset(self, index: np.ndarray) -> 'StaticLoads':
        return StaticLoads(
            self.thrust[index], self.chains[index], self.link[index], self.reading_loads[index]
        )


def weight_gradient(
    params: KinematicParameters, poses: np.ndarray, masses: MassModel
) -> np.ndarray:
    """Return G = dU/dX (N, 6) of the weights the platform carries (module doc)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    mass, moment = masses.platform_side(params)
    gravity = np.asarray(masses.gravity)
    rotation = rotation_from_trig(np.cos(poses[:, 3:6].T), np.sin(poses[:, 3:6].T))
    arm = rotation @ moment  # (N, 3): R h
    gradient = np.empty((len(poses), 6))
    gradient[:, :3] = -mass * gravity
    axes = euler_rate_axes(poses[:, 3:6])
    gradient[:, 3:] = -np.einsum('nik,ni->nk', axes, np.cross(arm, gravity))
    return gradient


def static_loads(
    params: KinematicParameters,
    poses: np.ndarray,
    masses: MassModel,
    mode: MeasuringMode | str,
    released: np.ndarray | None = None,
    sharing: LoadSharing | None = None,
) -> StaticLoads:
    """
    Return the static loads of the chains and the link at ``poses`` (N, 6) (module doc).

    ``released`` (N,): the chain released at each posture, 0-based (passive_actuator only).
    ``sharing``: the stiffness the compliant mode shares the load by (None: equal drives and a
    rigid link).
    """
    mode = MeasuringMode(mode)
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    n = len(poses)
    jacobian, gradient, moving_reading, link_row = _weights_held(params, poses, masses)
    moving = moving_reading is not None
    rows = np.arange(n)
    thrust: np.ndarray = np.zeros((n, 6))
    tension: np.ndarray = np.zeros(n)
    shared: SharedLoads | None = None
    if mode == MeasuringMode.PASSIVE_ACTUATOR:
        if released is None:
            raise InvalidMeasurementError(
                'the passive_actuator loads need the released chain of every posture'
            )
        index = np.asarray(released)
        if index.shape != (n,) or np.any((index < 0) | (index > 5)):
            raise InvalidMeasurementError(
                f'released chains must be {n} chain indices 0..5, got {np.unique(index)}'
            )
        carriers = jacobian.copy()
        carriers[rows, index] = -link_row  # the link takes the released chain's place
        unknowns = np.linalg.solve(np.swapaxes(carriers, 1, 2), gradient[..., None])[..., 0]
        tension = unknowns[rows, index]
        thrust = unknowns
        thrust[rows, index] = 0.0
    elif mode == MeasuringMode.LVDT:
        thrust = np.linalg.solve(np.swapaxes(jacobian, 1, 2), gradient[..., None])[..., 0]
    leg_factor = np.linalg.norm(jacobian[:, :, :3], axis=2)  # r_c = d lambda_c / d leg length
    if mode == MeasuringMode.COMPLIANT:
        unborne = moving_reading if moving else np.zeros((n, 6))
        shared = share_by_stiffness(jacobian, link_row, gradient, leg_factor, unborne, sharing)
        thrust, tension = shared.thrust, shared.tension
    # The leg carries the drive's thrust less the weight of what moves between them.
    chains = (thrust - moving_reading if moving else thrust) * leg_factor
    return StaticLoads(thrust, chains, tension, chains * leg_factor, shared)


def _weights_held(params: KinematicParameters, poses: np.ndarray, masses: MassModel):
    """
    Return J (N, 6, 6), G (N, 6), the weight between drive and spring (N, 6) or None, j_L.

    What every mode's balance starts from (module doc).
    """
    arch = params.architecture
    jacobian = np.array(arch.legs(arch.chains(params), poses).pose_jacobian())  # (N, 6, 6)
    gradient = weight_gradient(params, poses, masses)
    moving_reading = None
    if masses.actuator_moving_mass > 0.0:
        moving_pose, moving_reading = actuator_weight_loads(params, poses, masses)
        gradient = gradient + moving_pose
    legs = leg_weight_loads(params, poses, masses)
    if legs is not None:
        leg_pose, leg_reading = legs
        gradient = gradient + leg_pose
        moving_reading = leg_reading if moving_reading is None else moving_reading + leg_reading
    link_row = np.zeros((len(poses), 6))
    link_row[:, :3] = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    return jacobian, gradient, moving_reading, link_row


def released_force_loads(
    params: KinematicParameters, poses: np.ndarray, released: np.ndarray
) -> StaticLoads:
    """
    Return the change of the loads per newton of force on the released actuator (passive_actuator).

    A released actuator with friction (stiction) stops where its guide holds a force f along
    +lambda (anywhere within the friction's bound): its leg carries f r_c, and the five
    commanded chains and the link balance -J_r^T f (module doc: the released chain's row of J
    carries f in J^T tau - T j_L = G).  Linear in f; the loads of f are f times these.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    n = len(poses)
    index = np.asarray(released)
    if index.shape != (n,) or np.any((index < 0) | (index > 5)):
        raise InvalidMeasurementError(
            f'released chains must be {n} chain indices 0..5, got {np.unique(index)}'
        )
    arch = params.architecture
    jacobian = np.array(arch.legs(arch.chains(params), poses).pose_jacobian())  # (N, 6, 6)
    rows = np.arange(n)
    link_row = np.zeros((n, 6))
    link_row[:, :3] = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    carriers = jacobian.copy()
    carriers[rows, index] = -link_row
    unknowns = np.linalg.solve(
        np.swapaxes(carriers, 1, 2), -jacobian[rows, index][..., None]
    )[..., 0]
    tension = unknowns[rows, index]
    thrust = unknowns
    thrust[rows, index] = 1.0
    leg_factor = np.linalg.norm(jacobian[:, :, :3], axis=2)
    chains = thrust * leg_factor
    return StaticLoads(thrust, chains, tension, chains * leg_factor)


__all__ = [
    'actuator_weight_loads',
    'leg_weight_loads',
    'LoadSharing',
    'released_force_loads',
    'MassModel',
    'physical_source',
    'physical_weights',
    'STANDARD_GRAVITY',
    'StaticLoads',
    'static_loads',
    'weight_gradient',
]
