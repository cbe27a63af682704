"""
Conversions between ROS messages and hexacal contract types.

Imports the message packages but not rclpy, so it works in offline tools
(e.g. bag processing). Joints are looked up by name: order does not matter and
extra joints are ignored.

The actuator joints depend on the machine model (models.py): ``slider_1..6``
on a Hexa Slide, ``leg_1..6`` on a Gough-Stewart platform. Every conversion
that reads or writes actuator joints or parameters takes ``model`` (a model
name or a ``ModelLayout``), defaulting to the Hexa Slide, so callers written
before other models existed keep working unchanged. `actuator_model` tells
which model a message's joint names belong to.

The sensor conversions also take an `InputMapping` (inputs.py): the joint
names a user's drivers publish (e.g. one ros2_control ``/joint_states``), an
inclinometer that is a ``sensor_msgs/Imu`` (`imu_to_inclinometer_reading`, by
the convention inputs.py writes down) and per-channel inclinometer signs and
zero offsets. Without one, the contract's names are read, as always.

The device's turn about its link axis (rad: 0 normal mounting, pi reversed,
pi/2 a quarter turn) travels as the optional joint ``device_turn``
(DEVICE_TURN_JOINT) of the inclinometer and posture JointStates, whatever the
mapping: absent means 0, and it is written only when non-zero, so messages and
bags of a normally mounted device carry no trace of it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import math
import numbers

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from hexacal_msgs_py.deprecation import deprecated_attribute
from hexacal_msgs_py.errors import InvalidParametersError, InvalidReadingError
from hexacal_msgs_py.inputs import (
    imu_inclinometer_angles,
    inclinometer_angles_to_quaternion,
    InputMapping,
)
from hexacal_msgs_py.models import (
    DEFAULT_MODEL,
    model_for_actuator_names,
    model_for_vector_size,
    model_layout,
    ModelLayout,
    MODELS,
)
from hexacal_msgs_py.names import (
    DEVICE_TURN_JOINT,
    ENCODER_NAMES,
    INCLINOMETER_NAMES,
    LINK_LENGTH_JOINT,
)
from hexacal_msgs_py.parameters_file import validate_parameters
from hexacal_msgs_py.readings import (
    ActuatorReading,
    EncoderReading,
    InclinometerReading,
    NS_PER_S,
    PostureReading,
    PostureScatter,
)
import numpy as np
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, Header, MultiArrayDimension, MultiArrayLayout


ModelArgument = str | ModelLayout | None  # a model name or layout; None: the Hexa Slide


def layout_of(model: ModelArgument = None) -> ModelLayout:
    """
    Return the layout `model` names.

    The layout `model` names (None: the Hexa Slide; an unknown name: InvalidParametersError).
    """
    if isinstance(model, ModelLayout):
        return model
    return model_layout(DEFAULT_MODEL if model is None else model)


def parameters_layout(model: ModelArgument = None) -> tuple[tuple[str, int, int], ...]:
    """Float64MultiArray layout (label, size, stride) of a model's parameters: chains x fields."""
    layout = layout_of(model)
    return (
        ('chain', layout.n_chains, layout.n_parameters),
        (','.join(layout.fields), layout.fields_per_chain, layout.fields_per_chain),
    )


# Float64MultiArray layout of the parameters topic for the Hexa Slide: 6 chains x 9 fields
# (Gough-Stewart: 6 x 7, parameters_layout('gough_stewart')).
PARAMETERS_LAYOUT: tuple[tuple[str, int, int], ...] = parameters_layout()
_MODEL_OF_PARAMETERS_LAYOUT = {parameters_layout(layout): layout for layout in MODELS.values()}

DIAGNOSTIC_LEVELS = {
    'OK': DiagnosticStatus.OK,
    'WARN': DiagnosticStatus.WARN,
    'ERROR': DiagnosticStatus.ERROR,
    'STALE': DiagnosticStatus.STALE,
}
# Every status also carries its level's name as a value (the level itself is a byte).
LEVEL_NAME_KEY = 'level_name'
LEVEL_NAMES = {level[0]: name for name, level in DIAGNOSTIC_LEVELS.items()}


