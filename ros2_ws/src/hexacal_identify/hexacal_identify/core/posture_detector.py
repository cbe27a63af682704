"""
Synchronise the sensor streams and detect stationary postures (ROS-free, numpy only).

The measurement procedure (paper section 3) takes one reading per posture while
the manipulator stands still. Three ~100 Hz streams (slider positions,
inclinometer alpha/beta, rotary phi) are paired on the slider stamps by
`StreamSynchronizer`; `PostureDetector` then finds the stationary periods in
the paired samples and emits one averaged posture per period.

Channels are in `POSTURE_NAMES` order: six slider positions (m), alpha, beta,
phi (rad). Stamps are integer ns.
"""

from __future__ import annotations

from bisect import bisect_left
from collections import deque
from dataclasses import dataclass
from enum import StrEnum
import math
from typing import Any

from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.names import N_CHAINS, POSTURE_NAMES
from hexacal_msgs_py.readings import (
    ActuatorReading,
    EncoderReading,
    InclinometerReading,
    NS_PER_S,
    PostureReading,
    PostureScatter,
)
import numpy as np
from numpy.typing import ArrayLike

N_CHANNELS = len(POSTURE_NAMES)


# The values are the keys of the collector's status counters and summaries: StrEnum members
# equal and hash as their strings, and the counters store the plain values (.value) so their
# repr in logs and their JSON stay as before.
class Stream(StrEnum):
    """An input stream of the synchronizer."""

    SLIDERS = 'sliders'
    INCLINOMETER = 'inclinometer'
    ENCODER = 'encoder'


class RejectReason(StrEnum):
    """Why a reading (synchronizer) or a paired sample (detector) is not used."""

    DUPLICATE_STAMP = 'duplicate_stamp'
    OUT_OF_ORDER = 'out_of_order'
    NON_FINITE = 'non_finite'


class UnpairedReason(StrEnum):
    """Why a slider reading found no partner to be paired with."""

    NO_INCLINOMETER_WITHIN_SKEW = 'no_inclinometer_within_skew'
    NO_ENCODER_WITHIN_SKEW = 'no_encoder_within_skew'


class DropReason(StrEnum):
    """Why a partial stationary period is dropped (counted, never emitted)."""

    MOTION = 'motion'
    GAP = 'gap'
    END_OF_STREAM = 'end_of_stream'
    STREAM_STOPPED = 'stream_stopped'  # a sensor stream went silent (e.g. the driver died)
    # settled detector: the machine stood still, but a stream (e.g. a lagging inclinometer)
    # was still creeping towards its level when it moved on: no posture, and the stream named.
    UNSETTLED = 'unsettled'


# The names the collector, its health module and the tests import.
SLIDERS_STREAM = Stream.SLIDERS
INCLINOMETER_STREAM = Stream.INCLINOMETER
ENCODER_STREAM = Stream.ENCODER
STREAMS = tuple(Stream)
DUPLICATE_STAMP = RejectReason.DUPLICATE_STAMP
OUT_OF_ORDER = RejectReason.OUT_OF_ORDER
NON_FINITE = RejectReason.NON_FINITE
NO_INCLINOMETER_WITHIN_SKEW = UnpairedReason.NO_INCLINOMETER_WITHIN_SKEW
NO_ENCODER_WITHIN_SKEW = UnpairedReason.NO_ENCODER_WITHIN_SKEW
DROPPED_FOR_MOTION = DropReason.MOTION
DROPPED_FOR_GAP = DropReason.GAP
DROPPED_AT_END = DropReason.END_OF_STREAM
DROPPED_FOR_STREAM_STOP = DropReason.STREAM_STOPPED

# Largest stamp the detector takes (year 2116): stamp arithmetic stays within int64.
MAX_STAMP_NS = 2**62


# =========================================================================== synchronizer


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


