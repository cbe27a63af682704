"""
Bag -> postures: a bag's posture topic, else postures re-detected from its raw inputs.

No rclpy here: the message objects from a bag are decoded by mcap_ros2 and read
through the contract's name-based conversions.

Inputs from a user's own drivers: when the collector recorded an input mapping
(hexacal_msgs_py.inputs, in ``hexacal.collector``), the raw inputs are the
recorded topics (e.g. one /joint_states for all three, an Imu inclinometer)
read by that mapping, through the same contract conversions the collector uses;
a bag without one is read by the contract's topics and joints, as always.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hexacal_msgs_py.inputs import IMU_INCLINOMETER, INPUT_NAMES, InputMapping, InputMappingError
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.names import (
    IMU_TYPE,
    INCLINOMETER_TOPIC,
    JOINT_STATE_TYPE,
    LINK_TOPIC,
    POSTURE_TOPIC,
)
from hexacal_msgs_py.readings import PostureReading
import numpy as np

from .bag_checks import (
    bag_model,
    check_types,
    decoded_joint_state,
    model_of,
    RAW_TOPICS,
    RECORDED_MODEL_KEY,
    topic_key,
)
from .posture_checks import posture_problem
from .redetection import redetect
from ..bag.measuring import MEASURING_METADATA, MeasuringRecord
from ..bag.naming import COLLECTOR_METADATA  # the collector's record: model, detector, mapping
from ..core.errors import InvalidMeasurementError


@dataclass
class BagPostures:
    postures: list[PostureReading]
    source: str  # "posture topic" or "raw streams (re-detected)"
    plan: dict[str, str] = field(default_factory=dict)  # recorded posture plan metadata, if any
    ignored_topics: list[str] = field(default_factory=list)
    invalid_messages: int = 0  # readings of hexacal's inputs that were not valid (skipped)
    # Postures set aside (posture_problem): (index among the bag's postures, reason, description).
    rejected: list[tuple[int, str, str]] = field(default_factory=list)
    # The machine model that recorded the bag: its actuator joint names (else the collector's
    # metadata); None when the bag holds neither.
    model: str | None = None
    # The input mapping the collector recorded (topics and joints of the raw inputs); None: a bag
    # without one, whose raw inputs are the contract's topics and joints.
    mapping: InputMapping | None = None
    # The measuring mode and released actuators the collector recorded (bag.measuring); an empty
    # record (mode None) for a bag without one.
    measuring: MeasuringRecord = field(default_factory=MeasuringRecord)
    # What re-detection noticed in words, e.g. still periods a lagging stream never settled in.
    notes: list[str] = field(default_factory=list)

    @property
    def measuring_mode(self) -> str | None:
        """Return the measuring mode the bag was recorded in, None when it does not say."""
        return self.measuring.mode

    @property
    def released_joints(self) -> list[str] | None:
        """Return each posture's released actuator joint (passive_actuator), else None."""
        if self.measuring_mode != 'passive_actuator':
            return None
        return [self.measuring.released_at(p.stamp_ns) for p in self.postures]


def _screened(
    postures: list[PostureReading], model: str | None = None
) -> tuple[list[PostureReading], list[tuple[int, str, str]]]:
    kept, rejected = [], []
    for index, posture in enumerate(postures):
        problem = posture_problem(posture, model=model)
        if problem is None:
            kept.append(posture)
        else:
            rejected.append((index, *problem))
    return kept, rejected


# Where postures come from: the posture topic if the bag has one, else the raw inputs ("auto");
# only the posture topic; or always re-detected from the raw inputs.
POSTURE_SOURCES = ('auto', 'posture', 'raw')
# The collector's detector settings in its metadata record: re-detection uses them.
_DETECTOR_SETTINGS = (
    'window_s',
    'capture_s',
    'slider_tolerance_m',
    'angle_tolerance_rad',
    'max_gap_s',
    'max_skew_s',
)

CLOCK_OFFSET_SETTINGS = ('inclinometer_clock_offset_s', 'encoder_clock_offset_s')