def stamp_ns(stamp: Time) -> int:
    """builtin_interfaces/Time -> integer ns."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def to_stamp(ns: int) -> Time:
    """Integer ns -> builtin_interfaces/Time (nanosec always in [0, 1e9))."""
    seconds, nanoseconds = divmod(int(ns), NS_PER_S)
    return Time(sec=seconds, nanosec=nanoseconds)


def _joint_positions(msg: JointState, names: Sequence[str], what: str) -> list[float]:
    if len(msg.name) != len(msg.position):
        raise InvalidReadingError(
            f'{what}: JointState has {len(msg.name)} names but {len(msg.position)} positions'
        )
    index: dict[str, int] = {}
    for i, name in enumerate(msg.name):
        if name in index and name in names:
            raise InvalidReadingError(f"{what}: joint '{name}' appears more than once")
        index[name] = i
    missing = [name for name in names if name not in index]
    if missing:
        raise InvalidReadingError(
            f'{what}: JointState lacks joint(s) {", ".join(missing)} (names: {list(msg.name)})'
        )
    positions = []
    for name in names:
        try:
            value = float(msg.position[index[name]])
        except (TypeError, ValueError, IndexError) as error:
            raise InvalidReadingError(
                f"{what}: joint '{name}' position is not a number: {error}"
            ) from None
        if not math.isfinite(value):
            raise InvalidReadingError(f"{what}: joint '{name}' position is {value!r}")
        positions.append(value)
    return positions


def _device_turn(msg: JointState, what: str) -> float:
    """
    Return the optional DEVICE_TURN_JOINT position of `msg` (rad).

    The optional DEVICE_TURN_JOINT position of `msg` (rad); 0.0 when the joint is absent.
    """
    names = list(msg.name)
    if DEVICE_TURN_JOINT not in names:
        return 0.0
    (turn,) = _joint_positions(msg, (DEVICE_TURN_JOINT,), what)
    return turn


def _with_turn(
    names: Sequence[str], values: Sequence[float], turn: float
) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """Names and values with the device_turn joint appended when `turn` is non-zero."""
    if turn == 0.0:
        return tuple(names), tuple(values)
    return tuple(names) + (DEVICE_TURN_JOINT,), tuple(values) + (turn,)


def _joint_state(
    stamp: int, names: Sequence[str], positions: Sequence[float], frame_id: str
) -> JointState:
    return JointState(
        header=Header(stamp=to_stamp(stamp), frame_id=frame_id),
        name=list(names),
        position=[float(p) for p in positions],
    )


def actuator_model(names: Sequence[str]) -> ModelLayout | None:
    """
    Return the model whose six actuator joints all appear in `names`.

    The model whose six actuator joints all appear in `names` (a JointState's name list), or None.
    """
    return model_for_actuator_names(names)


def joint_state_to_actuator_reading(
    msg: JointState, model: ModelArgument = None, mapping: InputMapping | None = None
) -> ActuatorReading:
    """
    Convert a JointState with the model's actuator joints (m) to a ActuatorReading.

    JointState with the model's actuator joints (m) -> ActuatorReading.

    Hexa Slide (default): slider_1..slider_6; Gough-Stewart: leg_1..leg_6; with a
    `mapping`, its actuator_joints (in chain order) instead.
    """
    names = mapping.actuator_joints if mapping is not None else layout_of(model).actuator_names
    positions = _joint_positions(msg, names, 'sliders')
    return ActuatorReading(stamp_ns(msg.header.stamp), tuple(positions))


def joint_state_to_inclinometer_reading(
    msg: JointState, mapping: InputMapping | None = None
) -> InclinometerReading:
    """
    Convert a JointState with the inclinometer joints (rad) to a reading.

    JointState with joints inclinometer_x (alpha), inclinometer_y (beta) (rad).

    With a `mapping`: its inclinometer_joints, then its signs and offsets
    (alpha = sign * (position - offset), inputs.py). The optional joint
    device_turn (rad) gives the reading's device_turn; absent, it is 0.
    """
    if mapping is None:
        alpha, beta = _joint_positions(msg, INCLINOMETER_NAMES, 'inclinometer')
    else:
        alpha, beta = mapping.inclinometer_angles(
            *_joint_positions(msg, mapping.inclinometer_joints, 'inclinometer')
        )
    turn = _device_turn(msg, 'inclinometer')
    return InclinometerReading(stamp_ns(msg.header.stamp), alpha, beta, turn)


def imu_to_inclinometer_reading(
    msg: Imu, mapping: InputMapping | None = None
) -> InclinometerReading:
    """
    Convert a sensor_msgs/Imu to an InclinometerReading.

    sensor_msgs/Imu -> InclinometerReading: alpha, beta from the orientation (inputs.py's
    convention), then the mapping's signs and offsets.

    An Imu without an orientation estimate (orientation_covariance[0] = -1) or whose
    orientation is not a finite unit quaternion raises InvalidReadingError.
    """
    orientation = msg.orientation
    raw = imu_inclinometer_angles(
        (orientation.x, orientation.y, orientation.z, orientation.w),
        float(msg.orientation_covariance[0]),
    )
    alpha, beta = mapping.inclinometer_angles(*raw) if mapping is not None else raw
    return InclinometerReading(stamp_ns(msg.header.stamp), alpha, beta)


def inclinometer_angles_to_imu(
    reading: InclinometerReading,
    frame_id: str = '',
    mapping: InputMapping | None = None,
    yaw: float = 0.0,
) -> Imu:
    """
    Return an Imu whose orientation reads as `reading`.

    An Imu whose orientation reads as `reading` (after the mapping's signs and offsets), with
    heading `yaw`: what a simulated IMU on the link publishes. Only the orientation is filled;
    angular velocity and linear acceleration are marked unknown (covariance[0] = -1).
    """
    raw = (
        mapping.raw_inclinometer(reading.alpha, reading.beta)
        if mapping is not None
        else (reading.alpha, reading.beta)
    )
    x, y, z, w = inclinometer_angles_to_quaternion(*raw, yaw=yaw)
    message = Imu(header=Header(stamp=to_stamp(reading.stamp_ns), frame_id=frame_id))
    message.orientation.x, message.orientation.y = x, y
    message.orientation.z, message.orientation.w = z, w
    message.angular_velocity_covariance[0] = -1.0
    message.linear_acceleration_covariance[0] = -1.0
    return message


def joint_state_to_encoder_reading(
    msg: JointState, mapping: InputMapping | None = None
) -> EncoderReading:
    """
    Convert a JointState with the rotary joint (rad) to an EncoderReading.

    JointState with joint rotary (phi, rad) -> EncoderReading (the mapping's rotary_joint).
    """
    names = ENCODER_NAMES if mapping is None else (mapping.rotary_joint,)
    (phi,) = _joint_positions(msg, names, 'encoder')
    return EncoderReading(stamp_ns(msg.header.stamp), phi)


def joint_state_to_posture_reading(msg: JointState, model: ModelArgument = None) -> PostureReading:
    """
    Convert a JointState with all of the model's posture joints to a PostureReading.

    JointState with all of the model's posture joints -> PostureReading.

    The posture joints are the six actuators of the model (Hexa Slide, the
    default: slider_1..6; Gough-Stewart: leg_1..6), then inclinometer_x,
    inclinometer_y, rotary; the optional joint device_turn (rad, absent: 0)
    gives the reading's device_turn.  Where the message carries one value per joint in
    `velocity` and `effort`, they are the posture's scatter (PostureScatter: the standard errors
    of the means and the sample counts); else the reading has none.
    """
    names = layout_of(model).posture_names
    values = _joint_positions(msg, names, 'posture')
    turn = _device_turn(msg, 'posture')
    link_length = _link_length(msg)
    scatter = _posture_scatter(msg, names, link_length is not None)
    return PostureReading.from_values(
        stamp_ns(msg.header.stamp),
        values,
        device_turn=turn,
        scatter=scatter,
        link_length=link_length,
    )


def _link_length(msg: JointState) -> float | None:
    """Return the optional LINK_LENGTH_JOINT position of a posture (m), None when absent."""
    if LINK_LENGTH_JOINT not in msg.name:
        return None
    (length,) = _joint_positions(msg, (LINK_LENGTH_JOINT,), 'posture')
    return length


def _posture_scatter(
    msg: JointState, names: Sequence[str], with_link: bool = False
) -> PostureScatter | None:
    """Return the scatter a posture JointState carries in velocity/effort, or None."""
    count = len(msg.name)
    if count == 0 or len(msg.velocity) != count or len(msg.effort) != count:
        return None
    index = {name: i for i, name in enumerate(msg.name)}
    link_error = link_count = None
    if with_link:
        link_error = msg.velocity[index[LINK_LENGTH_JOINT]]
        link_count = msg.effort[index[LINK_LENGTH_JOINT]]
    return PostureScatter(
        tuple(msg.velocity[index[name]] for name in names),
        tuple(msg.effort[index[name]] for name in names),
        link_length_standard_error=link_error,
        link_length_sample_count=link_count,
    )


def actuator_reading_to_joint_state(
    reading: ActuatorReading, frame_id: str = '', model: ModelArgument = None
) -> JointState:
    """
    Convert a ActuatorReading to a JointState with the model's actuator joints.

    ActuatorReading -> JointState with the model's actuator joints (default slider_1..6).
    """
    return _joint_state(
        reading.stamp_ns, layout_of(model).actuator_names, reading.actuator_positions, frame_id
    )


def inclinometer_reading_to_joint_state(
    reading: InclinometerReading, frame_id: str = ''
) -> JointState:
    """
    Convert an InclinometerReading to a JointState.

    InclinometerReading -> JointState inclinometer_x, inclinometer_y (and device_turn if non-zero).
    """
    names, values = _with_turn(
        INCLINOMETER_NAMES, (reading.alpha, reading.beta), reading.device_turn
    )
    return _joint_state(reading.stamp_ns, names, values, frame_id)


def encoder_reading_to_joint_state(reading: EncoderReading, frame_id: str = '') -> JointState:
    return _joint_state(reading.stamp_ns, ENCODER_NAMES, (reading.phi,), frame_id)


def posture_reading_to_joint_state(
    reading: PostureReading, frame_id: str = '', model: ModelArgument = None
) -> JointState:
    """
    Convert a PostureReading to a JointState with the model's posture joints.

    PostureReading -> JointState with the model's posture joints (default: the Hexa Slide's), then
    device_turn when the reading's device_turn is non-zero, then link_length (m) when the reading
    has a measured link length.  A reading's scatter goes into `velocity` (standard errors of
    the means, m or rad) and `effort` (sample counts); the device_turn joint, set and not
    measured, gets 0 and 1, and so does link_length when the scatter does not know its own.
    """
    names, values = _with_turn(
        layout_of(model).posture_names, reading.values(), reading.device_turn
    )
    if reading.link_length is not None:
        names, values = names + (LINK_LENGTH_JOINT,), values + (reading.link_length,)
    message = _joint_state(reading.stamp_ns, names, values, frame_id)
    scatter = reading.scatter
    if scatter is not None:
        turn = [DEVICE_TURN_JOINT] if DEVICE_TURN_JOINT in names else []
        errors = [float(v) for v in scatter.standard_errors] + [0.0] * len(turn)
        counts = [float(n) for n in scatter.sample_counts] + [1.0] * len(turn)
        if reading.link_length is not None:
            link_error, link_count = _link_scatter(scatter)
            errors.append(link_error)
            counts.append(link_count)
        message.velocity = errors
        message.effort = counts
    return message


def _link_scatter(scatter: PostureScatter) -> tuple[float, float]:
    """Return the link length's standard error and count for velocity/effort (0, 1: unknown)."""
    error, count = scatter.link_length_standard_error, scatter.link_length_sample_count
    if error is None or count is None:
        return 0.0, 1.0
    return float(error), float(count)


