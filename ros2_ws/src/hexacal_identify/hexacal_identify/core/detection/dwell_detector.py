"""
Find the postures in raw sensor streams as a careful person would (ROS-free, numpy only).

`DwellDetector` takes each stream (actuators, inclinometer alpha/beta, rotary phi) on its
own stamps - no pairing of readings - and judges each on its own readings:

* Time is cut into a grid of blocks of window_s / 4 (stamps corrected by each stream's clock
  offset). At the end of every block each stream's last window_s (four blocks) is judged:
  moving when a channel's spread without spikes or the change of its level between the
  window's two halves exceeds the channel's tolerance (slider_tolerance_m,
  angle_tolerance_rad); settled when no channel's level (mean without spikes) changes
  significantly between the halves (more than SETTLED_SIGMAS standard errors, or one
  quantisation step); settling in between. A channel still creeping towards its level
  (an inclinometer lagging through its filter) is settling, so it is waited for.
* A posture is taken from the capture_s (rounded up to whole blocks) that follow a moment
  at which every stream was settled, once every stream's readings over it are in: each
  stream's capture must hold at least two readings, no interval longer than max_gap_s,
  no spread beyond the tolerance, and its level must equal the one of the settled window
  before it and the one of its own first half (same significance test). Otherwise the
  capture slides on by a block - the machine still stands (the executor waits for this
  posture), so a channel that is still creeping only delays the posture.
  At the end of a recording the last block may be partial (the data ended; no gap).
* Each channel of the posture is the mean of its readings in the capture without spikes
  (beyond SPIKE_SIGMAS robust sigmas from the median, counted per stream), with its own
  count and standard error (std / sqrt(n)): streams differ in rate and drops.
* Then the detector waits for motion: a stream moving, or its level leaving the posture's
  by more than the tolerance. A spike is one reading, not a sustained change of level, so it
  neither splits a dwell nor moves its mean; one dwell gives one posture.
* Clock offsets (stream stamps - actuator stamps) are given, or estimated from the starts of
  motion (core.clock_offset) when the stream is in `estimate_offsets`.
* The measured link length (LINK_STREAM: an LVDT in a telescopic link, the lvdt measuring
  mode, m) is one more stream when its readings arrive: judged, captured and averaged as the
  others (tolerance link_tolerance_m), stamped in the actuators' clock; the posture gets its
  mean as `link_length` and its standard error and count in the scatter.  Without link
  readings nothing changes.

Online (readings fed one by one or in chunks, as the collector does) and offline (whole
arrays) give exactly the same postures: the readings are cut into blocks only when the grid
reaches them. Memory is bounded: window and capture blocks per stream, and the readings
not yet reached (a stream that falls further than `horizon_s` behind the others is treated
as silent for the blocks it misses).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
import math
from typing import Any

from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.names import N_CHAINS
from hexacal_msgs_py.readings import NS_PER_S, PostureReading, PostureScatter
import numpy as np
from numpy.typing import ArrayLike

from . import robust_stats as robust
from . import stream_lane
from .clock_offset import departure_ns, OffsetEstimator
from .stream_lane import Judgement, StreamLane
from .vocabulary import (
    check_detector_settings,
    DetectedPosture,
    DetectorState,
    DroppedPeriod,
    DropReason,
    MAX_STAMP_NS,
    RejectReason,
    Stream,
)

# Channels of each stream, in POSTURE_NAMES order.
STREAM_WIDTHS = {Stream.SLIDERS: N_CHAINS, Stream.INCLINOMETER: 2, Stream.ENCODER: 1}
REFERENCE = Stream.SLIDERS  # offsets are against the actuator stream's clock
# The optional fourth stream: the link length an LVDT measures (m), published with the
# actuators' stamps.  Not a Stream (the collector's synchronizer pairs three streams).
LINK_STREAM = 'link'
BLOCKS_PER_WINDOW = stream_lane.BLOCKS_PER_WINDOW
# Levels differ significantly beyond 4 standard errors: with 9 channels judged at every block,
# 3 would call noise 'settling' every few blocks (Student t of ~30 samples), delaying postures.
SETTLED_SIGMAS = 4.0
# A stream this far (or the window and capture, if longer) behind the others is given up on
# for the blocks it misses (counted in `behind`): memory stays bounded when a stream stops or
# is stamped far off. Longer than the collector takes to call a stream stopped (1-2 s), so a
# capture a stopped stream leaves half done is dropped as such, not as a gap.
HORIZON_S = 3.0
# Blocks after a stream is first judged moving at which its start of motion is timed.
DEPARTURE_DELAY_BLOCKS = 2


class Verdict(StrEnum):
    """A stream's state over its last window."""

    MOVING = 'moving'
    SETTLING = 'settling'
    SETTLED = 'settled'
    UNKNOWN = 'unknown'  # a gap, or too few readings


