"""
Sensor models of the simulated machine (ROS-free): what real sensors do to the true readings.

The driver's ideal sensors read the truth plus uniform noise (simulation.SensorSimulator), all
three streams stamped together. Real ones do more; `SensorStreams` adds what the parameter
`sensor_effects` switches on ('' none, 'all', or a comma list of `SensorEffect` names):

- lag: the inclinometer's own low-pass filter, first order with time constant
  `inclinometer_time_constant_s`, discretised exactly per sample
  (y += (1 - exp(-dt / tau)) (x - y), dt = 1 / rate_hz), settled at the first sample.
  Only the inclinometer: encoders count positions, they have no filter to lag through.
- drift: the inclinometer's zero drifts linearly, `inclinometer_drift_rad_per_s` times the
  time since the first sample, the same on both axes (a thermal drift of the sensor).
- spikes: vibration. At a mean rate of `spike_rate_hz` (a Poisson process, one Bernoulli trial
  per sample) one inclinometer sample is off by `spike_size_rad` on each angle, each with a
  random sign. Only the inclinometer: it measures tilt through gravity, so the acceleration of
  a shaking machine reads as tilt; the actuator and rotary encoders measure positions, which
  vibration moves by far less than their resolution.
- noise: the existing uniform noise (slider_noise_m, angle_noise_rad), unchanged.
- quantisation: every channel rounded to the nearest multiple of its resolution
  (`actuator_resolution_m`, `inclinometer_resolution_rad`, `rotary_resolution_rad`; 0: none).
- clock: each stream stamped by its own clock: the true sample time plus the stream's offset
  (sliders 0: the reference clock; `inclinometer_clock_offset_s`, `encoder_clock_offset_s`)
  plus Gaussian jitter of `clock_jitter_s` per message, kept strictly increasing per stream.
- drops: each message of each stream is lost with probability `drop_probability`,
  independently (the sample is still taken: the inclinometer's filter runs on).

Order per sample: truth -> lag -> drift -> spike -> noise -> quantisation; then the stamps,
then the drops. The effects draw from a random stream of their own (a fixed number of draws
per sample, whichever effects are on), so the noise is the same with and without them, and
with `sensor_effects` '' the readings and stamps are exactly the ideal sensors'.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from enum import StrEnum
import math
from typing import Any, Mapping

from hexacal_driver.simulation import (
    exact_readings,
    SensorReadings,
    SensorSimulator,
    WalkSample,
)
import numpy as np

NS_PER_S = 1_000_000_000
EFFECTS_STREAM = 0x5E45EFF  # the effects' own random stream (the noise has NOISE_STREAM)
ALL_EFFECTS = 'all'
STREAMS = ('sliders', 'inclinometer', 'encoder')  # the order of SensorOutput.stamps_ns
# Per sample, whichever effects are on: uniforms (3 drops, spike, 2 spike signs), 3 normals.
_UNIFORMS, _NORMALS = 6, 3


class SensorEffect(StrEnum):
    """One way real sensors differ from ideal ones (see the module docstring)."""

    LAG = 'lag'
    QUANTISATION = 'quantisation'
    CLOCK = 'clock'
    DROPS = 'drops'
    SPIKES = 'spikes'
    DRIFT = 'drift'


def parse_effects(text: str) -> frozenset[SensorEffect]:
    """
    Return the effects named by `text`: '' none, 'all', or names separated by commas.

    Raises ValueError naming the unknown name and the valid ones.
    """
    effects: set[SensorEffect] = set()
    for part in str(text).split(','):
        name = part.strip().lower()
        if not name:
            continue
        if name == ALL_EFFECTS:
            effects.update(SensorEffect)
            continue
        try:
            effects.add(SensorEffect(name))
        except ValueError:
            valid = ', '.join(effect.value for effect in SensorEffect)
            raise ValueError(
                f"unknown sensor effect {name!r}: use '', {ALL_EFFECTS!r} or a comma list of "
                f'{valid}'
            ) from None
    return frozenset(effects)


def effects_text(effects: frozenset[SensorEffect]) -> str:
    """Return the effects in SensorEffect order, comma separated ('' for none)."""
    return ','.join(effect.value for effect in SensorEffect if effect in effects)


@dataclass(frozen=True)
class SensorSettings:
    """
    The sensor effects switched on and their parameters (SI units).

    The defaults are those of real devices of the class the paper's device uses: see
    docs/user-guide.md, "Sensor models".
    """

    effects: frozenset[SensorEffect] = field(default_factory=frozenset)
    inclinometer_time_constant_s: float = 0.1
    actuator_resolution_m: float = 1e-6
    inclinometer_resolution_rad: float = 5e-6
    rotary_resolution_rad: float = 2.0 * math.pi / 2**20
    inclinometer_clock_offset_s: float = 0.03
    encoder_clock_offset_s: float = 0.005
    clock_jitter_s: float = 0.001
    drop_probability: float = 0.01
    spike_rate_hz: float = 0.5
    spike_size_rad: float = 5e-4
    inclinometer_drift_rad_per_s: float = 5e-9

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> SensorSettings:
        """Build from parameter values: `sensor_effects` text and the numbers (else defaults)."""
        numbers = {
            item.name: float(values[item.name])
            for item in fields(cls)
            if item.name != 'effects' and item.name in values
        }
        return cls(parse_effects(values.get('sensor_effects', '')), **numbers)

    def describe(self) -> str:
        """Return the active effects with their parameters, as logged ('ideal sensors' if none)."""
        parts = {
            SensorEffect.LAG: f'lag (tau {self.inclinometer_time_constant_s:g} s)',
            SensorEffect.DRIFT: f'drift ({self.inclinometer_drift_rad_per_s:g} rad/s)',
            SensorEffect.SPIKES: (
                f'spikes ({self.spike_rate_hz:g} /s of {self.spike_size_rad:g} rad)'
            ),
            SensorEffect.QUANTISATION: (
                f'quantisation ({self.actuator_resolution_m:g} m, '
                f'{self.inclinometer_resolution_rad:g} rad, {self.rotary_resolution_rad:.3g} rad)'
            ),
            SensorEffect.CLOCK: (
                f'clock (offsets {self.inclinometer_clock_offset_s:g} s inclinometer, '
                f'{self.encoder_clock_offset_s:g} s encoder, jitter {self.clock_jitter_s:g} s)'
            ),
            SensorEffect.DROPS: f'drops ({self.drop_probability:g})',
        }
        active = [text for effect, text in parts.items() if effect in self.effects]
        return 'sensor effects: ' + ', '.join(active) if active else 'ideal sensors'


# The parameters of the sensor models (besides `sensor_effects`) and their defaults.
SENSOR_DEFAULTS: dict[str, float] = {
    item.name: getattr(SensorSettings(), item.name)
    for item in fields(SensorSettings)
    if item.name != 'effects'
}


@dataclass(frozen=True)
class SensorOutput:
    """One sample of the three streams: the readings and each stream's stamp (None: dropped)."""

    readings: SensorReadings
    stamps_ns: tuple[int | None, int | None, int | None]  # STREAMS order