def parameters_to_multiarray(vector: object, model: ModelArgument = None) -> Float64MultiArray:
    """
    Parameter vector -> Float64MultiArray with a chain x field layout.

    `model` defaults to the one model of the vector's size (54: Hexa Slide,
    6 x 9; 42: Gough-Stewart, 6 x 7); the dimension labels name the fields.
    """
    array = validate_parameters(vector, model)
    if model is None:
        model = model_for_vector_size(array.size)
    layout = MultiArrayLayout(
        dim=[
            MultiArrayDimension(label=label, size=size, stride=stride)
            for label, size, stride in parameters_layout(model)
        ],
        data_offset=0,
    )
    return Float64MultiArray(layout=layout, data=array.tolist())


def multiarray_model(msg: Float64MultiArray) -> ModelLayout:
    """
    Return the model whose layout a parameters message carries.

    The model whose layout a parameters message carries (InvalidParametersError if none).
    """
    layout = tuple((d.label, d.size, d.stride) for d in msg.layout.dim)
    if layout not in _MODEL_OF_PARAMETERS_LAYOUT:
        expected = ' or '.join(f'{parameters_layout(m)} ({m.name})' for m in MODELS.values())
        raise InvalidParametersError(
            f'parameters message layout must be {expected} (label, size, stride), got {layout}'
        )
    return _MODEL_OF_PARAMETERS_LAYOUT[layout]