def synchronize_arrays(
    actuator_stamps_ns: ArrayLike,
    actuator_positions_m: ArrayLike,
    inclinometer_stamps_ns: ArrayLike,
    inclinometer_angles_rad: ArrayLike,
    encoder_stamps_ns: ArrayLike,
    encoder_angles_rad: ArrayLike,
    max_skew_ns: int = 20_000_000,
) -> tuple[np.ndarray, np.ndarray]:
    """
    Offline, vectorised pairing (same rule as StreamSynchronizer) for recorded streams.

    Returns (stamps_ns (n,), values (n, 9)) for the slider samples that have an
    inclinometer and an encoder reading within max_skew_ns.
    """
    stamps, actuators = _sorted_unique(actuator_stamps_ns, actuator_positions_m, N_CHAINS)
    keep = np.ones(len(stamps), dtype=bool)
    columns = [actuators]
    for aux_stamps, aux_values, width in (
        (inclinometer_stamps_ns, inclinometer_angles_rad, 2),
        (encoder_stamps_ns, encoder_angles_rad, 1),
    ):
        aux_t, aux_v = _sorted_unique(aux_stamps, aux_values, width)
        if len(aux_t) == 0:
            return np.empty(0, dtype=np.int64), np.empty((0, N_CHANNELS))
        after = np.clip(np.searchsorted(aux_t, stamps, side='left'), 0, len(aux_t) - 1)
        before = np.clip(after - 1, 0, len(aux_t) - 1)
        skew_after = np.abs(aux_t[after] - stamps)
        skew_before = np.abs(aux_t[before] - stamps)
        nearest = np.where(skew_before <= skew_after, before, after)  # earlier wins a tie
        keep &= np.abs(aux_t[nearest] - stamps) <= max_skew_ns
        columns.append(aux_v[nearest])
    values = np.hstack(columns)
    return stamps[keep], values[keep]


def _sorted_unique(
    stamps_ns: ArrayLike, values: ArrayLike, width: int
) -> tuple[np.ndarray, np.ndarray]:
    stamps = np.asarray(stamps_ns, dtype=np.int64).ravel()
    array = np.asarray(values, dtype=np.float64).reshape(len(stamps), width)
    finite = np.all(np.isfinite(array), axis=1)
    stamps, array = stamps[finite], array[finite]
    order = np.argsort(stamps, kind='stable')
    stamps, array = stamps[order], array[order]
    first = np.ones(len(stamps), dtype=bool)
    first[1:] = stamps[1:] != stamps[:-1]  # keep the first of duplicated stamps
    return stamps[first], array[first]


# =========================================================================== detector


@dataclass(frozen=True)
class DetectedPosture:
    """One posture: the mean of the samples of a stationary period."""

    reading: PostureReading  # mean values; stamp = the last sample used
    first_stamp_ns: int
    sample_count: int
    std: tuple[float, ...]  # per channel, POSTURE_NAMES order (m, rad)

    @property
    def stamp_ns(self) -> int:
        return self.reading.stamp_ns

    @property
    def values(self) -> np.ndarray:
        return np.asarray(self.reading.values())

    @property
    def scatter(self) -> PostureScatter:
        """
        Per channel, the standard error of the mean and the sample count.

        The reading's own scatter where the detector set it (DwellDetector: per channel,
        spikes rejected), else std / sqrt(n) of the n paired samples (PostureDetector).
        """
        if self.reading.scatter is not None:
            return self.reading.scatter
        count = max(self.sample_count, 1)
        return PostureScatter(
            tuple(float(s) / math.sqrt(count) for s in self.std), (count,) * N_CHANNELS
        )


@dataclass(frozen=True)
class DroppedPeriod:
    """A stationary period that ended before capture_s: never emitted, only reported."""

    first_stamp_ns: int
    last_stamp_ns: int
    sample_count: int
    reason: DropReason


class DetectorState(StrEnum):
    """Where the detector is in its capture cycle."""

    ARMED = 'armed'  # waiting for a stationary period
    CAPTURING = 'capturing'  # stationary; averaging until capture_s
    CAPTURED = 'captured'  # posture emitted; waiting for motion


