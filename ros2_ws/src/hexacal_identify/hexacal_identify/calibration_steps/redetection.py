"""
Postures re-detected from a bag's raw input streams by the settled detector.

The raw inputs (sliders, inclinometer, encoder, and the lvdt's link length where recorded)
are read through the contract's conversions (or in place, for messages whose joint names
repeat) and handed to core.detection's dwell detector; each posture gets the device turn of
the inclinometer message nearest it.
"""

from __future__ import annotations

from dataclasses import replace
from math import isfinite as _isfinite

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
    from hexacal_msgs_py.errors import InvalidReadingError

    from ..bag import BagDecodeError
    from ..core.detection.dwell_detector import detect_dwell_postures, LINK_STREAM

    imu = mapping is not None and mapping.inclinometer_type == IMU_INCLINOMETER
    streams: dict[str, tuple[list[int], list]] = {t: ([], []) for t in RAW_TOPICS}
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
    # Without a mapping, the joints' places are learnt from the first message of each name list
    # the full conversion reads: the messages after it with that name list are read in place.
    known = _KnownJoints() if mapping is None else None
    inputs_of: dict[str, list[str]] = {}
    for input_topic in RAW_TOPICS:
        inputs_of.setdefault(topics[input_topic], []).append(input_topic)
    imu_topic = topics[INCLINOMETER_TOPIC] if imu else None
    invalid, checked = 0, set[str]()
    for message in reader.messages(list(inputs_of)):
        inputs = inputs_of[message.topic]
        try:
            decoded = (
                decoded_imu(message, checked)
                if message.topic == imu_topic
                else decoded_joint_state(message, checked)
            )
        except BagDecodeError:
            invalid += len(inputs)  # bytes that are no message: not used, counted
            continue
        stamp = None
        for key in inputs:
            value = None if known is None or imu else known.values(key, decoded)
            if value is None:
                try:
                    value = convert[key](decoded)
                except InvalidReadingError:
                    invalid += 1  # a bad reading is skipped; the synchroniser pairs around the gap
                    continue
                if known is not None and not imu:
                    known.learn(key, decoded, models)
            if stamp is None:
                stamp = decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec
            stamps, values = streams[key]
            stamps.append(stamp)
            values.append(value)
    arrays = [
        (np.array(streams[t][0], dtype=np.int64), np.array(streams[t][1], dtype=float))
        for t in RAW_TOPICS
    ]
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


class _KnownJoints:
    """
    Read the raw inputs' joints in place from messages whose name list was converted before.

    The same values as the contract's conversions (hexacal_msgs_py.conversions, no input
    mapping) for a message whose joint names equal those of one they converted: the positions at
    the same places, finite (and a device turn within its range), else None and the conversion
    decides (and names the problem).
    """

    def __init__(self) -> None:
        from hexacal_msgs_py.names import MAX_DEVICE_TURN

        self._max_turn = MAX_DEVICE_TURN
        self._places: dict[str, tuple[list[str], tuple[int, ...], int | None]] = {}

    def learn(self, key: str, decoded, models: set[str]) -> None:
        from hexacal_msgs_py.models import MODELS as LAYOUTS
        from hexacal_msgs_py.names import DEVICE_TURN_JOINT, ENCODER_NAMES, INCLINOMETER_NAMES

        names = list(decoded.name)
        if key == SLIDERS_TOPIC:
            carried = [m for m in models if all(n in names for n in LAYOUTS[m].actuator_names)]
            if len(carried) != 1:
                return
            joints = LAYOUTS[carried[0]].actuator_names
        else:
            joints = INCLINOMETER_NAMES if key == INCLINOMETER_TOPIC else ENCODER_NAMES
        turn = None
        if key == INCLINOMETER_TOPIC and DEVICE_TURN_JOINT in names:
            turn = names.index(DEVICE_TURN_JOINT)
        self._places[key] = (names, tuple(names.index(n) for n in joints), turn)

    def values(self, key: str, decoded) -> tuple[float, ...] | None:
        places = self._places.get(key)
        if places is None:
            return None
        names, indexes, turn = places
        position = decoded.position
        if len(position) != len(names) or decoded.name != names:
            return None
        values = tuple([float(position[i]) for i in indexes])
        if not all(map(_isfinite, values)):
            return None
        if key != INCLINOMETER_TOPIC:
            return values
        device_turn = 0.0 if turn is None else float(position[turn])
        if not abs(device_turn) <= self._max_turn:
            return None
        return (*values, device_turn)


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
