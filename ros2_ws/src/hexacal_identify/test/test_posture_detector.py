"""Stream synchronisation and stationary-posture detection on synthetic sensor streams."""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_identify.core.posture_detector import (
    detect_postures,
    DetectorState,
    DROPPED_AT_END,
    DROPPED_FOR_GAP,
    DROPPED_FOR_MOTION,
    DUPLICATE_STAMP,
    NO_ENCODER_WITHIN_SKEW,
    OUT_OF_ORDER,
    PostureDetector,
    StreamSynchronizer,
    synchronize_arrays,
)
from hexacal_msgs_py.readings import ActuatorReading, EncoderReading, InclinometerReading
import numpy as np
import pytest

NOISE = 20e-6  # uniform +-20 um on sliders, +-20 urad on angles
NOISE_STD = NOISE / np.sqrt(3.0)
T0_NS = 1_000_000_000_000


@dataclass
class Session:
    stamps_ns: np.ndarray  # (N,)
    values: np.ndarray  # (N, 9)
    holds: list[tuple[int, int, np.ndarray]]  # true stationary intervals [start, end) and values


def make_targets(rng: np.random.Generator, count: int) -> np.ndarray:
    """Postures whose sliders differ by 10-40 mm and angles by 10-50 mrad from the previous one."""
    targets = np.empty((count, 9))
    targets[0] = np.r_[rng.uniform(0.3, 0.5, 6), rng.uniform(-0.2, 0.2, 3)]
    for k in range(1, count):
        step = np.r_[rng.uniform(0.01, 0.04, 6), rng.uniform(0.01, 0.05, 3)]
        targets[k] = targets[k - 1] + rng.choice([-1.0, 1.0], 9) * step
    return targets


def make_session(
    rng: np.random.Generator,
    targets: np.ndarray,
    rate_hz: float = 100.0,
    hold_s: float | list[float] = 1.5,
    move_s: float = 1.0,
    settle_amplitude: float = 3e-4,
    noise: bool = True,
) -> Session:
    """Make holds joined by cosine moves; each hold starts with a decaying 8 Hz oscillation."""
    period_ns = int(round(1e9 / rate_hz))
    holds_s = [hold_s] * len(targets) if np.isscalar(hold_s) else list(hold_s)
    stamps, rows, holds = [], [], []
    t_ns = T0_NS
    for k, target in enumerate(targets):
        if k:
            n_move = int(round(move_s * rate_hz))
            s = (1 - np.cos(np.pi * np.arange(n_move) / n_move)) / 2
            rows.append(targets[k - 1] + np.outer(s, target - targets[k - 1]))
            stamps.append(t_ns + period_ns * np.arange(n_move, dtype=np.int64))
            t_ns += n_move * period_ns
        n_hold = int(round(holds_s[k] * rate_hz))
        since_s = np.arange(n_hold) / rate_hz
        ringing = settle_amplitude * np.exp(-since_s / 0.04) * np.cos(2 * np.pi * 8 * since_s)
        rows.append(target + np.outer(ringing, rng.choice([-1.0, 1.0], 9)))
        stamps.append(t_ns + period_ns * np.arange(n_hold, dtype=np.int64))
        holds.append((t_ns, t_ns + n_hold * period_ns, target))
        t_ns += n_hold * period_ns
    values = np.vstack(rows)
    if noise:
        values = values + rng.uniform(-NOISE, NOISE, values.shape)
    return Session(np.concatenate(stamps), values, holds)


def assert_matches_holds(postures, holds, sigmas: float = 5.0) -> None:
    assert len(postures) == len(holds)
    for posture, (start_ns, end_ns, target) in zip(postures, holds):
        assert start_ns <= posture.first_stamp_ns < posture.stamp_ns < end_ns
        bound = sigmas * NOISE_STD / np.sqrt(posture.sample_count)
        assert np.all(np.abs(posture.values - target) <= bound), (posture.values - target, bound)


# --------------------------------------------------------------------------- detector


def test_detects_each_stationary_period_once_with_mean_within_noise():
    rng = np.random.default_rng(7)
    session = make_session(rng, make_targets(rng, 8))
    postures = detect_postures(session.stamps_ns, session.values)
    assert_matches_holds(postures, session.holds)
    for posture in postures:
        assert posture.sample_count == 51  # capture_s = 0.5 s at 100 Hz, both ends included
        assert posture.stamp_ns - posture.first_stamp_ns == 500_000_000
        assert np.allclose(posture.std, NOISE_STD, rtol=0.35)
        assert posture.reading.stamp_ns == posture.stamp_ns


