"""
One sensor stream of the dwell detector, cut into blocks of a fixed time grid (ROS-free).

A lane keeps the stream's accepted readings (stamps strictly increasing, values finite)
in a queue until the detector needs them, then moves them into grid blocks of `block_ns`
by their stamp corrected by the stream's clock offset (corrected = stamp - offset). Taking
readings only when the grid reaches them makes the result independent of how the data
arrived (one by one, in chunks or as whole arrays) even while the offset is being
estimated: every reading is corrected with the offset known at the same point of the
computation. Memory: the queue (readings not yet reached) and the last `keep_blocks` blocks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Block:
    """The readings of one stream in one grid block."""

    stamps: np.ndarray  # corrected stamps (ns, int64), increasing
    raw_stamps: np.ndarray  # as received (the stream's own clock)
    values: np.ndarray  # (n, width)
    gap_in_ns: int  # largest interval between consecutive readings ending in this block


@dataclass
class LaneHealth:
    """What the collector's status says of a stream: rate, gaps, offset, spikes."""

    accepted: int = 0
    first_stamp_ns: int | None = None
    last_stamp_ns: int | None = None
    gaps: int = 0  # intervals between readings longer than max_gap
    largest_gap_ns: int = 0
    spikes_rejected: int = 0  # readings left out of posture means as spikes

    @property
    def rate_hz(self) -> float:
        if self.accepted < 2 or self.first_stamp_ns is None or self.last_stamp_ns is None:
            return 0.0
        return (self.accepted - 1) * 1e9 / max(self.last_stamp_ns - self.first_stamp_ns, 1)


