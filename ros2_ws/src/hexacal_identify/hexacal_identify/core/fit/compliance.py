"""
Axial compliances identified jointly with the geometry: the unknowns and their residual columns.

The static loads of each posture (core/fit/statics.py: the weights through the
measuring mode) turn compliances into deflections the encoders and the
inclinometer cannot see:

* chain c: the encoder reads ``lambda_joint + c_c q_c`` (q_c = ``reading_loads``,
  the leg's axial force times d lambda / d leg length), so forward kinematics
  solves for the corrected readings ``lambda_m - c_c q_c``;
* the link: it is ``L + c_L T`` long (T its tension), the length eq. 4's position,
  the sphere of eq. 8 and the fixed position of eq. 10 use.

Compliance choices (``COMPLIANCE_MODES``): ``none`` (the rigid model,
the rigid results to the bit), ``shared`` (one compliance for all six chains, ``chains``,
plus ``link``) and ``per_chain`` (``chain_1`` .. ``chain_6`` plus ``link``).  The
unknowns follow the device defects in the solver's vector, named
``compliance.<name>`` (m/N).  The loads are evaluated at the poses at the start
of each solver run and held through it (the model is then linear in the
compliances, its Jacobian exact); the solver runs again while they move.  In the
compliant mode with the drives' gain known (``drive_stiffness``) the load is shared by
the compliances themselves (load_sharing.py): there the loads are evaluated at each
trial's compliances, at the held poses, and the columns carry their derivatives.

What the data can separate: a chain compliance is told from its actuator's zero
offset only by how its load varies from posture to posture, and the link's from
the device's dL only by how the link's tension varies (identifiability names the
combinations it cannot).  In the lvdt mode the link carries no load: its
compliance has no effect and is not an unknown there.  In the passive_actuator mode a released
actuator's stiction (``released_friction``, N) leaves it holding an unknown force within
+-that bound: its loads per newton (statics.released_force_loads) times the compliances are
one more noise source of each posture, in the whitening of the rows.  The relative cost
(eqs. 12 + 13) pairs postures whose loads differ: it is not offered with
compliances.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from hexacal_msgs_py.measuring_modes import MeasuringMode
import numpy as np

from .residuals import ResidualBlock
from .statics import (
    LoadSharing, MassModel, released_force_loads, static_loads, StaticLoads
)
from ..architectures import KinematicParameters
from ..errors import InvalidMeasurementError
from ..machine.device import DeviceModel
from ..machine.measurements import Measurements, NoiseModel, simulate_measurements

NONE, SHARED, PER_CHAIN = 'none', 'shared', 'per_chain'
COMPLIANCE_MODES = (NONE, SHARED, PER_CHAIN)
LINK = 'link'
SHARED_CHAINS = 'chains'
COMPLIANCE_PREFIX = 'compliance.'
# A deflection that moves less than this between solver runs (1 nm, far below any reading noise)
# is settled: the loads are not evaluated again.
LOADS_TOLERANCE_M = 1e-9


def compliance_names(mode: str, measuring_mode: str, n_chains: int = 6) -> tuple[str, ...]:
    """Return the compliance unknowns of a choice, in the solver's order (module doc)."""
    if mode not in COMPLIANCE_MODES:
        raise ValueError(
            f'unknown compliance choice {mode!r}; choose one of {", ".join(COMPLIANCE_MODES)}'
        )
    if mode == NONE:
        return ()
    chains = (SHARED_CHAINS,) if mode == SHARED else tuple(
        f'chain_{c + 1}' for c in range(n_chains)
    )
    link = () if MeasuringMode(measuring_mode) == MeasuringMode.LVDT else (LINK,)
    return chains + link