def test_no_capture_during_motion():
    rng = np.random.default_rng(3)
    # Continuous motion: 20 mm / 20 mrad sinusoids, never still for a window.
    stamps = T0_NS + np.arange(3000, dtype=np.int64) * 10_000_000
    phase = 2 * np.pi * 0.2 * (stamps - T0_NS) / 1e9
    values = 0.4 + 0.02 * np.sin(phase[:, None] + np.arange(9)[None, :])
    values += rng.uniform(-NOISE, NOISE, values.shape)
    detector = PostureDetector()
    assert detector.update(stamps, values) == []
    assert detector.finish() is None and detector.dropped == {}

    # Stops too short to capture (window 0.3 s + capture 0.5 s > 0.6 s): dropped, never emitted.
    session = make_session(rng, make_targets(rng, 6), hold_s=0.6)
    detector = PostureDetector()
    assert detector.update(session.stamps_ns, session.values) == []
    assert detector.dropped.get(DROPPED_FOR_MOTION, 0) == 5
    assert detector.finish() is not None  # the last hold ends with the data
    assert all(d.sample_count < 51 for d in detector.recent_dropped)


def test_partial_period_at_end_is_reported_not_emitted():
    rng = np.random.default_rng(5)
    session = make_session(rng, make_targets(rng, 3), hold_s=[1.5, 1.5, 0.6])
    detector = PostureDetector()
    postures = detector.update(session.stamps_ns, session.values)
    assert_matches_holds(postures, session.holds[:2])
    assert detector.state is DetectorState.CAPTURING
    dropped = detector.finish()
    assert dropped is not None and dropped.reason == DROPPED_AT_END
    assert 0 < dropped.sample_count < 51
    assert dropped.last_stamp_ns == session.stamps_ns[-1]
    assert detector.dropped == {DROPPED_AT_END: 1}


@pytest.mark.parametrize('chunk', [1, 7, 64, 1000])
def test_streaming_in_any_chunks_equals_offline_detection(chunk):
    rng = np.random.default_rng(11)
    session = make_session(rng, make_targets(rng, 5))
    offline = detect_postures(session.stamps_ns, session.values)
    detector = PostureDetector()
    online = []
    for begin in range(0, len(session.stamps_ns), chunk):
        online += detector.update(
            session.stamps_ns[begin:begin + chunk], session.values[begin:begin + chunk]
        )
    assert [p.stamp_ns for p in online] == [p.stamp_ns for p in offline]
    for a, b in zip(online, offline):
        assert a.sample_count == b.sample_count
        assert np.allclose(a.values, b.values, rtol=0, atol=1e-12)


def test_gaps_abort_a_capture_but_never_duplicate_a_posture():
    rng = np.random.default_rng(13)
    targets = make_targets(rng, 3)
    session = make_session(rng, targets, hold_s=4.0)
    stamps, values = session.stamps_ns, session.values
    first_hold_start = session.holds[0][0]
    second_hold_start = session.holds[1][0]
    # 0.4 s gap inside the first capture; 0.5 s gap after the second posture was captured.
    in_capture = (stamps > first_hold_start + 500_000_000) & (
        stamps < first_hold_start + 900_000_000
    )
    after_capture = (stamps > second_hold_start + 2_000_000_000) & (
        stamps < second_hold_start + 2_500_000_000
    )
    keep = ~(in_capture | after_capture)
    detector = PostureDetector()
    postures = detector.update(stamps[keep], values[keep])
    assert detector.dropped == {DROPPED_FOR_GAP: 1}
    assert_matches_holds(postures, session.holds)  # once each, despite the gaps

    # The machine moved to a new posture during a gap: that posture is still captured.
    moved = make_session(rng, targets[:2], hold_s=[1.5, 3.0], move_s=0.5)
    hidden_move = (moved.stamps_ns >= moved.holds[0][1] - 100_000_000) & (
        moved.stamps_ns < moved.holds[1][0] + 100_000_000
    )
    postures = detect_postures(moved.stamps_ns[~hidden_move], moved.values[~hidden_move])
    assert len(postures) == 2
    assert np.all(np.abs(postures[1].values - targets[1]) < 1e-5)


