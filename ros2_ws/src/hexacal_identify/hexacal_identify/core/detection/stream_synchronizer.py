"""
The collector's input accounting: readings checked per stream, paired on the actuator stamps.

`StreamSynchronizer` accepts each stream's readings (stamps strictly increasing, counted by
`RejectReason` otherwise), tells each stream's health (`status`, `stale_streams`) and pairs
each actuator reading with the nearest inclinometer and encoder readings (ROS-free). The
settled detector (core.dwell_detector) judges the streams as they are; the collector uses
the synchronizer for its acceptance and health counters.
"""

from __future__ import annotations

from bisect import bisect_left
from collections import deque
from dataclasses import dataclass

from hexacal_msgs_py.readings import (
    ActuatorReading,
    EncoderReading,
    InclinometerReading,
    PostureReading,
)

from .vocabulary import RejectReason, Stream, UnpairedReason


@dataclass(frozen=True)
class StreamStatus:
    """Health of one input stream."""

    name: str
    last_stamp_ns: int | None
    accepted: int
    rejected: dict[str, int]
    stale: bool  # nothing received for longer than stale_after_ns (or never)


class _StreamState:
    """Keep one stream's recent readings for pairing."""

    def __init__(self, name: str, history: int):
        self.name = name
        self.last_stamp_ns: int | None = None
        self.accepted = 0
        self.rejected: dict[str, int] = {}
        # Stamps and values (tuples of floats) of the latest readings, oldest first; the stamps
        # strictly increase (accept), so the nearest reading is found by bisection.
        self.stamps: deque[int] = deque(maxlen=history)
        self.values: deque[tuple[float, ...]] = deque(maxlen=history)

    def accept(self, stamp_ns: int, values: tuple[float, ...]) -> bool:
        """Keep a reading unless its stamp repeats or goes back in time (counted)."""
        if self.last_stamp_ns is not None and stamp_ns <= self.last_stamp_ns:
            reason = (
                RejectReason.DUPLICATE_STAMP
                if stamp_ns == self.last_stamp_ns
                else RejectReason.OUT_OF_ORDER
            ).value
            self.rejected[reason] = self.rejected.get(reason, 0) + 1
            return False
        self.last_stamp_ns = stamp_ns
        self.accepted += 1
        self.stamps.append(stamp_ns)
        self.values.append(values)
        return True

    def nearest(self, stamp_ns: int, max_skew_ns: int) -> tuple[float, ...] | None:
        """Return the kept values closest to stamp_ns (earlier wins a tie) within max_skew_ns."""
        stamps = self.stamps
        after = bisect_left(stamps, stamp_ns)
        best, best_skew = None, max_skew_ns + 1
        if after > 0 and stamp_ns - stamps[after - 1] < best_skew:
            best, best_skew = self.values[after - 1], stamp_ns - stamps[after - 1]
        if after < len(stamps) and stamps[after] - stamp_ns < best_skew:
            best = self.values[after]
        return best


