"""Conversions between ROS messages and hexacal contract types.

Imports the message packages but not rclpy, so it works in offline tools
(e.g. bag processing). Joints are looked up by name: order does not matter and
extra joints are ignored.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import math
import numbers

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Header, MultiArrayDimension, MultiArrayLayout

from hexacal_msgs_py.errors import InvalidParametersError, InvalidReadingError
from hexacal_msgs_py.names import (
    ENCODER_NAMES,
    INCLINOMETER_NAMES,
    N_CHAINS,
    N_PARAMETERS,
    N_PARAMETERS_PER_CHAIN,
    PARAMETER_FIELDS,
    POSTURE_NAMES,
    SLIDER_NAMES,
)
from hexacal_msgs_py.parameters_file import validate_parameters
from hexacal_msgs_py.readings import (
    EncoderReading,
    InclinometerReading,
    PostureReading,
    SliderReading,
)

NS_PER_S = 1_000_000_000

# Float64MultiArray layout of the parameters topic: 6 chains x 9 fields.
PARAMETERS_LAYOUT: tuple[tuple[str, int, int], ...] = (
    ('chain', N_CHAINS, N_PARAMETERS),
    (','.join(PARAMETER_FIELDS), N_PARAMETERS_PER_CHAIN, N_PARAMETERS_PER_CHAIN),
)

DIAGNOSTIC_LEVELS = {
    'OK': DiagnosticStatus.OK,
    'WARN': DiagnosticStatus.WARN,
    'ERROR': DiagnosticStatus.ERROR,
    'STALE': DiagnosticStatus.STALE,
}


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
            f'{what}: JointState has {len(msg.name)} names but {len(msg.position)} positions')
    index: dict[str, int] = {}
    for i, name in enumerate(msg.name):
        if name in index and name in names:
            raise InvalidReadingError(f"{what}: joint '{name}' appears more than once")
        index[name] = i
    missing = [name for name in names if name not in index]
    if missing:
        raise InvalidReadingError(
            f"{what}: JointState lacks joint(s) {', '.join(missing)} "
            f'(names: {list(msg.name)})')
    positions = []
    for name in names:
        try:
            value = float(msg.position[index[name]])
        except (TypeError, ValueError, IndexError) as error:
            raise InvalidReadingError(f"{what}: joint '{name}' position is not a number: "
                                      f'{error}') from None
        if not math.isfinite(value):
            raise InvalidReadingError(f"{what}: joint '{name}' position is {value!r}")
        positions.append(value)
    return positions


def _joint_state(stamp: int, names: Sequence[str], positions: Sequence[float],
                 frame_id: str) -> JointState:
    return JointState(
        header=Header(stamp=to_stamp(stamp), frame_id=frame_id),
        name=list(names),
        position=[float(p) for p in positions],
    )


def joint_state_to_slider_reading(msg: JointState) -> SliderReading:
    """JointState with joints slider_1..slider_6 (m) -> SliderReading."""
    positions = _joint_positions(msg, SLIDER_NAMES, 'sliders')
    return SliderReading(stamp_ns(msg.header.stamp), tuple(positions))


def joint_state_to_inclinometer_reading(msg: JointState) -> InclinometerReading:
    """JointState with joints inclinometer_x (alpha), inclinometer_y (beta) (rad)."""
    alpha, beta = _joint_positions(msg, INCLINOMETER_NAMES, 'inclinometer')
    return InclinometerReading(stamp_ns(msg.header.stamp), alpha, beta)


def joint_state_to_encoder_reading(msg: JointState) -> EncoderReading:
    """JointState with joint rotary (phi, rad) -> EncoderReading."""
    (phi,) = _joint_positions(msg, ENCODER_NAMES, 'encoder')
    return EncoderReading(stamp_ns(msg.header.stamp), phi)


def joint_state_to_posture_reading(msg: JointState) -> PostureReading:
    """JointState with all POSTURE_NAMES joints -> PostureReading."""
    values = _joint_positions(msg, POSTURE_NAMES, 'posture')
    return PostureReading.from_values(stamp_ns(msg.header.stamp), values)


def slider_reading_to_joint_state(reading: SliderReading, frame_id: str = '') -> JointState:
    return _joint_state(reading.stamp_ns, SLIDER_NAMES, reading.slider_positions, frame_id)


def inclinometer_reading_to_joint_state(
        reading: InclinometerReading, frame_id: str = '') -> JointState:
    return _joint_state(
        reading.stamp_ns, INCLINOMETER_NAMES, (reading.alpha, reading.beta), frame_id)


def encoder_reading_to_joint_state(reading: EncoderReading, frame_id: str = '') -> JointState:
    return _joint_state(reading.stamp_ns, ENCODER_NAMES, (reading.phi,), frame_id)


def posture_reading_to_joint_state(reading: PostureReading, frame_id: str = '') -> JointState:
    return _joint_state(reading.stamp_ns, POSTURE_NAMES, reading.values(), frame_id)


def parameters_to_multiarray(vector: object) -> Float64MultiArray:
    """54-vector -> Float64MultiArray with a 6 x 9 (chain x field) layout."""
    array = validate_parameters(vector)
    layout = MultiArrayLayout(
        dim=[MultiArrayDimension(label=label, size=size, stride=stride)
             for label, size, stride in PARAMETERS_LAYOUT],
        data_offset=0,
    )
    return Float64MultiArray(layout=layout, data=array.tolist())


def multiarray_to_parameters(msg: Float64MultiArray) -> np.ndarray:
    """Float64MultiArray from parameters_to_multiarray() -> 54-vector (checked)."""
    layout = tuple((d.label, d.size, d.stride) for d in msg.layout.dim)
    if layout != PARAMETERS_LAYOUT:
        raise InvalidParametersError(
            f'parameters message layout must be {PARAMETERS_LAYOUT} (label, size, stride), '
            f'got {layout}')
    if msg.layout.data_offset != 0:
        raise InvalidParametersError(
            f'parameters message data_offset must be 0, got {msg.layout.data_offset}')
    if len(msg.data) != N_PARAMETERS:
        raise InvalidParametersError(
            f'parameters message must hold {N_PARAMETERS} values, got {len(msg.data)}')
    return validate_parameters(np.asarray(msg.data, dtype=np.float64))


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
    """DiagnosticArray holding one DiagnosticStatus; values become KeyValue strings.

    `level` is DiagnosticStatus.OK/WARN/ERROR/STALE, 0..3 or 'OK'..'STALE';
    `stamp` is in ns (the header stamp is left at zero when None).
    """
    status = DiagnosticStatus(
        level=_level_byte(level),
        name=name,
        message=message,
        hardware_id=hardware_id,
        values=[KeyValue(key=str(key), value=_value_text(value))
                for key, value in (values or {}).items()],
    )
    header = Header(stamp=to_stamp(stamp)) if stamp is not None else Header()
    return DiagnosticArray(header=header, status=[status])


def status_values(status: DiagnosticStatus) -> dict[str, str]:
    """KeyValue list of a DiagnosticStatus -> dict."""
    return {kv.key: kv.value for kv in status.values}
