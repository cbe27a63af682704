"""The dwell detector on synthetic raw streams with real-sensor effects, against their truth."""

from __future__ import annotations

from dataclasses import dataclass, field

from hexacal_identify.core.detection.dwell_detector import detect_dwell_postures, DwellDetector
from hexacal_identify.core.detection.robust_stats import quantum, robust_mean
from hexacal_msgs_py.errors import InvalidReadingError
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
        values = np.column_stack(
            [np.interp(times, fine, truth[:, c]) for c in range(truth.shape[1])]
        )
        values += rng.uniform(-noise, noise, values.shape)
        step = quantum_m if name == 'sliders' else quantum_rad
        if step:
            values = np.round(values / step) * step
        if spikes:
            where = rng.choice(len(values), spikes, replace=False)
            channels = rng.integers(0, values.shape[1], spikes)
            values[where, channels] += rng.choice([-1, 1], spikes) * 3e-3  # 3 mm / mrad
        keep = rng.random(len(times)) >= drop
        stamps = T0_NS + np.round((times + offset) * 1e9).astype(np.int64)
        streams[name] = (stamps[keep], values[keep])
    holds_ns = [(T0_NS + int(a * 1e9), T0_NS + int(b * 1e9)) for a, b in holds]
    offsets = {'inclinometer': int(offsets_s[0] * 1e9), 'encoder': int(offsets_s[1] * 1e9)}
    return Truth(streams, points, holds_ns, offsets)


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


def feed_online(truth: Truth, chunk_s: float, **options):
    """Feed the streams as the collector does: every chunk_s, what each stream stamped."""
    detector = DwellDetector(**options)
    postures = []
    end = max(stamps[-1] for stamps, _ in truth.streams.values())
    step = int(chunk_s * 1e9)
    for begin in range(T0_NS - step, int(end) + step, step):
        batch = {}
        for name, (stamps, values) in truth.streams.items():
            inside = (stamps >= begin) & (stamps < begin + step)
            if inside.any():
                batch[name] = (stamps[inside], values[inside])
        postures += detector.update(batch)
    postures += detector.finish()[0]
    return postures, detector


# --------------------------------------------------------------------------- per effect


def test_ideal_streams_give_one_posture_per_dwell_within_noise():
    truth = make_streams(seed=3)
    postures, detector = detect_dwell_postures(truth.streams)
    assert len(postures) == len(truth.targets)
    assert np.all(errors_in_se(postures, truth) < 4.0)
    for posture in postures:
        scatter = posture.scatter
        assert posture.reading.scatter == scatter
        # ~0.5 s at 100 Hz per stream; standard error of uniform +-10 um noise over ~50.
        assert all(45 <= n <= 60 for n in scatter.sample_counts)
        expected = NOISE / np.sqrt(3) / np.sqrt(np.array(scatter.sample_counts))
        assert np.allclose(scatter.standard_errors, expected, rtol=0.4)
        assert posture.first_stamp_ns < posture.stamp_ns
    assert detector.dropped == {} and detector.rejected == {}


def test_a_lagging_inclinometer_is_waited_for_and_its_postures_are_unbiased():
    truth = make_streams(seed=5, lag_s=0.2, hold_s=3.0)
    postures, _ = detect_dwell_postures(truth.streams)
    assert len(postures) == len(truth.targets)
    errors = errors_in_se(postures, truth)
    assert np.all(errors < 4.0), errors.max(axis=0)
    # Averaged while it still creeps, the inclinometer would be tens of urad off.
    assert bias(postures, truth) < 4e-6


def test_a_spike_neither_splits_nor_biases_a_dwell():
    truth = make_streams(seed=7, spikes=30)
    postures, detector = detect_dwell_postures(truth.streams)
    assert len(postures) == len(truth.targets)
    assert np.all(errors_in_se(postures, truth) < 4.0)
    spikes = sum(lane.health.spikes_rejected for lane in detector.lanes.values())
    assert spikes >= 1


def test_a_30_ms_clock_offset_is_estimated_and_the_postures_are_right():
    truth = make_streams(seed=9, offsets_s=(0.03, -0.02), count=16)
    postures, detector = detect_dwell_postures(truth.streams)
    assert detector.offsets_s['inclinometer'] == pytest.approx(0.03, abs=0.003)
    assert detector.offsets_s['encoder'] == pytest.approx(-0.02, abs=0.003)
    assert len(postures) == len(truth.targets)
    assert np.all(errors_in_se(postures, truth) < 4.0)
    # Stated offsets are used as they are.
    stated, fixed = detect_dwell_postures(
        truth.streams,
        clock_offsets_s={'inclinometer': 0.03, 'encoder': -0.02},
        estimate_offsets=(),
    )
    assert fixed.offsets_s == {'sliders': 0.0, 'inclinometer': 0.03, 'encoder': -0.02}
    assert len(stated) == len(truth.targets)