class StreamSynchronizer:
    """
    Pairs each slider reading with the nearest inclinometer and encoder readings.

    The slider stamp is the reference. A slider reading waits until both other
    streams have a reading at or after its stamp (so the nearest one is known)
    or until the slider stream has moved on by more than `max_skew_ns`; it is
    then paired with the nearest readings within `max_skew_ns`, or dropped and
    counted if one stream has none. Memory is bounded by `history` per stream.
    """

    def __init__(
        self, max_skew_ns: int = 20_000_000, stale_after_ns: int = 200_000_000, history: int = 64
    ):
        if max_skew_ns < 0 or stale_after_ns <= 0 or history < 2:
            raise ValueError('max_skew_ns must be >= 0, stale_after_ns > 0, history >= 2')
        self.max_skew_ns = int(max_skew_ns)
        self.stale_after_ns = int(stale_after_ns)
        self._streams = {stream.value: _StreamState(stream.value, history) for stream in Stream}
        self._pending: deque[tuple[int, tuple[float, ...]]] = deque()  # slider (stamp, values)
        self._history = history
        self.unpaired: dict[str, int] = {}
        self.emitted = 0

    def add_actuators(self, reading: ActuatorReading) -> list[PostureReading]:
        return _readings(
            self.add_values(Stream.SLIDERS, reading.stamp_ns, reading.actuator_positions)
        )

    def add_inclinometer(self, reading: InclinometerReading) -> list[PostureReading]:
        return _readings(
            self.add_values(Stream.INCLINOMETER, reading.stamp_ns, (reading.alpha, reading.beta))
        )

    def add_encoder(self, reading: EncoderReading) -> list[PostureReading]:
        return _readings(self.add_values(Stream.ENCODER, reading.stamp_ns, (reading.phi,)))

    def accept(self, stream: Stream, stamp_ns: int, values: tuple[float, ...]) -> bool:
        """
        Take a reading for the stream's health only (no pairing): the DwellDetector's path.

        Returns False for a stamp that repeats or goes back in time (counted in `rejected`).
        """
        return self._streams[stream].accept(stamp_ns, values)

    def add_values(
        self, stream: Stream, stamp_ns: int, values: tuple[float, ...]
    ) -> list[tuple[int, tuple[float, ...]]]:
        """
        add_actuators/add_inclinometer/add_encoder for already validated readings.

        `values` are the reading's numbers as a tuple of finite floats (six slider
        positions; alpha, beta; phi), `stamp_ns` a non-negative int. Returns the
        paired samples as (stamp_ns, nine values in POSTURE_NAMES order): the
        collector's per-message path, without building reading objects.
        """
        if stream == Stream.SLIDERS:
            if self._streams[Stream.SLIDERS].accept(stamp_ns, values):
                self._pending.append((stamp_ns, values))
            return self._resolve(force_count=max(0, len(self._pending) - self._history))
        self._streams[stream].accept(stamp_ns, values)
        return self._resolve()

    def flush(self) -> list[PostureReading]:
        """Pair every waiting slider reading with what has arrived (end of stream)."""
        return _readings(self._resolve(force_count=len(self._pending)))

    def status(self, now_ns: int) -> dict[str, StreamStatus]:
        return {
            name: StreamStatus(
                name,
                state.last_stamp_ns,
                state.accepted,
                dict(state.rejected),
                state.last_stamp_ns is None or now_ns - state.last_stamp_ns > self.stale_after_ns,
            )
            for name, state in self._streams.items()
        }

    def stale_streams(self, now_ns: int) -> list[str]:
        """Streams with no reading within stale_after_ns before now_ns."""
        return [name for name, status in self.status(now_ns).items() if status.stale]

    @property
    def pending(self) -> int:
        """Slider readings waiting for their inclinometer/encoder partners (at most history)."""
        return len(self._pending)

    @property
    def rejected(self) -> dict[str, dict[str, int]]:
        """Per stream, the count of rejected readings by reason."""
        return {name: dict(state.rejected) for name, state in self._streams.items()}

    def _resolve(self, force_count: int = 0) -> list[tuple[int, tuple[float, ...]]]:
        emitted: list[tuple[int, tuple[float, ...]]] = []
        if not self._pending:
            return emitted
        inclinometer = self._streams[Stream.INCLINOMETER]
        encoder = self._streams[Stream.ENCODER]
        newest_actuator_ns = self._streams[Stream.SLIDERS].last_stamp_ns
        assert newest_actuator_ns is not None  # a pending slider reading was accepted
        while self._pending:
            stamp, actuators = self._pending[0]
            ready = (
                force_count > 0
                or newest_actuator_ns - stamp > self.max_skew_ns
                or (
                    inclinometer.last_stamp_ns is not None
                    and inclinometer.last_stamp_ns >= stamp
                    and encoder.last_stamp_ns is not None
                    and encoder.last_stamp_ns >= stamp
                )
            )
            if not ready:
                break
            self._pending.popleft()
            force_count -= 1
            angles = inclinometer.nearest(stamp, self.max_skew_ns)
            rotary = encoder.nearest(stamp, self.max_skew_ns)
            if angles is None or rotary is None:
                reason = (
                    UnpairedReason.NO_INCLINOMETER_WITHIN_SKEW
                    if angles is None
                    else UnpairedReason.NO_ENCODER_WITHIN_SKEW
                ).value
                self.unpaired[reason] = self.unpaired.get(reason, 0) + 1
                continue
            emitted.append((stamp, actuators + angles + rotary))
        self.emitted += len(emitted)
        return emitted


def _readings(samples: list[tuple[int, tuple[float, ...]]]) -> list[PostureReading]:
    return [PostureReading.from_values(stamp, values) for stamp, values in samples]
