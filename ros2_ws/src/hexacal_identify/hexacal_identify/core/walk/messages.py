"""
What the executor hears and says (ROS-free).

Readings: joints picked by name from a JointState, a window of recent ones.
Said: the level of each line the walking code asks the node to log.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
import enum

import numpy as np


class LogLevel(enum.StrEnum):
    """The level of a line for the node's log."""

    INFO = 'info'
    WARN = 'warn'
    ERROR = 'error'


Messages = list[tuple[LogLevel, str]]  # (level, text) for the node to log, oldest first


def joint_positions(
    names: Sequence[str], positions: Sequence[float], wanted: Sequence[str]
) -> np.ndarray | None:
    """
    Return the positions of the `wanted` joints, in that order, from a JointState's fields.

    None if one is missing, repeated or not finite.
    """
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in index and name in wanted:
            return None
        index[name] = i
    try:
        values = np.array([float(positions[index[name]]) for name in wanted])
    except (KeyError, IndexError, TypeError, ValueError):
        return None
    return values if np.all(np.isfinite(values)) else None


class ReadingWindow:
    """Recent (time s, values) readings, oldest first, kept for `keep_s`."""

    def __init__(self, keep_s: float):
        self.keep_s = float(keep_s)
        self._times: deque[float] = deque()
        self._values: deque[np.ndarray] = deque()

    def add(self, now: float, values: np.ndarray) -> None:
        """Keep a reading received at `now` (s); forget those older than keep_s."""
        self._times.append(float(now))
        self._values.append(np.asarray(values, dtype=float))
        while self._times and self._times[0] < now - self.keep_s:
            self._times.popleft()
            self._values.popleft()

    @property
    def latest(self) -> np.ndarray | None:
        """Return the newest reading (None before the first)."""
        return self._values[-1] if self._values else None

    @property
    def newest_s(self) -> float | None:
        """Return the time (s) of the newest reading (None before the first)."""
        return self._times[-1] if self._times else None

    def timed(self, start: float, end: float) -> tuple[np.ndarray, np.ndarray]:
        """Return the times (n,) and readings (n, channels) received in [start, end]."""
        times = np.fromiter(self._times, dtype=float, count=len(self._times))
        chosen = (times >= start) & (times <= end)
        if not chosen.any():
            return np.empty(0), np.empty((0, 0))
        return times[chosen], np.array([v for v, keep in zip(self._values, chosen) if keep])

    def between(self, start: float, end: float) -> np.ndarray:
        """Return the readings received in [start, end], (n, channels)."""
        chosen = [v for t, v in zip(self._times, self._values) if start <= t <= end]
        return np.array(chosen) if chosen else np.empty((0, 0))