def postures_from_bag(
    path: Path | str, *, source: str = 'auto', **detector_options
) -> BagPostures:
    """
    Postures of a bag: its posture topic, else re-detected from the raw inputs.

    ``source``: "auto" (the posture topic if there is one, else the raw inputs), "posture"
    (the posture topic only) or "raw" (re-detect even when there is a posture topic).
    Re-detection uses the detector settings the collector recorded (``hexacal.collector``;
    the detector's defaults where none), ``detector_options`` override them (window_s,
    capture_s, slider_tolerance_m, angle_tolerance_rad, max_gap_s, max_skew_s; ``detector``
    'settled', the only one, ``inclinometer_clock_offset_s``/``encoder_clock_offset_s``
    (s; None: estimated, or the collector's when it was told them), see `redetect`).

    The raw inputs are the contract's topics (hexacal/sliders, hexacal/inclinometer,
    hexacal/encoder, any namespace) and joints, or, when the collector recorded an input
    mapping (hexacal_msgs_py.inputs: ``actuator_joints``, ``inclinometer_type``, the topic of
    each input, ...), the recorded topics read by that mapping: e.g. all three from one
    /joint_states with custom joint names, the inclinometer from a sensor_msgs/Imu, with
    signs and offsets applied. The posture topic has the contract's names either way.

    Either machine model: the actuator joints of the posture (or sliders) messages
    tell which (``model``), else the model the collector recorded; a bag mixing the
    joints of two models, or whose joints contradict the model its collector recorded,
    raises InvalidMeasurementError.

    Other topics are ignored; a bag with neither a posture topic nor all three raw
    inputs raises InvalidMeasurementError naming what is missing.  Bag-format
    problems raise the bag layer's BagError subclasses, also an input topic whose
    definition is another message version.  Messages that do not decode or are not
    valid readings are skipped and counted (``invalid_messages``, per reading);
    postures beyond a sensor's range are set aside with the reason (``rejected``).
    """
    from ..bag import open_bag

    if source not in POSTURE_SOURCES:
        raise ValueError(f'source must be one of {", ".join(POSTURE_SOURCES)}, got {source!r}')
    reader = open_bag(path)
    topics: dict[str, str] = {}
    for topic in reader.topics():
        key = topic_key(topic)
        if key in topics and key in (POSTURE_TOPIC, *RAW_TOPICS):
            raise InvalidMeasurementError(
                f'bag {path} holds {key} from several namespaces ({topics[key]}, {topic}): '
                'calibrate one machine at a time'
            )
        topics[key] = topic
    plan: dict[str, str] = {}
    collector: dict[str, str] = {}
    measuring = MeasuringRecord()
    for record in reader.metadata():
        if record.name.startswith('hexacal'):
            plan.update({f'{record.name}.{k}': v for k, v in record.data.items()})
        if record.name == COLLECTOR_METADATA:
            collector.update(record.data)
        if record.name == MEASURING_METADATA:  # rewritten as it changes: the last one holds
            measuring = MeasuringRecord.from_metadata(record.data)
    recorded_model = plan.get(RECORDED_MODEL_KEY) or None
    if recorded_model is not None and recorded_model not in MODELS:
        raise InvalidMeasurementError(
            f'bag {path}: its metadata names an unknown model {recorded_model!r} '
            f'({RECORDED_MODEL_KEY}); hexacal knows {", ".join(MODELS)}'
        )
    try:
        mapping = InputMapping.from_metadata(collector, recorded_model)
    except InputMappingError as error:
        raise InvalidMeasurementError(
            f'bag {path}: the input mapping its collector recorded '
            f'({COLLECTOR_METADATA}) is invalid: {error}'
        ) from None
    raw = _raw_topics(reader.topics(), topics, mapping)
    ours = {topics[POSTURE_TOPIC]} if POSTURE_TOPIC in topics else set()
    ours.update(raw.values())
    link_topic = topics.get(LINK_TOPIC)  # the lvdt's link length, when the machine has one
    if link_topic is not None:
        ours.add(link_topic)
    ignored = sorted(t for t in reader.topics() if t not in ours)
    expected = _expected_types(topics, raw, mapping)
    if link_topic is not None:
        expected[link_topic] = JOINT_STATE_TYPE
    check_types(reader, expected)
    if POSTURE_TOPIC in topics and source != 'raw':
        models: set[str] = set()
        postures, invalid = _valid(
            reader.messages([topics[POSTURE_TOPIC]]), lambda m: _posture(m, models, recorded_model)
        )
        model = bag_model(path, models, recorded_model)
        kept, rejected = _screened(postures, model)
        return BagPostures(
            kept, 'posture topic', plan, ignored, invalid, rejected, model, mapping, measuring
        )
    if source == 'posture':
        raise InvalidMeasurementError(f'bag {path} has no {POSTURE_TOPIC} topic')
    missing = [_input_text(t, mapping) for t in RAW_TOPICS if t not in raw]
    if missing:
        raise InvalidMeasurementError(
            f'bag {path} has no {POSTURE_TOPIC} topic and lacks the raw stream(s) '
            f'{", ".join(missing)} needed to re-detect postures'
            if POSTURE_TOPIC not in topics
            else f'bag {path} lacks the raw stream(s) {", ".join(missing)} needed to re-detect '
            'postures'
        )
    options: dict[str, Any] = {
        name: float(collector[name])
        for name in _DETECTOR_SETTINGS
        if _is_number(collector.get(name))
    }
    if collector.get('estimate_clock_offsets') == 'False':  # offsets the collector was told
        for name in CLOCK_OFFSET_SETTINGS:
            if _is_number(collector.get(name)):
                options[name] = float(collector[name])
    options.update(detector_options)
    models = set()
    if link_topic is not None:
        options['link_topic'] = link_topic
    notes: list[str] = []
    postures, invalid = redetect(
        reader, raw, mapping, models, recorded_model, notes=notes, **options
    )
    model = bag_model(path, models, recorded_model)
    kept, rejected = _screened(postures, model)
    return BagPostures(
        kept,
        'raw streams (re-detected)',
        plan,
        ignored,
        invalid,
        rejected,
        model,
        mapping,
        measuring,
        notes,
    )


