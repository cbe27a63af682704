"""
Measured postures: actuator readings, inclinometer angles and rotary angle per posture.

The six actuator readings are ``actuator_positions`` whatever the architecture
(Hexa Slide: slider positions along the rails; Gough-Stewart: leg extensions).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import enum

import numpy as np

from .device import DeviceDefects, DeviceModel, inclinometer_readings
from .kinematics import inverse_kinematics
from ..architectures import KinematicParameters
from ..errors import InvalidMeasurementError

N_CHANNELS = 9  # values per posture: 6 actuators, alpha, beta, phi
SPHERE = 'sphere'  # platform anywhere on the L-sphere (eqs. 7, 8, 12)
FIXED = 'fixed'  # inclinometer reads zero: position [0, 0, -L] (eqs. 10, 13)
POSTURE_KINDS = (SPHERE, FIXED)


@dataclass(frozen=True)
class MeasurementLimits:
    """Plausibility limits on readings; readings outside are rejected as invalid."""

    inclinometer_range_rad: float = np.radians(60.0)
    rotary_range_rad: float = np.pi
    # The actuator stroke postures are planned in (postures.Workspace.actuator_stroke_m: 0 .. 0.9 m
    # on the Hexa Slide's rails, 0 .. 0.5 m of the default Gough-Stewart legs) plus 0.1 m (device
    # defects move simulated actuators ~20 mm past it): a reading beyond is a sensor fault, not a
    # posture.
    actuator_min_m: float = -0.1
    actuator_max_m: float = 1.0
    # Rotary actuators (a motor turning a crank): readings are angles within +-pi (IK wraps them)
    # plus 0.1 rad of rounding and device defects.
    actuator_max_abs_rad: float = np.pi + 0.1

    def actuator_range(self, unit: str = 'm') -> tuple[float, float]:
        """Return the plausible (low, high) actuator reading in ``unit`` ('m' or 'rad')."""
        if unit == 'rad':
            return -self.actuator_max_abs_rad, self.actuator_max_abs_rad
        if unit != 'm':
            raise ValueError(f"actuator readings are in 'm' or 'rad', got {unit!r}")
        return self.actuator_min_m, self.actuator_max_m


@dataclass
class Measurements:
    """
    N measured postures (SI units).

    actuator_positions (N, 6) actuator readings lambda, m; inclinometer (N, 2) = [alpha, beta],
    rad; rotary (N,) = phi, rad; kinds (N,) 'sphere' or 'fixed'; device_turn (N,) rad: how far the
    device was turned about its link axis from its normal mounting for that posture (pi: the
    reversal procedure, device.py), readings as the sensors gave them; None = all normal.
    standard_errors (N, 9): how well each posture's nine values (6 actuators m, alpha, beta,
    phi rad; N_CHANNELS order) are known, the standard deviation of each value (the standard
    error of the mean of the samples averaged into it, PostureScatter); None = not known for
    every posture.
    """

    actuator_positions: np.ndarray
    inclinometer: np.ndarray
    rotary: np.ndarray
    kinds: np.ndarray = field(default=None)  # type: ignore[arg-type]
    link_lengths: np.ndarray | None = None  # LVDT variant: measured link length per posture, m
    device_turn: np.ndarray | None = None  # per posture: device turned about its link axis, rad
    standard_errors: np.ndarray | None = None  # (N, 9) std of each value (m, rad); None: unknown

    def __post_init__(self) -> None:
        self.actuator_positions = np.atleast_2d(np.asarray(self.actuator_positions, dtype=float))
        n = len(self.actuator_positions)
        self.inclinometer = (
            np.asarray(self.inclinometer, dtype=float).reshape(-1, 2) if n else np.zeros((0, 2))
        )
        self.rotary = np.asarray(self.rotary, dtype=float).reshape(-1)
        if self.kinds is None:
            self.kinds = np.full(n, SPHERE)
        self.kinds = np.asarray(self.kinds).astype(str)
        if self.link_lengths is not None:
            self.link_lengths = np.asarray(self.link_lengths, dtype=float).reshape(-1)
        if self.device_turn is not None:
            self.device_turn = np.asarray(self.device_turn, dtype=float).reshape(-1)
            if not np.any(self.device_turn):
                self.device_turn = None  # all in the normal mounting: the same as no turns
        if self.standard_errors is not None:
            self.standard_errors = np.asarray(self.standard_errors, dtype=float)

    @property
    def turns(self) -> np.ndarray:
        """(N,) device turn per posture, rad (zeros without turns)."""
        return self.device_turn if self.device_turn is not None else np.zeros(len(self))

    def __len__(self) -> int:
        return len(self.actuator_positions)

    def subset(self, indices: np.ndarray) -> 'Measurements':
        indices = np.asarray(indices, dtype=int)
        lengths = None if self.link_lengths is None else self.link_lengths[indices]
        turns = None if self.device_turn is None else self.device_turn[indices]
        errors = None if self.standard_errors is None else self.standard_errors[indices]
        return Measurements(
            self.actuator_positions[indices],
            self.inclinometer[indices],
            self.rotary[indices],
            self.kinds[indices],
            lengths,
            turns,
            errors,
        )

    @staticmethod
    def concatenate(parts: list['Measurements']) -> 'Measurements':
        lengths = None
        if any(p.link_lengths is not None for p in parts):
            if not all(p.link_lengths is not None for p in parts):
                raise InvalidMeasurementError(
                    'cannot mix postures with and without measured link lengths'
                )
            lengths = np.concatenate([p.link_lengths for p in parts])
        turns = None
        if any(p.device_turn is not None for p in parts):
            turns = np.concatenate([p.turns for p in parts])
        # The scatter is known for the whole only when it is known for every part.
        errors = None
        if parts and all(p.standard_errors is not None for p in parts):
            errors = np.concatenate([p.standard_errors for p in parts])
        return Measurements(
            np.concatenate([p.actuator_positions for p in parts]),
            np.concatenate([p.inclinometer for p in parts]),
            np.concatenate([p.rotary for p in parts]),
            np.concatenate([p.kinds for p in parts]),
            lengths,
            turns,
            errors,
        )

    def validate(
        self, limits: MeasurementLimits = MeasurementLimits(), actuator_unit: str = 'm'
    ) -> None:
        """
        Raise InvalidMeasurementError naming the first problem and the posture indices.

        ``actuator_unit`` is the model's (``ModelLayout.actuator_unit``): 'm' or 'rad'.
        """
        n = len(self)
        if self.actuator_positions.shape != (n, 6):
            raise InvalidMeasurementError(
                f'slider_positions must be (N, 6), got {self.actuator_positions.shape}'
            )
        if (
            self.inclinometer.shape != (n, 2)
            or self.rotary.shape != (n,)
            or self.kinds.shape != (n,)
        ):
            raise InvalidMeasurementError(
                f'inconsistent lengths: {n} slider rows, {len(self.inclinometer)} inclinometer '
                f'rows, {len(self.rotary)} rotary values, {len(self.kinds)} kinds'
            )
        channels = {
            'slider_positions': self.actuator_positions,
            'inclinometer': self.inclinometer,
            'rotary': self.rotary[:, None],
        }
        if self.link_lengths is not None:
            if self.link_lengths.shape != (n,):
                raise InvalidMeasurementError(
                    f'link_lengths must have one value per posture, got {self.link_lengths.shape}'
                )
            channels['link_lengths'] = self.link_lengths[:, None]
        if self.device_turn is not None:
            if self.device_turn.shape != (n,):
                raise InvalidMeasurementError(
                    f'device_turn must have one angle per posture, got {self.device_turn.shape}'
                )
            channels['device_turn'] = self.device_turn[:, None]
        if self.standard_errors is not None:
            if self.standard_errors.shape != (n, N_CHANNELS):
                raise InvalidMeasurementError(
                    f'standard_errors must be (N, {N_CHANNELS}) with N = {n}, got '
                    f'{self.standard_errors.shape}'
                )
            channels['standard_errors'] = self.standard_errors
        for name, values in channels.items():
            bad = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
            if bad.size:
                raise InvalidMeasurementError(
                    f'non-finite {name} (NaN or inf) at posture(s) {bad.tolist()}', bad
                )
        self._check_range(
            'inclinometer angle',
            np.abs(self.inclinometer).max(axis=1) if n else np.zeros(0),
            limits.inclinometer_range_rad,
            'rad',
        )
        self._check_range('rotary angle', np.abs(self.rotary), limits.rotary_range_rad, 'rad')
        least, most = limits.actuator_range(actuator_unit)
        low = np.flatnonzero(
            np.any(self.actuator_positions < least, axis=1)
            | np.any(self.actuator_positions > most, axis=1)
        )
        if low.size:
            what = 'slider position' if actuator_unit == 'm' else 'actuator reading'
            raise InvalidMeasurementError(
                f'{what} outside [{least:g}, {most:g}] {actuator_unit} at '
                f'posture(s) {low.tolist()}',
                low,
            )
        if self.standard_errors is not None and np.any(self.standard_errors < 0):
            bad = np.flatnonzero(np.any(self.standard_errors < 0, axis=1))
            raise InvalidMeasurementError(
                f'negative standard error at posture(s) {bad.tolist()}', bad
            )
        if self.link_lengths is not None and np.any(self.link_lengths <= 0):
            bad = np.flatnonzero(self.link_lengths <= 0)
            raise InvalidMeasurementError(
                f'measured link length must be positive at posture(s) {bad.tolist()}', bad
            )
        unknown = sorted(set(self.kinds) - set(POSTURE_KINDS))
        if unknown:
            raise InvalidMeasurementError(
                f'unknown posture kind(s) {unknown}; expected one of {POSTURE_KINDS}'
            )

    @staticmethod
    def _check_range(name: str, magnitude: np.ndarray, limit: float, unit: str) -> None:
        bad = np.flatnonzero(magnitude > limit)
        if bad.size:
            raise InvalidMeasurementError(
                f'{name} beyond its range of +-{limit:.4g} {unit} at posture(s) {bad.tolist()}',
                bad,
            )


@dataclass(frozen=True)
class NoiseModel:
    """
    Uniform measurement noise, half-widths in SI units (the paper's section 4 model).

    ``actuator_m`` is in the unit of the model's actuator readings (``ModelLayout.actuator_unit``):
    metres for sliders and legs, radians for a rotary hexapod's cranks (the name is the field's
    since the first, slider-only, version).
    """

    actuator_m: float = 0.0
    angle_rad: float = 0.0

    @classmethod
    def from_microns(cls, microns: float) -> 'NoiseModel':
        """Return 'X um' noise as in Table 3: +-X um on sliders (urad: cranks), urad on angles."""
        return cls(actuator_m=microns * 1e-6, angle_rad=microns * 1e-6)

    def standard_deviations(self) -> np.ndarray:
        """
        Return the std of the 9 readings of a posture.

        Std of the 9 readings of a posture (6 sliders, alpha, beta, phi): a / sqrt(3) for +-a
        uniform.
        """
        return np.array([self.actuator_m] * 6 + [self.angle_rad] * 3) / np.sqrt(3.0)

    @property
    def known(self) -> bool:
        return self.actuator_m > 0 and self.angle_rad > 0


class Weights(enum.StrEnum):
    """What weighed a fit's residuals: its JSON's ``weights`` values."""

    SCATTER = 'scatter'  # each posture's measured scatter (Measurements.standard_errors)
    NOISE_MODEL = 'noise_model'  # one NoiseModel shared by every posture
    NONE = 'none'  # unweighted (the channels' fixed scales only)


@dataclass(frozen=True)
class ScatterFloor:
    """
    The smallest standard deviation a posture's value is credited with when weighed by scatter.

    A posture's measured scatter (the standard error of each channel's mean) can under-state
    what the value is really known to: a quantised channel that did not move reads the same
    count in every sample (zero scatter, while the true value lies anywhere within one
    resolution step), a channel with one sample has no scatter at all, and a short dwell of
    correlated samples under-estimates it.  Weighing by such a figure would give one posture's
    channel an unbounded weight (a zero standard error: an infinite one), so each standard
    error is raised to at least this floor.  The defaults, 0.1 um on the actuators and 0.1 urad
    on the angles, are below what the averaged readings of today's encoders and inclinometers
    reach (their resolution over the square root of ~100 samples, and the repeatability of the
    machine itself is larger still) and far above rounding, so they only act where the scatter
    says nothing.  The noise model (``--noise-um``) is no floor: it states one spread for every
    posture, and raising each posture's scatter to it would undo what the scatter tells apart.
    SI units: standard deviations, m and rad.
    """

    actuator_m: float = 1e-7
    angle_rad: float = 1e-7

    def __post_init__(self) -> None:
        for name in ('actuator_m', 'angle_rad'):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(
                    f'the scatter floor {name} must be positive and finite, got {value!r}'
                )

    @classmethod
    def from_microns(cls, microns: float) -> 'ScatterFloor':
        """Return X um on the actuators and X urad on every angle."""
        return cls(actuator_m=microns * 1e-6, angle_rad=microns * 1e-6)

    def standard_deviations(self) -> np.ndarray:
        """Return the floor of the 9 values of a posture (6 actuators, alpha, beta, phi)."""
        return np.array([self.actuator_m] * 6 + [self.angle_rad] * 3)

    def apply(self, standard_errors: np.ndarray) -> np.ndarray:
        """Return (N, 9) standard errors raised to at least the floor, channel by channel."""
        return np.maximum(np.asarray(standard_errors, dtype=float), self.standard_deviations())


def simulate_measurements(
    params: KinematicParameters,
    poses: np.ndarray,
    kinds: np.ndarray | str = SPHERE,
    device: DeviceModel = DeviceModel(),
    noise: NoiseModel = NoiseModel(),
    rng: np.random.Generator | None = None,
    defects: DeviceDefects = DeviceDefects(),
    lvdt: bool = False,
    device_turn: np.ndarray | float | None = None,
) -> Measurements:
    """
    Simulate what the device and the actuator encoders read at ``poses``.

    What the device and the actuator encoders read at ``poses`` on the machine ``params`` (any
    architecture).

    The readings go through the defect model (a defective inclinometer reads the
    true link direction with offsets and a skewed axis, the rotary sensor adds
    phi0).  With ``lvdt`` the link is prismatic and an LVDT reports its length
    per posture, minus the offset dL (the device's length error); otherwise the
    poses must lie on the true sphere of radius L + dL.  ``device_turn`` (rad, per
    posture or one value): the device turned about its link axis (pi: reversed,
    device.py); the rotary sensor turns with it and reads phi - turn + phi0.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    rng = rng if rng is not None else np.random.default_rng(0)
    actuators = inverse_kinematics(params, poses)
    n = len(poses)
    turns = (
        None
        if device_turn is None
        else np.broadcast_to(np.asarray(device_turn, float), (n,)).copy()
    )
    alpha, beta = inclinometer_readings(poses[:, :3], defects, device.mount, turns)
    angles = np.column_stack([alpha, beta])
    rotary = poses[:, 5] + defects.phi0 - (0.0 if turns is None else turns)
    rotary = (rotary + np.pi) % (2.0 * np.pi) - np.pi  # the sensor's range
    if noise.actuator_m:
        actuators = actuators + rng.uniform(-noise.actuator_m, noise.actuator_m, actuators.shape)
    if noise.angle_rad:
        angles = angles + rng.uniform(-noise.angle_rad, noise.angle_rad, angles.shape)
        rotary = rotary + rng.uniform(-noise.angle_rad, noise.angle_rad, n)
    lengths = None
    if lvdt:
        lengths = np.linalg.norm(poses[:, :3], axis=1) - defects.dL
        if noise.actuator_m:
            lengths = lengths + rng.uniform(-noise.actuator_m, noise.actuator_m, n)
    kinds_array = np.full(n, kinds) if isinstance(kinds, str) else np.asarray(kinds)
    return Measurements(actuators, angles, rotary, kinds_array, lengths, turns)