def quantise(value: float, resolution: float) -> float:
    """Return `value` rounded to the nearest multiple of `resolution` (0: unchanged)."""
    return round(value / resolution) * resolution if resolution > 0.0 else value


class SensorStreams:
    """
    The sensors of the simulated machine as streams: one `read` per sample, in time order.

    `simulator` gives the truth's noise (and the device's mount and defects); `rng` is the
    effects' own Generator; `period_s` the time between samples (1 / rate_hz).
    """

    def __init__(
        self,
        simulator: SensorSimulator,
        settings: SensorSettings,
        rng: np.random.Generator,
        period_s: float,
    ) -> None:
        """Start with the inclinometer's filter empty (settled at the first sample)."""
        self.simulator = simulator
        self.settings = settings
        self.rng = rng
        self.period_s = float(period_s)
        effects = settings.effects
        self._lag = SensorEffect.LAG in effects
        self._drift = SensorEffect.DRIFT in effects
        self._spikes = SensorEffect.SPIKES in effects
        self._quantise = SensorEffect.QUANTISATION in effects
        self._clock = SensorEffect.CLOCK in effects
        self._drops = SensorEffect.DROPS in effects
        tau = settings.inclinometer_time_constant_s
        self._lag_gain = 1.0 - math.exp(-self.period_s / tau) if tau > 0.0 else 1.0
        self._spike_probability = 1.0 - math.exp(-settings.spike_rate_hz * self.period_s)
        self._offsets_ns = (
            0,
            round(settings.inclinometer_clock_offset_s * NS_PER_S),
            round(settings.encoder_clock_offset_s * NS_PER_S),
        )
        self._jitter_ns = settings.clock_jitter_s * NS_PER_S
        self._filtered: tuple[float, float] | None = None  # the inclinometer filter's output
        self._last_stamps = [-1, -1, -1]
        self.samples = 0  # samples read so far
        self.dropped = [0, 0, 0]  # messages dropped per stream (STREAMS order)
        self.spikes = 0  # inclinometer samples with a spike

    def read(self, sample: WalkSample, device_turn: float, stamp_ns: int) -> SensorOutput:
        """Return the sensors' output for `sample`, taken at `stamp_ns` (the reference clock)."""
        simulator = self.simulator
        exact = exact_readings(
            sample.pose, sample.actuators, simulator.mount, simulator.defects, device_turn
        )
        if not self.settings.effects:  # ideal sensors: exactly SensorSimulator.read
            self.samples += 1
            return SensorOutput(simulator.add_noise(exact), (stamp_ns, stamp_ns, stamp_ns))
        uniforms = self.rng.random(_UNIFORMS)
        normals = self.rng.standard_normal(_NORMALS)
        readings = simulator.add_noise(self._before_noise(exact, uniforms))
        if self._quantise:
            readings = self._quantised(readings)
        stamps: list[int | None] = list(self._stamps(stamp_ns, normals))
        if self._drops:
            for index in range(3):
                if uniforms[index] < self.settings.drop_probability:
                    stamps[index] = None
                    self.dropped[index] += 1
        self.samples += 1
        return SensorOutput(readings, (stamps[0], stamps[1], stamps[2]))

    def _before_noise(self, exact: SensorReadings, uniforms: np.ndarray) -> SensorReadings:
        """Return the readings after the inclinometer's lag, drift and spike."""
        alpha, beta = exact.alpha_rad, exact.beta_rad
        if self._lag:
            if self._filtered is not None:
                gain, (last_alpha, last_beta) = self._lag_gain, self._filtered
                alpha = last_alpha + gain * (alpha - last_alpha)
                beta = last_beta + gain * (beta - last_beta)
            self._filtered = (alpha, beta)
        if self._drift:
            drift = self.settings.inclinometer_drift_rad_per_s * self.samples * self.period_s
            alpha, beta = alpha + drift, beta + drift
        if self._spikes and uniforms[3] < self._spike_probability:
            size = self.settings.spike_size_rad
            alpha += size if uniforms[4] < 0.5 else -size
            beta += size if uniforms[5] < 0.5 else -size
            self.spikes += 1
        return SensorReadings(exact.actuators_m, alpha, beta, exact.phi_rad)

    def _quantised(self, readings: SensorReadings) -> SensorReadings:
        """Return the readings rounded to each channel's resolution."""
        settings = self.settings
        actuator = settings.actuator_resolution_m
        angle = settings.inclinometer_resolution_rad
        actuators = readings.actuators_m
        if actuator > 0.0:
            actuators = np.round(actuators / actuator) * actuator
        return SensorReadings(
            actuators,
            quantise(readings.alpha_rad, angle),
            quantise(readings.beta_rad, angle),
            quantise(readings.phi_rad, settings.rotary_resolution_rad),
        )

    def _stamps(self, stamp_ns: int, normals: np.ndarray) -> tuple[int, int, int]:
        """Return each stream's stamp: its own clock with `clock`, else all `stamp_ns`."""
        if not self._clock:
            return stamp_ns, stamp_ns, stamp_ns
        stamps = []
        for index in range(3):
            stamp = stamp_ns + self._offsets_ns[index] + round(normals[index] * self._jitter_ns)
            # A stream's stamps strictly increase, whatever the jitter draws.
            stamp = max(stamp, self._last_stamps[index] + 1)
            self._last_stamps[index] = stamp
            stamps.append(stamp)
        return stamps[0], stamps[1], stamps[2]