def multiarray_to_parameters(msg: Float64MultiArray, model: ModelArgument = None) -> np.ndarray:
    """
    Float64MultiArray from parameters_to_multiarray() -> parameter vector (checked).

    Without `model` the layout of any known model is accepted (multiarray_model
    tells which); with `model`, only that model's.
    """
    layout = tuple((d.label, d.size, d.stride) for d in msg.layout.dim)
    if model is not None and layout != parameters_layout(model):
        raise InvalidParametersError(
            f'parameters message layout must be {parameters_layout(model)} (label, size, stride) '
            f'for a {layout_of(model).name}, got {layout}'
        )
    found = multiarray_model(msg)
    if msg.layout.data_offset != 0:
        raise InvalidParametersError(
            f'parameters message data_offset must be 0, got {msg.layout.data_offset}'
        )
    if len(msg.data) != found.n_parameters:
        raise InvalidParametersError(
            f'parameters message must hold {found.n_parameters} values, got {len(msg.data)}'
        )
    return validate_parameters(np.asarray(msg.data, dtype=np.float64), found.name)


def _level_byte(level: int | bytes | str) -> bytes:
    if isinstance(level, str):
        if level.upper() not in DIAGNOSTIC_LEVELS:
            raise ValueError(f'diagnostic level must be one of {sorted(DIAGNOSTIC_LEVELS)}')
        return DIAGNOSTIC_LEVELS[level.upper()]
    if isinstance(level, bytes):
        if len(level) != 1:
            raise ValueError(f'diagnostic level must be one byte, got {level!r}')
        number = level[0]
    else:
        number = int(level)
    if number not in range(4):
        raise ValueError(f'diagnostic level must be 0 (OK) .. 3 (STALE), got {number}')
    return bytes([number])