# The lane's verdict codes, named.
_VERDICTS = {
    stream_lane.MOVING: Verdict.MOVING,
    stream_lane.SETTLING: Verdict.SETTLING,
    stream_lane.SETTLED: Verdict.SETTLED,
    stream_lane.UNKNOWN: Verdict.UNKNOWN,
}


@dataclass(frozen=True)
class _Capture:
    """One stream's robust means over a capture."""

    mean: robust.RobustMean
    stamps: np.ndarray


class DwellDetector:
    """Detect one posture per dwell in the three raw streams; see the module docstring."""

    def __init__(
        self,
        window_s: float = 0.3,
        slider_tolerance_m: float = 2e-4,
        angle_tolerance_rad: float = 2e-4,
        capture_s: float = 0.5,
        max_gap_s: float = 0.1,
        clock_offsets_s: Mapping[str, float] | None = None,
        estimate_offsets: tuple[str, ...] = (Stream.INCLINOMETER, Stream.ENCODER),
        link_tolerance_m: float | None = None,
    ) -> None:
        check_detector_settings(
            {'window_s': window_s, 'capture_s': capture_s, 'max_gap_s': max_gap_s},
            (slider_tolerance_m, angle_tolerance_rad),
        )
        offsets = dict(clock_offsets_s or {})
        unknown = (set(offsets) | set(estimate_offsets)) - {Stream.INCLINOMETER, Stream.ENCODER}
        if unknown:
            raise ValueError(f'clock offsets are of inclinometer and encoder, not {unknown}')
        if not all(math.isfinite(v) and abs(v) <= 1.0 for v in offsets.values()):
            raise ValueError(f'clock offsets must be finite and within +-1 s, got {offsets}')
        self.block_ns = max(int(round(window_s * NS_PER_S / BLOCKS_PER_WINDOW)), 1)
        self.capture_blocks = max(int(math.ceil(capture_s * NS_PER_S / self.block_ns)), 2)
        self.max_gap_ns = int(round(max_gap_s * NS_PER_S))
        keep = self.capture_blocks + 2 * BLOCKS_PER_WINDOW
        self.horizon_ns = max(int(HORIZON_S * NS_PER_S), keep * self.block_ns)
        self._keep = keep
        self.lanes: dict[str, StreamLane] = {
            stream: StreamLane(stream.value, width, self.block_ns, keep, self.max_gap_ns)
            for stream, width in STREAM_WIDTHS.items()
        }
        for stream, offset in offsets.items():
            self.lanes[Stream(stream)].offset_ns = int(round(offset * NS_PER_S))
        self.estimate_offsets = tuple(Stream(stream) for stream in estimate_offsets)
        self._estimators: dict[str, OffsetEstimator] = {
            stream: OffsetEstimator(BLOCKS_PER_WINDOW * self.block_ns)
            for stream in self.estimate_offsets
        }
        link_tolerance = slider_tolerance_m if link_tolerance_m is None else link_tolerance_m
        if not link_tolerance > 0:
            raise ValueError('tolerances must be > 0')
        self.tolerances: dict[str, np.ndarray] = {
            Stream.SLIDERS: np.full(N_CHAINS, slider_tolerance_m),
            Stream.INCLINOMETER: np.full(2, angle_tolerance_rad),
            Stream.ENCODER: np.full(1, angle_tolerance_rad),
            LINK_STREAM: np.full(1, link_tolerance),
        }
        self.state = DetectorState.ARMED
        self._next_block: int | None = None
        self._settled_at: deque[int] = deque(maxlen=self.capture_blocks + 2)
        self._verdicts: dict[str, Verdict] = dict.fromkeys(self.lanes, Verdict.UNKNOWN)
        self._capture_start: int | None = None
        self._moves_seen: dict[str, int] = {}
        self._posture_values: dict[str, np.ndarray] = {}
        self.rejected: dict[str, int] = {}
        self.dropped: dict[str, int] = {}
        self.recent_dropped: deque[DroppedPeriod] = deque(maxlen=16)
        self.behind: dict[str, int] = {}  # per stream, blocks judged without it (too late)
        self.emitted = 0
        self.slid = 0  # captures slid on because a stream was still settling
        # Still periods that ended with no posture because these streams never settled.
        self.unsettled: dict[str, int] = {}
        self._still_blocks = 0  # blocks with no stream moving since the last motion
        # Per stream, the blocks of this still period it held a posture up (settling, moving).
        self._settling: dict[str, int] = {}

    # ------------------------------------------------------------------ input

    def add(self, stream: str, stamps_ns: ArrayLike, values: ArrayLike) -> list[DetectedPosture]:
        """Feed readings of one stream (stamps (N,) ns, values (N, width)); return postures."""
        self._queue(self._stream(stream), stamps_ns, values)
        return self._run()

    def update(
        self, readings: Mapping[str, tuple[ArrayLike, ArrayLike]]
    ) -> list[DetectedPosture]:
        """Feed readings of several streams at once ({stream: (stamps, values)})."""
        for stream, (stamps, values) in readings.items():
            self._queue(self._stream(stream), stamps, values)
        return self._run()

    @property
    def has_link(self) -> bool:
        """Return True once link length readings arrived (the posture carries link_length)."""
        return LINK_STREAM in self.lanes

    def _stream(self, stream: str) -> str:
        """Return the stream's key; the link stream's lane is made when its readings come."""
        if stream == LINK_STREAM:
            if LINK_STREAM not in self.lanes:
                self.lanes[LINK_STREAM] = StreamLane(
                    LINK_STREAM, 1, self.block_ns, self._keep, self.max_gap_ns
                )
            return LINK_STREAM
        return Stream(stream)

    def finish(self) -> tuple[list[DetectedPosture], DroppedPeriod | None]:
        """End of data: detect what the last readings complete, then drop a partial capture."""
        for lane in self.lanes.values():
            lane.ended = True
        postures = self._run()
        return postures, self.abort(DropReason.END_OF_STREAM)

    def flush(self) -> list[DetectedPosture]:
        """
        Judge the readings in hand as if the data ended (every stream stopped); go on after.

        A posture whose capture the last readings complete is emitted; readings that come
        later are judged as usual.
        """
        for lane in self.lanes.values():
            lane.ended = True
        try:
            return self._run()
        finally:
            for lane in self.lanes.values():
                lane.ended = False

    def abort(self, reason: DropReason) -> DroppedPeriod | None:
        """Drop (count, never emit) a capture in progress, e.g. when a stream stopped."""
        if self.state is not DetectorState.CAPTURING:
            return None
        return self._drop(DropReason(reason), self._next_block or 0)

    @property
    def offsets_s(self) -> dict[str, float]:
        """Per stream, the clock offset in use (s; the actuators' is 0 by definition)."""
        return {lane.name: lane.offset_ns / NS_PER_S for lane in self.lanes.values()}

    @property
    def held_samples(self) -> int:
        """Return the number of readings in memory over all streams (bounded)."""
        return sum(lane.held for lane in self.lanes.values())

    def _queue(self, stream: str, stamps_ns: ArrayLike, values: ArrayLike) -> None:
        lane = self.lanes[stream]
        try:
            stamps = np.asarray(stamps_ns, dtype=np.int64).ravel()
            array = np.asarray(values, dtype=np.float64).reshape(len(stamps), lane.width)
        except (TypeError, ValueError, OverflowError) as error:
            raise InvalidReadingError(
                f'{stream}: stamps must be integer ns and values {lane.width} numbers each: '
                f'{error}'
            ) from None
        if stamps.size and (stamps.min() < 0 or stamps.max() > MAX_STAMP_NS):
            raise InvalidReadingError(f'{stream}: stamps must be in [0, {MAX_STAMP_NS}] ns')
        finite = np.all(np.isfinite(array), axis=1)
        self._count(self.rejected, RejectReason.NON_FINITE, np.count_nonzero(~finite))
        stamps, array = stamps[finite], array[finite]
        if not len(stamps):
            return
        last = lane.health.last_stamp_ns
        previous = np.iinfo(np.int64).min if last is None else last
        running = np.maximum.accumulate(np.concatenate(([previous], stamps[:-1])))
        increasing = stamps > running
        self._count(
            self.rejected,
            RejectReason.DUPLICATE_STAMP,
            np.count_nonzero(~increasing & (stamps == running)),
        )
        self._count(self.rejected, RejectReason.OUT_OF_ORDER, np.count_nonzero(stamps < running))
        lane.add(stamps[increasing], array[increasing])

    @staticmethod
    def _count(counter: dict[str, int], reason: StrEnum, n: Any) -> None:
        if n:
            counter[reason.value] = counter.get(reason.value, 0) + int(n)

    # ------------------------------------------------------------------ the grid

    def _run(self) -> list[DetectedPosture]:
        postures: list[DetectedPosture] = []
        while True:
            if self._next_block is None:
                self._next_block = self._start_block()  # fixed once chosen
            block = self._next_block
            if block is None or not self._complete(block) or self._past_the_end(block):
                return postures
            posture = self._at_block(block)
            if posture is not None:
                postures.append(posture)
            self._next_block = block + 1
            for lane in self.lanes.values():
                lane.forget_before(block + 1 - lane.keep_blocks)

    def _start_block(self) -> int | None:
        firsts = [lane.first_block() for lane in self.lanes.values()]
        known = [first for first in firsts if first is not None]
        if not known:
            return None
        if len(known) < len(firsts) and not self._given_up(min(known)):
            return None  # wait for every stream to begin
        return max(known) if len(known) == len(firsts) else min(known)

    def _past_the_end(self, block: int) -> bool:
        """Return True if every stream ended before this block (nothing more to judge)."""
        if not all(lane.ended for lane in self.lanes.values()):
            return False
        newest = [lane.newest_corrected_ns() for lane in self.lanes.values()]
        return all(n is None or n < block * self.block_ns for n in newest)

    def _given_up(self, block: int) -> bool:
        """Return True if some stream is past this block by more than the horizon."""
        newest = [lane.newest_corrected_ns() for lane in self.lanes.values()]
        end_ns = (block + 1) * self.block_ns
        return any(n is not None and n > end_ns + self.horizon_ns for n in newest)

    def _complete(self, block: int) -> bool:
        complete = [lane.complete_through(block) for lane in self.lanes.values()]
        if all(complete):
            return True
        # Ended streams are complete; the data of the others will come unless one is too late.
        if all(c or lane.ended for c, lane in zip(complete, self.lanes.values())):
            return True
        if not self._given_up(block):
            return False
        for done, lane in zip(complete, self.lanes.values()):
            if not done and not lane.ended:
                self.behind[lane.name] = self.behind.get(lane.name, 0) + 1
        return True

    def _at_block(self, block: int) -> DetectedPosture | None:
        judgements = {
            stream: lane.judge(block, self.tolerances[stream], SETTLED_SIGMAS)
            for stream, lane in self.lanes.items()
        }
        verdicts = {stream: self._verdict(j) for stream, j in judgements.items()}
        self._note_departures(verdicts, block)
        self._verdicts = verdicts
        values = set(verdicts.values())
        if values == {Verdict.SETTLED}:
            self._settled_at.append(block)
        unsettled = self._note_settling(verdicts, values)
        if self.state is DetectorState.CAPTURED:
            if Verdict.MOVING in values or self._left_posture(judgements):
                self.state = DetectorState.ARMED
            return None
        if Verdict.MOVING in values or Verdict.UNKNOWN in values:
            if self.state is DetectorState.CAPTURING:
                reason = DropReason.MOTION if Verdict.MOVING in values else DropReason.GAP
                self._drop(DropReason.UNSETTLED if unsettled else reason, block, count=False)
                if not unsettled:
                    self._count(self.dropped, reason, 1)
            return None
        if self.state is DetectorState.ARMED:
            if values == {Verdict.SETTLED}:
                self.state = DetectorState.CAPTURING
                self._capture_start = block
            return None
        return self._try_capture(block)

    def _note_settling(self, verdicts: dict[str, Verdict], values: set[Verdict]) -> bool:
        """
        Count a still period of the actuators that ends before every stream settled.

        The actuators stand still (not moving, not unknown) while another stream is still
        settling or moving (a lagging inclinometer): that stream is remembered; when the
        actuators move on with no posture taken, the period is counted in `unsettled` under the
        streams that held it up. Returns True if this block ended such a period.
        """
        if self.state is DetectorState.CAPTURED:
            self._still_blocks, self._settling = 0, {}
            return False
        reference = verdicts[REFERENCE]
        if reference not in (Verdict.MOVING, Verdict.UNKNOWN):
            self._still_blocks += 1
            holding = {
                stream
                for stream, verdict in verdicts.items()
                if verdict is Verdict.SETTLING
                or (verdict is Verdict.MOVING and stream != REFERENCE)
            }
            for stream in holding:
                self._settling[stream] = self._settling.get(stream, 0) + 1
            return False
        counted = bool(
            reference is Verdict.MOVING
            and self._settling
            and self._still_blocks >= BLOCKS_PER_WINDOW
        )
        if counted:
            self._count(self.dropped, DropReason.UNSETTLED, 1)
            # The stream that held the period up longest (noise makes others flicker).
            stream = str(max(self._settling, key=self._settling.__getitem__))
            self.unsettled[stream] = self.unsettled.get(stream, 0) + 1
        self._still_blocks, self._settling = 0, {}
        return counted

    # ------------------------------------------------------------------ judging

    def _verdict(self, judgement: Judgement) -> Verdict:
        if self.state is DetectorState.CAPTURED:
            # Waiting for motion only: settled or settling makes no difference (cheaper).
            return _VERDICTS[judgement.captured_verdict]
        return _VERDICTS[judgement.verdict]

    def _left_posture(self, judgements: dict[str, Judgement]) -> bool:
        """Return True if a stream's level left the posture's by more than its tolerance."""
        for stream, values in self._posture_values.items():
            level = judgements[stream].level
            if level is None:
                continue  # a gap: judged when data is back
            if np.any(np.abs(level - values) > self.tolerances[stream]):
                return True
        return False

    def _try_capture(self, block: int) -> DetectedPosture | None:
        start = block - self.capture_blocks + 1
        pre_end = start - 1
        if self._capture_start is None or pre_end < self._capture_start:
            return None
        if pre_end not in self._settled_at:
            self.slid += 1
            return None
        captures = {}
        for stream in self.lanes:
            capture = self._capture(stream, pre_end, start, block)
            if capture is None:
                self.slid += 1
                self._settling[stream] = self._settling.get(stream, 0) + 1  # held it up
                return None
            captures[stream] = capture
        return self._emit(captures, start, block)

    def _capture(
        self, stream: str, pre_end: int, start: int, block: int
    ) -> _Capture | None:
        lane = self.lanes[stream]
        pre = lane.samples(pre_end - BLOCKS_PER_WINDOW + 1, pre_end)[2]
        stamps, _, values = lane.samples(start, block)
        if len(values) < 2 or not len(pre):
            return None
        if not lane.gaps_ok(start, block, through_now=True):
            return None
        floor = robust.quantum(np.concatenate((pre, values)))
        tolerance = self.tolerances[stream]
        if np.any(robust.robust_spread(values, floor) > tolerance):
            return None
        half = len(values) // 2
        for before, after in ((pre, values), (values[:half], values[half:])):
            shift, threshold = robust.level_shift(before, after, SETTLED_SIGMAS, floor)
            if np.any(shift > threshold):
                return None
        return _Capture(robust.robust_mean(values, floor), stamps)

    def _emit(self, captures: dict[str, _Capture], start: int, block: int) -> DetectedPosture:
        means = [captures[stream].mean for stream in STREAM_WIDTHS]
        values = np.concatenate([m.mean for m in means])
        errors = np.concatenate([m.standard_error for m in means])
        counts = np.concatenate([m.count for m in means])
        std = np.concatenate([m.std for m in means])
        for stream, capture in captures.items():
            self.lanes[stream].health.spikes_rejected += int(capture.mean.rejected.sum())
            self._posture_values[stream] = capture.mean.mean
        reference = captures[REFERENCE].stamps
        link = captures[LINK_STREAM].mean if LINK_STREAM in captures else None
        scatter = PostureScatter(
            tuple(errors.tolist()),
            tuple(int(c) for c in counts),
            link_length_standard_error=None if link is None else float(link.standard_error[0]),
            link_length_sample_count=None if link is None else int(link.count[0]),
        )
        reading = PostureReading.from_values(
            int(reference[-1]),
            values.tolist(),
            scatter=scatter,
            link_length=None if link is None else float(link.mean[0]),
        )
        self.state = DetectorState.CAPTURED
        self._capture_start = None
        self.emitted += 1
        return DetectedPosture(reading, int(reference[0]), len(reference), tuple(std.tolist()))

    def _drop(self, reason: DropReason, block: int, count: bool = True) -> DroppedPeriod:
        start = self._capture_start if self._capture_start is not None else block
        stamps = self.lanes[REFERENCE].samples(start + 1, block)[0]
        first = int(stamps[0]) if len(stamps) else (start + 1) * self.block_ns
        last = int(stamps[-1]) if len(stamps) else first
        dropped = DroppedPeriod(first, last, len(stamps), reason)
        if count:
            self._count(self.dropped, reason, 1)
        self.recent_dropped.append(dropped)
        self.state = DetectorState.ARMED
        self._capture_start = None
        return dropped

    # ------------------------------------------------------------------ clock offsets

    def _note_departures(self, verdicts: dict[str, Verdict], block: int) -> None:
        """Feed the starts of motion to the offset estimators; apply their estimates."""
        if not self._estimators:
            return
        for stream, verdict in verdicts.items():
            still = self._verdicts.get(stream) in (Verdict.SETTLED, Verdict.SETTLING)
            if verdict is Verdict.MOVING and still:
                self._moves_seen[stream] = block
            seen = self._moves_seen.get(stream)
            if seen is None or block < seen + DEPARTURE_DELAY_BLOCKS:
                continue
            # Judged a little later, so the move's first readings are all in.
            del self._moves_seen[stream]
            when = self._departure(stream, seen, block)
            if when is None:
                continue
            if stream is REFERENCE:
                for estimator in self._estimators.values():
                    estimator.reference_departure(when)
            elif stream in self._estimators:
                self._estimators[stream].stream_departure(when)
        for stream, estimator in self._estimators.items():
            estimate = estimator.estimate_ns()
            if estimate is not None:
                self.lanes[stream].offset_ns = estimate

    def _departure(self, stream: str, seen: int, block: int) -> float | None:
        """Return when (raw stamps) the move first judged moving at block `seen` started."""
        lane = self.lanes[stream]
        first = seen - BLOCKS_PER_WINDOW + 1
        before = lane.samples(first, seen - BLOCKS_PER_WINDOW // 2)[2]
        _, raw, values = lane.samples(first, block)
        if len(before) < 2:
            return None
        floor = robust.quantum(before)
        level, sigma = robust.median_and_sigma(before)
        threshold = np.maximum(
            robust.SPIKE_SIGMAS * np.maximum(sigma, floor), 1e-3 * self.tolerances[stream]
        )
        # The actuators' stamps are the reference clock; another stream's are its own clock.
        return departure_ns(raw, values, level, threshold)


def detect_dwell_postures(
    streams: Mapping[str, tuple[ArrayLike, ArrayLike]], **options: Any
) -> tuple[list[DetectedPosture], DwellDetector]:
    """
    Offline detection over whole recorded streams ({stream: (stamps ns, values)}).

    The same computation as feeding the readings online; returns the postures and the
    detector (its counters, offsets and per-stream health).
    """
    detector = DwellDetector(**options)
    postures = detector.update(streams)
    postures += detector.finish()[0]
    return postures, detector
