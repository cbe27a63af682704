"""
Read sensor messages straight from their CDR bytes, checked against rclpy's decoding.

The collector takes its 1 kHz inputs as raw CDR (the bag records the bytes as they
arrived) and decoding every message with rclpy would cost more than the rest of its
work. A reader here is learned from one message that rclpy decoded and the contract
accepted; it then reads every later message laid out the same way in place, and answers
None for anything else, which the caller decodes the full way (so every problem is
reported exactly as the full decoding reports it).

Only XCDR1 little-endian (what Fast DDS sends) is read in place; alignment is relative to
byte 4, after the encapsulation header. Neither rclpy nor the core is imported: the
decoded messages are used through their attributes only.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import struct
from typing import Any, Sequence, TYPE_CHECKING

from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.inputs import imu_inclinometer_angles
from hexacal_msgs_py.names import DEVICE_TURN_JOINT, MAX_DEVICE_TURN
from hexacal_msgs_py.readings import NS_PER_S

if TYPE_CHECKING:
    import numpy as np

CDR_HEADER = b'\x00\x01\x00\x00'  # XCDR1 little endian, what Fast DDS sends
STAMP = struct.Struct('<iI')  # builtin_interfaces/Time (sec, nanosec) at byte 4
_UINT32 = struct.Struct('<I')
_DOUBLE = struct.Struct('<d')
_QUATERNION = struct.Struct('<4d')
# orientation, its covariance, angular velocity, its covariance, ..., all float64
_IMU_DOUBLES = 4 + 9 + 3 + 9 + 3 + 9


def header_stamp_ns(data: bytes) -> int:
    """Return the header stamp (ns) of stamped-message CDR bytes; 0 if there is none."""
    if len(data) < 12:
        return 0
    seconds, nanoseconds = STAMP.unpack_from(data, 4)
    return seconds * NS_PER_S + nanoseconds


def align(position: int, size: int) -> int:
    """Round `position` up to a multiple of `size` counted from byte 4 (after the header)."""
    return position + (-(position - 4)) % size


def skip_doubles(data: bytes, offset: int) -> tuple[int, int]:
    """Return (count, offset after) of the float64 sequence at `offset` (uint32 length first)."""
    offset = align(offset, 4)
    (count,) = _UINT32.unpack_from(data, offset)
    offset += 4
    if count:
        offset = align(offset, 8)
    return count, offset + 8 * count


def joint_state_positions_layout(data: bytes) -> tuple[int, int] | None:
    """Return (offset, count) of the positions in JointState CDR; None if malformed."""
    if data[:4] != CDR_HEADER:
        return None
    offset = 12  # after the header stamp; alignment is relative to byte 4
    try:
        (length,) = _UINT32.unpack_from(data, offset)  # frame_id
        offset += 4 + length
        offset = align(offset, 4)
        (names,) = _UINT32.unpack_from(data, offset)
        offset += 4
        for _ in range(names):
            offset = align(offset, 4)
            (length,) = _UINT32.unpack_from(data, offset)
            offset += 4 + length
        offset = align(offset, 4)
        (count,) = _UINT32.unpack_from(data, offset)
        offset += 4
        if count:
            offset = align(offset, 8)
    except struct.error:
        return None
    if offset + 8 * count > len(data):
        return None
    return offset, count


class _LearnedLayout:
    """The bytes a message must share with the learned one to be read in place."""

    size: int  # the learned message's length
    offset: int  # where the values read in place start
    prefix: bytes  # the learned bytes from after the stamp to ``offset``

    def fits(self, data: bytes) -> bool:
        """Return True if ``data`` has the learned size, CDR header and bytes up to ``offset``."""
        return (
            len(data) == self.size
            and data[12:self.offset] == self.prefix
            and data[:4] == CDR_HEADER
        )


class JointStateReader(_LearnedLayout):
    """
    Read the wanted positions straight from CDR bytes laid out like a known good message.

    Learned from a message that rclpy decoded and the contract accepted: every later message
    of the same size whose bytes equal it from the stamp to the positions (same frame_id,
    names, number of positions) and whose velocity and effort sequences have the same
    lengths has the same joints at the same offsets; the velocity and effort values may
    change (ros2_control's joint_state_broadcaster fills them). Anything else (and
    non-finite wanted values or negative stamps) goes the full way, which reports the
    problem. The wanted joints are any of the message's, in any order (extra joints are
    skipped). ValueError, KeyError or struct.error: no in-place reading for this message.
    """

    def __init__(self, data: bytes, message: Any, wanted: tuple[str, ...]) -> None:
        layout = joint_state_positions_layout(data)
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
            velocities, after = skip_doubles(data, suffix_start)
            efforts, end = skip_doubles(data, after)
        except struct.error:
            raise ValueError('no velocity and effort sequences') from None
        counts = (velocities, efforts)
        if counts != (len(message.velocity), len(message.effort)) or end > len(data):
            raise ValueError('layout does not match the decoded message')
        # The two sequence lengths, read with one unpack (the velocities between them skipped).
        self.counts_offset = align(suffix_start, 4)
        self.counts = struct.Struct(f'<I{align(after, 4) - self.counts_offset - 4}xI')
        self.expected_counts = counts
        if list(self.positions.unpack_from(data, offset)) != list(message.position):
            raise ValueError('layout does not match the decoded message')

    def read(self, data: bytes) -> tuple[int, tuple[float, ...]] | None:
        """Return (stamp_ns, wanted positions), or None: decode this message the full way."""
        if not self.fits(data):
            return None
        if self.counts.unpack_from(data, self.counts_offset) != self.expected_counts:
            return None
        seconds, nanoseconds = STAMP.unpack_from(data, 4)
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

    def read_many(self, messages: Sequence[bytes]) -> JointStateBlock:
        """
        Read every message `read` reads, at once: the same values, float bits and stamps.

        A recording's raw stream repeats one layout tens of thousands of times; reading them
        as one byte array costs a fraction of a call per message. Messages not read (another
        layout, a negative stamp, a non-finite wanted value, a device turn out of range) are
        left to the caller's full decoding, as `read` leaves them.
        """
        import numpy as np

        sizes = np.fromiter(map(len, messages), dtype=np.int64, count=len(messages))
        rows = np.flatnonzero(sizes == self.size)
        block = np.frombuffer(b''.join([messages[i] for i in rows.tolist()]), dtype=np.uint8)
        block = block.reshape(len(rows), self.size)
        learned = np.frombuffer(CDR_HEADER + b'\0' * 8 + self.prefix, dtype=np.uint8)
        fits = (block[:, :4] == learned[:4]).all(axis=1)
        fits &= (block[:, 12:self.offset] == learned[12:]).all(axis=1)
        counts = _column(block, self.counts_offset, '<u4')
        counts_after = self.counts_offset + self.counts.size - 4
        fits &= counts == self.expected_counts[0]
        fits &= _column(block, counts_after, '<u4') == self.expected_counts[1]
        seconds = _column(block, 4, '<i4').astype(np.int64)
        fits &= seconds >= 0
        positions = block[:, self.offset:self.offset + self.positions.size].copy()
        positions = positions.view('<f8').astype(float)
        values = positions[:, list(self.order)]
        fits &= np.isfinite(values).all(axis=1)
        turns = None
        if self.turn_index is not None:
            turns = positions[:, self.turn_index]
            fits &= np.abs(turns) <= MAX_DEVICE_TURN  # NaN is not: the full way reports it
            turns = turns[fits]
        stamps = seconds * NS_PER_S + _column(block, 8, '<u4').astype(np.int64)
        return JointStateBlock(rows[fits], stamps[fits], values[fits], turns)


@dataclass(frozen=True)
class JointStateBlock:
    """The messages a JointStateReader read at once (`JointStateReader.read_many`)."""

    rows: np.ndarray  # (n,) int: which of the messages given were read, ascending
    stamps_ns: np.ndarray  # (n,) int64: their header stamps
    values: np.ndarray  # (n, wanted) float: the wanted joints' positions, in the wanted order
    turns: np.ndarray | None  # (n,) float: the device turn where the layout carries one


def _column(block: np.ndarray, offset: int, dtype: str) -> np.ndarray:
    """Return the 4-byte field at `offset` of each row of `block` as one value per row."""
    return block[:, offset:offset + 4].copy().view(dtype)[:, 0]


class ImuReader(_LearnedLayout):
    """
    Read an Imu's orientation from CDR bytes laid out like a known good message.

    An Imu is fixed-size after its frame_id: every message of the learned size with the same
    frame_id has the orientation at the same offset. Returns the inclinometer's raw angles
    by the contract's convention (hexacal_msgs_py.inputs); anything it cannot read (another
    layout, a negative stamp, no orientation estimate, a quaternion that is not a unit one)
    goes the full way, which reports the problem.
    """

    turn_index = None  # an Imu carries no device turn
    last_turn = None

    def __init__(self, data: bytes, message: Any) -> None:
        if data[:4] != CDR_HEADER:
            raise ValueError('not a little-endian Imu')
        try:
            (length,) = _UINT32.unpack_from(data, 12)
        except struct.error:
            raise ValueError('not an Imu') from None
        self.offset = align(16 + length, 8)
        self.size = len(data)
        if self.offset + 8 * _IMU_DOUBLES > self.size:
            raise ValueError('not an Imu')
        self.prefix = bytes(data[12:self.offset])
        orientation = message.orientation
        if (
            _QUATERNION.unpack_from(data, self.offset)
            != (orientation.x, orientation.y, orientation.z, orientation.w)
            or _DOUBLE.unpack_from(data, self.offset + 32)[0] != message.orientation_covariance[0]
        ):
            raise ValueError('layout does not match the decoded message')

    def read(self, data: bytes) -> tuple[int, tuple[float, ...]] | None:
        """Return (stamp_ns, (raw alpha, raw beta)), or None: decode this message the full way."""
        if not self.fits(data):
            return None
        seconds, nanoseconds = STAMP.unpack_from(data, 4)
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