def _is_number(text: str | None) -> bool:
    try:
        return text is not None and np.isfinite(float(text))
    except ValueError:
        return False


def _input_text(input_topic: str, mapping: InputMapping | None) -> str:
    recorded = mapping.input_topic(input_topic) if mapping is not None else ''
    if recorded and recorded.lstrip('/') != input_topic:
        return f'{recorded} (the {INPUT_NAMES[input_topic]} input)'
    return '/' + input_topic


def _raw_topics(infos, topics: dict[str, str], mapping: InputMapping | None) -> dict[str, str]:
    """
    Return the bag topic of each raw input that the bag has.

    The recorded mapping's, else the contract's.
    """
    raw: dict[str, str] = {}
    by_name = {name.lstrip('/'): name for name in infos}
    for input_topic in RAW_TOPICS:
        recorded = mapping.input_topic(input_topic) if mapping is not None else ''
        if recorded:
            if recorded.lstrip('/') in by_name:
                raw[input_topic] = by_name[recorded.lstrip('/')]
        elif input_topic in topics:
            raw[input_topic] = topics[input_topic]
    return raw


def _expected_types(
    topics: dict[str, str], raw: dict[str, str], mapping: InputMapping | None
) -> dict[str, str]:
    """Return the message type each of the bag's posture and input topics must have."""
    expected = {topics[POSTURE_TOPIC]: JOINT_STATE_TYPE} if POSTURE_TOPIC in topics else {}
    for input_topic, name in raw.items():
        imu = (
            input_topic == INCLINOMETER_TOPIC
            and mapping is not None
            and mapping.inclinometer_type == IMU_INCLINOMETER
        )
        expected[name] = IMU_TYPE if imu else JOINT_STATE_TYPE
    return expected


def _valid(messages, convert) -> tuple[list, int]:
    """Convert every message that is a valid reading; count (and skip) the others."""
    from hexacal_msgs_py.errors import InvalidReadingError

    from ..bag import BagDecodeError

    converted, invalid, checked = [], 0, set[str]()
    for message in messages:
        try:
            converted.append(convert(decoded_joint_state(message, checked)))
        except (InvalidReadingError, BagDecodeError):
            # NaN, missing joint, mismatched lengths, bytes that are no JointState (the collector
            # records what arrived): not used, counted.
            invalid += 1
    return converted, invalid


def _posture(message, models: set[str], recorded_model: str | None) -> PostureReading:
    from hexacal_msgs_py.conversions import joint_state_to_posture_reading

    return joint_state_to_posture_reading(message, model_of(message, models, recorded_model))
