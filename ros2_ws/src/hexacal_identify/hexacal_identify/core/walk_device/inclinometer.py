"""
When the executor may judge a fixed-position posture on the inclinometer (ROS-free).

A real inclinometer lags behind the motion through its own filter (first order, a time
constant of a few tenths of a second) and its readings scatter. Judged on readings taken
while it still trends, the closed loop of eq. 10 corrects for an angle the platform no
longer has: it over-corrects, and the next lagging reading makes it oscillate. So after
every move the loop waits until the inclinometer has settled and averages only settled
readings (`judge_inclinometer`):

- Two consecutive windows of ``inclinometer_settle_s`` each, both after the move ended
  (the command's own time), must each hold `MIN_WINDOW_READINGS` readings.
- Settled: on both angles the medians of the two windows differ by no more than
  ``SETTLE_SIGMAS`` standard errors of that difference plus ``SETTLE_FRACTION`` of
  ``fixed_tolerance_rad``. The noise comes from the readings' successive differences
  (robustly: their median absolute deviation), which a slow trend barely enters, so a
  trending inclinometer does not hide behind its own trend; the medians ignore spikes.
  The tolerance term lets a noiseless or quantised inclinometer settle. What a first-order
  lag leaves in the later window is then about the trend over (exp(window / tau) - 1):
  0.4 times it for windows of 1.25 time constants, so the windows should be about the
  inclinometer's time constant or longer.
- The reading judged is the trimmed mean (``TRIM_FRACTION`` off each end) of the later
  window: the average of the settled readings, spikes left out (the earlier window, which
  holds more of the lag, only shows the trend has ended).

Until then the state says why not (`InclinometerState`); the posture's ``timeout_s``
bounds the wait and its skip reason names the state (core/walk/execution.py).
"""

from __future__ import annotations

from dataclasses import dataclass
import enum
import math

import numpy as np

MIN_WINDOW_READINGS = 3  # readings each window needs
SETTLE_SIGMAS = 3.0  # a trend within this many standard errors of the noise is no trend
SETTLE_FRACTION = 0.1  # ... nor one within this fraction of fixed_tolerance_rad
TRIM_FRACTION = 0.1  # of the readings cut off each end of the settled average (spikes)
_MAD_TO_SIGMA = 1.4826  # normal noise: sigma = 1.4826 * median absolute deviation
_MEDIAN_SE = 1.2533  # normal noise: the standard error of a median, in sigma / sqrt(n)


class InclinometerState(enum.StrEnum):
    """Where the inclinometer stands after a move (status field ``inclinometer``)."""

    WAITING = 'waiting'  # the two windows do not yet fit after the move
    NO_READINGS = 'no-readings'  # they fit, but hold too few readings
    SETTLING = 'settling'  # the readings still trend
    SETTLED = 'settled'


@dataclass(frozen=True)
class InclinometerJudgement:
    """What the inclinometer's readings since a move say (angles in rad)."""

    state: InclinometerState
    angles: tuple[float, float] | None = None  # (alpha, beta) averaged, once settled
    trend_rad: float = math.nan  # the larger |median(later) - median(earlier)| of the angles
    limit_rad: float = math.nan  # the trend the readings had to stay within (that angle's)
    noise_rad: float = math.nan  # the larger per-reading noise of the two angles
    readings: int = 0  # in both windows

    @property
    def settled(self) -> bool:
        """Return whether the readings may be judged."""
        return self.state == InclinometerState.SETTLED

    def describe(self, window_s: float) -> str:
        """Return the judgement in words, for a log line or a skip reason."""
        if self.state == InclinometerState.WAITING:
            return 'waiting for readings after the move'
        if self.state == InclinometerState.NO_READINGS:
            return (
                f'fewer than {MIN_WINDOW_READINGS} inclinometer readings in a {window_s:g} s '
                'window since the move'
            )
        verb = 'moved' if self.state == InclinometerState.SETTLING else 'settled:'
        return (
            f'inclinometer {verb} {self.trend_rad:.2g} rad between two {window_s:g} s windows '
            f'(settled within {self.limit_rad:.2g} rad; noise {self.noise_rad:.2g} rad, '
            f'{self.readings} readings)'
        )


def robust_noise(values: np.ndarray) -> np.ndarray:
    """
    Return each column's per-reading noise (standard deviation) from successive differences.

    The median absolute deviation of the differences, over sqrt(2): a trend slow against the
    reading rate adds little, a spike changes two differences of many.
    """
    differences = np.diff(values, axis=0)
    deviation = np.median(np.abs(differences - np.median(differences, axis=0)), axis=0)
    return _MAD_TO_SIGMA * deviation / math.sqrt(2.0)


def trimmed_mean(values: np.ndarray, fraction: float = TRIM_FRACTION) -> np.ndarray:
    """Return each column's mean without the `fraction` smallest and largest values."""
    ordered = np.sort(values, axis=0)
    cut = int(math.floor(fraction * len(ordered)))
    return ordered[cut:len(ordered) - cut].mean(axis=0)


def judge_inclinometer(
    times: np.ndarray,
    values: np.ndarray,
    now: float,
    since: float,
    window_s: float,
    tolerance_rad: float,
) -> InclinometerJudgement:
    """
    Return whether the inclinometer readings (times s, (n, 2) rad) have settled since `since`.

    The two windows are [now - 2 window_s, now - window_s) and [now - window_s, now];
    `tolerance_rad` is fixed_tolerance_rad (module docstring).
    """
    start = now - 2.0 * window_s
    if start < since:
        return InclinometerJudgement(InclinometerState.WAITING)
    times = np.asarray(times, dtype=float)
    chosen = (times >= start) & (times <= now)
    later = times[chosen] >= now - window_s
    readings = np.asarray(values, dtype=float).reshape(-1, 2)[chosen]
    earlier_count, later_count = int(np.count_nonzero(~later)), int(np.count_nonzero(later))
    if min(earlier_count, later_count) < MIN_WINDOW_READINGS:
        return InclinometerJudgement(
            InclinometerState.NO_READINGS, readings=earlier_count + later_count
        )
    trend = np.abs(np.median(readings[later], axis=0) - np.median(readings[~later], axis=0))
    noise = robust_noise(readings)
    standard_error = _MEDIAN_SE * noise * math.sqrt(1.0 / earlier_count + 1.0 / later_count)
    limit = SETTLE_SIGMAS * standard_error + SETTLE_FRACTION * tolerance_rad
    worst = int(np.argmax(trend / limit))
    settled = bool(np.all(trend <= limit))
    alpha, beta = trimmed_mean(readings[later]) if settled else (math.nan, math.nan)
    return InclinometerJudgement(
        InclinometerState.SETTLED if settled else InclinometerState.SETTLING,
        (float(alpha), float(beta)) if settled else None,
        float(trend[worst]),
        float(limit[worst]),
        float(noise.max()),
        len(readings),
    )
