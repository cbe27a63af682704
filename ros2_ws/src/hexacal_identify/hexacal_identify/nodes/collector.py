"""Node `collector`: turn the three sensor streams into postures, and record everything.

Subscribes `hexacal/sliders`, `hexacal/inclinometer` and `hexacal/encoder`
(SENSOR_QOS) as raw CDR, so the bag holds exactly the bytes that arrived;
pairs the streams on the slider stamps (StreamSynchronizer), finds the
stationary periods (PostureDetector) and publishes one averaged posture per
period on `hexacal/posture` (POSTURE_QOS, stamp = capture time).

Inputs from the user's own drivers (hexacal_msgs_py.inputs): the three inputs
are ROS names, so `--ros-args -r hexacal/sliders:=/joint_states` (and the same
for the other two) reads them from any topic; parameters `actuator_joints`
(six, chain order; default the model's), `inclinometer_joints` (two: alpha,
beta; default inclinometer_x, inclinometer_y) and `rotary_joint` (default
rotary) name the joints. Inputs remapped to one topic (ros2_control's
joint_state_broadcaster on /joint_states, extra joints besides) share one
subscription: each message is recorded once and every reading is taken from
it once. `inclinometer_type: imu` reads the inclinometer from a sensor_msgs/Imu
orientation (the convention of hexacal_msgs_py.inputs); `inclinometer_signs`
and `inclinometer_offsets_rad` correct either type per channel (angle = sign *
(raw - offset)). Postures and the bag's posture records keep the contract's
names; the bag records the inputs under their real topics and types and the
mapping in the `hexacal.collector` record (and metadata.yaml custom_data
`hexacal.inputs`), which the offline tools read. A bad mapping is a named error
at start (exit 2).

It also records `hexacal/platform_pose` (geometry_msgs/PoseStamped) and
`hexacal/machine_markers` (visualization_msgs/MarkerArray) as received, when
someone publishes them (the kinematics node), so a bag replays as a moving
machine; they play no part in the calibration.

The machine model (and so the actuator joints read on `hexacal/sliders` and
written on `hexacal/posture`: slider_1..6 on a Hexa Slide, leg_1..6 on a
Gough-Stewart platform) is the `model` parameter, or the model named by the
parameters YAML `parameters_file` (e.g. the nominal file identify uses), else the
Hexa Slide. Sliders messages without the model's actuator joints are invalid
(counted and logged, naming the model they do carry).

Recording goes to a rosbag2 MCAP bag `<output_dir>/<bag_name>/` (BagWriter):
the raw streams and the postures, flushed every `flush_every_s` and after every
posture (before publishing it), so a SIGKILL loses at most the posture in
progress and never one that was published (`reindex` restores metadata.yaml).
Services `hexacal/start_recording` and `hexacal/stop_recording`
(std_srvs/Trigger) open a new bag and close the current one. If the driver's
parameters can be read, the plan it walks is stored as bag metadata
`hexacal.plan`. The model that recorded the bag is stored twice: in the MCAP
metadata record `hexacal.collector` (key `model`, beside the detector settings)
and in metadata.yaml's `custom_data` (`hexacal.model`).

Invalid messages (NaN, missing joints, names and positions of different
lengths, undecodable bytes) are recorded as received, counted and logged
(throttled), and never stop the node. So are readings whose stamps repeat or go
back in time, slider readings without a partner within `max_skew_s` (stale or
missing inclinometer/encoder stamps) and messages DDS reports lost. A stream
with no message for `STREAM_STOPPED_S` is reported stopped, and a posture being
captured then is dropped (never published half-measured). Every change of these
counters, of the stopped streams or of the recording (e.g. disk full) is logged
and published on `hexacal/calibration_status` (status name 'hexacal collector').

Device turn: every posture says in which mounting of the device it was taken,
the device's rotation about its link axis from its normal mounting (rad: 0
normal, pi reversed, pi/2 a quarter turn), as the optional posture joint
`device_turn` (written only when non-zero; hexacal_msgs_py.conversions). It is
the `device_turn` joint of the inclinometer message the posture was paired
with when that message carries it (a simulated or instrumented device), else
the parameter `device_turn` (rad, -2 pi..2 pi, default 0, settable at run
time: an operator who turned a real device sets `ros2 param set /collector
device_turn 3.14159` before its postures).
"""

from __future__ import annotations

