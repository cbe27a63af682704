"""
One sensor stream of the dwell detector, cut into blocks of a fixed time grid (ROS-free).

A lane keeps the stream's accepted readings (stamps strictly increasing, values finite)
in a queue until the detector needs them, then moves them into grid blocks of `block_ns`
by their stamp corrected by the stream's clock offset (corrected = stamp - offset). Taking
readings only when the grid reaches them makes the result independent of how the data
arrived (one by one, in chunks or as whole arrays) even while the offset is being
estimated: every reading is corrected with the offset known at the same point of the
computation. Memory: the queue (readings not yet reached) and the last `keep_blocks` blocks.

`judge` gives the detector its verdict on the window ending at a block. It judges many blocks
at once: those whose readings are all queued already (a later reading is in), cut into blocks
with the offset in use as the grid would cut them, and keeps the verdicts until the grid
reaches them or the offset changes. The statistics of one window are those of the same
window computed alone (core.robust_stats `windows_*`), so a recording judged whole and fed
in chunks give the same verdicts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import robust_stats as robust

# Blocks of a window, and the blocks judged at once ahead of the grid (up to).
BLOCKS_PER_WINDOW = 4
JUDGED_AHEAD = 256

# Verdict codes of `judge` (the detector names them).
MOVING, SETTLING, SETTLED, UNKNOWN = range(4)


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
        self._judged: _Judged | None = None  # verdicts of blocks ahead (offset, first block)

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
            stamps = queued[: int(queued.searchsorted(end_ns, side='left')) + 1]
            corrected = stamps - self.offset_ns
            if self._previous_ns is not None:
                # An offset that grew must not move a reading before the one taken last.
                corrected = np.maximum(
                    corrected, self._previous_ns + 1 + np.arange(len(corrected), dtype=np.int64)
                )
            ids = corrected // self.block_ns
            count = int(ids.searchsorted(block, side='right'))
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
        intervals = np.empty(count, dtype=np.int64)
        intervals[0] = corrected[0] - previous
        np.subtract(corrected[1:], corrected[:-1], out=intervals[1:])
        self._previous_ns = int(corrected[-1])
        if ids[0] == ids[-1]:  # one block (the grid's usual step)
            self._put(int(ids[0]), Block(corrected, raw, values, int(intervals.max())))
            return
        starts = np.flatnonzero(ids[1:] != ids[:-1]) + 1
        bounds = [0, *starts.tolist(), count]
        for start, end in zip(bounds[:-1], bounds[1:]):
            block = Block(
                corrected[start:end],
                raw[start:end],
                values[start:end],
                int(intervals[start:end].max()),
            )
            self._put(int(ids[start]), block)

    def _put(self, key: int, block: Block) -> None:
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

    # ------------------------------------------------------------------ judging

    def judge(self, block: int, tolerance: np.ndarray, sigmas: float) -> Judgement:
        """
        Judge the window of the blocks up to `block` (the grid's newest, complete block).

        The detector's verdict on it (moving beyond `tolerance`, settled within `sigmas`
        standard errors, see core.dwell_detector) from the lane as it stands: its readings
        through `block` taken. Blocks whose readings are all queued already are judged
        ahead, with the offset in use.
        """
        judged = self._judged
        if (
            judged is None
            or judged.offset_ns != self.offset_ns
            or not judged.first <= block < judged.first + len(judged.verdicts)
        ):
            judged = self._judge_ahead(block, tolerance, sigmas)
            if judged is None:
                return self._judge_now(block, tolerance, sigmas)
            self._judged = judged
        at = block - judged.first
        verdict = int(judged.verdicts[at])
        level = None if verdict == UNKNOWN else judged.levels[at]
        return Judgement(verdict, int(judged.captured[at]), level)

    def _window_blocks(self, block: int) -> tuple[np.ndarray, np.ndarray, dict[int, int]]:
        """Return the taken readings of the window ending at `block`: values, ids, gaps."""
        keys = [k for k in range(block - BLOCKS_PER_WINDOW + 1, block + 1) if k in self._blocks]
        if not keys:
            return np.empty((0, self.width)), np.empty(0, dtype=np.int64), {}
        taken = [self._blocks[k] for k in keys]
        values = np.concatenate([b.values for b in taken]) if len(taken) > 1 else taken[0].values
        ids = np.repeat(np.array(keys, dtype=np.int64), [len(b.stamps) for b in taken])
        return values, ids, {k: b.gap_in_ns for k, b in zip(keys, taken)}

    def _judge_now(self, block: int, tolerance: np.ndarray, sigmas: float) -> Judgement:
        """Judge one block from the lane as it stands (its readings after it not all in)."""
        values, ids, gaps = self._window_blocks(block)
        ok = bool(gaps) and max(gaps.values()) <= self.max_gap_ns
        ok = ok and self.gap_after_ns() <= self.max_gap_ns
        verdicts, captured, levels = _judge_windows(
            values, ids, np.array([block]), np.array([ok]), tolerance, sigmas
        )
        verdict = int(verdicts[0])
        return Judgement(verdict, int(captured[0]), None if verdict == UNKNOWN else levels[0])

    def _judge_ahead(self, block: int, tolerance: np.ndarray, sigmas: float) -> _Judged | None:
        """
        Judge `block` and the blocks after it whose readings are all queued (None: none is).

        The queued readings are cut into blocks as `complete_through` will cut them with the
        same offset (the clamp after the last reading taken included); a block is judged when
        a reading beyond it is queued, so later readings cannot change its verdict.
        """
        queued = self._queue_stamps
        if not len(queued):
            return None
        limit_ns = (block + JUDGED_AHEAD + 1) * self.block_ns + self.offset_ns
        count = min(int(np.searchsorted(queued, limit_ns, side='left')) + 1, len(queued))
        corrected = queued[:count] - self.offset_ns
        if self._previous_ns is not None:
            corrected = np.maximum(
                corrected, self._previous_ns + 1 + np.arange(count, dtype=np.int64)
            )
        ids = corrected // self.block_ns
        last = int(ids[-1]) - 1  # the last block with a reading beyond it
        if last < block:
            return None
        inside = int(np.searchsorted(ids, last, side='right'))
        previous = corrected[0] if self._previous_ns is None else self._previous_ns
        intervals = np.diff(corrected[:inside], prepend=previous)
        blocks = np.arange(block, last + 1, dtype=np.int64)
        # The interval from each block's last reading to the next (`gap_after_ns` then).
        following = np.searchsorted(ids, blocks, side='right')
        before = np.where(following > 0, corrected[np.maximum(following - 1, 0)], 0)
        gap_after = (queued[following] - self.offset_ns - before).astype(float)
        if self._previous_ns is None:
            gap_after[following == 0] = np.inf
        else:
            gap_after[following == 0] = float(
                int(queued[0]) - self.offset_ns - self._previous_ns
            )
        # Per block from the window's first: the largest interval ending in it (-1: empty).
        taken_values, taken_ids, taken_gaps = self._window_blocks(block)
        origin = block - BLOCKS_PER_WINDOW + 1
        gaps = np.full(last - origin + 1, -1, dtype=np.int64)
        for key, gap in taken_gaps.items():
            gaps[key - origin] = gap
        np.maximum.at(gaps, ids[:inside] - origin, intervals)
        windows = np.lib.stride_tricks.sliding_window_view(gaps, BLOCKS_PER_WINDOW).max(axis=1)
        gaps_ok = (windows >= 0) & (windows <= self.max_gap_ns) & (gap_after <= self.max_gap_ns)
        values = np.concatenate((taken_values, self._queue_values[:inside]))
        all_ids = np.concatenate((taken_ids, ids[:inside]))
        verdicts, captured, levels = _judge_windows(
            values, all_ids, blocks, gaps_ok, tolerance, sigmas
        )
        return _Judged(self.offset_ns, block, verdicts, captured, levels)

    def forget_before(self, block: int) -> None:
        """Drop the blocks older than `block` (bounded memory)."""
        # Blocks are made in increasing order, so the oldest come first.
        while self._blocks:
            key = next(iter(self._blocks))
            if key >= block:
                return
            del self._blocks[key]


@dataclass(frozen=True)
class Judgement:
    """A stream's window ending at one block, judged (see StreamLane.judge)."""

    verdict: int  # MOVING, SETTLING, SETTLED or UNKNOWN, waiting for a posture
    captured_verdict: int  # MOVING or SETTLED (UNKNOWN), once a posture was taken
    level: np.ndarray | None  # median of the window's second half; None when UNKNOWN