def _value_text(value: object) -> str:
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))  # full precision
    return str(value)


def diagnostic_status(
    level: int | bytes | str,
    name: str,
    message: str,
    values: Mapping[str, object] | None = None,
    hardware_id: str = '',
    stamp: int | None = None,
) -> DiagnosticArray:
    """
    Return a DiagnosticArray holding one DiagnosticStatus.

    DiagnosticArray holding one DiagnosticStatus; values become KeyValue strings.

    `level` is DiagnosticStatus.OK/WARN/ERROR/STALE, 0..3 or 'OK'..'STALE';
    `stamp` is in ns (the header stamp is left at zero when None).
    """
    level_byte = _level_byte(level)
    pairs = [
        KeyValue(key=str(key), value=_value_text(value)) for key, value in (values or {}).items()
    ]
    # DiagnosticStatus.level is a byte ('\x01' in `ros2 topic echo`): its name goes along.
    pairs.append(KeyValue(key=LEVEL_NAME_KEY, value=LEVEL_NAMES[level_byte[0]]))
    status = DiagnosticStatus(
        level=level_byte,
        name=name,
        message=message,
        hardware_id=hardware_id,
        values=pairs,
    )
    header = Header(stamp=to_stamp(stamp)) if stamp is not None else Header()
    return DiagnosticArray(header=header, status=[status])


def status_values(status: DiagnosticStatus) -> dict[str, str]:
    """Return the KeyValue list of a DiagnosticStatus as a dict (the publisher's values)."""
    return {kv.key: kv.value for kv in status.values if kv.key != LEVEL_NAME_KEY}


# Renamed names: still importable for users' scripts, with a DeprecationWarning.
DEPRECATED_NAMES = {
    'joint_state_to_slider_reading': 'joint_state_to_actuator_reading',
    'slider_reading_to_joint_state': 'actuator_reading_to_joint_state',
}


def __getattr__(name: str) -> object:
    """Return a renamed name's new object, warning (PEP 562); else AttributeError."""
    return deprecated_attribute(__name__, name, DEPRECATED_NAMES, globals())
