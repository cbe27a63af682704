"""
Decode whole JointState and Imu messages from their CDR bytes, as a generic decoder does.

Offline re-detection reads every raw sensor message of a bag; a generic CDR decoder
interprets the schema field by field for each one. A raw stream repeats one layout (the
same frame_id, joint names and sequence lengths), so a layout is learned from a message
the generic decoder decoded: later messages of the same size whose bytes equal it up to
the values are built in place, with the generic decoder's own message classes (taken from
the learned message), so they compare equal to and print like the generic decoding.
Anything else (another layout, another encapsulation, big endian) goes to the generic
decoder, which also reports every problem. A layout is used only if building the learned
message in place gives back exactly what the generic decoder gave.

The CDR layouts are those of hexacal_msgs_py.cdr (XCDR1 little endian, alignment from byte
4). Neither rclpy nor a decoder library is imported.
"""

from __future__ import annotations

import struct
from typing import Any, Callable

from hexacal_msgs_py.cdr import align, CDR_HEADER, joint_state_positions_layout, STAMP

JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
IMU_TYPE = 'sensor_msgs/msg/Imu'

# Per message of a definition, its fields as (type, name), as rosbag2 stores the definition
# (ros2msg; 'pkg/msg/Type' spelled 'pkg/Type'). A schema whose every message has exactly these
# fields has the layouts read here.
_HEADER_FIELDS = {
    'std_msgs/Header': (('builtin_interfaces/Time', 'stamp'), ('string', 'frame_id')),
    'builtin_interfaces/Time': (('int32', 'sec'), ('uint32', 'nanosec')),
}
DEFINITIONS: dict[str, dict[str, tuple[tuple[str, str], ...]]] = {
    JOINT_STATE_TYPE: {
        'sensor_msgs/JointState': (
            ('std_msgs/Header', 'header'),
            ('string[]', 'name'),
            ('float64[]', 'position'),
            ('float64[]', 'velocity'),
            ('float64[]', 'effort'),
        ),
        **_HEADER_FIELDS,
    },
    IMU_TYPE: {
        'sensor_msgs/Imu': (
            ('std_msgs/Header', 'header'),
            ('geometry_msgs/Quaternion', 'orientation'),
            ('float64[9]', 'orientation_covariance'),
            ('geometry_msgs/Vector3', 'angular_velocity'),
            ('float64[9]', 'angular_velocity_covariance'),
            ('geometry_msgs/Vector3', 'linear_acceleration'),
            ('float64[9]', 'linear_acceleration_covariance'),
        ),
        'geometry_msgs/Quaternion': (
            ('float64', 'x'),
            ('float64', 'y'),
            ('float64', 'z'),
            ('float64', 'w'),
        ),
        'geometry_msgs/Vector3': (('float64', 'x'), ('float64', 'y'), ('float64', 'z')),
        **_HEADER_FIELDS,
    },
}

# Learned layouts kept per decoder; a stream that changes its layout all the time (a frame_id
# per message) stops being learned and goes the generic way only.
MAX_LAYOUTS = 64
_IMU_VALUES = struct.Struct('<37d')  # orientation, 3 x (covariance, vector), all float64
_IMU_FIELDS = tuple(name for _, name in DEFINITIONS[IMU_TYPE]['sensor_msgs/Imu'])


def _slots(cls: type) -> tuple[str, ...]:
    return tuple(getattr(cls, '__slots__', ()))


class _JointStateLayout:
    """A JointState layout: the bytes up to the positions and the sequence lengths."""

    def __init__(self, data: bytes, message: Any) -> None:
        if data[:4] != CDR_HEADER:
            raise ValueError('not little-endian XCDR1')
        layout = joint_state_positions_layout(data)
        if layout is None:
            raise ValueError('not a JointState')
        self.offset, self.count = layout
        self.prefix = bytes(data[12:self.offset])
        end = self.offset + 8 * self.count
        formats = [f'<{self.count}d']
        self.lengths: list[int] = []  # index of each sequence length among the values
        index = self.count
        for _ in ('velocity', 'effort'):  # each: uint32 length (4-aligned), float64s (8-aligned)
            length_at = align(end, 4)
            (length,) = struct.unpack_from('<I', data, length_at)
            start = align(length_at + 4, 8) if length else length_at + 4
            formats.append(f'{length_at - end}xI{start - length_at - 4}x{length}d')
            self.lengths.append(index)
            index += 1 + length
            end = start + 8 * length
        if end > len(data):
            raise ValueError('sequences overrun the message')
        self.values = struct.Struct(''.join(formats))
        self.velocity_count, self.effort_count = len(message.velocity), len(message.effort)
        self.names = tuple(message.name)
        self.frame_id = message.header.frame_id
        self.message_class = type(message)
        self.header_class = type(message.header)
        self.time_class = type(message.header.stamp)
        if (
            _slots(self.message_class) != ('header', 'name', 'position', 'velocity', 'effort')
            or _slots(self.header_class) != ('stamp', 'frame_id')
            or _slots(self.time_class) != ('sec', 'nanosec')
        ):
            raise ValueError('not the known JointState classes')

    def decode(self, data: bytes) -> Any:
        """Return the message built in place, or None: not this layout."""
        if data[12:self.offset] != self.prefix or data[:4] != CDR_HEADER:
            return None
        values = self.values.unpack_from(data, self.offset)
        velocity_at, effort_at = self.lengths
        if values[velocity_at] != self.velocity_count or values[effort_at] != self.effort_count:
            return None
        sec, nanosec = STAMP.unpack_from(data, 4)
        stamp = self.time_class()
        stamp.sec = sec
        stamp.nanosec = nanosec
        header = self.header_class()
        header.stamp = stamp
        header.frame_id = self.frame_id
        message = self.message_class()
        message.header = header
        message.name = list(self.names)
        message.position = list(values[:velocity_at])
        message.velocity = list(values[velocity_at + 1:effort_at])
        message.effort = list(values[effort_at + 1:])
        return message


