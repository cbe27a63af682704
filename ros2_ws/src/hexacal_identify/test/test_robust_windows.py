"""The robust statistics of many windows at once equal those of each window alone."""

from __future__ import annotations

from hexacal_identify.core.detection import robust_stats as robust
import numpy as np
import pytest


def windows(seed: int, channels: int) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Windows of 1-40 samples: noise, quantised steps, spikes, constant channels."""
    rng = np.random.default_rng(seed)
    parts = []
    for _ in range(60):
        count = int(rng.integers(1, 41))
        values = 0.4 + rng.uniform(-1e-5, 1e-5, (count, channels))
        kind = rng.integers(4)
        if kind == 1:
            values = np.round(values / 2e-6) * 2e-6  # quantised
        elif kind == 2:
            values[rng.integers(count)] += 1e-3  # a spike
        elif kind == 3:
            values[:, 0] = 0.25  # a noise-free channel
        parts.append(values)
    width = max(len(part) for part in parts)
    padded = np.zeros((len(parts), width, channels))
    valid = np.zeros((len(parts), width), dtype=bool)
    for row, part in enumerate(parts):
        padded[row, : len(part)] = part
        valid[row, : len(part)] = True
    return parts, padded, valid


@pytest.mark.parametrize('channels', [1, 2, 6])
def test_each_window_is_computed_as_alone(channels):
    parts, padded, valid = windows(channels, channels)
    with np.errstate(invalid='ignore'):
        floor = robust.windows_quantum(padded, valid)
        spread = robust.windows_spread(padded, valid, floor)
        means = robust.windows_mean(padded, valid, floor)
        medians = robust.windows_median(padded, valid)
    for row, part in enumerate(parts):
        alone = robust.quantum(part)
        # Sorting, medians, minima and maxima are exact.
        assert np.array_equal(floor[row], alone)
        assert np.array_equal(spread[row], robust.robust_spread(part, alone))
        assert np.array_equal(medians[row], robust.median(part))
        mean = robust.robust_mean(part, alone)
        assert np.array_equal(means.count[row], mean.count)
        # Sums run in sample order; numpy may sum one channel pairwise: the last bits differ.
        assert np.allclose(means.mean[row], mean.mean, rtol=1e-15, atol=0.0)
        assert np.allclose(means.std[row], mean.std, rtol=1e-12, atol=1e-20)
        if len(part) >= 2:
            half = len(part) // 2
            first = robust.windows_mean(
                padded[row:row + 1, :half], valid[row:row + 1, :half], floor[row:row + 1]
            )
            second_values = part[half:]
            second = robust.windows_mean(
                second_values[None], np.ones((1, len(second_values)), dtype=bool),
                floor[row:row + 1]
            )
            shift, threshold = robust.windows_level_shift(first, second, 4.0, floor[row:row + 1])
            old_shift, old_threshold = robust.level_shift(part[:half], part[half:], 4.0, alone)
            assert np.allclose(shift[0], old_shift, rtol=1e-12, atol=1e-20)
            assert np.allclose(threshold[0], old_threshold, rtol=1e-12, atol=1e-20)


def test_a_window_does_not_depend_on_the_windows_beside_it():
    parts, padded, valid = windows(7, 3)
    with np.errstate(invalid='ignore'):
        floor = robust.windows_quantum(padded, valid)
        together = robust.windows_mean(padded, valid, floor)
        for row in range(len(parts)):
            one = slice(row, row + 1)
            alone = robust.windows_mean(padded[one], valid[one], floor[one])
            assert np.array_equal(alone.mean[0], together.mean[row])  # bit for bit
            assert np.array_equal(alone.std[0], together.std[row])