import bisect
from dataclasses import replace
from datetime import datetime
import heapq
import json
import math
from pathlib import Path
import struct
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from hexacal_msgs_py.conversions import (
    actuator_model,
    diagnostic_status,
    imu_to_inclinometer_reading,
    joint_state_to_encoder_reading,
    joint_state_to_inclinometer_reading,
    joint_state_to_slider_reading,
    posture_reading_to_joint_state,
)
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.inputs import (
    DEFAULT_INCLINOMETER_JOINTS,
    DEFAULT_OFFSETS_RAD,
    DEFAULT_ROTARY_JOINT,
    DEFAULT_SIGNS,
    IMU_INCLINOMETER,
    imu_inclinometer_angles,
    INCLINOMETER_TYPES,
    InputMapping,
)
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.names import (
    CALIBRATION_STATUS_TOPIC,
    DEVICE_TURN_JOINT,
    ENCODER_TOPIC,
    IMU_TYPE,
    INCLINOMETER_TOPIC,
    JOINT_STATE_TYPE,
    MACHINE_MARKERS_TOPIC,
    MARKER_ARRAY_TYPE,
    MAX_DEVICE_TURN,
    PLATFORM_POSE_TOPIC,
    POSE_STAMPED_TYPE,
    POSTURE_TOPIC,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.parameters_file import read_parameters_file
from hexacal_msgs_py.qos import MARKERS_QOS, POSE_QOS, POSTURE_QOS, SENSOR_QOS, STATUS_QOS
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import QoSSubscriptionEventType, SubscriptionEventCallbacks
from rclpy.exceptions import (
    InvalidHandle,
    InvalidParameterTypeException,
    InvalidParameterValueException,
)
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray
import yaml

from ..bag import BagError, BagWriter
from ..core.posture_detector import (
    DetectedPosture,
    DROPPED_AT_END,
    DROPPED_FOR_STREAM_STOP,
    ENCODER_STREAM,
    INCLINOMETER_STREAM,
    PostureDetector,
    SLIDERS_STREAM,
    StreamSynchronizer,
)
from .runtime import run_node

NODE_NAME = 'collector'
START_RECORDING_SERVICE = 'hexacal/start_recording'
STOP_RECORDING_SERVICE = 'hexacal/stop_recording'
PLAN_METADATA = 'hexacal.plan'
COLLECTOR_METADATA = 'hexacal.collector'
MODEL_CUSTOM_DATA = 'hexacal.model'  # metadata.yaml custom_data key naming the recording's model
INPUTS_CUSTOM_DATA = 'hexacal.inputs'  # metadata.yaml custom_data: the input mapping as JSON
MODEL_CHOICES = ('', *MODELS)
# Driver parameters that describe the plan it walks (see hexacal_driver.driver_node).
DRIVER_PLAN_PARAMETERS = (
    'plan',
    'plan_name',
    'postures',
    'seed',
    'link_length',
    'settle_s',
    'dwell_s',
    'rate_hz',
    'slider_noise_m',
    'angle_noise_rad',
    'device_defects',
    'device_turn',
)
# Device turns carried by inclinometer messages, kept for looking up a posture's turn.
MAX_TURN_CHANGES = 1000
INVALID_LOG_PERIOD_S = 5.0
STALE_LOG_PERIOD_S = 10.0
NS_PER_S = 1_000_000_000
STATUS_NAME = 'hexacal collector'
RAW_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)
# A stream with no message for this long (receipt time) has stopped, e.g. the driver died.
STREAM_STOPPED_S = 1.0
# The sensor publishers are best effort (SENSOR_QOS); a deep reader queue absorbs executor
# pauses (bag flushes, GC) at 1 kHz instead of overwriting samples.
SENSOR_SUBSCRIPTION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=SENSOR_QOS.reliability,
    durability=SENSOR_QOS.durability,
)
# The sensor streams are not executor callbacks: a timer takes everything queued every
# POLL_PERIOD_S (30 messages at 3 x 1 kHz; the reader queues hold 1 s) and handles it in one go,
# so the executor wakes 100 times a second instead of 3000. Messages are handled in stamp order
# across the streams (each stream in arrival order) and the detector gets them as one batch.
POLL_PERIOD_S = 0.01
_STREAM_OF_TOPIC = {
    SLIDERS_TOPIC: SLIDERS_STREAM,
    INCLINOMETER_TOPIC: INCLINOMETER_STREAM,
    ENCODER_TOPIC: ENCODER_STREAM,
}
# Recorded as received when published (the kinematics node), not used by the calibration:
# (topic, message class, type name, QoS).
RECORDED_ONLY_TOPICS = (
    (PLATFORM_POSE_TOPIC, PoseStamped, POSE_STAMPED_TYPE, POSE_QOS),
    (MACHINE_MARKERS_TOPIC, MarkerArray, MARKER_ARRAY_TYPE, MARKERS_QOS),
)
_CDR_HEADER = b'\x00\x01\x00\x00'  # XCDR1 little endian, what Fast DDS sends
_STAMP = struct.Struct('<iI')
_UINT32 = struct.Struct('<I')
_DOUBLE = struct.Struct('<d')
_QUATERNION = struct.Struct('<4d')
_IMU_DOUBLES = (
    4 + 9 + 3 + 9 + 3 + 9
)  # orientation, its covariance, angular velocity, ..., all float64


class CollectorConfigurationError(Exception):
    """The collector's parameters contradict each other (e.g. model and parameters_file)."""


def resolve_model(model: str, parameters_file: str) -> str:
    """The collector's model: `model`, else the model `parameters_file` names, else the Hexa Slide.

    Both given and different: CollectorConfigurationError; an unreadable file:
    its ParameterFileError (a contract error naming the file and key).
    """
    if not parameters_file:
        return model or DEFAULT_MODEL
    named = read_parameters_file(parameters_file).model
    if model and model != named:
        raise CollectorConfigurationError(
            f'model {model!r} contradicts parameters_file {parameters_file}, a {named} parameters '
            "file: leave model '' or name the file's model"
        )
    return named


class _PolledGroup(CallbackGroup):
    """Callback group the executor never waits on: the collector's timer takes its messages."""

    def can_execute(self, entity) -> bool:
        return False

    def beginning_execution(self, entity) -> bool:
        return False

    def ending_execution(self, entity) -> None:
        pass


def _stamp_of(data: bytes) -> int:
    """Header stamp (ns) of JointState CDR bytes; 0 if there is none (invalid anyway)."""
    if len(data) < 12:
        return 0
    seconds, nanoseconds = _STAMP.unpack_from(data, 4)
    return seconds * NS_PER_S + nanoseconds


def _align(position: int, size: int) -> int:
    """`position` rounded up to a multiple of `size` counted from byte 4 (after the CDR header)."""
    return position + (-(position - 4)) % size


def _skip_doubles(data: bytes, offset: int) -> tuple[int, int]:
    """(count, offset after) of the float64 sequence at `offset` (its uint32 length first)."""
    offset = _align(offset, 4)
    (count,) = _UINT32.unpack_from(data, offset)
    offset += 4
    if count:
        offset = _align(offset, 8)
    return count, offset + 8 * count


def _positions_layout(data: bytes) -> tuple[int, int] | None:
    """(offset, count) of the position doubles in little-endian JointState CDR, None if malformed."""
    if data[:4] != _CDR_HEADER:
        return None
    offset = 12  # after the header stamp; alignment is relative to byte 4
    try:
        (length,) = _UINT32.unpack_from(data, offset)  # frame_id
        offset += 4 + length
        offset = _align(offset, 4)
        (names,) = _UINT32.unpack_from(data, offset)
        offset += 4
        for _ in range(names):
            offset = _align(offset, 4)
            (length,) = _UINT32.unpack_from(data, offset)
            offset += 4 + length
        offset = _align(offset, 4)
        (count,) = _UINT32.unpack_from(data, offset)
        offset += 4
        if count:
            offset = _align(offset, 8)
    except struct.error:
        return None
    if offset + 8 * count > len(data):
        return None
    return offset, count


