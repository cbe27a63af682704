"""
Postures re-detected from a bag's raw input streams by the settled detector.

The raw inputs (sliders, inclinometer, encoder, and the lvdt's link length where recorded)
are read through the contract's conversions (or at once, for the messages laid out like one
they read: hexacal_msgs_py.cdr.JointStateReader.read_many) and handed to core.detection's dwell
detector; each posture gets the device turn of the inclinometer message nearest it.
"""

from __future__ import annotations

from dataclasses import replace

from hexacal_msgs_py.inputs import IMU_INCLINOMETER, InputMapping
from hexacal_msgs_py.names import (
    ENCODER_TOPIC,
    INCLINOMETER_TOPIC,
    LINK_LENGTH_JOINT,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.readings import PostureReading
import numpy as np

from .bag_checks import decoded_imu, decoded_joint_state, model_of, RAW_TOPICS
from ..core.detection.vocabulary import detector_problem


def redetect(
    reader,
    topics: dict[str, str],
    mapping: InputMapping | None,
    models: set[str],
    recorded_model: str | None,
    max_skew_s: float | None = None,
    detector: str = 'settled',
    inclinometer_clock_offset_s: float | None = None,
    encoder_clock_offset_s: float | None = None,
    link_topic: str | None = None,
    notes: list[str] | None = None,
    **detector_options,
) -> tuple[list[PostureReading], int]:
    """
    Re-detect the postures of the raw inputs (`topics`: input -> bag topic), read by `mapping`.

    `notes` receives what the settled detector noticed in words (unsettled_notes).

    Inputs that share a topic (one /joint_states) are read from each of its messages once;
    a reading that is not valid counts once in the returned number of invalid readings.
    ``detector``: 'settled' (core.dwell_detector, each stream judged on its own readings,
    postures with their scatter; a clock offset given is used, None: estimated), the only one
    (ValueError naming it for another, e.g. the removed 'window'). ``max_skew_s``: the
    collector's pairing setting, recorded with the others; the detector does not pair.
    ``link_topic``: the recorded lvdt link length stream (hexacal/link), one more stream of the
    detector (the postures get their link_length).
    """
    problem = detector_problem(detector)
    if problem is not None:
        raise ValueError(problem)
    from hexacal_msgs_py.conversions import (
        imu_to_inclinometer_reading,
        joint_state_to_actuator_reading,
        joint_state_to_encoder_reading,
        joint_state_to_inclinometer_reading,
    )
    from ..core.detection.dwell_detector import detect_dwell_postures, LINK_STREAM

    imu = mapping is not None and mapping.inclinometer_type == IMU_INCLINOMETER
    convert = {
        SLIDERS_TOPIC: lambda m: (
            joint_state_to_actuator_reading(
                m, model_of(m, models, recorded_model), mapping
            ).actuator_positions
        ),
        INCLINOMETER_TOPIC: lambda m: (lambda r: (r.alpha, r.beta, r.device_turn))(
            imu_to_inclinometer_reading(m, mapping)
            if imu
            else joint_state_to_inclinometer_reading(m, mapping)
        ),
        ENCODER_TOPIC: lambda m: (joint_state_to_encoder_reading(m, mapping).phi,),
    }
    inputs_of: dict[str, list[str]] = {}
    for input_topic in RAW_TOPICS:
        inputs_of.setdefault(topics[input_topic], []).append(input_topic)
    imu_topic = topics[INCLINOMETER_TOPIC] if imu else None
    by_topic: dict[str, list] = {topic: [] for topic in inputs_of}
    for message in reader.messages(list(inputs_of)):
        by_topic[message.topic].append(message)
    invalid = 0
    streams: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for topic, messages in by_topic.items():
        # Without a mapping, messages laid out like one the conversions read are read at once.
        wanted = None if mapping is not None or topic == imu_topic else _wanted_joints(
            models, recorded_model
        )
        topic_streams, bad = _read_topic(
            messages, inputs_of[topic], convert, topic == imu_topic, wanted
        )
        streams.update(topic_streams)
        invalid += bad
    arrays = [streams[t] for t in RAW_TOPICS]
    # The inclinometer's device_turn joint (the mounting) rides beside alpha, beta: not a channel
    # to synchronise.
    inclinometer_stamps, inclinometer = arrays[1]
    inclinometer = inclinometer.reshape(-1, 3)
    given = {'inclinometer': inclinometer_clock_offset_s, 'encoder': encoder_clock_offset_s}
    streams_in = {
        'sliders': arrays[0],
        'inclinometer': (inclinometer_stamps, inclinometer[:, :2]),
        'encoder': arrays[2],
    }
    if link_topic is not None:
        link, bad = _link_stream(reader, link_topic)
        invalid += bad
        if len(link[0]):
            streams_in[LINK_STREAM] = link
    found, dwell = detect_dwell_postures(
        streams_in,
        clock_offsets_s={k: v for k, v in given.items() if v is not None},
        estimate_offsets=tuple(k for k, v in given.items() if v is None),
        **detector_options,
    )
    if notes is not None:
        notes.extend(unsettled_notes(dwell.unsettled))
    # The turn of the inclinometer message at the posture's time, in the inclinometer's clock.
    shift = int(round(dwell.offsets_s['inclinometer'] * 1_000_000_000))
    readings = [d.reading for d in found]
    return _with_turns(readings, inclinometer_stamps - shift, inclinometer[:, 2]), invalid


MAX_LAYOUTS = 64  # layouts read at once per topic; a stream that changes it more goes one by one


def _wanted_joints(models: set[str], recorded_model: str | None):
    """Return wanted(key, decoded): the joints the conversion of input `key` reads, in order."""
    from hexacal_msgs_py.models import MODELS as LAYOUTS
    from hexacal_msgs_py.names import ENCODER_NAMES, INCLINOMETER_NAMES

    def wanted(key: str, decoded) -> tuple[str, ...]:
        if key == SLIDERS_TOPIC:
            return tuple(LAYOUTS[model_of(decoded, models, recorded_model)].actuator_names)
        return tuple(INCLINOMETER_NAMES if key == INCLINOMETER_TOPIC else ENCODER_NAMES)

    return wanted


def _read_topic(messages: list, keys: list[str], convert, imu: bool, wanted) -> tuple[
    dict[str, tuple[np.ndarray, np.ndarray]], int
]:
    """
    Return each input's (stamps ns, values) of one topic's messages and the invalid count.

    Each message is read by the contract's conversions; with `wanted` (no input mapping, not an
    Imu), the later messages laid out like one that every input read are read at once
    (JointStateReader.read_many: the same values) and not again.
    """
    from hexacal_msgs_py.errors import InvalidReadingError

    from ..bag import BagDecodeError

    parts: dict[str, list] = {key: [] for key in keys}  # (rows, stamps, values) per input
    pending = np.ones(len(messages), dtype=bool)
    invalid, layouts, checked = 0, 0, set[str]()
    for row in range(len(messages)):
        if not pending[row]:
            continue
        message = messages[row]
        try:
            decoded = (
                decoded_imu(message, checked) if imu else decoded_joint_state(message, checked)
            )
        except BagDecodeError:
            invalid += len(keys)  # bytes that are no message: not used, counted
            continue
        read = 0
        for key in keys:
            try:
                value = convert[key](decoded)
            except InvalidReadingError:
                invalid += 1  # a bad reading is skipped; the detector reads around the gap
                continue
            stamp = decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec
            parts[key].append(([row], [stamp], [value]))
            read += 1
        if wanted is not None and read == len(keys) and layouts < MAX_LAYOUTS:
            layouts += 1
            later = np.flatnonzero(pending[row + 1:]) + row + 1
            for key, block in _read_at_once(message, decoded, keys, wanted, messages, later):
                parts[key].append(block)
                pending[block[0]] = False
    return {key: _in_order(parts[key]) for key in keys}, invalid


def _read_at_once(message, decoded, keys, wanted, messages, rows: np.ndarray) -> list:
    """Return (key, (rows, stamps, values)) of the `rows` every input's reader reads at once."""
    import struct

    from hexacal_msgs_py.cdr import JointStateReader

    try:
        readers = {
            key: JointStateReader(message.data_bytes, decoded, wanted(key, decoded))
            for key in keys
        }
    except (KeyError, ValueError, struct.error):
        return []  # not a layout read in place: these messages go one by one
    data = [messages[i].data_bytes for i in rows]
    blocks = {key: reader.read_many(data) for key, reader in readers.items()}
    common = blocks[keys[0]].rows
    for block in blocks.values():
        common = np.intersect1d(common, block.rows)  # a message is read by all inputs or none
    found = []
    for key, block in blocks.items():
        kept = np.isin(block.rows, common)
        values = block.values[kept]
        if key == INCLINOMETER_TOPIC:
            turns = np.zeros(len(values)) if block.turns is None else block.turns[kept]
            values = np.column_stack([values, turns])
        found.append((key, (rows[common], block.stamps_ns[kept], values)))
    return found


def _in_order(parts: list) -> tuple[np.ndarray, np.ndarray]:
    """Return the (stamps, values) of `parts` ((rows, stamps, values) each) in message order."""
    if not parts:
        return np.array([], dtype=np.int64), np.array([], dtype=float)
    rows = np.concatenate([np.asarray(p[0], dtype=np.int64) for p in parts])
    stamps = np.concatenate([np.asarray(p[1], dtype=np.int64) for p in parts])
    values = np.concatenate([np.asarray(p[2], dtype=float).reshape(len(p[0]), -1) for p in parts])
    order = np.argsort(rows, kind='stable')
    return stamps[order], values[order]


def _link_stream(reader, topic: str) -> tuple[tuple[np.ndarray, np.ndarray], int]:
    """Return the recorded link lengths ((stamps ns, values (N, 1) m)) and the invalid count."""
    from ..bag import BagDecodeError

    stamps: list[int] = []
    values: list[float] = []
    invalid, checked = 0, set[str]()
    for message in reader.messages([topic]):
        try:
            decoded = decoded_joint_state(message, checked)
            names = list(decoded.name)
            value = float(decoded.position[names.index(LINK_LENGTH_JOINT)])
        except (BagDecodeError, ValueError, IndexError):
            invalid += 1  # not a message, or without the link_length joint: not used, counted
            continue
        if not np.isfinite(value) or value <= 0.0:
            invalid += 1
            continue
        stamps.append(decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec)
        values.append(value)
    arrays = (np.array(stamps, dtype=np.int64), np.array(values, dtype=float).reshape(-1, 1))
    return arrays, invalid


def unsettled_notes(unsettled: dict[str, int]) -> list[str]:
    """
    Say in words which still periods gave no posture because a stream never settled in them.

    `unsettled` is the settled detector's count per stream (DwellDetector.unsettled).
    """
    return [
        f'{count} still period(s) ended before the {stream} readings settled, so no posture was '
        'taken there (readings still creeping towards their level, e.g. an inclinometer lagging '
        'through its own filter for longer than the machine stands still): hold each posture '
        'longer'
        for stream, count in sorted(unsettled.items())
        if count
    ]


def _with_turns(
    readings: list[PostureReading], stamps: np.ndarray, turns: np.ndarray
) -> list[PostureReading]:
    """
    Return each reading with the device turn of the nearest inclinometer message.

    Each reading with the device turn of the inclinometer message nearest its stamp (the mounting
    it was in).
    """
    if not len(turns) or not np.any(turns):
        return readings
    order = np.argsort(stamps, kind='stable')
    stamps, turns = stamps[order], turns[order]
    out = []
    for reading in readings:
        index = int(np.clip(np.searchsorted(stamps, reading.stamp_ns), 0, len(stamps) - 1))
        around = np.arange(max(index - 1, 0), index + 1)
        nearest = around[np.argmin(np.abs(stamps[around] - reading.stamp_ns))]
        out.append(
            replace(reading, device_turn=float(turns[nearest])) if turns[nearest] else reading
        )
    return out
