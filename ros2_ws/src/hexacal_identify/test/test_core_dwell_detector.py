"""The dwell detector on synthetic raw streams with real-sensor effects, against the old one."""

from __future__ import annotations

from dataclasses import dataclass, field

from hexacal_identify.core.dwell_detector import detect_dwell_postures, DwellDetector
from hexacal_identify.core.posture_detector import detect_postures, synchronize_arrays
from hexacal_identify.core.robust_stats import quantum, robust_mean
import numpy as np
import pytest

T0_NS = 1_000_000_000_000
NOISE = 10e-6  # uniform +-10 um / urad, as the simulated driver's default
SLICES = {'sliders': slice(0, 6), 'inclinometer': slice(6, 8), 'encoder': slice(8, 9)}


@dataclass
class Truth:
    """Streams and the settled values of the dwells they hold."""

    streams: dict[str, tuple[np.ndarray, np.ndarray]]
    targets: np.ndarray  # (postures, 9)
    holds: list[tuple[int, int]]  # [start, end) of each dwell, actuator clock (ns)
    offsets_ns: dict[str, int] = field(default_factory=dict)


def targets(rng: np.random.Generator, count: int) -> np.ndarray:
    """Postures 10-40 mm / 10-50 mrad apart."""
    out = np.empty((count, 9))
    out[0] = np.r_[rng.uniform(0.3, 0.5, 6), rng.uniform(-0.2, 0.2, 3)]
    for k in range(1, count):
        step = np.r_[rng.uniform(0.01, 0.04, 6), rng.uniform(0.01, 0.05, 3)]
        out[k] = out[k - 1] + rng.choice([-1.0, 1.0], 9) * step
    return out


def motion(points: np.ndarray, hold_s: float, move_s: float):
    """Return the true trajectory as a function of time (s) and the dwells [start, end) (s)."""
    holds, t = [], 0.0
    for k in range(len(points)):
        holds.append((t, t + hold_s))
        t += hold_s + move_s

    def at(times: np.ndarray) -> np.ndarray:
        out = np.empty((len(times), 9))
        for k, (start, end) in enumerate(holds):
            after = times >= start
            out[after] = points[k]
            if k + 1 < len(points):
                moving = (times >= end) & (times < end + move_s)
                s = (1 - np.cos(np.pi * (times[moving] - end) / move_s)) / 2
                out[moving] = points[k] + np.outer(s, points[k + 1] - points[k])
        return out

    return at, holds


def make_streams(
    seed: int = 0,
    count: int = 12,
    hold_s: float = 2.5,
    move_s: float = 1.0,
    rates: tuple[float, float, float] = (100.0, 100.0, 100.0),
    lag_s: float = 0.0,
    spikes: int = 0,
    offsets_s: tuple[float, float] = (0.0, 0.0),
    drop: float = 0.0,
    quantum_m: float = 0.0,
    quantum_rad: float = 0.0,
    noise: float = NOISE,
) -> Truth:
    """Sample the motion per stream at its own rate, with its sensor's effects."""
    rng = np.random.default_rng(seed)
    points = targets(rng, count)
    at, holds = motion(points, hold_s, move_s)
    end_s = holds[-1][1]
    streams = {}
    for (name, part), rate, offset in zip(SLICES.items(), rates, (0.0, *offsets_s)):
        fine = np.arange(0.0, end_s, 1e-3)
        truth = at(fine)[:, part]
        if name == 'inclinometer' and lag_s:
            # First-order lag of the sensor's own filter, exact per 1 ms step.
            decay = np.exp(-1e-3 / lag_s)
            for i in range(1, len(truth)):
                truth[i] = decay * truth[i - 1] + (1 - decay) * truth[i]
        times = np.arange(0.0, end_s, 1.0 / rate)
        values = np.column_stack([np.interp(times, fine, truth[:, c]) for c in range(truth.shape[1])])
        values += rng.uniform(-noise, noise, values.shape)
        step = quantum_m if name == 'sliders' else quantum_rad
        if step:
            values = np.round(values / step) * step
        if spikes:
            where = rng.choice(len(values), spikes, replace=False)
            values[where, rng.integers(0, values.shape[1], spikes)] += rng.choice([-1, 1], spikes) * 3e-3
        keep = rng.random(len(times)) >= drop
        stamps = T0_NS + np.round((times + offset) * 1e9).astype(np.int64)
        streams[name] = (stamps[keep], values[keep])
    holds_ns = [(T0_NS + int(a * 1e9), T0_NS + int(b * 1e9)) for a, b in holds]
    offsets = {'inclinometer': int(offsets_s[0] * 1e9), 'encoder': int(offsets_s[1] * 1e9)}
    return Truth(streams, points, holds_ns, offsets)


def old_detector(truth: Truth, **options):
    """Today's detector: pair on the slider stamps, then the window detector."""
    (st, sv), (it, iv), (et, ev) = (truth.streams[name] for name in SLICES)
    stamps, values = synchronize_arrays(st, sv, it, iv, et, ev)
    return detect_postures(stamps, values, **options)


def errors_in_se(postures, truth: Truth) -> np.ndarray:
    """Per posture and channel: |value - settled truth| / standard error (matched by time)."""
    out = []
    for posture in postures:
        index = [k for k, (a, b) in enumerate(truth.holds) if a <= posture.stamp_ns <= b]
        assert len(index) == 1, posture.stamp_ns
        error = np.abs(posture.values - truth.targets[index[0]])
        out.append(error / np.maximum(posture.scatter.standard_errors, 1e-12))
    return np.array(out)


def bias(postures, truth: Truth) -> float:
    """Largest |value - settled truth| over postures and channels (m or rad)."""
    errors = []
    for posture in postures:
        nearest = [k for k, (a, b) in enumerate(truth.holds) if a <= posture.stamp_ns <= b][0]
        errors.append(np.max(np.abs(posture.values - truth.targets[nearest])))
    return float(max(errors))
