"""
Robust per-channel statistics of a few hundred sensor samples (ROS-free, numpy only).

The dwell detector (core.dwell_detector) judges and averages each stream on its own samples
with these: a spike is a sample beyond SPIKE_SIGMAS robust sigmas (median absolute
deviation, MAD) from the median; levels are means of the samples without spikes; and the
quantisation step read from the data is the floor of every threshold, so a noise-free
quantised channel (MAD 0) is neither 'trending' at one step nor rejected as spikes.
All functions take an (n, channels) array and work per column.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# sigma = MAD_TO_SIGMA * MAD for Gaussian noise (1 / Phi^-1(3/4)).
MAD_TO_SIGMA = 1.482602218505602
# A sample further than this many robust sigmas (or quantisation steps) from the median is
# a spike: 5 sigma is never reached by uniform noise and once in 1.7 million by Gaussian noise.
SPIKE_SIGMAS = 5.0


def quantum(values: np.ndarray) -> np.ndarray:
    """
    Return per channel the smallest non-zero step between the sorted samples (0 if none).

    Of quantised readings this is the resolution (or a multiple of it); of continuous
    noise it is tiny and so harmless as a floor. Steps to the smallest or largest sample are
    left out: a lone spike on a noise-free channel is no resolution step.
    """
    if len(values) < 4:
        return np.zeros(values.shape[1])
    steps = np.diff(np.sort(values, axis=0), axis=0)[1:-1]
    steps = np.where(steps > 0.0, steps, np.inf)
    smallest = steps.min(axis=0)
    return np.where(np.isfinite(smallest), smallest, 0.0)


def median(values: np.ndarray) -> np.ndarray:
    """Return per channel the median, as numpy's (one sort is cheaper for few samples)."""
    ordered = np.sort(values, axis=0)
    middle = len(values) // 2
    if len(values) % 2:
        return ordered[middle]
    return (ordered[middle - 1] + ordered[middle]) / 2.0