_UNKNOWN, _MOVING, _STILL = 0, 1, 2  # per-sample window verdicts


class _WindowBuffer:
    """Preallocated storage for the samples of the last window (constant size in steady state)."""

    def __init__(self, capacity: int):
        self.stamps = np.empty(capacity, dtype=np.int64)
        self.values = np.empty((capacity, N_CHANNELS), dtype=np.float64)
        self.count = 0
        self.growths = 0

    @property
    def capacity(self) -> int:
        return len(self.stamps)

    def replace(self, stamps: np.ndarray, values: np.ndarray) -> None:
        while len(stamps) > self.capacity:  # rate above max_rate_hz: grow, do not lose data
            self.stamps = np.empty(2 * self.capacity, dtype=np.int64)
            self.values = np.empty((2 * self.capacity, N_CHANNELS), dtype=np.float64)
            self.growths += 1
        self.count = len(stamps)
        self.stamps[: self.count] = stamps
        self.values[: self.count] = values

    def clear(self) -> None:
        self.count = 0


def _window_extrema(
    values: np.ndarray, starts: np.ndarray, ends: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-row max and min of values[starts[i]:ends[i] + 1] (exact, vectorised)."""
    if len(starts) <= 16:  # online use: one or a few samples per call
        maxima = np.array([values[s:e + 1].max(axis=0) for s, e in zip(starts, ends)])
        minima = np.array([values[s:e + 1].min(axis=0) for s, e in zip(starts, ends)])
        return maxima.reshape(-1, N_CHANNELS), minima.reshape(-1, N_CHANNELS)
    # Sparse table: level k holds max/min over 2**k rows; each window is two overlapping blocks.
    lengths = ends - starts + 1
    levels = np.frexp(lengths.astype(np.float64))[1] - 1  # floor(log2(length))
    maxima = np.empty((len(starts), N_CHANNELS))
    minima = np.empty((len(starts), N_CHANNELS))
    table_max, table_min = values, values
    for level in range(int(levels.max()) + 1):
        if level:
            half = 1 << (level - 1)
            table_max = np.maximum(table_max[:-half], table_max[half:])
            table_min = np.minimum(table_min[:-half], table_min[half:])
        rows = np.flatnonzero(levels == level)
        if len(rows):
            left = starts[rows]
            right = ends[rows] - (1 << level) + 1
            maxima[rows] = np.maximum(table_max[left], table_max[right])
            minima[rows] = np.minimum(table_min[left], table_min[right])
    return maxima, minima


def check_detector_settings(durations: dict[str, float], tolerances: tuple[float, ...]) -> None:
    """
    Raise ValueError unless every duration (or rate) and every tolerance is > 0 (not NaN).

    The message names the durations in the given order, as both detectors always said.
    """
    if not all(value > 0 for value in durations.values()):
        *first, last = durations
        raise ValueError(f'{", ".join(first)} and {last} must be > 0')
    if not all(tolerance > 0 for tolerance in tolerances):
        raise ValueError('tolerances must be > 0')


class PostureDetector:
    """
    Detects stationary periods in synchronised samples and emits one posture per period.

    A sample is stationary when, over the `window_s` before it, the peak-to-peak
    of every channel is within its tolerance. The first stationary sample starts
    a period; once the period spans `capture_s` the mean of its samples is
    emitted (the window's own samples, which may include settling, are not
    averaged). The detector then waits for motion before the next capture. A
    period interrupted by motion or by a data gap longer than `max_gap_s` is
    dropped and counted, never emitted. Memory is a fixed window buffer.
    """

    # Default tolerances: 0.2 mm / 0.2 mrad is 5x the 40 um / 40 urad peak-to-peak of the
    # +-20 um / +-20 urad noise, yet a move of tens of mm in ~1 s covers mm within one window.
    def __init__(
        self,
        window_s: float = 0.3,
        slider_tolerance_m: float = 2e-4,
        angle_tolerance_rad: float = 2e-4,
        capture_s: float = 0.5,
        max_gap_s: float = 0.1,
        max_rate_hz: float = 2000.0,
        batch_size: int = 4096,
    ):
        check_detector_settings(
            {
                'window_s': window_s,
                'capture_s': capture_s,
                'max_gap_s': max_gap_s,
                'max_rate_hz': max_rate_hz,
            },
            (slider_tolerance_m, angle_tolerance_rad),
        )
        self.window_ns = int(round(window_s * NS_PER_S))
        self.capture_ns = int(round(capture_s * NS_PER_S))
        self.max_gap_ns = int(round(max_gap_s * NS_PER_S))
        self.tolerances = np.array(
            [slider_tolerance_m] * N_CHAINS + [angle_tolerance_rad] * (N_CHANNELS - N_CHAINS)
        )
        self._batch_size = int(batch_size)
        self._window = _WindowBuffer(int(math.ceil(window_s * max_rate_hz)) + 2)
        self._segment_start_ns: int | None = None
        self._last_stamp_ns: int | None = None
        self.state = DetectorState.ARMED
        self._recheck_after_gap = False
        self._last_posture_values: np.ndarray | None = None
        # Running sums of the period, relative to its first sample (avoids cancellation).
        self._period_first_ns = 0
        self._period_last_ns = 0
        self._period_count = 0
        self._period_reference = np.zeros(N_CHANNELS)
        self._period_sum = np.zeros(N_CHANNELS)
        self._period_sum_squares = np.zeros(N_CHANNELS)
        self.rejected: dict[str, int] = {}
        self.dropped: dict[str, int] = {}
        self.recent_dropped: deque[DroppedPeriod] = deque(maxlen=16)
        self.emitted = 0

    @property
    def buffer_capacity(self) -> int:
        """Rows of the window buffer; constant unless the rate exceeds max_rate_hz."""
        return self._window.capacity

    @property
    def buffered_samples(self) -> int:
        return self._window.count

    def add(self, sample: PostureReading) -> list[DetectedPosture]:
        """Feed one synchronised sample (e.g. from StreamSynchronizer)."""
        return self.update(
            np.array([sample.stamp_ns], dtype=np.int64),
            np.array([sample.values()], dtype=np.float64),
        )

    def update(self, stamps_ns: ArrayLike, values: ArrayLike) -> list[DetectedPosture]:
        """Feed N samples: stamps (N,) in ns, values (N, 9); returns the postures completed."""
        try:
            stamps = np.asarray(stamps_ns, dtype=np.int64).ravel()
            array = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError, OverflowError) as error:
            raise InvalidReadingError(
                f'stamps must be integer ns and values numbers: {error}'
            ) from None
        if stamps.size and (stamps.min() < 0 or stamps.max() > MAX_STAMP_NS):
            raise InvalidReadingError(
                f'stamps must be in [0, {MAX_STAMP_NS}] ns, got [{stamps.min()}, {stamps.max()}]'
            )
        if array.shape != (len(stamps), N_CHANNELS):
            raise InvalidReadingError(
                f'values must have shape ({len(stamps)}, {N_CHANNELS}) '
                f'for {len(stamps)} stamps, got {array.shape}'
            )
        postures: list[DetectedPosture] = []
        for begin in range(0, len(stamps), self._batch_size):
            chunk_stamps, chunk_values = self._accepted(
                stamps[begin:begin + self._batch_size], array[begin:begin + self._batch_size]
            )
            if len(chunk_stamps):
                postures.extend(self._process(chunk_stamps, chunk_values))
        return postures

    def finish(self) -> DroppedPeriod | None:
        """End of data: report (never emit) a period still being captured."""
        return self.abort(DropReason.END_OF_STREAM)

    def abort(self, reason: DropReason) -> DroppedPeriod | None:
        """
        Drop (count, never emit) a period being captured, e.g. when a stream stopped.

        Returns the dropped period, or None if nothing was being captured. Samples
        that arrive later start a new period after the usual window.
        """
        if self.state is not DetectorState.CAPTURING:
            return None
        return self._drop(reason)

    # ------------------------------------------------------------------ internals

    def _count(self, counter: dict[str, int], reason: StrEnum, n: int | np.integer[Any]) -> None:
        if n:
            # The plain string as the key: the counters are logged and published as before.
            counter[reason.value] = counter.get(reason.value, 0) + int(n)

    def _accepted(self, stamps: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Drop non-finite samples and stamps that do not increase (counted)."""
        finite = np.all(np.isfinite(values), axis=1)
        self._count(self.rejected, RejectReason.NON_FINITE, np.count_nonzero(~finite))
        stamps, values = stamps[finite], values[finite]
        if not len(stamps):
            return stamps, values
        previous = np.iinfo(np.int64).min if self._last_stamp_ns is None else self._last_stamp_ns
        running_max = np.maximum.accumulate(np.concatenate(([previous], stamps[:-1])))
        increasing = stamps > running_max
        self._count(
            self.rejected,
            RejectReason.DUPLICATE_STAMP,
            np.count_nonzero(~increasing & (stamps == running_max)),
        )
        self._count(
            self.rejected, RejectReason.OUT_OF_ORDER, np.count_nonzero(stamps < running_max)
        )
        return stamps[increasing], values[increasing]

    def _process(self, stamps: np.ndarray, values: np.ndarray) -> list[DetectedPosture]:
        history = self._window.count
        all_stamps = np.concatenate((self._window.stamps[:history], stamps))
        all_values = np.concatenate((self._window.values[:history], values))
        indices = np.arange(history, history + len(stamps))
        previous = np.concatenate(
            ([stamps[0] if self._last_stamp_ns is None else self._last_stamp_ns], stamps[:-1])
        )
        gap = stamps - previous > self.max_gap_ns
        if self._last_stamp_ns is None:
            gap[0] = True
        # Index (into all_*) of the first sample of each sample's contiguous segment;
        # the window buffer only ever holds the current segment, so -1 means index 0.
        segment_index = np.maximum.accumulate(np.where(gap, indices, -1))
        segment_start_ns = np.where(
            segment_index >= 0,
            all_stamps[np.maximum(segment_index, 0)],
            self._segment_start_ns if self._segment_start_ns is not None else stamps[0],
        )
        window_start = np.maximum(
            np.searchsorted(all_stamps, stamps - self.window_ns, side='left'),
            np.maximum(segment_index, 0),
        )
        maxima, minima = _window_extrema(all_values, window_start, indices)
        full = stamps - self.window_ns >= segment_start_ns
        with np.errstate(over='ignore'):  # readings near the float range: inf spread = moving
            still = np.all(maxima - minima <= self.tolerances, axis=1)
            window_mid = (maxima + minima) / 2
        verdicts = np.where(full, np.where(still, _STILL, _MOVING), _UNKNOWN)
        postures = self._run_states(stamps, values, verdicts, window_mid)

        # Keep the samples a later window can reach: same segment, within window_ns of the last.
        self._last_stamp_ns = int(stamps[-1])
        self._segment_start_ns = int(segment_start_ns[-1])
        keep_from = max(
            int(np.searchsorted(all_stamps, stamps[-1] - self.window_ns, 'left')),
            int(max(segment_index[-1], 0)),
        )
        self._window.replace(all_stamps[keep_from:], all_values[keep_from:])
        return postures

    def _run_states(
        self, stamps: np.ndarray, values: np.ndarray, verdicts: np.ndarray, window_mid: np.ndarray
    ) -> list[DetectedPosture]:
        """Advance the state machine over runs of equal verdicts (few runs per batch)."""
        postures: list[DetectedPosture] = []
        boundaries = np.flatnonzero(np.diff(verdicts)) + 1
        run_starts = np.concatenate(([0], boundaries))
        run_ends = np.concatenate((boundaries, [len(verdicts)]))
        for begin, end in zip(run_starts.tolist(), run_ends.tolist()):
            verdict = verdicts[begin]
            if verdict == _UNKNOWN:  # window not full: just after the start or a gap
                if self.state is DetectorState.CAPTURING:
                    self._drop(DropReason.GAP)
                elif self.state is DetectorState.CAPTURED:
                    self._recheck_after_gap = True
                continue
            if verdict == _MOVING:
                if self.state is DetectorState.CAPTURING:
                    self._drop(DropReason.MOTION)
                self.state = DetectorState.ARMED
                self._recheck_after_gap = False
                continue
            if self.state is DetectorState.CAPTURED:
                if not self._recheck_after_gap:
                    continue
                # Still again after a gap: a new posture only if it moved during the gap.
                self._recheck_after_gap = False
                if np.all(
                    np.abs(window_mid[begin] - self._last_posture_values) <= self.tolerances
                ):
                    continue
                self.state = DetectorState.ARMED
            position = begin
            if self.state is DetectorState.ARMED:
                self._start_period(int(stamps[begin]), values[begin])
            target_ns = self._period_first_ns + self.capture_ns
            last = begin + int(np.searchsorted(stamps[begin:end], target_ns, side='left'))
            if last < end:
                self._accumulate(stamps, values, position, last + 1)
                postures.append(self._emit())
            else:
                self._accumulate(stamps, values, position, end)
        return postures

    def _start_period(self, stamp_ns: int, values: np.ndarray) -> None:
        self.state = DetectorState.CAPTURING
        self._period_first_ns = stamp_ns
        self._period_last_ns = stamp_ns
        self._period_count = 0
        self._period_reference = values.copy()
        self._period_sum[:] = 0.0
        self._period_sum_squares[:] = 0.0

    def _accumulate(self, stamps: np.ndarray, values: np.ndarray, begin: int, end: int) -> None:
        deviations = values[begin:end] - self._period_reference
        self._period_sum += deviations.sum(axis=0)
        self._period_sum_squares += np.square(deviations).sum(axis=0)
        self._period_count += end - begin
        self._period_last_ns = int(stamps[end - 1])

    def _emit(self) -> DetectedPosture:
        count = self._period_count
        mean_deviation = self._period_sum / count
        mean = self._period_reference + mean_deviation
        if count > 1:
            variance = (self._period_sum_squares - count * mean_deviation**2) / (count - 1)
            std = np.sqrt(np.maximum(variance, 0.0))
        else:
            std = np.zeros(N_CHANNELS)
        self.state = DetectorState.CAPTURED
        self._recheck_after_gap = False
        self._last_posture_values = mean
        self.emitted += 1
        return DetectedPosture(
            PostureReading.from_values(self._period_last_ns, mean.tolist()),
            self._period_first_ns,
            count,
            tuple(std.tolist()),
        )

    def _drop(self, reason: DropReason) -> DroppedPeriod:
        reason = DropReason(reason)  # a caller's plain string too, if it names a reason
        dropped = DroppedPeriod(
            self._period_first_ns, self._period_last_ns, self._period_count, reason
        )
        self._count(self.dropped, reason, 1)
        self.recent_dropped.append(dropped)
        self.state = DetectorState.ARMED
        return dropped


def detect_postures(
    stamps_ns: ArrayLike, values: ArrayLike, **detector_options: Any
) -> list[DetectedPosture]:
    """
    Offline detection over recorded samples: stamps (N,) ns, values (N, 9).

    Uses PostureDetector (same results as feeding the samples one by one),
    in batches, so memory stays bounded for long recordings.
    """
    detector = PostureDetector(**detector_options)
    postures = detector.update(stamps_ns, values)
    detector.finish()
    return postures