@dataclass(frozen=True)
class _Judged:
    offset_ns: int
    first: int
    verdicts: np.ndarray  # (blocks,) codes
    captured: np.ndarray  # (blocks,) codes
    levels: np.ndarray  # (blocks, width)


def _judge_windows(
    values: np.ndarray,
    ids: np.ndarray,
    blocks: np.ndarray,
    gaps_ok: np.ndarray,
    tolerance: np.ndarray,
    sigmas: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Judge the window ending at each of `blocks` (the readings `values` in grid blocks `ids`).

    A window's first half is its first two blocks, its second half the last two. `gaps_ok`
    per block: no interval beyond max_gap in the window. Returns the verdict codes waiting for
    a posture and once captured, and the medians of the second halves (see the detector).
    """
    half = BLOCKS_PER_WINDOW // 2
    start = np.searchsorted(ids, blocks - BLOCKS_PER_WINDOW + 1, side='left')
    middle = np.searchsorted(ids, blocks - half + 1, side='left')
    end = np.searchsorted(ids, blocks, side='right')
    known = gaps_ok & (middle > start) & (end > middle)
    verdicts = np.full(len(blocks), UNKNOWN)
    captured = np.full(len(blocks), UNKNOWN)
    levels = np.zeros((len(blocks), values.shape[1]))
    if not known.any():
        return verdicts, captured, levels
    chosen = np.flatnonzero(known)
    start, middle, end = start[chosen], middle[chosen], end[chosen]

    def padded(first: np.ndarray, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        index = first[:, None] + np.arange(int((last - first).max()))[None, :]
        valid = index < last[:, None]
        return values[np.where(valid, index, 0)], valid

    with np.errstate(invalid='ignore', over='ignore'):
        both, both_valid = padded(start, end)
        floor = robust.windows_quantum(both, both_valid)
        spread = robust.windows_spread(both, both_valid, floor)
        first = robust.windows_mean(*padded(start, middle), floor)
        second = robust.windows_mean(*padded(middle, end), floor)
        shift, threshold = robust.windows_level_shift(first, second, sigmas, floor)
        spreading = np.any(spread > tolerance, axis=1)
        moved = np.any(np.abs(second.median - first.median) > tolerance, axis=1)
        verdict = np.where(
            spreading | np.any(shift > tolerance, axis=1),
            MOVING,
            np.where(np.all(shift <= threshold, axis=1), SETTLED, SETTLING),
        )
    verdicts[chosen] = verdict
    captured[chosen] = np.where(spreading | moved, MOVING, SETTLED)
    levels[chosen] = second.median
    return verdicts, captured, levels