def test_drops_and_different_rates_give_per_channel_counts():
    truth = make_streams(seed=11, rates=(100.0, 50.0, 200.0), drop=0.1)
    postures, detector = detect_dwell_postures(truth.streams)
    assert len(postures) == len(truth.targets)
    assert np.all(errors_in_se(postures, truth) < 4.0)
    counts = np.array([p.scatter.sample_counts for p in postures])
    # About 0.525 s of each stream, 10 % dropped: ~47, ~24 and ~95 readings.
    assert np.all((counts[:, :6] > 35) & (counts[:, :6] < 60))
    assert np.all((counts[:, 6:8] > 15) & (counts[:, 6:8] < 30))
    assert np.all((counts[:, 8] > 75) & (counts[:, 8] < 115))
    rates = {lane.name: lane.health.rate_hz for lane in detector.lanes.values()}
    assert rates['sliders'] == pytest.approx(90, rel=0.05)
    assert rates['inclinometer'] == pytest.approx(45, rel=0.05)
    assert rates['encoder'] == pytest.approx(180, rel=0.05)


def test_quantised_noise_free_channels_give_finite_non_negative_standard_errors():
    truth = make_streams(seed=13, noise=0.0, quantum_m=1e-6, quantum_rad=2e-5)
    postures, _ = detect_dwell_postures(truth.streams)
    assert len(postures) == len(truth.targets)
    for posture in postures:
        errors = np.array(posture.scatter.standard_errors)
        assert np.all(np.isfinite(errors)) and np.all(errors >= 0.0)
    # Within half a resolution step of the truth.
    assert bias(postures, truth) <= 1e-5 + 1e-12
    assert np.array_equal(quantum(np.array([[0.0], [0.0], [2e-5], [2e-5], [4e-5]])), [2e-5])
    mean = robust_mean(np.full((10, 1), 3e-5), np.zeros(1))
    assert mean.standard_error[0] == 0.0 and mean.count[0] == 10


def test_gaps_drop_a_capture_and_the_end_of_data_drops_a_partial_one():
    truth = make_streams(seed=15, count=3, hold_s=3.0)
    stamps, values = truth.streams['encoder']
    start = truth.holds[1][0]
    hole = (stamps > start + 700_000_000) & (stamps < start + 1_000_000_000)
    truth.streams['encoder'] = (stamps[~hole], values[~hole])
    postures, detector = detect_dwell_postures(truth.streams)
    assert len(postures) == 3  # the dwell is still captured after the gap
    assert detector.lanes['encoder'].health.gaps == 1
    assert detector.lanes['encoder'].health.largest_gap_ns >= 300_000_000
    # The data ends 0.55 s into the second dwell: settled, but too short to capture.
    short = make_streams(seed=15, count=2, hold_s=2.0)
    end = short.holds[1][0] + 550_000_000
    for name, (stamps, values) in short.streams.items():
        short.streams[name] = (stamps[stamps <= end], values[stamps <= end])
    found, ended = detect_dwell_postures(short.streams)
    assert len(found) == 1 and ended.dropped == {'end_of_stream': 1}


# --------------------------------------------------------------------------- online, memory


@pytest.mark.slow
@pytest.mark.parametrize('chunk_s', [0.01, 0.037, 0.5])
def test_online_in_chunks_equals_offline_exactly(chunk_s):
    truth = make_streams(seed=17, count=8, lag_s=0.1, spikes=10, offsets_s=(0.03, -0.01))
    offline, _ = detect_dwell_postures(truth.streams)
    online, _ = feed_online(truth, chunk_s)
    assert len(online) == len(offline) == 8
    for a, b in zip(online, offline):
        assert a.reading == b.reading and a.first_stamp_ns == b.first_stamp_ns