class _FastJointState:
    """Reads the wanted positions straight from CDR bytes laid out like a known good message.

    Learned from a message that rclpy decoded and the contract accepted: every later message
    of the same size whose bytes equal it from the stamp to the positions (same frame_id,
    names, number of positions) and whose velocity and effort sequences have the same lengths
    has the same joints at the same offsets; the velocity and effort values may change (ros2_control's
    joint_state_broadcaster fills them). Anything else (and non-finite wanted values or
    negative stamps) goes the full way, which reports the problem exactly as before. The wanted
    joints are any of the message's, in any order (extra joints are skipped).
    """

    def __init__(self, data: bytes, message: JointState, wanted: tuple[str, ...]) -> None:
        layout = _positions_layout(data)
        if layout is None:
            raise ValueError('not a little-endian JointState')
        offset, count = layout
        if count != len(message.position):
            raise ValueError('layout does not match the decoded message')
        index = {name: i for i, name in enumerate(message.name)}
        self.order = tuple(index[name] for name in wanted)
        # The optional device_turn joint (read beside the wanted ones; None: not carried).
        self.turn_index = index.get(DEVICE_TURN_JOINT)
        self.last_turn: float | None = None
        self.positions = struct.Struct(f'<{count}d')
        self.offset = offset
        self.size = len(data)
        self.prefix = bytes(data[12:offset])
        suffix_start = offset + 8 * count
        try:
            velocities, after = _skip_doubles(data, suffix_start)
            efforts, end = _skip_doubles(data, after)
        except struct.error:
            raise ValueError('no velocity and effort sequences') from None
        if (velocities, efforts) != (len(message.velocity), len(message.effort)) or end > len(
            data
        ):
            raise ValueError('layout does not match the decoded message')
        # The two sequence lengths, read with one unpack (the velocities between them skipped).
        self.counts_offset = _align(suffix_start, 4)
        self.counts = struct.Struct(f'<I{_align(after, 4) - self.counts_offset - 4}xI')
        self.expected_counts = (velocities, efforts)
        if list(self.positions.unpack_from(data, offset)) != list(message.position):
            raise ValueError('layout does not match the decoded message')

    def read(self, data: bytes) -> tuple[int, tuple[float, ...]] | None:
        """(stamp_ns, wanted positions), or None: decode this message the full way."""
        if (
            len(data) != self.size
            or data[12 : self.offset] != self.prefix
            or data[:4] != _CDR_HEADER
        ):
            return None
        if self.counts.unpack_from(data, self.counts_offset) != self.expected_counts:
            return None
        seconds, nanoseconds = _STAMP.unpack_from(data, 4)
        if seconds < 0:
            return None
        positions = self.positions.unpack_from(data, self.offset)
        values = tuple(positions[i] for i in self.order)
        for value in values:
            if not math.isfinite(value):
                return None
        if self.turn_index is not None:
            turn = positions[self.turn_index]
            if not abs(turn) <= MAX_DEVICE_TURN:  # NaN too: the full way reports it
                return None
            self.last_turn = turn
        return seconds * NS_PER_S + nanoseconds, values


class _FastImu:
    """Reads an Imu's orientation from CDR bytes laid out like a known good message.

    An Imu is fixed-size after its frame_id: every message of the learned size with the same
    frame_id has the orientation at the same offset. Returns the inclinometer's raw angles by
    the contract's convention (hexacal_msgs_py.inputs); anything it cannot read (another
    layout, a negative stamp, no orientation estimate, a quaternion that is not a unit one)
    goes the full way, which reports the problem.
    """

    turn_index = None  # an Imu carries no device turn
    last_turn = None

    def __init__(self, data: bytes, message: Imu) -> None:
        if data[:4] != _CDR_HEADER:
            raise ValueError('not a little-endian Imu')
        try:
            (length,) = _UINT32.unpack_from(data, 12)
        except struct.error:
            raise ValueError('not an Imu') from None
        self.offset = _align(16 + length, 8)
        self.size = len(data)
        if self.offset + 8 * _IMU_DOUBLES > self.size:
            raise ValueError('not an Imu')
        self.prefix = bytes(data[12 : self.offset])
        orientation = message.orientation
        if (
            _QUATERNION.unpack_from(data, self.offset)
            != (orientation.x, orientation.y, orientation.z, orientation.w)
            or _DOUBLE.unpack_from(data, self.offset + 32)[0] != message.orientation_covariance[0]
        ):
            raise ValueError('layout does not match the decoded message')

    def read(self, data: bytes) -> tuple[int, tuple[float, ...]] | None:
        """(stamp_ns, (raw alpha, raw beta)), or None: decode this message the full way."""
        if (
            len(data) != self.size
            or data[12 : self.offset] != self.prefix
            or data[:4] != _CDR_HEADER
        ):
            return None
        seconds, nanoseconds = _STAMP.unpack_from(data, 4)
        if seconds < 0:
            return None
        try:
            angles = imu_inclinometer_angles(
                _QUATERNION.unpack_from(data, self.offset),
                _DOUBLE.unpack_from(data, self.offset + 32)[0],
            )
        except InvalidReadingError:
            return None
        return seconds * NS_PER_S + nanoseconds, angles


class _Source:
    """One subscribed topic and the inputs read from it (several when remapped to one topic)."""

    def __init__(
        self,
        name: str,
        inputs: tuple[str, ...],
        message_type: type,
        type_name: str,
        qos: QoSProfile,
        mapping: InputMapping,
    ) -> None:
        self.name = name  # resolved topic name, as recorded
        self.inputs = inputs  # contract input topics, in RAW_TOPICS order
        self.message_type = message_type
        self.type_name = type_name
        self.qos_yaml = qos_profiles_yaml(qos)
        self.subscription = None
        self.fast: _FastJointState | _FastImu | None = None
        self.key = '+'.join(inputs)  # the loss counter's name: lost.<inputs>
        self.has_inclinometer = INCLINOMETER_TOPIC in inputs  # may carry the device turn
        self.stream: str | None = None  # set when the in-place values are the one input's reading
        # Where each input's values are in the wanted joints' values of a JointState source.
        self.wanted: tuple[str, ...] = ()
        self.slices: list[tuple[str, int, int]] = []
        for topic in inputs:
            joints = mapping.input_joints(topic)
            self.slices.append((topic, len(self.wanted), len(self.wanted) + len(joints)))
            self.wanted += joints


_DETECTOR_PARAMETERS = {
    # name: (default, description, low, high); defaults are PostureDetector's.
    'window_s': (
        0.3,
        'a sample is stationary when every channel stayed within its tolerance '
        'over this window (s)',
        0.02,
        10.0,
    ),
    'capture_s': (0.5, 'stationary time averaged into one posture (s)', 0.02, 60.0),
    'slider_tolerance_m': (
        2e-4,
        'peak-to-peak slider motion still counted as stationary (m)',
        1e-7,
        0.1,
    ),
    'angle_tolerance_rad': (
        2e-4,
        'peak-to-peak angle motion still counted as stationary (rad)',
        1e-7,
        0.1,
    ),
    'max_gap_s': (
        0.1,
        'a longer gap in the data drops the posture being captured (s)',
        0.001,
        10.0,
    ),
    'max_skew_s': (0.02, 'largest stamp difference of paired sensor readings (s)', 0.0, 1.0),
}


def qos_profiles_yaml(profile: QoSProfile) -> str:
    """offered_qos_profiles text of a topic (rosbag2 metadata version 9 spelling)."""

    def duration(value) -> dict[str, int]:
        seconds, nanoseconds = divmod(int(value.nanoseconds), NS_PER_S)
        return {'sec': seconds, 'nsec': nanoseconds}

    return yaml.safe_dump(
        [
            {
                'history': profile.history.name.lower(),
                'depth': int(profile.depth),
                'reliability': profile.reliability.name.lower(),
                'durability': profile.durability.name.lower(),
                'deadline': duration(profile.deadline),
                'lifespan': duration(profile.lifespan),
                'liveliness': profile.liveliness.name.lower(),
                'liveliness_lease_duration': duration(profile.liveliness_lease_duration),
                'avoid_ros_namespace_conventions': bool(profile.avoid_ros_namespace_conventions),
            }
        ],
        sort_keys=False,
    )


