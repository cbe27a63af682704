"""
The collector's inputs: one subscribed topic's CDR messages to each input's reading.

An input topic carries one input (hexacal/sliders, hexacal/inclinometer, hexacal/encoder,
each remappable) or several (all three remapped to /joint_states share one subscription:
each message is recorded once and every reading is taken from it once). A message is read
in place (hexacal_msgs_py.cdr) once a reader was learned from a fully valid message, else
decoded by rclpy and checked by the contract, which names every problem.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
import heapq
import struct
from typing import Any

from geometry_msgs.msg import PoseStamped
from hexacal_msgs_py.cdr import ImuReader, JointStateReader
from hexacal_msgs_py.conversions import (
    actuator_model,
    imu_to_inclinometer_reading,
    joint_state_to_actuator_reading,
    joint_state_to_encoder_reading,
    joint_state_to_inclinometer_reading,
)
from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.inputs import (
    DEFAULT_OFFSETS_RAD,
    DEFAULT_SIGNS,
    IMU_INCLINOMETER,
    InputMapping,
)
from hexacal_msgs_py.names import (
    DEVICE_TURN_JOINT,
    ENCODER_TOPIC,
    IMU_TYPE,
    INCLINOMETER_TOPIC,
    JOINT_STATE_TYPE,
    MACHINE_MARKERS_TOPIC,
    MARKER_ARRAY_TYPE,
    PLATFORM_POSE_TOPIC,
    POSE_STAMPED_TYPE,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.qos import MARKERS_QOS, POSE_QOS
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import MarkerArray

from ..bag.qos_yaml import qos_profiles_yaml
from ..core.detection.stream_synchronizer import StreamSynchronizer
from ..core.detection.turn_history import TurnHistory
from ..core.detection.vocabulary import Stream

RAW_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)
STREAM_OF_TOPIC = {
    SLIDERS_TOPIC: Stream.SLIDERS,
    INCLINOMETER_TOPIC: Stream.INCLINOMETER,
    ENCODER_TOPIC: Stream.ENCODER,
}
# Recorded as received when published (the kinematics node), not used by the calibration:
# (topic, message class, type name, the publishers' QoS).
RECORDED_ONLY_TOPICS = (
    (PLATFORM_POSE_TOPIC, PoseStamped, POSE_STAMPED_TYPE, POSE_QOS),
    (MACHINE_MARKERS_TOPIC, MarkerArray, MARKER_ARRAY_TYPE, MARKERS_QOS),
)
Readings = tuple[int, list[tuple[str, tuple[float, ...]]]]  # stamp, [(input, values)]


class InputSource:
    """One subscribed topic and the inputs read from it (several when remapped to one)."""

    def __init__(
        self,
        name: str,
        inputs: tuple[str, ...],
        message_type: type,
        type_name: str,
        qos: Any,
        mapping: InputMapping,
    ) -> None:
        self.name = name  # resolved topic name, as recorded
        self.inputs = inputs  # contract input topics, in RAW_TOPICS order
        self.message_type = message_type
        self.type_name = type_name
        self.qos = qos  # the publishers' QoS, recorded in the bag (replay offers it again)
        self.qos_yaml = qos_profiles_yaml(qos)
        self.polled: Any = None  # its PolledSubscription
        self.fast: JointStateReader | ImuReader | None = None
        self.key = '+'.join(inputs)  # the loss counter's name: lost.<inputs>
        self.has_inclinometer = INCLINOMETER_TOPIC in inputs  # may carry the device turn
        self.stream: Stream | None = None  # set when the in-place values are the one reading
        # Where each input's values are in the wanted joints' values of a JointState source.
        self.wanted: tuple[str, ...] = ()
        self.slices: list[tuple[str, int, int]] = []
        for topic in inputs:
            joints = mapping.input_joints(topic)
            self.slices.append((topic, len(self.wanted), len(self.wanted) + len(joints)))
            self.wanted += joints


def stamp_ordered(batches: Sequence[list[tuple]]) -> Iterable[tuple]:
    """Return the (stamp, ...) entries of the streams' batches in stamp order, each in its own."""
    if len(batches) > 1:  # each stream keeps its arrival order
        return heapq.merge(*batches, key=lambda entry: entry[0])
    return batches[0] if batches else ()


