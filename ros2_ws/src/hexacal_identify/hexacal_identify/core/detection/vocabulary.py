"""
What the posture detector says, in the words every user of it shares (ROS-free).

The streams it reads (`Stream`), why a reading or a period is not used (`RejectReason`,
`UnpairedReason`, `DropReason`), where it is in its capture cycle (`DetectorState`), what it
gives (`DetectedPosture`, `DroppedPeriod`) and the check of its settings. The detector is
core.dwell_detector (the `settled` detector); the collector node, its health summary
(core.collector_health) and the input synchronizer (core.stream_synchronizer) use the same
words. Channels are in `POSTURE_NAMES` order: six actuators (m), alpha, beta, phi (rad).
Stamps are integer ns.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
import math

from hexacal_msgs_py.names import POSTURE_NAMES
from hexacal_msgs_py.readings import PostureReading, PostureScatter
import numpy as np

# The detectors a collector or a re-detection may name: the settled-streams detector only.
DETECTORS = ('settled',)
# The detector that was removed, and the version that removed it: named when it is asked for.
REMOVED_DETECTORS = {'window': '0.2.0'}


def detector_problem(name: object) -> str | None:
    """Return why `name` is no detector (None if it is one), naming `settled`."""
    if name in DETECTORS:
        return None
    if name in REMOVED_DETECTORS:
        return (
            f'detector {name!r} was removed in hexacal {REMOVED_DETECTORS[str(name)]}: '
            "use 'settled' (each stream judged on its own readings, the only detector)"
        )
    return f"detector must be 'settled', got {name!r}"


N_CHANNELS = len(POSTURE_NAMES)


# The values are the keys of the collector's status counters and summaries: StrEnum members
# equal and hash as their strings, and the counters store the plain values (.value) so their
# repr in logs and their JSON stay as before.
class Stream(StrEnum):
    """An input stream of the detector (and of the collector's synchronizer)."""

    SLIDERS = 'sliders'
    INCLINOMETER = 'inclinometer'
    ENCODER = 'encoder'


class RejectReason(StrEnum):
    """Why a reading is not used (synchronizer and detector)."""

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
        spikes rejected), else std / sqrt(n) of the n samples.
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


def check_detector_settings(durations: dict[str, float], tolerances: tuple[float, ...]) -> None:
    """
    Raise ValueError unless every duration (or rate) and every tolerance is > 0 (not NaN).

    The message names the durations in the given order.
    """
    if not all(value > 0 for value in durations.values()):
        *first, last = durations
        raise ValueError(f'{", ".join(first)} and {last} must be > 0')
    if not all(tolerance > 0 for tolerance in tolerances):
        raise ValueError('tolerances must be > 0')
