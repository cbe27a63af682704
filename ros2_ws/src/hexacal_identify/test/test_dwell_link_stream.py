"""The settled detector with the lvdt's link length as a fourth stream (issue #18)."""

from __future__ import annotations

from hexacal_identify.core.detection.dwell_detector import (
    detect_dwell_postures,
    DwellDetector,
    LINK_STREAM,
)
import numpy as np
from test_core_dwell_detector import make_streams, Truth

NOMINAL_L = 0.3
LINK_NOISE = 2e-6  # uniform +-2 um


def with_link(truth: Truth, seed: int = 5) -> np.ndarray:
    """Add a link stream (the sliders' stamps) whose length differs per dwell; return them."""
    rng = np.random.default_rng(seed)
    lengths = NOMINAL_L + rng.uniform(-3e-3, 3e-3, len(truth.holds))
    stamps = truth.streams['sliders'][0]
    values = np.full(len(stamps), NOMINAL_L)
    for (start, end), length in zip(truth.holds, lengths):
        values[(stamps >= start) & (stamps < end)] = length
    values += rng.uniform(-LINK_NOISE, LINK_NOISE, len(stamps))
    truth.streams[LINK_STREAM] = (stamps, values[:, None])
    return lengths


def test_without_link_readings_postures_are_unchanged_and_have_no_link_length():
    truth = make_streams(seed=3, count=6)
    postures, detector = detect_dwell_postures(truth.streams)
    assert len(postures) == 6 and not detector.has_link
    assert all(p.reading.link_length is None for p in postures)
    assert all(p.reading.scatter.link_length_sample_count is None for p in postures)


def test_link_stream_gives_each_posture_its_length_and_standard_error():
    truth = make_streams(seed=3, count=6)
    plain, _ = detect_dwell_postures(dict(truth.streams))
    lengths = with_link(truth)
    postures, detector = detect_dwell_postures(truth.streams)
    assert detector.has_link and len(postures) == len(plain) == 6
    for posture, plain_posture, length in zip(postures, plain, lengths):
        reading = posture.reading
        # The same dwell (the link may shift the capture by a block: the means move by noise).
        assert np.allclose(reading.values(), plain_posture.reading.values(), atol=5e-6)
        error = reading.scatter.link_length_standard_error
        assert reading.scatter.link_length_sample_count >= 20
        assert 0 < error < LINK_NOISE
        assert abs(reading.link_length - length) < 6 * error


def test_link_stream_online_in_chunks_equals_offline():
    truth = make_streams(seed=4, count=4)
    with_link(truth)
    offline, _ = detect_dwell_postures(truth.streams)
    detector = DwellDetector()
    online = []
    end = max(stamps[-1] for stamps, _ in truth.streams.values())
    start = min(stamps[0] for stamps, _ in truth.streams.values())
    step = 50_000_000
    for left in range(start, end + step, step):
        chunk = {
            name: (stamps[(stamps >= left) & (stamps < left + step)],
                   values[(stamps >= left) & (stamps < left + step)])
            for name, (stamps, values) in truth.streams.items()
        }
        online += detector.update({k: v for k, v in chunk.items() if len(v[0])})
    online += detector.finish()[0]
    assert [p.reading for p in online] == [p.reading for p in offline]
    assert all(p.reading.link_length is not None for p in online)


def test_a_link_moving_within_a_dwell_is_judged_moving():
    truth = make_streams(seed=3, count=3)
    with_link(truth)
    stamps, values = truth.streams[LINK_STREAM]
    start, end = truth.holds[1]
    middle = (start + end) // 2
    ramp = (stamps >= middle) & (stamps < end)
    values = values.copy()
    values[ramp, 0] += np.linspace(0.0, 2e-3, np.count_nonzero(ramp))  # the link slides 2 mm
    truth.streams[LINK_STREAM] = (stamps, values)
    postures, _ = detect_dwell_postures(truth.streams)
    for posture in postures:
        assert not (middle <= posture.reading.stamp_ns < end)
