"""The collector's input synchronizer on synthetic sensor streams: pairing, rejects, staleness."""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_identify.core.detection.stream_synchronizer import StreamSynchronizer
from hexacal_identify.core.detection.vocabulary import (
    DUPLICATE_STAMP,
    NO_ENCODER_WITHIN_SKEW,
    OUT_OF_ORDER,
)
from hexacal_msgs_py.readings import ActuatorReading, EncoderReading, InclinometerReading
import numpy as np

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