def input_sources(
    mapping: InputMapping, topic_names: dict[str, str], qos: Any
) -> list[InputSource]:
    """Return one source per distinct input topic (inputs remapped to one topic share it)."""
    transform = mapping_transforms_inclinometer(mapping)
    sources = []
    for name in dict.fromkeys(mapping.topics):
        inputs = tuple(topic for topic in RAW_TOPICS if topic_names[topic] == name)
        imu = inputs == (INCLINOMETER_TOPIC,) and mapping.inclinometer_type == IMU_INCLINOMETER
        source = InputSource(
            name,
            inputs,
            Imu if imu else JointState,
            IMU_TYPE if imu else JOINT_STATE_TYPE,
            qos,
            mapping,
        )
        # A source of one input whose in-place values are its reading as they are.
        (topic, *others) = inputs
        if not others and not (topic == INCLINOMETER_TOPIC and transform):
            source.stream = STREAM_OF_TOPIC[topic]
        sources.append(source)
    return sources


def recorded_only_sources(
    resolve: Callable[[str], str], mapping: InputMapping
) -> list[InputSource]:
    """Return the recorded-only topics' sources, except those remapped onto an input."""
    sources = []
    for topic, message_type, type_name, qos in RECORDED_ONLY_TOPICS:
        name = resolve(topic)
        if name not in mapping.topics:  # else one subscription per topic: the input's
            sources.append(InputSource(name, (), message_type, type_name, qos, mapping))
    return sources


def link_source(name: str, mapping: InputMapping, qos: Any) -> InputSource:
    """Return the lvdt link length topic's source (recorded when published; not an input)."""
    return InputSource(name, (), JointState, JOINT_STATE_TYPE, qos, mapping)


def mapping_transforms_inclinometer(mapping: InputMapping) -> bool:
    """Return True if the mapping corrects the inclinometer (signs or offsets not default)."""
    corrections = (mapping.inclinometer_signs, mapping.inclinometer_offsets_rad)
    return corrections != (DEFAULT_SIGNS, DEFAULT_OFFSETS_RAD)


