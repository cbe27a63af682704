"""
What the collector reports about its inputs: counters, stopped streams, status decisions.

Everything not used is counted by stream and reason (`problems`): invalid messages, messages
DDS reports lost, readings whose stamps repeat or go back, slider readings without a
partner (the synchronizer's pairing; the detector itself does not pair), time the detector
judged without a stream stamped too far behind, samples and periods the detector rejects or
drops, the streams that stopped and a recording error. The status is published when that
changes (`decide_status`), with the fields `status_values` gives.

What the collector node decides besides: the detector its parameters describe
(`dwell_detector`, `detector_settings`), the lvdt's link lengths it takes as a detector stream
(`LinkReadings`), what it says when streams stop or resume and when the data ends
(`stopped_lines`, `end_of_data`), and the lines it logs (`start_lines`, `posture_line`,
`turn_change_line`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Any

from hexacal_msgs_py.models import ActuatorQuantities, LINEAR_ACTUATOR
from hexacal_msgs_py.names import DEVICE_TURN_JOINT, LINK_LENGTH_JOINT
from hexacal_msgs_py.readings import NS_PER_S, PostureReading

from ..detection.dwell_detector import DwellDetector, LINK_STREAM
from ..detection.stream_synchronizer import StreamSynchronizer
from ..detection.turn_history import TurnHistory
from ..detection.vocabulary import DetectedPosture, DropReason, Stream


class Outcome(StrEnum):
    """The collector's state as its status's `outcome` value says it."""

    RECORDING = 'recording'
    NOT_RECORDING = 'not-recording'
    RECORDING_STOPPED = 'recording-stopped'


class Level(StrEnum):
    """The diagnostic level of a status."""

    OK = 'OK'
    WARN = 'WARN'
    ERROR = 'ERROR'


class ProblemKey(StrEnum):
    """The problem keys (or key prefixes, before a '.') of the status values."""

    INVALID = 'invalid'
    LOST = 'lost'
    REJECTED = 'rejected'
    UNPAIRED = 'unpaired'
    BEHIND = 'behind'  # settled detector: blocks judged without a stream stamped too far behind
    UNSETTLED = 'unsettled'  # settled detector: still periods a stream never settled in
    REJECTED_SAMPLES = 'rejected.samples'
    DROPPED = 'dropped'
    STREAMS_STOPPED = 'streams_stopped'
    RECORDING_ERROR = 'recording_error'


# Logged where they happen, so not logged again as 'not used' counters.
_LOGGED_WHERE_THEY_HAPPEN = (
    f'{ProblemKey.INVALID}.',
    str(ProblemKey.STREAMS_STOPPED),
    str(ProblemKey.RECORDING_ERROR),
    f'{ProblemKey.DROPPED}.{DropReason.STREAM_STOPPED}',
)


@dataclass
class InputCounters:
    """Messages received, invalid and lost per input, and when each input last received."""

    topics: tuple[str, ...]  # the contract input topics
    received: dict[str, int] = field(default_factory=dict)
    invalid: dict[str, int] = field(default_factory=dict)
    lost: dict[str, int] = field(default_factory=dict)  # by subscription key, from DDS
    last_receipt_ns: dict[str, int] = field(default_factory=dict)  # monotonic receipt time

    def __post_init__(self) -> None:
        self.received = {topic: 0 for topic in self.topics}

    def count_received(self, topics: Iterable[str], now_ns: int) -> None:
        """Count one message received (monotonic `now_ns`) for each of these inputs."""
        for topic in topics:
            self.received[topic] += 1
            self.last_receipt_ns[topic] = now_ns

    def count_invalid(self, topic: str) -> int:
        """Count an invalid message of `topic`; return how many so far."""
        self.invalid[topic] = self.invalid.get(topic, 0) + 1
        return self.invalid[topic]

    def all_stopped(self, now_ns: int, stopped_after_s: float) -> bool:
        """Return True if every input received and then went silent for `stopped_after_s`."""
        return all(
            topic in self.last_receipt_ns
            and now_ns - self.last_receipt_ns[topic] > stopped_after_s * NS_PER_S
            for topic in self.topics
        )

    def stopped(
        self, now_ns: int, stopped_after_s: float, topic_names: Mapping[str, str]
    ) -> tuple[str, ...]:
        """
        Return the topic names of the inputs silent for longer than `stopped_after_s`.

        Receipt time, not stamps (a dead driver sends nothing); an input that never received
        has not stopped. Inputs remapped to one topic stop together: it is named once.
        """
        return tuple(
            dict.fromkeys(
                topic_names[topic]
                for topic in self.topics
                if topic in self.last_receipt_ns
                and now_ns - self.last_receipt_ns[topic] > stopped_after_s * NS_PER_S
            )
        )


def problems(
    counters: InputCounters,
    synchronizer: StreamSynchronizer,
    detector: DwellDetector,
    stopped_streams: tuple[str, ...],
    recording_error: str | None,
) -> dict[str, object]:
    """Return the counters of everything not used, by stream and reason (the status's)."""
    found: dict[str, object] = {}
    for topic, count in sorted(counters.invalid.items()):
        found[f'{ProblemKey.INVALID}.{topic}'] = count
    for topic, count in sorted(counters.lost.items()):
        if count:
            found[f'{ProblemKey.LOST}.{topic}'] = count
    for stream, reasons in synchronizer.rejected.items():
        for reason, count in sorted(reasons.items()):
            found[f'{ProblemKey.REJECTED}.{stream}.{reason}'] = count
    for reason, count in sorted(synchronizer.unpaired.items()):
        found[f'{ProblemKey.UNPAIRED}.{reason}'] = count
    for stream, count in sorted(getattr(detector, 'behind', {}).items()):
        found[f'{ProblemKey.BEHIND}.{stream}'] = count
    for stream, count in sorted(getattr(detector, 'unsettled', {}).items()):
        found[f'{ProblemKey.UNSETTLED}.{stream}'] = count
    for reason, count in sorted(detector.rejected.items()):
        found[f'{ProblemKey.REJECTED_SAMPLES}.{reason}'] = count
    for reason, count in sorted(detector.dropped.items()):
        found[f'{ProblemKey.DROPPED}.{reason}'] = count
    if stopped_streams:
        found[ProblemKey.STREAMS_STOPPED.value] = ', '.join(stopped_streams)
    if recording_error:
        found[ProblemKey.RECORDING_ERROR.value] = recording_error
    return found


@dataclass(frozen=True)
class StatusDecision:
    """A status to publish: its level, outcome and message, and the counters to log."""

    level: Level
    outcome: Outcome
    message: str
    changed: tuple[str, ...]  # problem keys new or changed since the last status
    to_log: tuple[str, ...]  # changed counters not logged where they happened


def decide_status(
    found: dict[str, object],
    previous: dict[str, object] | None,
    recording_error: str | None,
    recording: bool,
    statistics_changed: bool = False,
) -> StatusDecision | None:
    """
    Return the status to publish for these problems, None if they did not change.

    A change of the streams' statistics alone (`statistics_changed`) publishes too, but is no
    problem (level OK unless a problem is new).
    """
    if found == previous and not statistics_changed:
        return None
    before = previous or {}
    changed = tuple(key for key, value in found.items() if before.get(key) != value)
    if recording_error:
        level, outcome = Level.ERROR, Outcome.RECORDING_STOPPED
        message = f'recording stopped: {recording_error}'
    else:
        level = Level.WARN if changed else Level.OK  # a new or grown problem; OK once all clear
        outcome = Outcome.RECORDING if recording else Outcome.NOT_RECORDING
        message = (
            '; '.join(f'{key}: {found[key]}' for key in changed) if changed else 'no new problems'
        )
    to_log = tuple(key for key in changed if not key.startswith(_LOGGED_WHERE_THEY_HAPPEN))
    return StatusDecision(level, outcome, message, changed, to_log)


def silent_streams(
    synchronizer: StreamSynchronizer, now_ns: int, topic_names: Mapping[str, str]
) -> list[str]:
    """Return the topic names of the streams whose stamps went stale (each topic once)."""
    status = synchronizer.status(now_ns)
    return list(
        dict.fromkeys(
            topic_names[stream]
            for stream, state in status.items()
            if state.last_stamp_ns is not None and state.stale
        )
    )


def summary(
    postures_published: int,
    counters: InputCounters,
    synchronizer: StreamSynchronizer,
    detector: DwellDetector,
) -> str:
    """Return the collector's closing summary line."""
    rejected = {stream: reasons for stream, reasons in synchronizer.rejected.items() if reasons}
    return (
        f'{postures_published} postures published; messages received '
        f'{counters.received}; invalid messages {counters.invalid or 0}; '
        f'lost {counters.lost or 0}; stamps rejected {rejected or 0}; '
        f'periods dropped {detector.dropped or 0}; '
        f'unpaired samples {synchronizer.unpaired or 0}'
    )


# Resolution of the stream statistics in the status: finer changes do not publish a new one.
STATISTICS_DIGITS = {'rate_hz': 1, 'largest_gap_s': 3, 'clock_offset_s': 4}


def stream_statistics(
    detector: DwellDetector, topic_names: Mapping[str, str]
) -> dict[str, object]:
    """
    Return per stream its rate, gaps, clock offset and spikes rejected (the status's values).

    Keys `stream.<stream>.rate_hz` (Hz), `.gaps` (intervals between readings longer than
    max_gap_s), `.largest_gap_s` (s, the longest of them, 0 if none), `.clock_offset_s` (its
    stamps minus the actuators', s: estimated or given) and `.spikes_rejected` (readings left
    out of posture means); `stream.<stream>.topic` names its topic.
    """
    values: dict[str, object] = {}
    offsets = detector.offsets_s
    for stream, lane in detector.lanes.items():
        health = lane.health
        key = f'stream.{stream}'
        values[f'{key}.topic'] = topic_names.get(stream, '')
        values[f'{key}.rate_hz'] = round(health.rate_hz, STATISTICS_DIGITS['rate_hz'])
        values[f'{key}.gaps'] = health.gaps
        values[f'{key}.largest_gap_s'] = round(
            health.largest_gap_ns / NS_PER_S, STATISTICS_DIGITS['largest_gap_s']
        )
        values[f'{key}.clock_offset_s'] = round(
            offsets[stream], STATISTICS_DIGITS['clock_offset_s']
        )
        values[f'{key}.spikes_rejected'] = health.spikes_rejected
    return values


def dwell_detector(value: Mapping[str, Any], settings: Mapping[str, Any]) -> DwellDetector:
    """Return the settled-streams detector of the collector's parameters."""
    offsets: dict[str, float] = {
        Stream.INCLINOMETER: value['inclinometer_clock_offset_s'],
        Stream.ENCODER: value['encoder_clock_offset_s'],
    }
    return DwellDetector(
        window_s=settings['window_s'],
        slider_tolerance_m=settings['slider_tolerance_m'],
        angle_tolerance_rad=settings['angle_tolerance_rad'],
        capture_s=settings['capture_s'],
        max_gap_s=settings['max_gap_s'],
        clock_offsets_s=offsets,
        estimate_offsets=tuple(offsets) if value['estimate_clock_offsets'] else (),
    )


def detector_settings(
    value: Mapping[str, Any], detector: Iterable[str], dwell: Iterable[str]
) -> tuple[dict[str, str], dict[str, Any]]:
    """
    Return the detector's settings as the bag records them, and the detector's own.

    `detector`, `dwell`: the names of the detector's and the dwell's parameters; max_skew_s
    is the synchronizer's, not the detector's.
    """
    settings = {name: value[name] for name in detector}
    recorded = {name: repr(setting) for name, setting in settings.items()}
    recorded.update({name: repr(value[name]) for name in dwell})
    del settings['max_skew_s']
    return recorded, settings


class LinkReadings:
    """The lvdt's link lengths (hexacal/link) since the detector last took them."""

    def __init__(self) -> None:
        """Start with none."""
        self._stamps: list[int] = []
        self._values: list[float] = []

    def add(self, names: Sequence[str], positions: Sequence[float], stamp_ns: int) -> str | None:
        """Keep the link length of a JointState's fields; return why not (None: kept)."""
        try:
            value = float(positions[list(names).index(LINK_LENGTH_JOINT)])
        except (ValueError, IndexError, TypeError) as error:
            return f'no {LINK_LENGTH_JOINT} position ({error})'
        if not (value > 0.0 and value < float('inf')):
            return f'{LINK_LENGTH_JOINT} {value!r} m is not a length'
        self._stamps.append(stamp_ns)
        self._values.append(value)
        return None

    def take(self) -> dict:
        """Return the readings since the last call, as a detector stream (or nothing)."""
        if not self._stamps:
            return {}
        stamps, values = self._stamps, self._values
        self._stamps, self._values = [], []
        return {LINK_STREAM: (stamps, [[value] for value in values])}


def stopped_lines(
    previous: tuple[str, ...], stopped: tuple[str, ...], stopped_s: float
) -> list[tuple[Level, str]]:
    """Return what to log when the stopped streams change (none when they do not)."""
    if stopped == previous:
        return []
    if stopped:
        return [(
            Level.WARN,
            f'stream(s) stopped: no message on {", ".join(stopped)} for {stopped_s:g} s',
        )]
    return [(Level.OK, f'stream(s) resumed: {", ".join(previous)}')]


def dropped_line(detector: DwellDetector, stopped: Sequence[str]) -> str | None:
    """Drop a posture the stopped streams leave half-captured; return the line saying so."""
    dropped = detector.abort(DropReason.STREAM_STOPPED)
    if dropped is None:
        return None
    return (
        f'dropped a partial posture ({dropped.sample_count} samples over '
        f'{(dropped.last_stamp_ns - dropped.first_stamp_ns) / NS_PER_S:.2f} s, '
        f'never published): {", ".join(stopped)} stopped'
    )


def end_of_data(
    counters: InputCounters, detector: DwellDetector, now_ns: int, stopped_s: float
) -> list[DetectedPosture]:
    """
    Return the postures the last readings complete once every stream has stopped.

    Every stream stopped: the data ended, so a capture the last readings complete is a
    posture (its last block needs no later reading).
    """
    if not counters.all_stopped(now_ns, stopped_s):
        return []
    return list(detector.flush())


def status_values(
    outcome: str,
    postures_published: int,
    bag: str,
    counters: InputCounters,
    problems: Mapping[str, object],
    streams: Mapping[str, object],
) -> dict[str, object]:
    """Return the fields of the collector's status."""
    return {
        'outcome': outcome,
        'postures_published': postures_published,
        'bag': bag,
        **{f'received.{topic}': count for topic, count in counters.received.items()},
        **problems,
        **streams,
    }


def start_lines(
    posture_topic: str,
    value: Mapping[str, Any],
    model: str,
    actuator_names: Sequence[str],
    inputs: str,
    device_turn: float,
) -> list[str]:
    """Return what the collector logs at the start."""
    lines = [
        f'collecting postures on {posture_topic} (window {value["window_s"]:g} s, capture '
        f'{value["capture_s"]:g} s); model {model}, actuator joints '
        f'{actuator_names[0]}..{actuator_names[-1]}',
        f'inputs: {inputs}',
    ]
    if device_turn != 0.0:
        lines.append(
            f'device_turn {device_turn:.6g} rad for postures whose inclinometer message has no '
            f'{DEVICE_TURN_JOINT} joint'
        )
    return lines


def turn_change_line(previous: float, turn: float) -> str | None:
    """Return the line on a new device_turn setting (None: unchanged)."""
    if turn == previous:
        return None
    return (
        f'device_turn {previous:.6g} -> {turn:.6g} rad: postures from now on whose '
        f'inclinometer message has no {DEVICE_TURN_JOINT} joint carry it'
    )


def posture_line(
    count: int,
    posture: DetectedPosture,
    turn: float,
    quantities: ActuatorQuantities = LINEAR_ACTUATOR,
) -> str:
    """
    Return the line on the `count`-th posture published (its samples, spread, turn).

    The actuators' spread is in um, or urad for actuators that turn (`quantities`).
    """
    spread = quantities.shown_small(max(posture.std[:6]))
    spread_urad = max(posture.std[6:]) * 1e6
    turned = f', device turn {turn:.6g} rad' if turn != 0.0 else ''
    return (
        f'posture {count}: {posture.sample_count} samples, std <= {spread} '
        f'(actuators) / {spread_urad:.1f} urad (angles){turned}'
    )


def plan_record(names: Sequence[str], values: Iterable[object]) -> dict[str, str]:
    """Return the driver's plan parameters as the bag records them (those it has)."""
    return {name: str(value) for name, value in zip(names, values) if value is not None}


def turned_reading(
    posture: DetectedPosture,
    detector: DwellDetector,
    turns: TurnHistory,
    max_skew_ns: int,
    device_turn: float,
) -> tuple[PostureReading, float]:
    """
    Return the posture's reading with its device turn, and the turn.

    The turn of the inclinometer messages paired with its last sample, else the setting
    `device_turn`. The posture's stamp is the actuators'; the inclinometer messages are in
    their own clock (the detector's offset).
    """
    offset_ns = int(detector.offsets_s[Stream.INCLINOMETER] * NS_PER_S)
    turn = turns.turn_at(posture.reading.stamp_ns + offset_ns, max_skew_ns, device_turn)
    reading = posture.reading if turn == 0.0 else replace(posture.reading, device_turn=turn)
    return reading, turn
