"""
Where the collector's readings come from (ROS-free).

Topics, joint names, the inclinometer convention (ROS-free).

A real machine's drivers publish under their own names. The collector reads the
six actuator values, the two inclinometer angles and the rotary angle from any
topics (ROS remapping of ``hexacal/sliders``, ``hexacal/inclinometer``,
``hexacal/encoder``; all three may be one ``sensor_msgs/JointState`` such as
ros2_control's ``/joint_states``) by the joint names an `InputMapping` gives,
and translates them to the contract's names on ``hexacal/posture``. The bag
records the inputs as received plus the mapping (`InputMapping.to_metadata`),
so the offline tools read them the same way.

The inclinometer may be a ``sensor_msgs/Imu``; its two angles come from the
orientation quaternion by one convention, owned here and used by the collector
and by the offline bag reading:

    up = R^T (0, 0, 1)                       (the vertical in the sensor's frame:
                                              the third row of R, yaw-free)
    alpha = atan2(-up_y, up_z)               (about X)
    beta  = atan2(up_x, hypot(up_y, up_z))   (about Y)

R is the orientation (sensor frame -> the IMU's gravity-aligned world frame,
Z up, as sensor_msgs/Imu and REP-145 define it). Only the direction of gravity
in the sensor frame enters, which is what an inclinometer senses: the IMU's
heading (yaw about the world's Z, magnetometer or integrated) does not matter.

Why this is core/machine/device.py's reading: device.py defines alpha and beta as what
an ideal biaxial inclinometer on the link reads, the link pointing from O to the
platform along ``u = (cos a sin b, -sin a, -cos a cos b)`` on the hanging mount
(eq. 4) and ``-u`` standing. That is the link turned by ``R_link = R_Y(-beta)
R_X(-alpha)`` (a U joint whose base-fixed axis is Y and link-fixed axis X) from
its zero-reading position (vertical, sensor axes along the base's X, Y, Z): R_link
(0, 0, -1) = u, R_link (0, 0, 1) = -u. An IMU fixed on the link with its axes
along the base's at zero reading has orientation ``R = R_Z(yaw) R_link``, and
the formulas above give back exactly (alpha, beta) from it, whatever the yaw and
on either mount (`inclinometer_angles_to_quaternion` is the inverse; the tests
go round trip through core.device's readings). In words: the sensor's up vector
is (sin b, -sin a cos b, cos a cos b). For small tilts alpha is minus the
sensor's right-handed rotation about X and beta minus its rotation about Y: the
signs of eq. 4 with the hanging z (device.py), not REP-103's right-hand rule. A
sensor mounted otherwise (an axis reversed, turned by 180 deg about Z, an IMU
that reports the opposite sense, a zero that is not level) is corrected per
channel by `inclinometer_signs` and `inclinometer_offsets_rad`:

    angle = sign * (raw - offset)

for both inclinometer types (``raw`` is the JointState position or the angle
from the quaternion; the offset is the raw reading with the link level, rad).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import json
import math
import numbers
from typing import Any, cast

from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.interface_names import (  # noqa: F401 - re-exported
    IMU_INCLINOMETER,
    INCLINOMETER_TYPES,
    JOINT_STATE_INCLINOMETER,
)
from hexacal_msgs_py.models import DEFAULT_MODEL, model_layout
from hexacal_msgs_py.names import (
    ENCODER_NAMES,
    ENCODER_TOPIC,
    INCLINOMETER_NAMES,
    INCLINOMETER_TOPIC,
    SLIDERS_TOPIC,
)

# The three inputs, by their contract topic (what a remapping renames), in this order everywhere.
INPUT_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)
INPUT_NAMES = {
    SLIDERS_TOPIC: 'sliders',
    INCLINOMETER_TOPIC: 'inclinometer',
    ENCODER_TOPIC: 'encoder',
}
DEFAULT_INCLINOMETER_JOINTS: tuple[str, str] = (INCLINOMETER_NAMES[0], INCLINOMETER_NAMES[1])
DEFAULT_ROTARY_JOINT: str = ENCODER_NAMES[0]
DEFAULT_SIGNS = (1.0, 1.0)
DEFAULT_OFFSETS_RAD = (0.0, 0.0)
# A unit quaternion's norm may be off by float32 rounding in a driver; more is not an orientation.
QUATERNION_NORM_TOLERANCE = 1e-3

# Keys of the mapping in the collector's bag metadata record (hexacal.collector): lists as JSON.
MAPPING_KEYS = (
    'actuator_joints',
    'inclinometer_joints',
    'rotary_joint',
    'inclinometer_type',
    'inclinometer_signs',
    'inclinometer_offsets_rad',
    'sliders_topic',
    'inclinometer_topic',
    'encoder_topic',
)
_TOPIC_KEYS = {
    SLIDERS_TOPIC: 'sliders_topic',
    INCLINOMETER_TOPIC: 'inclinometer_topic',
    ENCODER_TOPIC: 'encoder_topic',
}


class InputMappingError(HexacalContractError, ValueError):
    """An input mapping parameter is wrong; `parameter` names it."""

    def __init__(self, parameter: str, message: str) -> None:
        super().__init__(f'{parameter}: {message}')
        self.parameter = parameter


# --------------------------------------------------------------------------- the convention


def _finite(name: str, value: object) -> float:
    if isinstance(value, (bool, str, bytes)):
        raise InvalidReadingError(f'inclinometer: {name} must be a number, got {value!r}')
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidReadingError(
            f'inclinometer: {name} must be a number, got {value!r}'
        ) from None
    if not math.isfinite(number):
        raise InvalidReadingError(f'inclinometer: {name} is {number!r}')
    return number


def quaternion_to_inclinometer_angles(
    x: float, y: float, z: float, w: float
) -> tuple[float, float]:
    """
    (alpha, beta) in rad of an orientation quaternion (x, y, z, w), by the module's convention.

    The quaternion must be finite and of unit norm (within QUATERNION_NORM_TOLERANCE; it is
    normalised), else InvalidReadingError, e.g. for the all-zero orientation of an IMU that
    does not estimate one.
    """
    x, y, z, w = (_finite(f'orientation.{n}', v) for n, v in zip('xyzw', (x, y, z, w)))
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not abs(norm - 1.0) <= QUATERNION_NORM_TOLERANCE:
        raise InvalidReadingError(
            f'inclinometer: orientation ({x!r}, {y!r}, {z!r}, {w!r}) is not a unit quaternion '
            f'(norm {norm:.6g})'
        )
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    # The third row of the rotation matrix: the world's up axis in the sensor frame.
    up_x = 2.0 * (x * z - w * y)
    up_y = 2.0 * (y * z + w * x)
    up_z = 1.0 - 2.0 * (x * x + y * y)
    return math.atan2(-up_y, up_z), math.atan2(up_x, math.hypot(up_y, up_z))


def inclinometer_angles_to_quaternion(
    alpha: float, beta: float, yaw: float = 0.0
) -> tuple[float, float, float, float]:
    """
    Return the orientation (x, y, z, w) of an IMU on the link that reads (alpha, beta).

    R_Z(yaw) R_Y(-beta) R_X(-alpha).

    The inverse of `quaternion_to_inclinometer_angles` for |alpha| < pi, |beta| < pi/2 (any yaw):
    what a simulated or test IMU publishes.
    """

    def product(a, b):
        ax, ay, az, aw = a
        bx, by, bz, bw = b
        return (
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        )

    about_x = (math.sin(-alpha / 2.0), 0.0, 0.0, math.cos(-alpha / 2.0))
    about_y = (0.0, math.sin(-beta / 2.0), 0.0, math.cos(-beta / 2.0))
    about_z = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
    return product(about_z, product(about_y, about_x))


def imu_inclinometer_angles(
    orientation: Sequence[float], orientation_covariance_0: float = 0.0
) -> tuple[float, float]:
    """
    (alpha, beta) of an Imu's orientation (x, y, z, w) before signs and offsets.

    sensor_msgs/Imu marks "no orientation estimate" with orientation_covariance[0] = -1:
    InvalidReadingError, as for a quaternion that is not a finite unit one.
    """
    if orientation_covariance_0 == -1.0:
        raise InvalidReadingError(
            'inclinometer: the Imu has no orientation estimate (orientation_covariance[0] = -1)'
        )
    return quaternion_to_inclinometer_angles(*orientation)


# --------------------------------------------------------------------------- the mapping


def _names(parameter: str, value: object, count: int) -> tuple[str, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise InputMappingError(parameter, f'must be a list of {count} joint names, got {value!r}')
    names = tuple(value)
    if len(names) != count:
        raise InputMappingError(
            parameter, f'must name {count} joints, got {len(names)}: {list(names)}'
        )
    for name in names:
        if not isinstance(name, str) or not name:
            raise InputMappingError(
                parameter, f'joint names must be non-empty strings, got {name!r}'
            )
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise InputMappingError(parameter, f'names joint(s) {", ".join(repeated)} more than once')
    return names


def _numbers(parameter: str, value: object) -> tuple[float, float]:
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) or len(value) != 2:
        raise InputMappingError(parameter, f'must be 2 numbers (alpha, beta), got {value!r}')
    numbers_ = []
    for item in value:
        if isinstance(item, bool) or not isinstance(item, numbers.Real):
            raise InputMappingError(parameter, f'must be 2 numbers (alpha, beta), got {value!r}')
        numbers_.append(float(item))
    return numbers_[0], numbers_[1]


@dataclass(frozen=True)
class InputMapping:
    """
    Which joints of which topics are the readings, and how the inclinometer is read.

    ``topics`` are the topics the three inputs were taken from (sliders, inclinometer,
    encoder; resolved names as recorded, e.g. all three '/joint_states'), '' where not
    known. Validated on construction (InputMappingError naming the parameter).
    """

    actuator_joints: tuple[str, ...]
    inclinometer_joints: tuple[str, ...] = DEFAULT_INCLINOMETER_JOINTS
    rotary_joint: str = DEFAULT_ROTARY_JOINT
    inclinometer_type: str = JOINT_STATE_INCLINOMETER
    inclinometer_signs: tuple[float, float] = DEFAULT_SIGNS
    inclinometer_offsets_rad: tuple[float, float] = DEFAULT_OFFSETS_RAD
    topics: tuple[str, str, str] = ('', '', '')

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, 'actuator_joints', _names('actuator_joints', self.actuator_joints, 6))
        set_(
            self, 'inclinometer_joints', _names('inclinometer_joints', self.inclinometer_joints, 2)
        )
        if not isinstance(self.rotary_joint, str) or not self.rotary_joint:
            raise InputMappingError(
                'rotary_joint', f'must be a joint name, got {self.rotary_joint!r}'
            )
        if self.inclinometer_type not in INCLINOMETER_TYPES:
            raise InputMappingError(
                'inclinometer_type',
                f"must be 'joint_state' or 'imu', got {self.inclinometer_type!r}",
            )
        signs = _numbers('inclinometer_signs', self.inclinometer_signs)
        if any(sign not in (1.0, -1.0) for sign in signs):
            raise InputMappingError(
                'inclinometer_signs', f'each sign must be 1 or -1, got {list(signs)}'
            )
        set_(self, 'inclinometer_signs', signs)
        offsets = _numbers('inclinometer_offsets_rad', self.inclinometer_offsets_rad)
        if not all(math.isfinite(offset) and abs(offset) <= math.pi for offset in offsets):
            raise InputMappingError(
                'inclinometer_offsets_rad',
                f'each offset must be finite, within +-pi rad, got {list(offsets)}',
            )
        set_(self, 'inclinometer_offsets_rad', offsets)
        topics = tuple(self.topics)
        if len(topics) != 3 or not all(isinstance(topic, str) for topic in topics):
            raise InputMappingError(
                'topics',
                f'must be 3 topic names (sliders, inclinometer, encoder), got {self.topics!r}',
            )
        set_(self, 'topics', topics)
        self._check_shared_topics()

    @classmethod
    def default(
        cls, model: str | None = None, topics: Sequence[str] = ('', '', '')
    ) -> InputMapping:
        """
        Return the contract's joints.

        `model`'s actuators, inclinometer_x/_y, rotary.
        """
        three = cast('tuple[str, str, str]', tuple(topics))  # __post_init__ checks them
        return cls(model_layout(model or DEFAULT_MODEL).actuator_names, topics=three)

    def _check_shared_topics(self) -> None:
        """
        Check that inputs read from one topic are one message.

        One type, every joint named once.
        """
        sliders, inclinometer, encoder = self.topics
        imu = self.inclinometer_type == IMU_INCLINOMETER
        if imu and inclinometer and inclinometer in (sliders, encoder):
            other = 'sliders' if inclinometer == sliders else 'encoder'
            raise InputMappingError(
                'inclinometer_type',
                f"'imu' needs a topic of its own: {inclinometer} is also the "
                f'{other} input, a sensor_msgs/JointState',
            )
        joints: dict[str, list[tuple[str, str]]] = {}
        for topic, what, names in (
            (sliders, 'actuator_joints', self.actuator_joints),
            (inclinometer, 'inclinometer_joints', () if imu else self.inclinometer_joints),
            (encoder, 'rotary_joint', (self.rotary_joint,)),
        ):
            if topic:
                for name in names:
                    joints.setdefault(topic, []).append((name, what))
        for topic, named in joints.items():
            seen: dict[str, str] = {}
            for name, what in named:
                if name in seen and seen[name] != what:
                    raise InputMappingError(
                        what,
                        f'joint {name!r} is also in {seen[name]}, and both are read from '
                        f'{topic}: every reading needs its own joint',
                    )
                seen[name] = what

    # ------------------------------------------------------------------ reading

    def input_joints(self, input_topic: str) -> tuple[str, ...]:
        """
        Return the joints a JointState input carries.

        The joints a JointState input carries (by contract topic); () for an Imu inclinometer.
        """
        if input_topic == SLIDERS_TOPIC:
            return self.actuator_joints
        if input_topic == INCLINOMETER_TOPIC:
            return () if self.inclinometer_type == IMU_INCLINOMETER else self.inclinometer_joints
        if input_topic == ENCODER_TOPIC:
            return (self.rotary_joint,)
        raise KeyError(input_topic)

    def input_topic(self, input_topic: str) -> str:
        """Return the topic an input was taken from ('' if not known)."""
        return self.topics[INPUT_TOPICS.index(input_topic)]

    def inclinometer_angles(self, raw_alpha: float, raw_beta: float) -> tuple[float, float]:
        """
        Return hexacal's (alpha, beta) from the sensor's raw angles.

        Sign * (raw - offset) per channel.
        """
        (sign_a, sign_b), (offset_a, offset_b) = (
            self.inclinometer_signs,
            self.inclinometer_offsets_rad,
        )
        return sign_a * (raw_alpha - offset_a), sign_b * (raw_beta - offset_b)

    def raw_inclinometer(self, alpha: float, beta: float) -> tuple[float, float]:
        """
        Return the sensor's raw angles that read as hexacal's (alpha, beta).

        The sensor's raw angles that read as hexacal's (alpha, beta) (the inverse, for simulators).
        """
        (sign_a, sign_b), (offset_a, offset_b) = (
            self.inclinometer_signs,
            self.inclinometer_offsets_rad,
        )
        return sign_a * alpha + offset_a, sign_b * beta + offset_b

    def is_contract(self, model: str | None = None) -> bool:
        """
        Return True if the joints, type, signs and offsets are the contract's.

        True if the joints, type, signs and offsets are the contract's (topics aside).
        """
        return self == InputMapping.default(model, self.topics)

    # ------------------------------------------------------------------ bag metadata

    def to_metadata(self) -> dict[str, str]:
        """
        Return the mapping as the string map of a bag metadata record.

        The mapping as the string map of a bag metadata record (MAPPING_KEYS; lists as JSON).
        """
        return {
            'actuator_joints': json.dumps(list(self.actuator_joints)),
            'inclinometer_joints': json.dumps(list(self.inclinometer_joints)),
            'rotary_joint': self.rotary_joint,
            'inclinometer_type': self.inclinometer_type,
            'inclinometer_signs': json.dumps(list(self.inclinometer_signs)),
            'inclinometer_offsets_rad': json.dumps(list(self.inclinometer_offsets_rad)),
            **{_TOPIC_KEYS[topic]: self.input_topic(topic) for topic in INPUT_TOPICS},
        }

    @classmethod
    def from_metadata(
        cls, record: Mapping[str, str], model: str | None = None
    ) -> InputMapping | None:
        """
        Return the mapping a bag metadata record holds, None if it holds none.

        The mapping a bag metadata record holds, None if it holds none (a bag recorded before
        mappings existed: read as the contract's names and topics). Missing keys take the defaults;
        a value that does not parse is an InputMappingError naming its key.
        """
        if not any(key in record for key in MAPPING_KEYS):
            return None

        def listed(key: str, default: Sequence) -> Any:  # a tuple, checked by __post_init__
            if key not in record:
                return tuple(default)
            try:
                value = json.loads(record[key])
            except (TypeError, ValueError) as error:
                raise InputMappingError(
                    key, f'recorded value {record[key]!r} is not a JSON list: {error}'
                ) from None
            if not isinstance(value, list):
                raise InputMappingError(key, f'recorded value {record[key]!r} is not a list')
            return tuple(value)

        default = cls.default(model)
        return cls(
            actuator_joints=listed('actuator_joints', default.actuator_joints),
            inclinometer_joints=listed('inclinometer_joints', default.inclinometer_joints),
            rotary_joint=record.get('rotary_joint', default.rotary_joint),
            inclinometer_type=record.get('inclinometer_type', default.inclinometer_type),
            inclinometer_signs=listed('inclinometer_signs', default.inclinometer_signs),
            inclinometer_offsets_rad=listed(
                'inclinometer_offsets_rad', default.inclinometer_offsets_rad
            ),
            topics=cast(
                'tuple[str, str, str]',
                tuple(record.get(_TOPIC_KEYS[topic], '') for topic in INPUT_TOPICS),
            ),
        )

    def describe(self) -> str:
        """One line: which topic and joints each reading comes from."""

        def where(topic: str) -> str:
            return self.input_topic(topic) or topic

        joints = self.actuator_joints
        text = (
            f'sliders <- {where(SLIDERS_TOPIC)} [{", ".join(joints)}]; inclinometer <- '
            f'{where(INCLINOMETER_TOPIC)} '
        )
        if self.inclinometer_type == IMU_INCLINOMETER:
            text += '(sensor_msgs/Imu orientation)'
        else:
            text += f'[{", ".join(self.inclinometer_joints)}]'
        if (self.inclinometer_signs, self.inclinometer_offsets_rad) != (
            DEFAULT_SIGNS,
            DEFAULT_OFFSETS_RAD,
        ):
            text += (
                f' signs {list(self.inclinometer_signs)}, offsets '
                f'{list(self.inclinometer_offsets_rad)} rad'
            )
        return text + f'; encoder <- {where(ENCODER_TOPIC)} [{self.rotary_joint}]'