def test_out_of_order_duplicate_and_non_finite_samples_are_rejected_and_counted():
    rng = np.random.default_rng(17)
    session = make_session(rng, make_targets(rng, 3))
    stamps, values = session.stamps_ns.copy(), session.values.copy()
    order = np.arange(len(stamps))
    order[100], order[101] = 101, 100  # one swapped pair: the late one is out of order
    stamps, values = stamps[order], values[order]
    stamps = np.insert(stamps, 200, stamps[199])  # a duplicated stamp
    values = np.insert(values, 200, values[199], axis=0)
    values[300, 2] = np.nan
    detector = PostureDetector()
    postures = detector.update(stamps, values)
    assert detector.rejected == {OUT_OF_ORDER: 1, DUPLICATE_STAMP: 1, 'non_finite': 1}
    assert_matches_holds(postures, session.holds)


def test_one_khz_for_ten_minutes_in_constant_memory():
    rng = np.random.default_rng(19)
    targets = make_targets(rng, 151)  # 151 x 3 s holds + 150 x 1 s moves = 603 s at 1 kHz
    session = make_session(rng, targets, rate_hz=1000.0, hold_s=3.0)
    assert len(session.stamps_ns) >= 600_000
    detector = PostureDetector()
    capacity = detector.buffer_capacity
    assert capacity == 602  # 0.3 s at the 2 kHz design rate, plus two
    found = []
    for start in range(0, len(session.stamps_ns), 5000):
        found += detector.update(
            session.stamps_ns[start:start + 5000], session.values[start:start + 5000]
        )
        assert detector.buffered_samples <= 301  # the last 0.3 s at 1 kHz
        assert detector.buffer_capacity == capacity
    assert_matches_holds(found, session.holds)
    assert all(p.sample_count == 501 for p in found)


# --------------------------------------------------------------------------- synchronizer


def _streams(rng, session, inclinometer_offset_ns, encoder_offset_ns, jitter_ns=1_000_000):
    """Three independent streams sampling the same motion at their own (jittered) stamps."""

    def sample(offset_ns):
        stamps = (
            session.stamps_ns
            + offset_ns
            + rng.integers(-jitter_ns, jitter_ns + 1, len(session.stamps_ns))
        )
        values = np.array(
            [np.interp(stamps, session.stamps_ns, session.values[:, c]) for c in range(9)]
        ).T
        return stamps, values

    sliders = [
        ActuatorReading(int(t), tuple(v[:6])) for t, v in zip(session.stamps_ns, session.values)
    ]
    inc_t, inc_v = sample(inclinometer_offset_ns)
    inclinometer = [InclinometerReading(int(t), v[6], v[7]) for t, v in zip(inc_t, inc_v)]
    enc_t, enc_v = sample(encoder_offset_ns)
    encoder = [EncoderReading(int(t), v[8]) for t, v in zip(enc_t, enc_v)]
    return sliders, inclinometer, encoder


def _deliver(rng, synchronizer, sliders, inclinometer, encoder, max_delay_ns=15_000_000):
    """Feed readings in arrival order: each stream in order, streams delayed independently."""
    arrivals = []
    for kind, readings in (('s', sliders), ('i', inclinometer), ('e', encoder)):
        # Arrival times follow list order, so readings placed out of order arrive out of order.
        times = np.sort([r.stamp_ns for r in readings]) + rng.integers(0, max_delay_ns + 1)
        times += rng.integers(0, 2_000_000, len(times))
        for position, (time_ns, reading) in enumerate(zip(times.tolist(), readings)):
            arrivals.append((time_ns, kind, position, reading))
    arrivals.sort(key=lambda a: a[:3])
    add = {
        's': synchronizer.add_actuators,
        'i': synchronizer.add_inclinometer,
        'e': synchronizer.add_encoder,
    }
    samples = []
    for _, kind, _, reading in arrivals:
        samples += add[kind](reading)
    return samples + synchronizer.flush()