@dataclass(frozen=True)
class ComplianceModel:
    """What the solver needs to identify compliances (module doc); ``none`` = rigid."""

    mode: str = NONE
    masses: MassModel = MassModel()
    measuring_mode: str = MeasuringMode.PASSIVE_ACTUATOR.value
    # Per posture of the measurement set: the released chain, 0-based (passive_actuator).
    released: np.ndarray | None = field(default=None, compare=False)
    # name -> (value, std) m/N: a datasheet figure weighed against the data like a device prior.
    prior: dict[str, tuple[float, float]] = field(default_factory=dict, compare=False)
    held: tuple[str, ...] = ()  # names held at their start (prior or zero), not identified
    # passive_actuator: the released actuator's friction bound (N, the physical description's
    # released_friction.coulomb): it stops holding an unknown force within +-this, weighed as
    # a noise source of each posture (uniform: std bound / sqrt(3)); 0 = frictionless.
    released_friction: float = 0.0
    # compliant: the servos' gain (N/m or N m/rad, one or six: the physical description's
    # drives.kp); the load is then shared by the drives' and the identified compliances'
    # stiffness (statics.LoadSharing), else by equal drives and a rigid link.
    drive_stiffness: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        names = self.names
        unknown = sorted((set(self.prior) | set(self.held)) - set(names))
        if unknown:
            raise ValueError(
                f'unknown compliance(s) {unknown} for the {self.mode} choice in the '
                f'{self.measuring_mode} mode; choose from {", ".join(names) or "none"}'
            )
        friction = float(self.released_friction)
        if not (np.isfinite(friction) and friction >= 0):
            raise ValueError(f'released_friction must be a force >= 0 N, got {friction!r}')
        if self.drive_stiffness is not None:
            LoadSharing.of(self.drive_stiffness)  # ValueError names a bad gain
        for name, (value, std) in self.prior.items():
            if not (np.isfinite(value) and np.isfinite(std) and std > 0):
                raise ValueError(f'compliance prior {name}: value and a std > 0 m/N, got '
                                 f'{value!r} +- {std!r}')

    @property
    def active(self) -> bool:
        return self.mode != NONE

    @property
    def names(self) -> tuple[str, ...]:
        return compliance_names(self.mode, self.measuring_mode)

    @property
    def unknown_names(self) -> list[str]:
        return [COMPLIANCE_PREFIX + name for name in self.names]

    @property
    def has_link(self) -> bool:
        return LINK in self.names

    def start(self) -> np.ndarray:
        """Return the start values: the prior where given, else zero (rigid)."""
        return np.array([self.prior.get(name, (0.0, 0.0))[0] for name in self.names])

    def free(self) -> np.ndarray:
        return np.array([name not in self.held for name in self.names], bool)

    def prior_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (indices into the compliance unknowns, values, stds) of the priors."""
        indices = [k for k, name in enumerate(self.names) if name in self.prior]
        values = np.array([self.prior[self.names[k]][0] for k in indices])
        stds = np.array([self.prior[self.names[k]][1] for k in indices])
        return np.array(indices, int), values, stds

    def validate(self, cost: str, n_postures: int) -> None:
        if not self.active:
            return
        if cost == 'relative':
            raise ValueError(
                'compliances are identified with the absolute, sphere, fixed or sphere-fixed '
                'cost: the relative cost (eqs. 12 + 13) pairs postures whose loads differ'
            )
        if MeasuringMode(self.measuring_mode) == MeasuringMode.PASSIVE_ACTUATOR:
            if self.released is None or len(self.released) != n_postures:
                raise InvalidMeasurementError(
                    'compliances in the passive_actuator mode need the released chain of every '
                    f'posture ({n_postures}); the postures carry '
                    f'{"none" if self.released is None else len(self.released)}'
                )

    def chain_values(self, values: np.ndarray) -> np.ndarray:
        """Return the six chains' compliances (6,) from the compliance unknowns."""
        if self.mode == SHARED:
            return np.full(6, values[0])
        return np.asarray(values[:6])

    def link_value(self, values: np.ndarray) -> float:
        return float(values[-1]) if self.has_link else 0.0

    def loads(
        self,
        params: KinematicParameters,
        poses: np.ndarray,
        used: np.ndarray,
        values: np.ndarray | None = None,
    ) -> StaticLoads:
        """
        Return the static loads at the poses of postures ``used`` (of the measurement set).

        ``values``: the compliances the compliant mode shares the load by (with
        ``drive_stiffness``; None: rigid chains and link behind the drives).
        """
        released = None if self.released is None else np.asarray(self.released)[used]
        return static_loads(
            params, poses, self.masses, self.measuring_mode, released, self.sharing(values)
        )

    @property
    def shares_by_values(self) -> bool:
        """Return True when the loads move with the identified compliances (compliant mode)."""
        return self.active and self.sharing(None) is not None

    def load_sensitivities(
        self, loads: StaticLoads, values: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return d reading_loads / d unknowns (N, 6, U) and d link tension / d unknowns (N, U).

        Of ``loads`` evaluated at ``values`` where the loads move with the compliances
        (``shares_by_values``: they carry their solved system, load_sharing.py).
        """
        assert loads.shared is not None
        readings, link = loads.shared.sensitivities()
        per_unknown = np.zeros((7, len(self.names)))  # (c_1..c_6, c_L) -> the unknowns
        if self.mode == SHARED:
            per_unknown[:6, 0] = 1.0
        else:
            per_unknown[:6, :6] = np.eye(6)
        per_unknown[6, -1] = 1.0
        # A negative estimate counts as rigid (LoadSharing): the loads do not move with it.
        per_unknown[:, np.asarray(values) < 0.0] = 0.0
        return readings @ per_unknown, link @ per_unknown

    def sharing(self, values: np.ndarray | None) -> LoadSharing | None:
        """Return the stiffnesses the compliant mode's load is shared by, or None (statics)."""
        compliant = MeasuringMode(self.measuring_mode) == MeasuringMode.COMPLIANT
        if self.drive_stiffness is None or not compliant:
            return None
        if values is None or not self.active:
            return LoadSharing.of(self.drive_stiffness)
        values = np.asarray(values, dtype=float)
        return LoadSharing.of(
            self.drive_stiffness, self.chain_values(values), self.link_value(values)
        )

    @property
    def weighs_friction(self) -> bool:
        """Return True when the released actuator's friction is a noise source of the fit."""
        return (
            self.active
            and self.released_friction > 0.0
            and MeasuringMode(self.measuring_mode) == MeasuringMode.PASSIVE_ACTUATOR
        )

    def friction_noise(
        self,
        params: KinematicParameters,
        poses: np.ndarray,
        used: np.ndarray,
        block: ResidualBlock,
        values: np.ndarray,
        dl_column: int,
    ) -> tuple[np.ndarray, float]:
        """
        Return d rows / d released force (rows,) at the compliances ``values``, and its variance.

        The force on the released actuator (within +-released_friction) moves the loads by
        ``released_force_loads`` per newton, the deflections with them by the compliances: a
        noise source shared by a posture's rows (row_weights.py whitens them by it).
        """
        assert self.released is not None  # validate() refuses passive postures without them
        unit = released_force_loads(params, poses, np.asarray(self.released)[used])
        derivative = self.columns(block, unit, dl_column) @ np.asarray(values, dtype=float)
        return derivative, self.released_friction**2 / 3.0

    def corrected(
        self,
        measurements: Measurements,
        loads: StaticLoads,
        values: np.ndarray,
        link_length: float,
    ) -> Measurements:
        """Return the readings at the joints and the link's loaded lengths (module doc)."""
        actuators = measurements.actuator_positions - loads.reading_loads * self.chain_values(
            values
        )
        lengths = (
            measurements.link_lengths
            if measurements.link_lengths is not None
            else np.full(len(measurements), link_length)
        )
        if self.has_link:
            lengths = lengths + self.link_value(values) * loads.link
        return replace(measurements, actuator_positions=actuators, link_lengths=lengths)

    def columns(
        self,
        block: ResidualBlock,
        loads: StaticLoads,
        dl_column: int,
        moving: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> np.ndarray:
        """
        Return d rows / d compliances (rows, unknowns) of a block with noise derivatives.

        ``block.noise_jacobian[:, :6]`` is d row / d reading of the row's posture (through FK)
        and column ``dl_column`` of its Jacobian d row / d dL, which is d row / d link length
        for every cost offered here.  ``moving``: (values, ``load_sensitivities``) where the
        loads move with the compliances: the deflections c q and c_L T gain c dq and c_L dT.
        """
        assert block.noise_jacobian is not None and block.jacobian is not None
        postures = block.postures
        d_readings = -block.noise_jacobian[:, :6] * loads.reading_loads[postures]
        if self.mode == SHARED:
            chains = d_readings.sum(axis=1, keepdims=True)
        else:
            chains = d_readings
        if not self.has_link:
            return chains
        link = block.jacobian[:, dl_column] * loads.link[postures]
        columns = np.column_stack([chains, link])
        if moving is not None:
            values, d_reading_loads, d_tension = moving
            shifts = self.chain_values(values)[None, :, None] * d_reading_loads[postures]
            columns = columns - np.einsum('rc,rcu->ru', block.noise_jacobian[:, :6], shifts)
            stretch = self.link_value(values) * d_tension[postures]
            columns = columns + block.jacobian[:, dl_column, None] * stretch
        return columns

    def deflections(self, loads: StaticLoads, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the reading shifts (N, 6) and the link's stretch (N,), m."""
        shifts = loads.reading_loads * self.chain_values(values)
        return shifts, self.link_value(values) * loads.link


def simulate_loaded_measurements(
    params: KinematicParameters,
    poses: np.ndarray,
    model: ComplianceModel,
    values: np.ndarray,
    device: DeviceModel = DeviceModel(),
    noise: NoiseModel = NoiseModel(),
    rng: np.random.Generator | None = None,
    settle_iterations: int = 4,
) -> tuple[Measurements, np.ndarray]:
    """
    Return what the encoders and the device read on a machine loaded by its weights, and the poses.

    ``poses`` (N, 6) give the direction of the link and the orientation; the platform stands where
    the loaded link's length puts it (P scaled to ``L + c_L T``, T at that pose, settled by a few
    fixed-point steps).  Encoders read ``lambda_joint + c_c q_c`` (module doc), then the sensors'
    noise is added as ``simulate_measurements`` adds it.  Sphere postures, no device defects.
    """
    poses = np.array(np.atleast_2d(poses), dtype=float)
    direction = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    used = np.arange(len(poses))
    for _ in range(settle_iterations):
        loads = model.loads(params, poses, used, values)
        poses[:, :3] = direction * (device.link_length + model.link_value(values) * loads.link)[
            :, None
        ]
    loads = model.loads(params, poses, used, values)
    rigid = simulate_measurements(params, poses, device=device, noise=NoiseModel(), lvdt=True)
    rng = rng if rng is not None else np.random.default_rng(0)
    shifts, _ = model.deflections(loads, values)
    actuators = rigid.actuator_positions + shifts
    angles, rotary = rigid.inclinometer, rigid.rotary
    if noise.actuator_m:
        actuators = actuators + rng.uniform(-noise.actuator_m, noise.actuator_m, actuators.shape)
    if noise.angle_rad:
        angles = angles + rng.uniform(-noise.angle_rad, noise.angle_rad, angles.shape)
        rotary = rotary + rng.uniform(-noise.angle_rad, noise.angle_rad, rotary.shape)
    lvdt = MeasuringMode(model.measuring_mode) == MeasuringMode.LVDT
    lengths = rigid.link_lengths if lvdt else None
    return Measurements(actuators, angles, rotary, link_lengths=lengths), poses


__all__ = [
    'COMPLIANCE_MODES',
    'COMPLIANCE_PREFIX',
    'ComplianceModel',
    'LINK',
    'NONE',
    'PER_CHAIN',
    'SHARED',
    'SHARED_CHAINS',
    'compliance_names',
    'simulate_loaded_measurements',
]