def _float_descriptor(
    description: str, low: float, high: float, read_only: bool = True
) -> ParameterDescriptor:
    return ParameterDescriptor(
        description=description,
        read_only=read_only,
        floating_point_range=[FloatingPointRange(from_value=low, to_value=high, step=0.0)],
    )


class CollectorNode(Node):
    """Synchronise, detect postures, publish them and record the bag."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.declare_parameter(
            'output_dir',
            'bags',
            ParameterDescriptor(description='directory that receives the bag directories'),
        )
        self.declare_parameter(
            'bag_name',
            '',
            ParameterDescriptor(description='bag directory name; empty: hexacal_<date>_<time>'),
        )
        self.declare_parameter(
            'record',
            True,
            ParameterDescriptor(
                description='record from the start (else only after hexacal/start_recording)',
                read_only=True,
            ),
        )
        self.declare_parameter(
            'flush_every_s',
            0.5,
            _float_descriptor(
                'period of making the bag durable on disk (s); it is also flushed after every '
                'posture',
                0.05,
                60.0,
                read_only=False,
            ),
        )
        self.declare_parameter(
            'driver_node',
            'driver',
            ParameterDescriptor(
                description='node (relative to this namespace) whose plan parameters are recorded',
                read_only=True,
            ),
        )
        self.declare_parameter(
            'model',
            '',
            ParameterDescriptor(
                description="machine model, which names the actuator joints: 'hexa_slide' "
                "(slider_1..6) or 'gough_stewart' (leg_1..6); '' = the model of parameters_file, "
                'else hexa_slide',
                read_only=True,
                additional_constraints="'', " + ', '.join(repr(name) for name in MODELS),
            ),
        )
        self.declare_parameter(
            'parameters_file',
            '',
            ParameterDescriptor(
                description="a parameters YAML of the machine (e.g. identify's nominal file) whose "
                "'model' key gives the model; '' = none",
                read_only=True,
            ),
        )
        for name, (default, description, low, high) in _DETECTOR_PARAMETERS.items():
            self.declare_parameter(name, default, _float_descriptor(description, low, high))
        self.declare_parameter(
            'device_turn',
            0.0,
            _float_descriptor(
                "the device's rotation about its link axis from its normal mounting (rad; 0 normal, "
                'pi reversed, pi/2 a quarter turn) for postures whose inclinometer message has no '
                f"'{DEVICE_TURN_JOINT}' joint (a message that has it wins); settable at run time",
                -MAX_DEVICE_TURN,
                MAX_DEVICE_TURN,
                read_only=False,
            ),
        )
        self.device_turn = self._checked_turn(self.get_parameter('device_turn').value)
        # (inclinometer stamp, turn carried from then on, None: not carried), in stamp order.
        self._turn_changes: list[tuple[int, float | None]] = []
        value = {
            name: self.get_parameter(name).value
            for name in (
                'record',
                'flush_every_s',
                'driver_node',
                'model',
                'parameters_file',
                *_DETECTOR_PARAMETERS,
            )
        }
        self.model = resolve_model(value['model'], value['parameters_file'])
        self.actuator_names = MODELS[self.model].actuator_names
        self.mapping = self._declare_inputs()

        self.synchronizer = StreamSynchronizer(max_skew_ns=int(value['max_skew_s'] * NS_PER_S))
        self.detector = PostureDetector(
            window_s=value['window_s'],
            capture_s=value['capture_s'],
            slider_tolerance_m=value['slider_tolerance_m'],
            angle_tolerance_rad=value['angle_tolerance_rad'],
            max_gap_s=value['max_gap_s'],
        )
        self.detector_settings = {name: repr(value[name]) for name in _DETECTOR_PARAMETERS}
        self.postures_published = 0
        self.invalid: dict[str, int] = {}
        self.received = {topic: 0 for topic in RAW_TOPICS}
        self.lost: dict[str, int] = {}  # messages DDS reports lost (best effort)
        self._last_receipt_ns: dict[str, int] = {}
        self.stopped_streams: tuple[str, ...] = ()
        self.recording_error: str | None = None
        self._reported: dict[str, object] | None = None  # problems in the last status
        self.writer: BagWriter | None = None
        self.bag_postures = 0
        self._bag_counter = 0
        self._plan_recorded = False
        self._plan_request = None

        self._posture_pub = self.create_publisher(JointState, POSTURE_TOPIC, POSTURE_QOS)
        self._status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self.topic_names = {
            topic: resolved for topic, resolved in zip(RAW_TOPICS, self.mapping.topics)
        }
        self.topic_names[POSTURE_TOPIC] = self.resolve_topic_name(POSTURE_TOPIC)
        self._qos_yaml = {POSTURE_TOPIC: qos_profiles_yaml(POSTURE_QOS)}
        polled = _PolledGroup()
        # One subscription per distinct input topic: inputs remapped to one topic share it.
        self._sources: list[_Source] = []
        for name in dict.fromkeys(self.mapping.topics):
            inputs = tuple(topic for topic in RAW_TOPICS if self.topic_names[topic] == name)
            imu = (
                inputs == (INCLINOMETER_TOPIC,)
                and self.mapping.inclinometer_type == IMU_INCLINOMETER
            )
            source = _Source(
                name,
                inputs,
                Imu if imu else JointState,
                IMU_TYPE if imu else JOINT_STATE_TYPE,
                SENSOR_QOS,
                self.mapping,
            )
            source.subscription = self.create_subscription(
                source.message_type,
                name,
                lambda data, info, source=source: self._on_raw(source, data, info),
                SENSOR_SUBSCRIPTION_QOS,
                raw=True,
                callback_group=polled,
                event_callbacks=SubscriptionEventCallbacks(
                    message_lost=lambda status, key=source.key: self._on_lost(key, status)
                ),
            )
            self._sources.append(source)
        # Their QoS event handlers are in the polled group too: in the wait set, a subscription's
        # events wake the executor on every message. The loss count is read by housekeeping.
        self._lost_handlers = {
            source.key: [
                handler
                for handler in source.subscription.event_handlers
                if handler.event_type == QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST
            ]
            for source in self._sources
        }
        # Recorded as received, when published; taken by the same poll (no executor wake-ups).
        self._recorded_only: list[_Source] = []
        for topic, message_type, type_name, qos in RECORDED_ONLY_TOPICS:
            name = self.resolve_topic_name(topic)
            if name in self.mapping.topics:
                continue  # remapped onto an input: one subscription per topic
            source = _Source(name, (), message_type, type_name, qos, self.mapping)
            # The publisher's QoS is what the bag records (replay offers it again); the reader's
            # queue is deep, as for the sensors: a pose stream at the sensor rate between polls.
            reader_qos = QoSProfile(
                history=HistoryPolicy.KEEP_LAST,
                depth=SENSOR_SUBSCRIPTION_QOS.depth,
                reliability=qos.reliability,
                durability=qos.durability,
            )
            source.subscription = self.create_subscription(
                message_type,
                name,
                lambda data, info, source=source: self._record_only(source, data, info),
                reader_qos,
                raw=True,
                callback_group=polled,
            )
            self._recorded_only.append(source)
        self._recorded_only_added: set[str] = set()  # registered in the current bag
        self._transform_inclinometer = (
            self.mapping.inclinometer_signs,
            self.mapping.inclinometer_offsets_rad,
        ) != (DEFAULT_SIGNS, DEFAULT_OFFSETS_RAD)
        for source in self._sources:
            # A source of one input whose in-place values are its reading as they are.
            (topic, *others) = source.inputs
            if not others and not (topic == INCLINOMETER_TOPIC and self._transform_inclinometer):
                source.stream = _STREAM_OF_TOPIC[topic]
        self._samples: list[tuple[int, tuple[float, ...]]] = []  # paired, for the detector
        self._poll_timer = self.create_timer(POLL_PERIOD_S, self._poll)
        self.create_service(Trigger, START_RECORDING_SERVICE, self._start_recording)
        self.create_service(Trigger, STOP_RECORDING_SERVICE, self._stop_recording)
        self._driver_parameters = AsyncParameterClient(self, value['driver_node'])
        self._flush_timer = self.create_timer(value['flush_every_s'], self._flush)
        self._housekeeping_timer = self.create_timer(1.0, self._housekeeping)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self.get_logger().info(
            f'collecting postures on {self.topic_names[POSTURE_TOPIC]} (window '
            f'{value["window_s"]:g} s, capture {value["capture_s"]:g} s); model {self.model}, '
            f'actuator joints {self.actuator_names[0]}..{self.actuator_names[-1]}'
        )
        self.get_logger().info(f'inputs: {self.mapping.describe()}')
        if self.device_turn != 0.0:
            self.get_logger().info(
                f'device_turn {self.device_turn:.6g} rad for postures whose inclinometer '
                f'message has no {DEVICE_TURN_JOINT} joint'
            )
        if value['record']:
            self.open_bag()

    # ------------------------------------------------------------------ parameters

    def _declare_inputs(self) -> InputMapping:
        """The input mapping parameters (read only), validated: InputMappingError names the problem."""

        def declare(name: str, default, description: str, constraints: str = ''):
            # Dynamic typing: [1, -1] (integers) is as good as [1.0, -1.0]; InputMapping checks types.
            return self.declare_parameter(
                name,
                default,
                ParameterDescriptor(
                    description=description,
                    read_only=True,
                    dynamic_typing=True,
                    additional_constraints=constraints,
                ),
            ).value

        actuators = declare(
            'actuator_joints',
            list(self.actuator_names),
            'the six actuator joints in chain order, as the sliders input (hexacal/sliders, or '
            'the topic it is remapped to, e.g. /joint_states) names them; default: the '
            "model's (slider_1..6 or leg_1..6)",
            'six distinct names',
        )
        inclinometer = declare(
            'inclinometer_joints',
            list(DEFAULT_INCLINOMETER_JOINTS),
            'the inclinometer joints alpha (about X), beta (about Y) of a JointState '
            'inclinometer input (rad)',
            'two distinct names',
        )
        rotary = declare(
            'rotary_joint',
            DEFAULT_ROTARY_JOINT,
            'the rotary sensor joint (phi, rad) of the encoder input',
        )
        kind = declare(
            'inclinometer_type',
            'joint_state',
            "'joint_state': the inclinometer input is a sensor_msgs/JointState with "
            "inclinometer_joints; 'imu': a sensor_msgs/Imu whose orientation gives alpha and beta "
            '(hexacal_msgs_py.inputs)',
            ', '.join(repr(t) for t in INCLINOMETER_TYPES),
        )
        signs = declare(
            'inclinometer_signs',
            list(DEFAULT_SIGNS),
            'per channel (alpha, beta): 1 or -1; angle = sign * (raw - offset)',
            'two values, each 1 or -1',
        )
        offsets = declare(
            'inclinometer_offsets_rad',
            list(DEFAULT_OFFSETS_RAD),
            'per channel (alpha, beta): the raw reading with the link level (rad); '
            'angle = sign * (raw - offset)',
            'two finite values within +-pi',
        )
        return InputMapping(
            actuator_joints=actuators,
            inclinometer_joints=inclinometer,
            rotary_joint=rotary,
            inclinometer_type=kind,
            inclinometer_signs=signs,
            inclinometer_offsets_rad=offsets,
            topics=tuple(self.resolve_topic_name(topic) for topic in RAW_TOPICS),
        )

    @staticmethod
    def _checked_turn(value: object) -> float:
        """The device_turn parameter as a float; InvalidParameterValueException if not a finite
        angle within +-2 pi rad."""
        problem = CollectorNode._turn_problem(value)
        if problem is not None:
            raise InvalidParameterValueException('device_turn', value, problem)
        return float(value)

    @staticmethod
    def _turn_problem(value: object) -> str | None:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f'device_turn must be a number (rad), got {value!r}'
        if not abs(float(value)) <= MAX_DEVICE_TURN:
            return f'device_turn must be a finite angle within +-2 pi rad, got {value!r}'
        return None

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name == 'device_turn':
                problem = self._turn_problem(parameter.value)
                if problem is not None:
                    return SetParametersResult(successful=False, reason=problem)
            if parameter.name == 'bag_name' and (
                '/' in parameter.value or parameter.value in ('.', '..')
            ):
                return SetParametersResult(
                    successful=False,
                    reason=(f'bag_name must be a plain directory name, got {parameter.value!r}'),
                )
            if parameter.name == 'output_dir' and not parameter.value:
                return SetParametersResult(successful=False, reason='output_dir must not be empty')
            if parameter.name == 'model' and parameter.value not in MODEL_CHOICES:
                return SetParametersResult(
                    successful=False,
                    reason=(
                        f"model must be '' or one of {', '.join(MODELS)}, got {parameter.value!r}"
                    ),
                )
            if parameter.name == 'parameters_file' and parameter.value:
                try:
                    read_parameters_file(parameter.value)
                except HexacalContractError as error:
                    return SetParametersResult(
                        successful=False, reason=f'parameters_file: {error}'
                    )
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'flush_every_s':
                self._flush_timer.timer_period_ns = int(parameter.value * NS_PER_S)
            if parameter.name == 'device_turn':
                previous, self.device_turn = self.device_turn, float(parameter.value)
                if self.device_turn != previous:
                    self.get_logger().info(
                        f'device_turn {previous:.6g} -> {self.device_turn:.6g} rad: postures '
                        f'from now on whose inclinometer message has no {DEVICE_TURN_JOINT} '
                        'joint carry it'
                    )

    # ------------------------------------------------------------------ streams

    def _poll(self) -> None:
        """Take every queued sensor message, handle them in stamp order, then run the detector."""
        batches = []
        for source in self._sources:
            taken = []
            try:
                with source.subscription.handle:
                    take = source.subscription.handle.take_message
                    while len(taken) < SENSOR_SUBSCRIPTION_QOS.depth:  # bounded under any flow
                        item = take(source.message_type, True)
                        if item is None:
                            break
                        taken.append((_stamp_of(item[0]), source, item[0], item[1]))
            except InvalidHandle:
                continue  # shutting down
            if taken:
                batches.append(taken)
        if len(batches) > 1:  # each stream keeps its arrival order
            messages = heapq.merge(*batches, key=lambda entry: entry[0])
        else:
            messages = batches[0] if batches else ()
        for _, source, data, info in messages:
            self._on_raw(source, data, info)
        self._detect()
        for source in self._recorded_only:
            self._take_recorded_only(source)

    def _on_raw(self, source: _Source, data: bytes, info: dict) -> None:
        """One message of an input topic: recorded once, each input's reading taken once."""
        now_ns = time.monotonic_ns()
        for topic in source.inputs:
            self.received[topic] += 1
            self._last_receipt_ns[topic] = now_ns
        received_ns = info.get('received_timestamp') or self.get_clock().now().nanoseconds
        self._record(source.name, data, received_ns, info.get('source_timestamp') or None)
        readings = None
        if source.fast is not None:
            raw = source.fast.read(data)
            if raw is not None:
                if source.has_inclinometer:
                    self._note_turn(raw[0], source.fast.last_turn)
                if source.stream is not None:  # one input, its values as read: the 1 kHz path
                    samples = self.synchronizer.add_values(source.stream, *raw)
                    if samples:
                        self._samples += samples
                    return
                readings = self._split(source, *raw)
        if readings is None:
            readings = self._decode(source, data)
            if readings is None:
                return
        stamp, values = readings
        for topic, reading in values:
            samples = self.synchronizer.add_values(_STREAM_OF_TOPIC[topic], stamp, reading)
            if samples:
                self._samples += samples

    def _split(self, source: _Source, stamp: int, raw: tuple[float, ...]):
        """(stamp, [(input, values)]) of a fast read: each input's slice, the inclinometer corrected."""
        if source.message_type is Imu:
            angles = (
                self.mapping.inclinometer_angles(*raw) if self._transform_inclinometer else raw
            )
            return stamp, [(INCLINOMETER_TOPIC, angles)]
        values = []
        for topic, start, end in source.slices:
            reading = raw[start:end]
            if topic == INCLINOMETER_TOPIC and self._transform_inclinometer:
                reading = self.mapping.inclinometer_angles(*reading)
            values.append((topic, reading))
        return stamp, values

    def _decode(self, source: _Source, data: bytes):
        """rclpy decoding and the contract's checks: (stamp_ns, [(input, values)] of the valid
        inputs), None if none is valid; learns the in-place reader from a fully valid message."""
        try:
            message = deserialize_message(data, source.message_type)
        except Exception as error:  # noqa: BLE001 - any undecodable bytes count as invalid
            for topic in source.inputs:
                self._invalid(topic, f'cannot decode a {source.type_name}: {error}')
            return None
        values = []
        stamp = None
        for topic in source.inputs:
            try:
                if topic == SLIDERS_TOPIC:
                    sliders = self._slider_reading(message)
                    stamp, reading = sliders.stamp_ns, sliders.slider_positions
                elif topic == INCLINOMETER_TOPIC:
                    imu = source.message_type is Imu
                    angles = (
                        imu_to_inclinometer_reading(message, self.mapping)
                        if imu
                        else joint_state_to_inclinometer_reading(message, self.mapping)
                    )
                    stamp, reading = angles.stamp_ns, (angles.alpha, angles.beta)
                    carried = not imu and DEVICE_TURN_JOINT in message.name
                    self._note_turn(stamp, angles.device_turn if carried else None)
                else:
                    rotary = joint_state_to_encoder_reading(message, self.mapping)
                    stamp, reading = rotary.stamp_ns, (rotary.phi,)
            except InvalidReadingError as error:
                self._invalid(topic, str(error))
                continue
            values.append((topic, reading))
        if not values:
            return None
        if len(values) == len(source.inputs):
            try:
                fast = (
                    _FastImu(data, message)
                    if source.message_type is Imu
                    else _FastJointState(data, message, source.wanted)
                )
            except (ValueError, KeyError, struct.error):
                pass  # decoded the full way every time
            else:
                raw = fast.read(data)
                if raw is not None and self._split(source, *raw) == (stamp, values):
                    source.fast = fast
        return stamp, values

    def _slider_reading(self, message: JointState):
        """The actuator joints of a sliders message; another model's joints are named."""
        try:
            return joint_state_to_slider_reading(message, self.model, self.mapping)
        except InvalidReadingError as error:
            carried = actuator_model(message.name)
            if carried is not None and carried.name != self.model:
                raise InvalidReadingError(
                    f'{error}; it carries the actuator joints of a {carried.name} '
                    f'({carried.actuator_names[0]}..{carried.actuator_names[-1]}) but this '
                    f'collector records a {self.model} (parameters model / parameters_file)'
                ) from None
            raise

    def _take_recorded_only(self, source: _Source) -> None:
        """Record what arrived on a recorded-only topic (platform pose, machine markers)."""
        try:
            with source.subscription.handle:
                take = source.subscription.handle.take_message
                for _ in range(SENSOR_SUBSCRIPTION_QOS.depth):
                    item = take(source.message_type, True)
                    if item is None:
                        break
                    self._record_only(source, *item)
        except InvalidHandle:
            pass  # shutting down

    def _record_only(self, source: _Source, data: bytes, info: dict) -> None:
        if self.writer is None:
            return
        if source.name not in self._recorded_only_added:
            try:
                self.writer.add_topic(source.name, source.type_name, source.qos_yaml)
            except BagError as error:
                self._recording_failed(error)
                return
            self._recorded_only_added.add(source.name)
        received_ns = info.get('received_timestamp') or self.get_clock().now().nanoseconds
        self._record(source.name, data, received_ns, info.get('source_timestamp') or None)

    def _detect(self) -> None:
        """Run the posture detector over the samples paired since the last call."""
        if not self._samples:
            return
        samples, self._samples = self._samples, []
        for posture in self.detector.update(
            [stamp for stamp, _ in samples], [values for _, values in samples]
        ):
            self._on_posture(posture)

    def _poll_lost(self) -> None:
        """Read the DDS loss reports of the polled subscriptions (the executor does not wait on
        them); a report calls _on_lost as the executor would."""
        for handlers in self._lost_handlers.values():
            for handler in handlers:
                handler._ready_to_take_data = True  # what a ready wait set sets before take_data
                try:
                    status = handler.take_data()
                except InvalidHandle:
                    continue
                if status is not None and status.total_count_change:
                    handler.callback(status)

    def _on_lost(self, topic: str, status) -> None:
        self.lost[topic] = int(status.total_count)

    def _invalid(self, topic: str, problem: str) -> None:
        self.invalid[topic] = self.invalid.get(topic, 0) + 1
        self.get_logger().warning(
            f'ignored an invalid message on {self.topic_names[topic]} '
            f'({self.invalid[topic]} so far): {problem}',
            throttle_duration_sec=INVALID_LOG_PERIOD_S,
        )

    def _note_turn(self, stamp_ns: int, turn: float | None) -> None:
        """The device turn an inclinometer message stamped `stamp_ns` carries (None: none)."""
        changes = self._turn_changes
        if changes:
            if changes[-1][1] == turn:
                return
        elif turn is None:
            return  # nothing carried yet: the parameter
        changes.append((stamp_ns, turn))
        if len(changes) > MAX_TURN_CHANGES:
            del changes[: len(changes) - MAX_TURN_CHANGES]

    def _turn_at(self, stamp_ns: int) -> float:
        """The device turn of a posture stamped `stamp_ns` (its last sample): the one the
        inclinometer messages carried then, else the device_turn parameter."""
        changes = self._turn_changes
        limit = stamp_ns + self.synchronizer.max_skew_ns  # the paired inclinometer stamp
        at = bisect.bisect_right(changes, limit, key=lambda change: change[0])
        turn = changes[at - 1][1] if at else None
        if at > 1:
            del changes[: at - 1]  # later postures are later
        return self.device_turn if turn is None else turn

    def _on_posture(self, posture: DetectedPosture) -> None:
        turn = self._turn_at(posture.reading.stamp_ns)
        reading = posture.reading if turn == 0.0 else replace(posture.reading, device_turn=turn)
        message = posture_reading_to_joint_state(reading, model=self.model)
        if self.writer is not None:
            # Durable before it is published: whoever received a posture finds it in the bag.
            # BagWriter.write encodes the exact wire CDR; rclpy's serialize_message appends
            # padding bytes that strict readers (rosbags) reject.
            self._record(
                self.topic_names[POSTURE_TOPIC], message, self.get_clock().now().nanoseconds
            )
            if self.writer is not None:
                self.bag_postures += 1
                self._flush()
        self._posture_pub.publish(message)
        self.postures_published += 1
        spread_um = max(posture.std[:6]) * 1e6
        spread_urad = max(posture.std[6:]) * 1e6
        turned = f', device turn {turn:.6g} rad' if turn != 0.0 else ''
        self.get_logger().info(
            f'posture {self.postures_published}: {posture.sample_count} samples, '
            f'std <= {spread_um:.1f} um (sliders) / {spread_urad:.1f} urad (angles){turned}'
        )

    # ------------------------------------------------------------------ recording

    def _record(
        self,
        name: str,
        data: bytes | JointState,
        log_time_ns: int,
        publish_time_ns: int | None = None,
    ) -> None:
        """Write CDR bytes as received, or encode a message, on the bag topic `name`; a bag error
        stops recording."""
        if self.writer is None:
            return
        try:
            if isinstance(data, bytes):
                self.writer.write_raw(name, data, log_time_ns, publish_time_ns)
            else:
                self.writer.write(name, data, log_time_ns)
        except BagError as error:
            self._recording_failed(error)

    def _recording_failed(self, error: BagError) -> None:
        """Stop recording after a bag error (e.g. disk full); the bag stays readable."""
        self.recording_error = f'{error.reason}: {error}'
        self.get_logger().error(f'recording stopped: {error}')
        self.close_bag()
        self._publish_status()

    def _flush(self) -> None:
        if self.writer is None or self.writer.message_count == self.writer.flushed_message_count:
            return
        try:
            self.writer.flush()
        except BagError as error:
            self._recording_failed(error)

    def _next_bag_directory(self) -> Path:
        output_dir = Path(self.get_parameter('output_dir').value)
        base = self.get_parameter('bag_name').value or datetime.now().strftime(
            'hexacal_%Y%m%d_%H%M%S'
        )
        self._bag_counter += 1
        candidate = output_dir / base
        if self.get_parameter('bag_name').value and self._bag_counter == 1:
            return candidate  # an explicit name is used as given (BagWriter refuses to overwrite)
        suffix = 1
        while candidate.exists():
            suffix += 1
            candidate = output_dir / f'{base}_{suffix}'
        return candidate

    def open_bag(self) -> str:
        """Start recording into a new bag directory; returns its path (BagError on failure)."""
        if self.writer is not None:
            return str(self.writer.directory)
        directory = self._next_bag_directory()
        try:
            writer = BagWriter(
                directory,
                custom_data={
                    'hexacal.recorded_by': self.get_fully_qualified_name(),
                    MODEL_CUSTOM_DATA: self.model,
                    INPUTS_CUSTOM_DATA: json.dumps(self.mapping.to_metadata()),
                },
            )
        except BagError as error:
            self.get_logger().error(f'cannot record to {directory}: {error}')
            raise
        try:
            # The inputs under their real topics and types (e.g. /joint_states once for all three).
            for source in self._sources:
                writer.add_topic(source.name, source.type_name, source.qos_yaml)
            writer.add_topic(
                self.topic_names[POSTURE_TOPIC], JOINT_STATE_TYPE, self._qos_yaml[POSTURE_TOPIC]
            )
            writer.write_metadata(
                COLLECTOR_METADATA,
                {
                    'namespace': self.get_namespace(),
                    'model': self.model,
                    **self.detector_settings,
                    **self.mapping.to_metadata(),
                },
            )
        except BagError as error:
            self.get_logger().error(f'cannot record to {directory}: {error}')
            try:
                writer.close()
            except BagError:
                pass  # already reported
            raise
        self.writer, self.bag_postures = writer, 0
        self._recorded_only_added = set()
        self.recording_error = None
        self._plan_recorded, self._plan_request = False, None
        self.get_logger().info(f'recording to {directory}')
        return str(directory)

    def close_bag(self, log: bool = True) -> str | None:
        """Finish the bag (metadata.yaml); returns what happened, None if not recording."""
        writer, self.writer = self.writer, None
        if writer is None:
            return None
        try:
            writer.close()
            text = (
                f'closed bag {writer.directory}: {writer.message_count} messages, '
                f'{self.bag_postures} postures'
            )
        except BagError as error:
            text = f'closing {writer.directory}: {error}'
        if log:
            self.get_logger().info(text)
        return text

    def _start_recording(
        self, request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        if self.writer is not None:
            response.success = True
            response.message = f'already recording to {self.writer.directory}'
            return response
        try:
            response.message = f'recording to {self.open_bag()}'
            response.success = True
        except BagError as error:
            response.success, response.message = False, f'cannot record: {error}'
        return response

    def _stop_recording(
        self, request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        text = self.close_bag()
        response.success = text is not None
        response.message = text or 'not recording'
        return response

    # ------------------------------------------------------------------ housekeeping

    def _housekeeping(self) -> None:
        self._poll_lost()
        now_ns = self.get_clock().now().nanoseconds
        status = self.synchronizer.status(now_ns)
        silent = list(
            dict.fromkeys(
                self.topic_names[topic]
                for topic, name in (
                    (SLIDERS_TOPIC, 'sliders'),
                    (INCLINOMETER_TOPIC, 'inclinometer'),
                    (ENCODER_TOPIC, 'encoder'),
                )
                if status[name].last_stamp_ns is not None and status[name].stale
            )
        )
        if silent:
            self.get_logger().warning(
                f'no recent data on {", ".join(silent)}', throttle_duration_sec=STALE_LOG_PERIOD_S
            )
        self._check_streams()
        self._publish_status()
        self._request_plan()

    def _check_streams(self) -> None:
        """Report streams that stopped (receipt time) and drop a posture they leave half-captured."""
        now_ns = time.monotonic_ns()
        # Inputs remapped to one topic stop together: the topic is named once.
        stopped = tuple(
            dict.fromkeys(
                self.topic_names[topic]
                for topic in RAW_TOPICS
                if topic in self._last_receipt_ns
                and now_ns - self._last_receipt_ns[topic] > STREAM_STOPPED_S * NS_PER_S
            )
        )
        if stopped != self.stopped_streams:
            if stopped:
                self.get_logger().warning(
                    f'stream(s) stopped: no message on {", ".join(stopped)} for '
                    f'{STREAM_STOPPED_S:g} s'
                )
            else:
                self.get_logger().info(f'stream(s) resumed: {", ".join(self.stopped_streams)}')
            self.stopped_streams = stopped
        if stopped:
            self._detect()  # normally nothing left: _poll runs the detector after each batch
            dropped = self.detector.abort(DROPPED_FOR_STREAM_STOP)
            if dropped is not None:
                self.get_logger().warning(
                    f'dropped a partial posture ({dropped.sample_count} samples over '
                    f'{(dropped.last_stamp_ns - dropped.first_stamp_ns) / NS_PER_S:.2f} s, '
                    f'never published): {", ".join(stopped)} stopped'
                )

    def problems(self) -> dict[str, object]:
        """Counters of everything not used, by stream and reason (what the status reports)."""
        problems: dict[str, object] = {}
        for topic, count in sorted(self.invalid.items()):
            problems[f'invalid.{topic}'] = count
        for topic, count in sorted(self.lost.items()):
            if count:
                problems[f'lost.{topic}'] = count
        for stream, reasons in self.synchronizer.rejected.items():
            for reason, count in sorted(reasons.items()):
                problems[f'rejected.{stream}.{reason}'] = count
        for reason, count in sorted(self.synchronizer.unpaired.items()):
            problems[f'unpaired.{reason}'] = count
        for reason, count in sorted(self.detector.rejected.items()):
            problems[f'rejected.samples.{reason}'] = count
        for reason, count in sorted(self.detector.dropped.items()):
            problems[f'dropped.{reason}'] = count
        if self.stopped_streams:
            problems['streams_stopped'] = ', '.join(self.stopped_streams)
        if self.recording_error:
            problems['recording_error'] = self.recording_error
        return problems

    def _publish_status(self) -> None:
        """Publish on hexacal/calibration_status when a problem counter or state changed."""
        problems = self.problems()
        if problems == self._reported:
            return
        previous = self._reported or {}
        changed = [key for key, value in problems.items() if previous.get(key) != value]
        self._reported = problems
        if self.recording_error:
            level, outcome = 'ERROR', 'recording-stopped'
            message = f'recording stopped: {self.recording_error}'
        else:
            level = 'WARN' if changed else 'OK'  # a new or grown problem; 'OK' once all clear
            outcome = 'recording' if self.writer is not None else 'not-recording'
            message = (
                '; '.join(f'{key}: {problems[key]}' for key in changed)
                if changed
                else 'no new problems'
            )
        values: dict[str, object] = {
            'outcome': outcome,
            'postures_published': self.postures_published,
            'bag': str(self.writer.directory) if self.writer is not None else '',
            **{f'received.{topic}': count for topic, count in self.received.items()},
            **problems,
        }
        self._status_pub.publish(
            diagnostic_status(
                level,
                STATUS_NAME,
                message,
                values,
                hardware_id=self.get_fully_qualified_name(),
                stamp=self.get_clock().now().nanoseconds,
            )
        )
        # Invalid messages, stopped streams, their dropped postures and recording errors are
        # logged where they happen.
        counters = [
            key
            for key in changed
            if not key.startswith(
                (
                    'invalid.',
                    'streams_stopped',
                    'recording_error',
                    f'dropped.{DROPPED_FOR_STREAM_STOP}',
                )
            )
        ]
        if counters:
            self.get_logger().warning(
                'not used: ' + '; '.join(f'{key}: {problems[key]}' for key in counters),
                throttle_duration_sec=INVALID_LOG_PERIOD_S,
            )

    def _request_plan(self) -> None:
        """Ask the driver for its plan once per bag (optional: the bag is fine without it)."""
        if self.writer is None or self._plan_recorded or self._plan_request is not None:
            return
        if not self._driver_parameters.services_are_ready():
            return
        writer = self.writer
        self._plan_request = self._driver_parameters.get_parameters(list(DRIVER_PLAN_PARAMETERS))
        self._plan_request.add_done_callback(lambda future: self._record_plan(writer, future))

    def _record_plan(self, writer: BagWriter, future) -> None:
        self._plan_request = None
        if writer is not self.writer or future.exception() is not None:
            return
        plan = {}
        for name, value in zip(DRIVER_PLAN_PARAMETERS, future.result().values):
            python_value = parameter_value_to_python(value)
            if python_value is not None:
                plan[name] = str(python_value)
        if not plan:
            return
        try:
            writer.write_metadata(PLAN_METADATA, plan)
        except BagError as error:
            self._recording_failed(error)
            return
        self._plan_recorded = True
        self.get_logger().info(f"recorded the driver's plan {plan.get('plan_name', plan)}")

    def summary(self) -> str:
        self.detector.abort(DROPPED_AT_END)  # a posture still being captured is never published
        dropped = self.detector.dropped
        rejected = {
            stream: reasons for stream, reasons in self.synchronizer.rejected.items() if reasons
        }
        return (
            f'{self.postures_published} postures published; messages received '
            f'{self.received}; invalid messages {self.invalid or 0}; lost {self.lost or 0}; '
            f'stamps rejected {rejected or 0}; periods dropped {dropped or 0}; '
            f'unpaired samples {self.synchronizer.unpaired or 0}'
        )


def _finish(node: CollectorNode) -> list[str]:
    closed = node.close_bag(log=False)  # metadata.yaml and the MCAP footer: the bag is complete
    return [closed, node.summary()]


def main(args: list[str] | None = None) -> int:
    return run_node(
        NODE_NAME,
        CollectorNode,
        args=args,
        finish=_finish,
        startup_errors=(
            InvalidParameterValueException,
            InvalidParameterTypeException,
            BagError,
            CollectorConfigurationError,
            HexacalContractError,
        ),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