class InputReader:
    """Read the inputs' messages into the synchronizer; collect each stream's readings."""

    def __init__(
        self,
        mapping: InputMapping,
        model: str,
        synchronizer: StreamSynchronizer,
        turns: TurnHistory,
        on_invalid: Callable[[str, str], None],
    ) -> None:
        self.mapping = mapping
        self.model = model
        self.synchronizer = synchronizer
        self.turns = turns
        self.on_invalid = on_invalid  # (input topic, problem)
        self.transform_inclinometer = mapping_transforms_inclinometer(mapping)
        # Per stream, the accepted readings (stamps, values) for the detector, which takes the
        # streams as they are.
        self.readings: dict[Stream, tuple[list[int], list[tuple[float, ...]]]] = {
            stream: ([], []) for stream in Stream
        }

    def take_readings(self) -> dict[Stream, tuple[list[int], list[tuple[float, ...]]]]:
        """Return each stream's readings accepted since the last call."""
        readings = self.readings
        self.readings = {stream: ([], []) for stream in Stream}
        return {stream: lists for stream, lists in readings.items() if lists[0]}

    def _add(self, stream: Stream, stamp: int, values: tuple[float, ...]) -> None:
        if self.synchronizer.accept(stream, stamp, values):
            stamps, rows = self.readings[stream]
            stamps.append(stamp)
            rows.append(values)

    def read(self, source: InputSource, data: bytes) -> None:
        """Read one message of `source`: each input's reading taken once."""
        readings = None
        if source.fast is not None:
            raw = source.fast.read(data)
            if raw is not None:
                if source.has_inclinometer:
                    self.turns.note(raw[0], source.fast.last_turn)
                if source.stream is not None:  # one input, its values as read: the 1 kHz path
                    self._add(source.stream, *raw)
                    return
                readings = self._split(source, *raw)
        if readings is None:
            readings = self._decode(source, data)
            if readings is None:
                return
        stamp, values = readings
        for topic, reading in values:
            self._add(STREAM_OF_TOPIC[topic], stamp, reading)

    def _split(self, source: InputSource, stamp: int, raw: tuple[float, ...]) -> Readings:
        """Return each input's slice of a fast read, the inclinometer corrected."""
        if source.message_type is Imu:
            angles = self.mapping.inclinometer_angles(*raw) if self.transform_inclinometer else raw
            return stamp, [(INCLINOMETER_TOPIC, angles)]
        values = []
        for topic, start, end in source.slices:
            reading = raw[start:end]
            if topic == INCLINOMETER_TOPIC and self.transform_inclinometer:
                reading = self.mapping.inclinometer_angles(*reading)
            values.append((topic, reading))
        return stamp, values

    def _decode(self, source: InputSource, data: bytes) -> Readings | None:
        """
        Decode with rclpy and check with the contract; learn the in-place reader.

        Returns the valid inputs' readings, None if none is valid. A fully valid message
        whose in-place reading gives the same teaches the source its in-place reader.
        """
        try:
            message = deserialize_message(data, source.message_type)
        except Exception as error:  # noqa: B902 - any undecodable bytes count as invalid
            for topic in source.inputs:
                self.on_invalid(topic, f'cannot decode a {source.type_name}: {error}')
            return None
        values = []
        stamp = None
        for topic in source.inputs:
            try:
                stamp, reading = self._reading(source, topic, message)
            except InvalidReadingError as error:
                self.on_invalid(topic, str(error))
                continue
            values.append((topic, reading))
        if not values or stamp is None:  # no input was valid
            return None
        if len(values) == len(source.inputs):
            try:
                fast = (
                    ImuReader(data, message)
                    if source.message_type is Imu
                    else JointStateReader(data, message, source.wanted)
                )
            except (ValueError, KeyError, struct.error):
                pass  # decoded the full way every time
            else:
                raw = fast.read(data)
                if raw is not None and self._split(source, *raw) == (stamp, values):
                    source.fast = fast
        return stamp, values

    def _reading(
        self, source: InputSource, topic: str, message: Any
    ) -> tuple[int, tuple[float, ...]]:
        """Return (stamp_ns, values) of one input of a decoded message (InvalidReadingError)."""
        if topic == SLIDERS_TOPIC:
            sliders = self._actuator_reading(message)
            return sliders.stamp_ns, sliders.actuator_positions
        if topic == INCLINOMETER_TOPIC:
            imu = source.message_type is Imu
            angles = (
                imu_to_inclinometer_reading(message, self.mapping)
                if imu
                else joint_state_to_inclinometer_reading(message, self.mapping)
            )
            carried = not imu and DEVICE_TURN_JOINT in message.name
            self.turns.note(angles.stamp_ns, angles.device_turn if carried else None)
            return angles.stamp_ns, (angles.alpha, angles.beta)
        rotary = joint_state_to_encoder_reading(message, self.mapping)
        return rotary.stamp_ns, (rotary.phi,)

    def _actuator_reading(self, message: JointState) -> Any:
        """Return the actuator joints of a sliders message; another model's joints are named."""
        try:
            return joint_state_to_actuator_reading(message, self.model, self.mapping)
        except InvalidReadingError as error:
            carried = actuator_model(message.name)
            if carried is not None and carried.name != self.model:
                raise InvalidReadingError(
                    f'{error}; it carries the actuator joints of a {carried.name} '
                    f'({carried.actuator_names[0]}..{carried.actuator_names[-1]}) but this '
                    f'collector records a {self.model} (parameters model / parameters_file)'
                ) from None
            raise