def test_synchronizer_pairs_each_slider_reading_with_the_nearest_readings():
    rng = np.random.default_rng(23)
    session = make_session(rng, make_targets(rng, 3), noise=False)
    sliders, inclinometer, encoder = _streams(rng, session, 4_000_000, -3_000_000)
    synchronizer = StreamSynchronizer()
    samples = _deliver(rng, synchronizer, sliders, inclinometer, encoder)
    assert len(samples) == len(sliders)  # every slider reading paired, none twice
    inc_stamps = np.array([r.stamp_ns for r in inclinometer])
    enc_stamps = np.array([r.stamp_ns for r in encoder])
    for sample in samples:
        nearest_inc = inclinometer[int(np.argmin(np.abs(inc_stamps - sample.stamp_ns)))]
        nearest_enc = encoder[int(np.argmin(np.abs(enc_stamps - sample.stamp_ns)))]
        assert (sample.alpha, sample.beta, sample.phi) == (
            nearest_inc.alpha,
            nearest_inc.beta,
            nearest_enc.phi,
        )
    # The offline, vectorised pairing agrees.
    stamps, values = synchronize_arrays(
        [r.stamp_ns for r in sliders],
        [r.actuator_positions for r in sliders],
        inc_stamps,
        [(r.alpha, r.beta) for r in inclinometer],
        enc_stamps,
        [r.phi for r in encoder],
    )
    assert stamps.tolist() == [s.stamp_ns for s in samples]
    assert np.array_equal(values, np.array([s.values() for s in samples]))


def test_synchronizer_rejects_out_of_order_and_duplicates_and_reports_stale_streams():
    synchronizer = StreamSynchronizer(max_skew_ns=20_000_000, stale_after_ns=100_000_000)
    ms = 1_000_000
    for k in range(10):
        synchronizer.add_inclinometer(InclinometerReading(T0_NS + k * 10 * ms, 0.1, 0.2))
        synchronizer.add_encoder(EncoderReading(T0_NS + k * 10 * ms + ms, 0.3))
    synchronizer.add_inclinometer(InclinometerReading(T0_NS + 90 * ms, 0.1, 0.2))  # duplicate
    synchronizer.add_inclinometer(InclinometerReading(T0_NS + 50 * ms, 0.1, 0.2))  # late
    synchronizer.add_encoder(EncoderReading(T0_NS + 5 * ms, 0.3))  # late
    assert synchronizer.rejected == {
        'sliders': {},
        'inclinometer': {DUPLICATE_STAMP: 1, OUT_OF_ORDER: 1},
        'encoder': {OUT_OF_ORDER: 1},
    }
    out = []
    for k in range(10):
        out += synchronizer.add_actuators(
            ActuatorReading(T0_NS + k * 10 * ms + 2 * ms, (0.4,) * 6)
        )
    assert len(out) == 9  # the last waits for a later inclinometer/encoder reading
    assert all(s.values()[6:] == (0.1, 0.2, 0.3) for s in out)

    # The encoder stops; sliders and inclinometer go on for 0.5 s.
    for k in range(10, 60):
        synchronizer.add_inclinometer(InclinometerReading(T0_NS + k * 10 * ms, 0.1, 0.2))
        out += synchronizer.add_actuators(
            ActuatorReading(T0_NS + k * 10 * ms + 2 * ms, (0.4,) * 6)
        )
        assert synchronizer.pending <= 64
    now = T0_NS + 600 * ms
    assert synchronizer.stale_streams(now) == ['encoder']
    status = synchronizer.status(now)['encoder']
    assert status.stale and status.last_stamp_ns == T0_NS + 91 * ms and status.accepted == 10
    # Paired while the last encoder reading (91 ms) was within 20 ms: sliders at 92 and 102 ms.
    assert len(out) == 11
    # Dropped: 112 ms .. 562 ms; 572, 582, 592 ms still wait (within 20 ms of the newest).
    assert synchronizer.unpaired == {NO_ENCODER_WITHIN_SKEW: 46}
    assert synchronizer.pending == 3


def test_skewed_jittered_reordered_streams_still_give_the_right_postures():
    rng = np.random.default_rng(29)
    session = make_session(rng, make_targets(rng, 6))
    sliders, inclinometer, encoder = _streams(rng, session, 7_000_000, -5_000_000)
    # Swap some neighbours so a few readings arrive out of order, and repeat some.
    for readings in (sliders, inclinometer, encoder):
        for index in rng.choice(len(readings) - 1, 10, replace=False):
            readings[index], readings[index + 1] = readings[index + 1], readings[index]
        for index in rng.choice(len(readings), 5, replace=False):
            readings.insert(int(index), readings[int(index)])
    synchronizer = StreamSynchronizer()
    detector = PostureDetector()
    postures = []
    for sample in _deliver(rng, synchronizer, sliders, inclinometer, encoder, max_delay_ns=0):
        postures += detector.add(sample)
    assert detector.finish() is None
    assert sum(sum(r.values()) for r in synchronizer.rejected.values()) >= 30
    # Interpolated aux streams add up to a 7 ms x velocity error only while moving: means hold.
    assert_matches_holds(postures, session.holds, sigmas=6.0)
