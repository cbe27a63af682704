"""
Estimate a stream's clock offset against the actuator stream from the starts of motion.

A stream stamped by another computer's clock carries offset = its stamps - the actuator
stamps of the same instant. Every move of the machine starts in all streams at once, so
the difference between the time a stream is seen to leave its settled level and the time
the actuators are, over many moves, is the offset (median: robust to a missed or
misattributed start).

Why the starts and not the ends of moves: a channel that lags through its own filter
(first-order, time constant tau) reaches its new level about tau late, so its move ends
say 'offset + tau'; its start is delayed far less: the filtered output of a move starting
as (t - t0)^p grows as (t - t0)^(p+1) / ((p+1) tau) at first, which the power-law fit of
`departure_ns` reads as a start late by a small fraction of tau (measured: a 0.1 s lag
reads as 4 ms on the simulated driver's quintic moves, a 0.2 s lag as 18 ms on cosine
moves). Where that matters, state the offset (a parameter): it is then used as it is.
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
    three, so a spike is no departure). A move starts from rest, so the deviation grows as a
    power of the time since its start t0 (squared at constant acceleration, cubed for a
    quintic time law): level crossings give t0 (`_extrapolated_start`), the same instant for
    every channel whatever its share of the move (a threshold crossing is later for a
    channel that moves less). The median over the channels; where no channel
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


# Deviation levels (in thresholds) whose first crossings time an onset, and the onset powers
# tried: 2 for constant acceleration, 3 for a quintic time law's zero-jerk start.
ONSET_LEVELS = (2.0, 4.0, 8.0, 16.0, 32.0)
ONSET_POWERS = (1.5, 2.0, 2.5, 3.0, 3.5, 4.0)


def _extrapolated_start(
    raw_stamps: np.ndarray, dev: np.ndarray, limit: float, last: int
) -> float | None:
    """
    Return the start t0 of a power-law onset dev = c (t - t0)^p, fitted to level crossings.

    The first crossings t_i of the levels L_i (ONSET_LEVELS thresholds) after `last` satisfy
    t_i = t0 + k L_i^(1/p): for each power p of ONSET_POWERS a straight line in L^(1/p);
    the best fitting one's intercept is t0 (at least four crossings).
    """
    levels, times = [], []
    for factor in ONSET_LEVELS:
        level = factor * limit
        above = np.flatnonzero(dev[last + 1:] > level)
        if not len(above):
            break
        index = last + 1 + int(above[0])
        low, high = dev[index - 1], dev[index]
        fraction = min(max((level - low) / (high - low), 0.0), 1.0) if high > low else 1.0
        before, after = float(raw_stamps[index - 1]), float(raw_stamps[index])
        levels.append(factor)
        times.append(before + fraction * (after - before))
    if len(times) < 4:
        return None
    crossing = np.array(times) - times[0]
    best, best_residual = None, np.inf
    for power in ONSET_POWERS:
        design = np.column_stack((np.ones(len(levels)), np.power(levels, 1.0 / power)))
        solution, residual, _, _ = np.linalg.lstsq(design, crossing, rcond=None)
        error = float(residual[0]) if len(residual) else 0.0
        if solution[1] > 0 and error < best_residual:
            best, best_residual = times[0] + float(solution[0]), error
    if best is None or not raw_stamps[0] <= best <= times[0]:
        return None
    return best


class OffsetEstimator:
    """Match a stream's departures with the actuators' and keep their time differences."""

    def __init__(self, max_match_ns: int) -> None:
        self.max_match_ns = max_match_ns
        self._reference: deque[float] = deque(maxlen=4)  # unmatched actuator departures
        self._stream: deque[float] = deque(maxlen=4)  # unmatched departures of this stream
        self.differences: deque[float] = deque(maxlen=KEPT_EDGES)
        self._estimate: int | None = None  # of the differences as they stand

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
                self._estimate = self._median()
                self._stream.remove(own)
                self._reference.remove(nearest)

    def estimate_ns(self) -> int | None:
        """Return the median difference once MIN_EDGES are matched, else None."""
        return self._estimate

    def _median(self) -> int | None:
        if len(self.differences) < MIN_EDGES:
            return None
        return int(round(float(np.median(self.differences))))