def median_and_sigma(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return per channel the median and the robust sigma (MAD_TO_SIGMA * MAD)."""
    center = median(values)
    return center, MAD_TO_SIGMA * median(np.abs(values - center))


def spike_mask(values: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Return the (n, channels) mask of samples that are not spikes (floor: e.g. quantum)."""
    return _spike_mask(values, floor)[0]


def _spike_mask(values: np.ndarray, floor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    center, sigma = median_and_sigma(values)
    limit = SPIKE_SIGMAS * np.maximum(sigma, floor)
    return np.abs(values - center) <= limit, center


def robust_spread(values: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Return per channel the peak-to-peak of the samples that are not spikes."""
    kept = spike_mask(values, floor)
    high = np.where(kept, values, -np.inf).max(axis=0)
    low = np.where(kept, values, np.inf).min(axis=0)
    return np.where(kept.any(axis=0), high - low, 0.0)


def level_shift(
    before: np.ndarray, after: np.ndarray, sigmas: float, floor: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return per channel how far the level moved from `before` to `after`, and its threshold.

    The level of each part is the mean of its samples without spikes (more efficient than a
    median, and as robust once spikes are out); the threshold is `sigmas` standard errors of
    the difference (the pooled scatter of both parts about their own means, so a trend does
    not inflate it) or the floor (e.g. the quantisation step: a level can move by one step on
    noise alone), whichever is larger.
    """
    first = robust_mean(before, floor)
    second = robust_mean(after, floor)
    squares = first.std**2 * np.maximum(first.count - 1, 0) + second.std**2 * np.maximum(
        second.count - 1, 0
    )
    pooled = np.sqrt(squares / np.maximum(first.count + second.count - 2, 1))
    error = pooled * np.sqrt(
        1.0 / np.maximum(first.count, 1) + 1.0 / np.maximum(second.count, 1)
    )
    return np.abs(second.mean - first.mean), np.maximum(sigmas * error, floor)


@dataclass(frozen=True)
class RobustMean:
    """Per channel: the mean of the samples that are not spikes, its scatter and counts."""

    mean: np.ndarray
    std: np.ndarray  # sample standard deviation of the kept samples (0 with one sample)
    standard_error: np.ndarray  # std / sqrt(count)
    count: np.ndarray  # samples kept (int)
    rejected: np.ndarray  # spikes rejected (int)


def robust_mean(values: np.ndarray, floor: np.ndarray) -> RobustMean:
    """Return the spike-rejected mean of each channel with its standard error and counts."""
    kept, center = _spike_mask(values, floor)
    count = kept.sum(axis=0)
    safe = np.maximum(count, 1)
    # Deviations from the median: no cancellation for readings far from zero.
    deviation = np.where(kept, values - center, 0.0)
    mean_deviation = deviation.sum(axis=0) / safe
    squares = np.where(kept, (values - center - mean_deviation) ** 2, 0.0).sum(axis=0)
    std = np.sqrt(squares / np.maximum(count - 1, 1))
    std = np.where(count > 1, std, 0.0)
    return RobustMean(
        center + mean_deviation, std, std / np.sqrt(safe), count, len(values) - count
    )


# ---------------------------------------------------------------------- many windows at once
#
# The same statistics of many windows in one call: `values` (windows, n, channels) holds each
# window's samples first, `valid` (windows, n) says which are samples (the rest is padding).
# Sorting, medians and comparisons are exact, and sums run in sample order (a cumulative sum),
# so a window's result does not depend on how many windows are computed with it.


def _padded_sort(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    return np.sort(np.where(valid[..., None], values, np.inf), axis=1)


def _sorted_median(ordered: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Return per window and channel the median of sorted samples (count >= 1 each)."""
    middle = np.maximum(count, 1) // 2
    rows = np.arange(len(ordered))
    upper = ordered[rows, middle]
    lower = ordered[rows, np.maximum(middle - 1, 0)]
    return np.where((count % 2 == 1)[:, None], upper, (lower + upper) / 2.0)


def windows_median(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Return `median` of each window (windows, channels); a window must hold a sample."""
    return _sorted_median(_padded_sort(values, valid), valid.sum(axis=1))


def windows_quantum(values: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Return `quantum` of each window (windows, channels)."""
    count = valid.sum(axis=1)
    ordered = _padded_sort(values, valid)
    with np.errstate(invalid='ignore'):
        steps = np.diff(ordered, axis=1)
    # quantum's steps[1:-1]: indices 1 .. count - 3 of the count - 1 steps.
    index = np.arange(steps.shape[1])
    inner = (index >= 1) & (index[None, :] <= (count - 3)[:, None])
    steps = np.where(inner[..., None] & (steps > 0.0), steps, np.inf)
    smallest = steps.min(axis=1)
    smallest = np.where(np.isfinite(smallest), smallest, 0.0)
    return np.where((count >= 4)[:, None], smallest, 0.0)


@dataclass(frozen=True)
class WindowsMean:
    """Per window and channel: `robust_mean`'s mean, std and count, and the median."""

    mean: np.ndarray
    std: np.ndarray
    count: np.ndarray
    median: np.ndarray


def _windows_spikes(
    values: np.ndarray, valid: np.ndarray, floor: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return the mask of samples that are not spikes and the medians (`_spike_mask`)."""
    count = valid.sum(axis=1)
    center = _sorted_median(_padded_sort(values, valid), count)
    deviation = np.abs(values - center[:, None, :])
    sigma = MAD_TO_SIGMA * _sorted_median(_padded_sort(deviation, valid), count)
    limit = SPIKE_SIGMAS * np.maximum(sigma, floor)
    return valid[..., None] & (deviation <= limit[:, None, :]), center


def windows_spread(values: np.ndarray, valid: np.ndarray, floor: np.ndarray) -> np.ndarray:
    """Return `robust_spread` of each window (windows, channels)."""
    kept = _windows_spikes(values, valid, floor)[0]
    high = np.where(kept, values, -np.inf).max(axis=1)
    low = np.where(kept, values, np.inf).min(axis=1)
    return np.where(kept.any(axis=1), high - low, 0.0)


def windows_mean(values: np.ndarray, valid: np.ndarray, floor: np.ndarray) -> WindowsMean:
    """Return `robust_mean` of each window (the sums in sample order) and its median."""
    kept, center = _windows_spikes(values, valid, floor)
    count = kept.sum(axis=1)
    safe = np.maximum(count, 1)
    deviation = np.where(kept, values - center[:, None, :], 0.0)
    mean_deviation = np.cumsum(deviation, axis=1)[:, -1] / safe
    squares = np.where(kept, (values - center[:, None, :] - mean_deviation[:, None, :]) ** 2, 0.0)
    std = np.sqrt(np.cumsum(squares, axis=1)[:, -1] / np.maximum(count - 1, 1))
    std = np.where(count > 1, std, 0.0)
    return WindowsMean(center + mean_deviation, std, count, center)


def windows_level_shift(
    first: WindowsMean, second: WindowsMean, sigmas: float, floor: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Return `level_shift` of each window's two parts, from their `windows_mean`."""
    squares = first.std**2 * np.maximum(first.count - 1, 0) + second.std**2 * np.maximum(
        second.count - 1, 0
    )
    pooled = np.sqrt(squares / np.maximum(first.count + second.count - 2, 1))
    error = pooled * np.sqrt(
        1.0 / np.maximum(first.count, 1) + 1.0 / np.maximum(second.count, 1)
    )
    return np.abs(second.mean - first.mean), np.maximum(sigmas * error, floor)