class StreamLane:
    """Queue and grid blocks of one stream."""

    def __init__(
        self, name: str, width: int, block_ns: int, keep_blocks: int, max_gap_ns: int
    ) -> None:
        self.name = name
        self.width = width
        self.block_ns = block_ns
        self.keep_blocks = keep_blocks
        self.max_gap_ns = max_gap_ns
        self.offset_ns = 0
        self.health = LaneHealth()
        self._queue_stamps = np.empty(0, dtype=np.int64)
        self._queue_values = np.empty((0, width))
        self._blocks: dict[int, Block] = {}
        self._previous_ns: int | None = None  # corrected stamp of the last reading taken
        self.ended = False  # no more readings will come (end of data, or given up on)

    # ------------------------------------------------------------------ input

    def add(self, stamps: np.ndarray, values: np.ndarray) -> None:
        """Queue accepted readings (stamps increasing past the last one; the caller checks)."""
        if not len(stamps):
            return
        health = self.health
        previous = health.last_stamp_ns
        intervals = np.diff(stamps) if previous is None else np.diff(stamps, prepend=previous)
        long = intervals[intervals > self.max_gap_ns]
        health.gaps += len(long)
        if len(long):
            health.largest_gap_ns = max(health.largest_gap_ns, int(long.max()))
        if health.first_stamp_ns is None:
            health.first_stamp_ns = int(stamps[0])
        health.last_stamp_ns = int(stamps[-1])
        health.accepted += len(stamps)
        self._queue_stamps = np.concatenate((self._queue_stamps, stamps))
        self._queue_values = np.concatenate((self._queue_values, values))

    @property
    def queued(self) -> int:
        return len(self._queue_stamps)

    @property
    def held(self) -> int:
        """Return the number of readings in memory: queued and in the kept blocks."""
        return self.queued + sum(len(block.stamps) for block in self._blocks.values())

    def newest_corrected_ns(self) -> int | None:
        last = self.health.last_stamp_ns
        return None if last is None else last - self.offset_ns

    def first_block(self) -> int | None:
        """Return the grid block of the first queued reading (None if none is queued)."""
        if not len(self._queue_stamps):
            return None
        return int((int(self._queue_stamps[0]) - self.offset_ns) // self.block_ns)

    # ------------------------------------------------------------------ grid

    def complete_through(self, block: int) -> bool:
        """
        Move the readings of blocks <= `block` into blocks; True once that block is complete.

        Complete: a reading beyond it was received, or the lane ended.
        """
        queued = self._queue_stamps
        if len(queued):
            # Only the readings up to the first beyond the block (the queue may hold a whole
            # recording): the clamp below only moves readings later, never earlier.
            end_ns = (block + 1) * self.block_ns + self.offset_ns
            stamps = queued[: int(np.searchsorted(queued, end_ns, side='left')) + 1]
            corrected = stamps - self.offset_ns
            if self._previous_ns is not None:
                # An offset that grew must not move a reading before the one taken last.
                corrected = np.maximum(
                    corrected, self._previous_ns + 1 + np.arange(len(corrected), dtype=np.int64)
                )
            ids = corrected // self.block_ns
            count = int(np.searchsorted(ids, block, side='right'))
            if count:
                self._take(corrected[:count], ids[:count], count)
            if count < len(queued):
                return True
        return self.ended

    def _take(self, corrected: np.ndarray, ids: np.ndarray, count: int) -> None:
        raw = self._queue_stamps[:count]
        values = self._queue_values[:count]
        self._queue_stamps = self._queue_stamps[count:]
        self._queue_values = self._queue_values[count:]
        previous = corrected[0] if self._previous_ns is None else self._previous_ns
        intervals = np.diff(corrected, prepend=previous)
        self._previous_ns = int(corrected[-1])
        starts = np.flatnonzero(np.diff(ids, prepend=ids[0] - 1))
        ends = np.append(starts[1:], count)
        for start, end in zip(starts.tolist(), ends.tolist()):
            key = int(ids[start])
            block = Block(
                corrected[start:end],
                raw[start:end],
                values[start:end],
                int(intervals[start:end].max()),
            )
            old = self._blocks.get(key)
            if old is not None:  # the block had readings taken before (a lane that ended)
                block = Block(
                    np.concatenate((old.stamps, block.stamps)),
                    np.concatenate((old.raw_stamps, block.raw_stamps)),
                    np.concatenate((old.values, block.values)),
                    max(old.gap_in_ns, block.gap_in_ns),
                )
            self._blocks[key] = block

    def gap_after_ns(self) -> float:
        """
        Return the interval from the last reading taken to the next queued one.

        Infinite while none is queued; 0 once the lane ended with its last reading taken (the
        data ended, no gap: a posture captured up to the end of a recording counts).
        """
        if self._previous_ns is None:
            return np.inf
        if not len(self._queue_stamps):
            return 0.0 if self.ended else np.inf
        return float(int(self._queue_stamps[0]) - self.offset_ns - self._previous_ns)

    def samples(self, first: int, last: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the corrected stamps, raw stamps and values of blocks first..last."""
        blocks = [self._blocks[k] for k in range(first, last + 1) if k in self._blocks]
        if not blocks:
            return (
                np.empty(0, dtype=np.int64),
                np.empty(0, dtype=np.int64),
                np.empty((0, self.width)),
            )
        if len(blocks) == 1:
            return blocks[0].stamps, blocks[0].raw_stamps, blocks[0].values
        return (
            np.concatenate([b.stamps for b in blocks]),
            np.concatenate([b.raw_stamps for b in blocks]),
            np.concatenate([b.values for b in blocks]),
        )

    def gaps_ok(self, first: int, last: int, through_now: bool) -> bool:
        """
        Return True if blocks first..last hold readings no further apart than max_gap.

        The interval into the first reading of the range counts; with `through_now` also the
        interval from the last reading to the next one (`last` is the newest grid block).
        """
        gaps = [self._blocks[k].gap_in_ns for k in range(first, last + 1) if k in self._blocks]
        if not gaps or max(gaps) > self.max_gap_ns:
            return False
        return not through_now or self.gap_after_ns() <= self.max_gap_ns

    def forget_before(self, block: int) -> None:
        """Drop the blocks older than `block` (bounded memory)."""
        for key in [k for k in self._blocks if k < block]:
            del self._blocks[key]
