"""
Estimate a stream's clock offset against the actuator stream from the starts of motion.

A stream stamped by another computer's clock carries offset = its stamps - the actuator
stamps of the same instant. Every move of the machine starts in all streams at once, so
the difference between the time a stream is seen to leave its settled level and the time
the actuators are, over many moves, is the offset (median: robust to a missed or
misattributed start).

Why the starts and not the ends of moves: a channel that lags through its own filter
(first-order, time constant tau) reaches its new level about tau late, so its move ends
say 'offset + tau'; its start is delayed far less (the filtered output of a move starting
with constant acceleration a grows as a t^3 / (6 tau) at first, instead of a t^2 / 2: the
extrapolated start of `departure_ns` is late by a fraction of tau that shrinks with the
noise). A stated offset (a parameter) is used as it is.
"""

from __future__ import annotations

from collections import deque

import numpy as np

# Departures a stream and the actuators must share to say the offset; and how many recent ones
# the estimate is the median of (the clock may drift slowly).
MIN_EDGES = 3
KEPT_EDGES = 15


def departure_ns(
    raw_stamps: np.ndarray, values: np.ndarray, level: np.ndarray, threshold: np.ndarray
) -> float | None:
    """
    Return the time (ns, raw stamps) the readings start leaving `level` for good.

    Per channel: the readings after the last one within `threshold` of the level (at least
    three, so a spike is no departure). A move starts from rest with about constant
    acceleration, so the deviation grows as (t - t0)^2: a straight line through the square
    roots of the departed deviations up to 30 thresholds meets zero at the start t0, the
    same instant for every channel whatever its share of the move (a threshold crossing is
    later for a channel that moves less). The median over the channels; where no channel
    has two such readings, the interpolated threshold crossing of the one that went furthest.
    """
    deviation = np.abs(values - level)
    count = len(values)
    starts, crossing, best_reach = [], None, 0.0
    for channel in range(values.shape[1]):
        dev, limit = deviation[:, channel], threshold[channel]
        within = np.flatnonzero(dev <= limit)
        if not len(within) or int(within[-1]) > count - 4:
            continue  # never settled here, or not departed for good
        last = int(within[-1])
        fitted = _extrapolated_start(raw_stamps, dev, limit, last)
        if fitted is not None:
            starts.append(fitted)
        reach = dev[-1] / limit
        if reach > best_reach:
            low, high = dev[last], dev[last + 1]
            fraction = min(max((limit - low) / (high - low), 0.0), 1.0) if high > low else 0.0
            start_ns, end_ns = float(raw_stamps[last]), float(raw_stamps[last + 1])
            crossing, best_reach = start_ns + fraction * (end_ns - start_ns), reach
    return float(np.median(starts)) if starts else crossing


def _extrapolated_start(
    raw_stamps: np.ndarray, dev: np.ndarray, limit: float, last: int
) -> float | None:
    after = np.arange(last + 1, len(dev))
    fit = after[dev[after] <= 30.0 * limit]
    if len(fit) < 2:
        return None
    times = raw_stamps[fit].astype(np.float64)
    slope, intercept = np.polyfit(times - times[0], np.sqrt(dev[fit]), 1)
    if slope <= 0:
        return None
    start = times[0] - intercept / slope
    return float(start) if raw_stamps[0] <= start <= times[0] else None


class OffsetEstimator:
    """Match a stream's departures with the actuators' and keep their time differences."""

    def __init__(self, max_match_ns: int) -> None:
        self.max_match_ns = max_match_ns
        self._reference: deque[float] = deque(maxlen=4)  # unmatched actuator departures
        self._stream: deque[float] = deque(maxlen=4)  # unmatched departures of this stream
        self.differences: deque[float] = deque(maxlen=KEPT_EDGES)

    def reference_departure(self, stamp_ns: float) -> None:
        self._reference.append(stamp_ns)
        self._match()

    def stream_departure(self, stamp_ns: float) -> None:
        self._stream.append(stamp_ns)
        self._match()

    def _match(self) -> None:
        for own in list(self._stream):
            if not self._reference:
                return
            nearest = min(self._reference, key=lambda reference: abs(own - reference))
            if abs(own - nearest) <= self.max_match_ns:
                self.differences.append(own - nearest)
                self._stream.remove(own)
                self._reference.remove(nearest)

    def estimate_ns(self) -> int | None:
        """Return the median difference once MIN_EDGES are matched, else None."""
        if len(self.differences) < MIN_EDGES:
            return None
        return int(round(float(np.median(self.differences))))