@pytest.mark.slow
def test_memory_is_bounded_over_a_long_run():
    truth = make_streams(seed=19, count=24, hold_s=2.0, move_s=0.5)
    detector = DwellDetector()
    found = []
    step = 10_000_000
    end = max(stamps[-1] for stamps, _ in truth.streams.values())
    held = []
    for begin in range(T0_NS, int(end) + step, step):
        batch = {}
        for name, (stamps, values) in truth.streams.items():
            first, last = np.searchsorted(stamps, [begin, begin + step])  # stamps are sorted
            batch[name] = (stamps[first:last], values[first:last])
        found += detector.update(batch)
        held.append(detector.held_samples)
    assert len(found) == 24
    # Window, capture and a block of each stream at 100 Hz: never more than ~1.2 s x 3 streams.
    assert max(held) <= 400 and max(held[len(held) // 2:]) <= max(held[: len(held) // 2]) + 10


@pytest.mark.parametrize('seed', range(5))
def test_disordered_repeated_and_non_finite_readings_are_counted_never_fatal(seed):
    rng = np.random.default_rng(seed)
    truth = make_streams(seed=seed, count=4)
    detector = DwellDetector()
    postures = []
    for name, (stamps, values) in truth.streams.items():
        stamps, values = stamps.copy(), values.copy()
        swap = rng.choice(len(stamps) - 1, 20, replace=False)
        stamps[swap], stamps[swap + 1] = stamps[swap + 1], stamps[swap].copy()
        values[rng.choice(len(values), 10, replace=False), 0] = np.nan
        stamps[rng.choice(len(stamps), 5, replace=False)] = stamps[0]
        for begin in range(0, len(stamps), 37):
            postures += detector.add(name, stamps[begin:begin + 37], values[begin:begin + 37])
    postures += detector.finish()[0]
    assert detector.rejected['non_finite'] == 30
    assert detector.rejected.get('out_of_order', 0) + detector.rejected.get(
        'duplicate_stamp', 0
    ) >= 3 * 20
    for posture in postures:
        assert np.all(np.isfinite(posture.values))
        assert np.all(np.isfinite(posture.scatter.standard_errors))
    with pytest.raises(InvalidReadingError):
        detector.add('sliders', [1, 2], [[0.0] * 5, [0.0] * 5])
    with pytest.raises(ValueError):
        DwellDetector(clock_offsets_s={'sliders': 0.1})


def test_a_dwell_too_short_for_a_lagging_channel_is_counted_and_names_the_stream():
    """A first-order lag of 0.5 s cannot settle in a 1.5 s dwell: no posture, the stream named."""
    from hexacal_identify.core.detection.dwell_detector import detect_dwell_postures

    rate, tau, dwell, move = 100.0, 0.5, 1.5, 0.5
    period = dwell + move
    t = np.arange(0.0, 8 * period, 1.0 / rate)
    phase = np.clip((t % period - dwell) / move, 0.0, 1.0)  # still, then a 0.5 s ramp
    level = (np.floor(t / period) + phase) * 0.005  # 5 mm / 5 mrad per move
    rng = np.random.default_rng(1)
    lagged = np.empty_like(level)
    lagged[0] = level[0]
    for k in range(1, len(t)):
        gain = 1.0 - np.exp(-1.0 / (rate * tau))
        lagged[k] = lagged[k - 1] + gain * (level[k] - lagged[k - 1])
    stamps = (t * 1e9).astype(np.int64) + 1_000_000_000
    noise = rng.uniform(-1e-5, 1e-5, (len(t), 9))
    found, detector = detect_dwell_postures(
        {
            'sliders': (stamps, level[:, None] + noise[:, :6]),
            'inclinometer': (stamps, lagged[:, None] + noise[:, 6:8]),
            'encoder': (stamps, level[:, None] + noise[:, 8:]),
        },
        estimate_offsets=(),
    )
    assert detector.unsettled.get('inclinometer', 0) >= 5
    assert set(detector.unsettled) == {'inclinometer'}
    assert detector.dropped.get('unsettled', 0) == detector.unsettled['inclinometer']
    assert len(found) <= 2  # no biased posture of a still-creeping channel


@pytest.mark.parametrize(
    ('detector', 'settings', 'message'),
    [
        (DwellDetector, {'capture_s': 0.0}, 'window_s, capture_s and max_gap_s must be > 0'),
        (DwellDetector, {'window_s': float('nan')}, 'window_s, capture_s and max_gap_s must'),
        (DwellDetector, {'angle_tolerance_rad': -1e-4}, 'tolerances must be > 0'),
        (DwellDetector, {'link_tolerance_m': 0.0}, 'tolerances must be > 0'),
        (DwellDetector, {'slider_tolerance_m': float('nan')}, 'tolerances must be > 0'),
    ],
)
def test_the_detector_refuses_settings_that_are_not_positive(detector, settings, message):
    """The settings check (check_detector_settings) names the settings."""
    with pytest.raises(ValueError, match=message):
        detector(**settings)