class _ImuLayout:
    """An Imu layout: fixed size after its frame_id, the bytes up to the orientation."""

    def __init__(self, data: bytes, message: Any) -> None:
        if data[:4] != CDR_HEADER or len(data) < 16:
            raise ValueError('not little-endian XCDR1')
        (length,) = struct.unpack_from('<I', data, 12)
        self.offset = align(16 + length, 8)
        if self.offset + _IMU_VALUES.size > len(data):
            raise ValueError('not an Imu')
        self.prefix = bytes(data[12:self.offset])
        self.frame_id = message.header.frame_id
        self.message_class = type(message)
        self.header_class = type(message.header)
        self.time_class = type(message.header.stamp)
        self.quaternion_class = type(message.orientation)
        self.vector_class = type(message.angular_velocity)
        if (
            _slots(self.message_class) != _IMU_FIELDS
            or type(message.linear_acceleration) is not self.vector_class
            or _slots(self.header_class) != ('stamp', 'frame_id')
            or _slots(self.time_class) != ('sec', 'nanosec')
            or _slots(self.quaternion_class) != ('x', 'y', 'z', 'w')
            or _slots(self.vector_class) != ('x', 'y', 'z')
        ):
            raise ValueError('not the known Imu classes')

    def _vector(self, values: tuple[float, ...], start: int) -> Any:
        vector = self.vector_class()
        vector.x, vector.y, vector.z = values[start:start + 3]
        return vector

    def decode(self, data: bytes) -> Any:
        """Return the message built in place, or None: not this layout."""
        if data[12:self.offset] != self.prefix or data[:4] != CDR_HEADER:
            return None
        values = _IMU_VALUES.unpack_from(data, self.offset)
        sec, nanosec = STAMP.unpack_from(data, 4)
        stamp = self.time_class()
        stamp.sec = sec
        stamp.nanosec = nanosec
        header = self.header_class()
        header.stamp = stamp
        header.frame_id = self.frame_id
        orientation = self.quaternion_class()
        orientation.x, orientation.y, orientation.z, orientation.w = values[:4]
        message = self.message_class()
        message.header = header
        message.orientation = orientation
        message.orientation_covariance = list(values[4:13])
        message.angular_velocity = self._vector(values, 13)
        message.angular_velocity_covariance = list(values[16:25])
        message.linear_acceleration = self._vector(values, 25)
        message.linear_acceleration_covariance = list(values[28:37])
        return message


_LAYOUTS: dict[str, Callable[[bytes, Any], Any]] = {
    JOINT_STATE_TYPE: _JointStateLayout,
    IMU_TYPE: _ImuLayout,
}


class MessageDecoder:
    """
    Decode the CDR bytes of one message type, in place where a learned layout fits.

    ``generic`` decodes any message of the type (and raises for bytes that are none); its
    results are returned for every message no learned layout fits, and teach the layouts.
    """

    def __init__(self, type_name: str, generic: Callable[[bytes], Any]) -> None:
        self._layout_class = _LAYOUTS[type_name]
        self._generic = generic
        self._by_size: dict[int, list[Any]] = {}
        self._learned = 0
        self.in_place = 0  # messages built in place (for benchmarks and tests)

    def __call__(self, data: bytes) -> Any:
        """Return the decoded message (the generic decoder's errors propagate)."""
        layouts = self._by_size.get(len(data))
        if layouts is not None:
            for layout in layouts:
                message = layout.decode(data)
                if message is not None:
                    self.in_place += 1
                    return message
        message = self._generic(data)
        if self._learned < MAX_LAYOUTS:
            self._learn(bytes(data), message)
        return message

    def _learn(self, data: bytes, message: Any) -> None:
        """Keep the layout of ``data`` if building it in place gives exactly ``message``."""
        self._learned += 1
        try:
            layout = self._layout_class(data, message)
            rebuilt = layout.decode(data)
            same = rebuilt is not None and rebuilt == message and repr(rebuilt) == repr(message)
        except (AttributeError, TypeError, ValueError, struct.error):
            return  # not the known layout or classes: this message stays generic
        if same:
            self._by_size.setdefault(len(data), []).append(layout)
