"""The postures received live, and those rejected on receipt (counted by reason)."""

from __future__ import annotations

from dataclasses import dataclass
import threading

from hexacal_msgs_py.readings import PostureReading


@dataclass(frozen=True)
class Receipt:
    """What became of one posture received: stored, or rejected with a reason."""

    stored: bool
    count: int  # postures stored so far
    rejected: int  # postures rejected so far, all reasons
    rejection: str = ''  # '<reason>: <detail>' of this posture ('' when stored)


class PostureStore:
    """
    Every valid posture received, with the model of its joints; rejections counted.

    Thread-safe: the posture callback adds while a calibration or verification takes its
    postures on another thread.
    """

    def __init__(self) -> None:
        """Start empty."""
        self._lock = threading.Lock()
        self._postures: list[PostureReading] = []
        self._models: list[str] = []  # the model of each stored posture's joints
        self._rejected: dict[str, int] = {}
        self._rejected_total = 0
        self._last_rejection = ''

    def add(self, posture: PostureReading, model: str) -> Receipt:
        """Store a valid posture of `model`."""
        with self._lock:
            self._postures.append(posture)
            self._models.append(model)
            return Receipt(True, len(self._postures), self._rejected_total)

    def reject(self, reason: str, detail: str) -> Receipt:
        """Count a posture that is never stored; the postures already received are kept."""
        with self._lock:
            self._rejected_total += 1
            self._rejected[reason] = self._rejected.get(reason, 0) + 1
            self._last_rejection = f'{reason}: {detail}'
            return Receipt(
                False, len(self._postures), self._rejected_total, self._last_rejection
            )

    def __len__(self) -> int:
        """Return the number of postures stored."""
        with self._lock:
            return len(self._postures)

    @property
    def rejected(self) -> int:
        """Return the number of postures rejected so far, all reasons."""
        with self._lock:
            return self._rejected_total

    def since(self, start: int = 0) -> tuple[list[PostureReading], set[str]]:
        """Return the postures stored from index `start` on, and the models of their joints."""
        with self._lock:
            return list(self._postures[start:]), set(self._models[start:])

    def rejection_values(self) -> dict[str, object]:
        """Return the status keys of the rejections ({} when none was rejected)."""
        with self._lock:
            if not self._rejected_total:
                return {}
            return {
                'postures_rejected': self._rejected_total,
                **{f'rejected.{reason}': n for reason, n in sorted(self._rejected.items())},
                'last_rejection': self._last_rejection,
            }

    def summary(self, count: int) -> str:
        """Return the status message of the collecting status with `count` postures stored."""
        with self._lock:
            text = f'{count} postures received'
            if self._rejected_total:
                text += f', {self._rejected_total} rejected (last: {self._last_rejection})'
            return text
