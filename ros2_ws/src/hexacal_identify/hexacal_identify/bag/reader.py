"""
Read rosbag2 MCAP bags (a bag directory or a single .mcap file) without ROS.

A complete MCAP file (valid footer and summary CRC) is indexed from its
summary; any damaged record in it raises `BagCorruptError`. A file without a
valid footer (the recorder was killed, the disk filled up) is read by a
forward scan that keeps every complete record and chunk and stops cleanly at
the first incomplete or damaged one; the file is then reported as truncated.
Every problem with the input surfaces as a `BagError` subclass.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import io
from io import BytesIO
import os
from pathlib import Path
import re
import struct
from typing import Any, Callable, Iterable, Iterator, Mapping, NamedTuple
import zlib

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
)

from .errors import (
    BagCorruptError,
    BagDecodeError,
    BagEmptyError,
    BagError,
    BagFormatError,
    BagMetadataError,
    BagMissingFileError,
    BagNotFoundError,
    BagSchemaError,
)
from .schemas import field_signature, MESSAGE_ENCODING, normalize_type_name, SCHEMA_ENCODING

MCAP_MAGIC = b'\x89MCAP0\r\n'
METADATA_FILE_NAME = 'metadata.yaml'
STORAGE_IDENTIFIER = 'mcap'

_RECORD_HEADER = struct.Struct('<BQ')
_MESSAGE_PREFIX = struct.Struct('<HIQQ')  # channel_id, sequence, log_time, publish_time
_FOOTER_BODY = struct.Struct('<QQI')  # summary_start, summary_offset_start, summary_crc
_FOOTER_RECORD_SIZE = _RECORD_HEADER.size + _FOOTER_BODY.size
_CHANNEL_ID = struct.Struct('<H')
# Chunk index: message_start_time, message_end_time, chunk_start_offset, chunk_length, then the
# byte length of the message_index_offsets map of (channel id u16, offset u64) entries.
_CHUNK_INDEX_PREFIX = struct.Struct('<QQQQI')
_CHUNK_INDEX_ENTRY_SIZE = 10
# A corrupt length field must not make us allocate gigabytes.
_MAX_UNCOMPRESSED_CHUNK_BYTES = 1 << 30
_DECODABLE_SCHEMA_ENCODINGS = (SCHEMA_ENCODING, 'ros2idl')


# --------------------------------------------------------------------------- public data


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag."""

    type_name: str
    count: int
    qos_profiles: str  # offered_qos_profiles YAML text, as stored in the MCAP channel


@dataclass(frozen=True)
class FileInfo:
    """One MCAP file of a bag."""

    path: str
    size_bytes: int
    message_count: int
    start_time_ns: int | None
    end_time_ns: int | None
    truncated: bool  # no valid footer: read up to the last complete record
    truncation_note: str = ''


@dataclass(frozen=True)
class BagInfo:
    """Summary of a bag, as printed by the bag-info command."""

    path: str
    storage_identifier: str
    files: tuple[FileInfo, ...]
    topics: dict[str, TopicInfo]
    message_count: int
    start_time_ns: int | None
    end_time_ns: int | None
    size_bytes: int

    @property
    def duration_ns(self) -> int:
        if self.start_time_ns is None or self.end_time_ns is None:
            return 0
        return self.end_time_ns - self.start_time_ns

    @property
    def truncated(self) -> bool:
        return any(f.truncated for f in self.files)

    def format(self) -> str:  # noqa: A003 (the method name users call)
        """Human-readable text in the layout of `ros2 bag info`."""
        lines = [
            f'Files:             {", ".join(Path(f.path).name for f in self.files)}',
            f'Bag size:          {_format_size(self.size_bytes)}',
            f'Storage id:        {self.storage_identifier}',
            f'Duration:          {self.duration_ns / 1e9:.9f}s',
            f'Start:             {_format_stamp(self.start_time_ns)}',
            f'End:               {_format_stamp(self.end_time_ns)}',
            f'Messages:          {self.message_count}',
        ]
        topic_lines = [
            f'Topic: {name} | Type: {topic.type_name} | Count: {topic.count} | '
            'Serialization Format: cdr'
            for name, topic in sorted(self.topics.items())
        ]
        lines.append('Topic information: ' + ('\n                   '.join(topic_lines) or '-'))
        for file_info in self.files:
            if file_info.truncated:
                lines.append(
                    f'Truncated:         {Path(file_info.path).name}: {file_info.truncation_note}'
                )
        return '\n'.join(lines)


@dataclass(frozen=True)
class MetadataRecord:
    """An MCAP metadata record (name + string map)."""

    name: str
    data: dict[str, str]


_UNDECODED = object()  # BagMessage._decoded before the first decoding


@dataclass
class BagMessage:
    """One message of a bag; `decoded` decodes the CDR bytes on first access."""

    topic: str
    type_name: str
    log_time_ns: int
    publish_time_ns: int
    data_bytes: bytes
    _decode: Callable[[bytes], Any] = field(repr=False, compare=False)
    # Cached here rather than by functools.cached_property, whose lock (Python 3.11) costs as
    # much as decoding a message in place.
    _decoded: Any = field(default=_UNDECODED, init=False, repr=False, compare=False)

    @property
    def decoded(self) -> Any:
        decoded = self._decoded
        if decoded is not _UNDECODED:
            return decoded
        try:
            decoded = self._decode(self.data_bytes)
        except BagError:
            raise
        except Exception as error:  # noqa: BLE001 - any decoder failure is a named error here
            raise BagDecodeError(
                f'message on topic {self.topic!r} at log time {self.log_time_ns} ns does not '
                f'decode as {self.type_name}: {type(error).__name__}: {error}',
                topic=self.topic,
                log_time_ns=self.log_time_ns,
            ) from error
        self._decoded = decoded
        return decoded


# --------------------------------------------------------------------------- record parsing


class _Damage(Exception):
    """A record that cannot be parsed (internal; becomes a truncation stop or BagCorruptError)."""


class _StrictStream(ReadDataStream):
    """ReadDataStream that treats a short read as the end of data instead of returning less."""

    def read(self, length: int) -> bytes:
        data = super().read(length) if length else b''
        if len(data) != length:
            raise EndOfFile()
        return data


class _RawMessage(NamedTuple):
    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


_PARSERS: dict[int, Callable[[ReadDataStream], Any]] = {
    Opcode.HEADER: Header.read,
    Opcode.FOOTER: Footer.read,
    Opcode.SCHEMA: Schema.read,
    Opcode.CHANNEL: Channel.read,
    Opcode.CHUNK: Chunk.read,
    Opcode.METADATA: Metadata.read,
    Opcode.METADATA_INDEX: MetadataIndex.read,
    Opcode.STATISTICS: Statistics.read,
}


def _parse_record(opcode: int, body: bytes) -> Any:
    """Parse one record body, or None for record kinds this reader does not need."""
    if opcode == Opcode.MESSAGE:
        if len(body) < _MESSAGE_PREFIX.size:
            raise _Damage(f'message record of {len(body)} bytes is too short')
        return _RawMessage(*_MESSAGE_PREFIX.unpack_from(body), body[_MESSAGE_PREFIX.size:])
    parser = _PARSERS.get(opcode)
    if parser is None:
        return None
    try:
        return parser(_StrictStream(BytesIO(body)))
    except Exception as error:  # noqa: BLE001 - any failure of mcap's parsers means damage
        raise _Damage(
            f'{Opcode(opcode).name} record does not parse: {type(error).__name__} {error}'
        ) from error


def _decompress(chunk: Chunk) -> bytes:
    if chunk.uncompressed_size > _MAX_UNCOMPRESSED_CHUNK_BYTES:
        raise _Damage(f'chunk claims {chunk.uncompressed_size} uncompressed bytes')
    try:
        if chunk.compression == '':
            data = chunk.data
        elif chunk.compression == 'zstd':
            import zstandard

            data = zstandard.ZstdDecompressor().decompress(
                chunk.data, max_output_size=chunk.uncompressed_size
            )
        elif chunk.compression == 'lz4':
            import lz4.frame

            data = lz4.frame.decompress(chunk.data)
        else:
            raise _Damage(f'unsupported chunk compression {chunk.compression!r}')
    except _Damage:
        raise
    except Exception as error:  # noqa: BLE001 - codec errors have library-specific types
        raise _Damage(f'{chunk.compression} chunk does not decompress: {error}') from error
    if len(data) != chunk.uncompressed_size:
        raise _Damage(
            f'chunk decompresses to {len(data)} bytes, header says {chunk.uncompressed_size}'
        )
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise _Damage('chunk CRC mismatch')
    return data


def _chunk_records(chunk: Chunk, ignore_channels: frozenset[int] = frozenset()) -> list[Any]:
    """
    All schema, channel and message records of a chunk (all or nothing).

    Messages on ``ignore_channels`` are left out (not unpacked; still checked for length).
    """
    data = _decompress(chunk)
    records = []
    position = 0
    while position < len(data):
        if len(data) - position < _RECORD_HEADER.size:
            raise _Damage('chunk ends inside a record header')
        opcode, length = _RECORD_HEADER.unpack_from(data, position)
        position += _RECORD_HEADER.size
        if length > len(data) - position:
            raise _Damage(f'record of {length} bytes overruns its chunk')
        if (
            opcode == Opcode.MESSAGE
            and ignore_channels
            and length >= _MESSAGE_PREFIX.size
            and _CHANNEL_ID.unpack_from(data, position)[0] in ignore_channels
        ):
            pass
        elif opcode in (Opcode.MESSAGE, Opcode.SCHEMA, Opcode.CHANNEL):
            records.append(_parse_record(opcode, data[position:position + length]))
        position += length
    return records


def _chunk_index_channels(body: bytes) -> tuple[int, frozenset[int]]:
    """
    Return the chunk start offset and channel ids of a chunk index record.

    (chunk_start_offset, ids of the channels with messages in the chunk) of a chunk index record.
    """
    if len(body) < _CHUNK_INDEX_PREFIX.size:
        raise _Damage(f'chunk index record of {len(body)} bytes is too short')
    _, _, chunk_offset, _, map_length = _CHUNK_INDEX_PREFIX.unpack_from(body)
    start = _CHUNK_INDEX_PREFIX.size
    if map_length % _CHUNK_INDEX_ENTRY_SIZE or map_length > len(body) - start:
        raise _Damage("chunk index's message index offsets overrun the record")
    return chunk_offset, frozenset(
        _CHANNEL_ID.unpack_from(body, position)[0]
        for position in range(start, start + map_length, _CHUNK_INDEX_ENTRY_SIZE)
    )


class _Scan:
    """
    Forward scan of an MCAP data section, expanding chunks.

    With `strict` (the file has a valid footer) damage raises BagCorruptError;
    otherwise the scan stops at the first incomplete or damaged record and
    records where and why in `stop_offset` / `stop_reason`.
    """

    def __init__(self, path: Path, size: int, strict: bool):
        self.path = path
        self.size = size
        self.strict = strict
        self.reached_end = False  # saw DataEnd (or a footer): the data section is complete
        self.record_offset = -1  # offset of the top-level record being read
        self.stop_offset = -1
        self.stop_reason = ''

    def stop(self, offset: int | None, reason: str) -> None:
        """Raise for a complete file; remember the truncation point otherwise."""
        offset = self.record_offset if offset is None else offset
        if self.strict:
            raise BagCorruptError(
                f'{self.path}: damaged MCAP at byte {offset}: {reason}',
                path=str(self.path),
                offset=offset,
            )
        self.stop_offset = offset
        self.stop_reason = f'stopped at byte {offset} of {self.size}: {reason}'

    def records(
        self,
        skip_chunks: frozenset[int] = frozenset(),
        ignore_channels: frozenset[int] = frozenset(),
    ) -> Iterator[Any]:
        """
        Yield records in file order.

        Records in file order; chunks expanded except those starting at an offset in
        ``skip_chunks``.

        Messages on ``ignore_channels`` are left out of the expanded chunks.
        """
        try:
            handle = open(self.path, 'rb')
        except OSError as error:
            raise BagNotFoundError(f'cannot open {self.path}: {error}') from error
        with handle:
            handle.seek(len(MCAP_MAGIC))
            offset = len(MCAP_MAGIC)
            while True:
                self.record_offset = offset
                head = handle.read(_RECORD_HEADER.size)
                if len(head) < _RECORD_HEADER.size:
                    self.stop(
                        offset,
                        'file ends before the footer'
                        if not head
                        else 'file ends inside a record header',
                    )
                    return
                opcode, length = _RECORD_HEADER.unpack(head)
                available = self.size - offset - _RECORD_HEADER.size
                if length > available:
                    self.stop(
                        offset,
                        f'{_opcode_name(opcode)} record of {length} bytes, '
                        f'only {available} left in the file',
                    )
                    return
                if opcode == Opcode.CHUNK and offset in skip_chunks:
                    offset += _RECORD_HEADER.size + length
                    handle.seek(offset)
                    continue
                body = handle.read(length)
                if len(body) < length:
                    self.stop(offset, 'file shrank while reading')
                    return
                try:
                    if offset == len(MCAP_MAGIC) and opcode != Opcode.HEADER:
                        raise _Damage('first record is not an MCAP header')
                    if opcode == Opcode.CHUNK:
                        parsed = _chunk_records(_parse_record(opcode, body), ignore_channels)
                    else:
                        record = _parse_record(opcode, body)
                        parsed = [] if record is None else [record]
                except _Damage as damage:
                    self.stop(offset, str(damage))
                    return
                yield from parsed
                offset += _RECORD_HEADER.size + length
                if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    self.reached_end = True
                    return


def _opcode_name(opcode: int) -> str:
    try:
        return Opcode(opcode).name
    except ValueError:
        return f'unknown (opcode {opcode:#x})'


# --------------------------------------------------------------------------- one MCAP file


class _McapFile:
    """Schemas, channels, counts and metadata of one MCAP file, from its summary or a scan."""

    def __init__(self, path: Path):
        self.path = path
        try:
            self.size = path.stat().st_size
            with open(path, 'rb') as handle:
                magic = handle.read(len(MCAP_MAGIC))
                footer = self._read_footer(handle)
        except OSError as error:
            raise BagNotFoundError(f'cannot read {path}: {error}') from error
        if self.size == 0:
            raise BagEmptyError(f'{path} is empty (0 bytes)')
        if magic != MCAP_MAGIC:
            raise BagFormatError(f'{path} is not an MCAP file (no MCAP magic at its start)')
        self.complete = footer is not None
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.counts: dict[int, int] = {}
        self.start_time_ns: int | None = None
        self.end_time_ns: int | None = None
        self.metadata: list[MetadataRecord] = []
        # chunk offset -> the channels it holds messages of, from the summary's chunk indexes
        # (empty without a summary, or if any chunk index does not parse).
        self.chunk_channels: dict[int, frozenset[int]] = {}
        self.truncation_note = ''
        if not (footer is not None and footer.summary_start and self._load_summary(footer)):
            self._index_by_scan()

    def scan(self) -> _Scan:
        return _Scan(self.path, self.size, strict=self.complete)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    def info(self) -> FileInfo:
        return FileInfo(
            str(self.path),
            self.size,
            self.message_count,
            self.start_time_ns,
            self.end_time_ns,
            not self.complete,
            self.truncation_note,
        )

    def _read_footer(self, handle: Any) -> Footer | None:
        """
        Return the footer if the file ends with a valid one, else None.

        The footer if the file ends with a valid one (summary CRC checked), else None.
        """
        tail_size = _FOOTER_RECORD_SIZE + len(MCAP_MAGIC)
        size = os.fstat(handle.fileno()).st_size
        if size < 2 * len(MCAP_MAGIC) + _FOOTER_RECORD_SIZE:
            return None
        handle.seek(size - tail_size)
        tail = handle.read(tail_size)
        opcode, length = _RECORD_HEADER.unpack_from(tail)
        if (
            opcode != Opcode.FOOTER
            or length != _FOOTER_BODY.size
            or tail[-len(MCAP_MAGIC):] != MCAP_MAGIC
        ):
            return None
        summary_start, summary_offset_start, summary_crc = _FOOTER_BODY.unpack_from(
            tail, _RECORD_HEADER.size
        )
        footer_offset = size - tail_size
        if summary_start and not len(MCAP_MAGIC) <= summary_start <= footer_offset:
            return None
        if summary_crc:
            crc = 0
            if summary_start:
                handle.seek(summary_start)
                crc = zlib.crc32(handle.read(footer_offset - summary_start))
            crc = zlib.crc32(tail[: _RECORD_HEADER.size + 16], crc)
            if crc != summary_crc:
                return None
        self._footer_offset = footer_offset
        return Footer(
            summary_start=summary_start,
            summary_offset_start=summary_offset_start,
            summary_crc=summary_crc,
        )

    def _load_summary(self, footer: Footer) -> bool:
        """Index from the summary section; False if it lacks statistics or channels."""
        statistics: Statistics | None = None
        metadata_indexes: list[MetadataIndex] = []
        chunk_channels: dict[int, frozenset[int]] | None = {}
        with open(self.path, 'rb') as handle:
            handle.seek(footer.summary_start)
            data = handle.read(self._footer_offset - footer.summary_start)
            position = 0
            try:
                while position < len(data):
                    if len(data) - position < _RECORD_HEADER.size:
                        raise _Damage('summary ends inside a record header')
                    opcode, length = _RECORD_HEADER.unpack_from(data, position)
                    position += _RECORD_HEADER.size
                    if length > len(data) - position:
                        raise _Damage('summary record overruns the summary section')
                    if opcode == Opcode.CHUNK_INDEX:
                        if chunk_channels is not None:
                            try:
                                offset, channel_ids = _chunk_index_channels(
                                    data[position:position + length]
                                )
                                chunk_channels[offset] = channel_ids
                            except _Damage:
                                chunk_channels = None  # not used: every chunk is read
                        position += length
                        continue
                    record = _parse_record(opcode, data[position:position + length])
                    position += length
                    if isinstance(record, Schema):
                        self.schemas[record.id] = record
                    elif isinstance(record, Channel):
                        self.channels[record.id] = record
                    elif isinstance(record, Statistics):
                        statistics = record
                    elif isinstance(record, MetadataIndex):
                        metadata_indexes.append(record)
                if statistics is None or len(self.channels) < statistics.channel_count:
                    self.schemas.clear()
                    self.channels.clear()
                    return False
                for index in metadata_indexes:
                    handle.seek(index.offset)
                    raw = handle.read(index.length)
                    if len(raw) != index.length or index.length < _RECORD_HEADER.size:
                        raise _Damage(f'metadata index points outside the file ({index.offset})')
                    opcode, length = _RECORD_HEADER.unpack_from(raw)
                    if opcode != Opcode.METADATA or length != index.length - _RECORD_HEADER.size:
                        raise _Damage('metadata index points at a non-metadata record')
                    record = _parse_record(opcode, raw[_RECORD_HEADER.size:])
                    self.metadata.append(MetadataRecord(record.name, dict(record.metadata)))
            except _Damage as damage:
                raise BagCorruptError(
                    f'{self.path}: damaged MCAP summary: {damage}', path=str(self.path)
                ) from damage
        self.counts = {cid: statistics.channel_message_counts.get(cid, 0) for cid in self.channels}
        self.chunk_channels = chunk_channels or {}
        if statistics.message_count:
            self.start_time_ns = statistics.message_start_time
            self.end_time_ns = statistics.message_end_time
        return True

    def _index_by_scan(self) -> None:
        scan = self.scan()
        for record in scan.records():
            if isinstance(record, _RawMessage):
                if record.channel_id not in self.channels:
                    scan.stop(None, f'message on unknown channel {record.channel_id}')
                    break
                self.counts[record.channel_id] = self.counts.get(record.channel_id, 0) + 1
                if self.start_time_ns is None or record.log_time < self.start_time_ns:
                    self.start_time_ns = record.log_time
                if self.end_time_ns is None or record.log_time > self.end_time_ns:
                    self.end_time_ns = record.log_time
            elif isinstance(record, Schema):
                self.schemas[record.id] = record
            elif isinstance(record, Channel):
                self.channels[record.id] = record
                self.counts.setdefault(record.id, 0)
            elif isinstance(record, Metadata):
                self.metadata.append(MetadataRecord(record.name, dict(record.metadata)))
        if not self.complete:
            self.truncation_note = (
                'data section complete, summary/footer missing'
                if scan.reached_end
                else scan.stop_reason
            )


# --------------------------------------------------------------------------- the bag


def _topic_key(topic: str) -> str:
    # rosbag2 stores absolute names; accept 'hexacal/posture' for '/hexacal/posture'.
    return topic.lstrip('/')


class _Topic(NamedTuple):
    name: str
    type_name: str
    qos_profiles: str


class BagReader:
    """
    Read the messages, topics and metadata of a bag opened with `open_bag`.

    JointState and Imu messages are decoded in place where their layout repeats
    (hexacal_msgs_py.cdr_messages), giving exactly the generic decoder's messages; with
    ``fast_decoding`` False (benchmarks, comparisons) every message takes the generic decoder.
    """

    fast_decoding = True

    def __init__(
        self, path: Path, files: list[_McapFile], expect_types: Mapping[str, str] | None = None
    ):
        self.path = path
        self._files = files
        self._topics: dict[str, _Topic] = {}
        self._channel_topics: list[dict[int, _Topic]] = []
        self._decoders: dict[tuple[int, int], Callable[[bytes], Any]] = {}
        for mcap_file in files:
            channel_topics: dict[int, _Topic] = {}
            for channel in mcap_file.channels.values():
                topic = self._validated_topic(mcap_file, channel)
                known = self._topics.setdefault(topic.name, topic)
                if known.type_name != topic.type_name:
                    raise BagSchemaError(
                        f'topic {topic.name!r} has type {known.type_name} in one file and '
                        f'{topic.type_name} in {mcap_file.path}',
                        topic=topic.name,
                        expected=known.type_name,
                        found=topic.type_name,
                    )
                channel_topics[channel.id] = topic
            self._channel_topics.append(channel_topics)
        for topic_name, expected in (expect_types or {}).items():
            self._check_type(topic_name, expected)

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc_info: object) -> None:
        pass  # files are opened per iteration; nothing stays open

    def _validated_topic(self, mcap_file: _McapFile, channel: Channel) -> _Topic:
        schema = mcap_file.schemas.get(channel.schema_id)
        if schema is None:
            raise BagSchemaError(
                f'topic {channel.topic!r} in {mcap_file.path} has no schema', topic=channel.topic
            )
        if channel.message_encoding != MESSAGE_ENCODING:
            raise BagSchemaError(
                f'topic {channel.topic!r} in {mcap_file.path} has message encoding '
                f'{channel.message_encoding!r}, expected {MESSAGE_ENCODING!r}',
                topic=channel.topic,
                expected=MESSAGE_ENCODING,
                found=channel.message_encoding,
            )
        if schema.encoding not in _DECODABLE_SCHEMA_ENCODINGS:
            raise BagSchemaError(
                f'topic {channel.topic!r} in {mcap_file.path} has schema encoding '
                f'{schema.encoding!r}, expected {SCHEMA_ENCODING!r}',
                topic=channel.topic,
                expected=SCHEMA_ENCODING,
                found=schema.encoding,
            )
        return _Topic(channel.topic, schema.name, channel.metadata.get('offered_qos_profiles', ''))

    def _find_topic(self, topic_name: str) -> _Topic | None:
        for topic in self._topics.values():
            if _topic_key(topic.name) == _topic_key(topic_name):
                return topic
        return None

    def _check_type(self, topic_name: str, expected: str) -> None:
        topic = self._find_topic(topic_name)
        if topic is None:
            return  # an absent topic is not a mismatch (e.g. a bag without a posture topic)
        try:
            matches = normalize_type_name(topic.type_name) == normalize_type_name(expected)
        except BagSchemaError:
            matches = False
        if not matches:
            raise BagSchemaError(
                f'topic {topic.name!r} in {self.path} has type {topic.type_name}, '
                f'expected {expected}',
                topic=topic.name,
                expected=expected,
                found=topic.type_name,
            )

    def topics(self) -> dict[str, TopicInfo]:
        counts: dict[str, int] = {name: 0 for name in self._topics}
        for mcap_file, channel_topics in zip(self._files, self._channel_topics):
            for channel_id, topic in channel_topics.items():
                counts[topic.name] += mcap_file.counts.get(channel_id, 0)
        return {
            name: TopicInfo(topic.type_name, counts[name], topic.qos_profiles)
            for name, topic in self._topics.items()
        }

    def schemas(self, topic_name: str) -> list[tuple[str, str]]:
        """Return (encoding, text) of the schema of `topic_name` in each file having the topic."""
        found = []
        for mcap_file, channel_topics in zip(self._files, self._channel_topics):
            for channel_id, topic in channel_topics.items():
                if _topic_key(topic.name) == _topic_key(topic_name):
                    schema = mcap_file.schemas[mcap_file.channels[channel_id].schema_id]
                    found.append((schema.encoding, schema.data.decode('utf-8', errors='replace')))
        return found

    def metadata(self) -> list[MetadataRecord]:
        """All MCAP metadata records, in file order."""
        return [record for mcap_file in self._files for record in mcap_file.metadata]

    def info(self) -> BagInfo:
        files = tuple(mcap_file.info() for mcap_file in self._files)
        starts = [f.start_time_ns for f in files if f.start_time_ns is not None]
        ends = [f.end_time_ns for f in files if f.end_time_ns is not None]
        return BagInfo(
            path=str(self.path),
            storage_identifier=STORAGE_IDENTIFIER,
            files=files,
            topics=self.topics(),
            message_count=sum(f.message_count for f in files),
            start_time_ns=min(starts) if starts else None,
            end_time_ns=max(ends) if ends else None,
            size_bytes=sum(f.size_bytes for f in files),
        )

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
        """Messages in file order (the order they were written), optionally of some topics."""
        wanted = None if topics is None else {_topic_key(t) for t in topics}
        for file_index, (mcap_file, channel_topics) in enumerate(
            zip(self._files, self._channel_topics)
        ):
            selected = {
                cid: topic
                for cid, topic in channel_topics.items()
                if wanted is None or _topic_key(topic.name) in wanted
            }
            if not selected:
                continue
            scan = mcap_file.scan()
            # A complete file's summary says which channels each chunk holds: chunks with none of
            # the selected ones (and no unknown channel, which the scan would report) are not read,
            # and messages of known unselected channels are not unpacked.
            skip_chunks = frozenset(
                offset
                for offset, ids in mcap_file.chunk_channels.items()
                if ids and ids.isdisjoint(selected) and ids <= channel_topics.keys()
            )
            ignore_channels = frozenset(channel_topics.keys() - selected.keys())
            for record in scan.records(skip_chunks, ignore_channels):
                if not isinstance(record, _RawMessage):
                    continue
                topic = selected.get(record.channel_id)
                if topic is None:
                    if record.channel_id not in channel_topics:
                        scan.stop(None, f'message on unknown channel {record.channel_id}')
                        break
                    continue
                yield BagMessage(
                    topic.name,
                    topic.type_name,
                    record.log_time,
                    record.publish_time,
                    record.data,
                    self._lazy_decoder(file_index, mcap_file, record.channel_id),
                )

    def _lazy_decoder(
        self, file_index: int, mcap_file: _McapFile, channel_id: int
    ) -> Callable[[bytes], Any]:
        """Return a decode function per schema that parses the schema on its first call only."""
        channel = mcap_file.channels[channel_id]
        key = (file_index, channel.schema_id)
        decode = self._decoders.get(key)
        if decode is None:
            schema = mcap_file.schemas[channel.schema_id]
            built: list[Callable[[bytes], Any]] = []

            def decode(data: bytes) -> Any:
                if not built:
                    generic = self._build_decoder(schema, channel.topic)
                    built.append(_in_place(schema, generic) if self.fast_decoding else generic)
                return built[0](data)

            self._decoders[key] = decode
        return decode

    @staticmethod
    def _build_decoder(schema: Schema, topic: str) -> Callable[[bytes], Any]:
        if schema.encoding != SCHEMA_ENCODING:
            raise BagSchemaError(
                f'topic {topic!r}: cannot decode schema encoding {schema.encoding!r}, '
                f'only {SCHEMA_ENCODING!r}',
                topic=topic,
                expected=SCHEMA_ENCODING,
                found=schema.encoding,
            )
        from mcap_ros2.decoder import DecoderFactory

        parser_output = io.StringIO()
        try:
            # The vendored rosidl parser prints its complaints to stderr; keep them for the error.
            with contextlib.redirect_stderr(parser_output):
                decoder = DecoderFactory().decoder_for(MESSAGE_ENCODING, schema)
        except Exception as error:  # noqa: BLE001 - schema parser errors have many types
            detail = parser_output.getvalue().strip().splitlines()
            raise BagSchemaError(
                f'topic {topic!r}: schema {schema.name} does not parse: '
                f'{type(error).__name__}: {error}' + (f' ({detail[0]})' if detail else ''),
                topic=topic,
                found=schema.name,
            ) from error
        if decoder is None:
            raise BagSchemaError(
                f'topic {topic!r}: no decoder for schema {schema.name}',
                topic=topic,
                found=schema.name,
            )
        return decoder


def _definition_fields(text: str) -> dict[str, tuple[tuple[str, str], ...]] | None:
    """Return each message's fields in a ros2msg definition ('': the top level); None: unnamed."""
    sections = re.split(r'^={80}\s*$', text, flags=re.MULTILINE)
    fields = {'': field_signature(sections[0])}
    for section in sections[1:]:
        match = re.match(r'\s*MSG: (\S+)\s*\n', section)
        if match is None:
            return None
        fields[match.group(1).replace('/msg/', '/')] = field_signature(section[match.end():])
    return fields


def _in_place(schema: Schema, generic: Callable[[bytes], Any]) -> Callable[[bytes], Any]:
    """
    Return a decoder that reads ``schema``'s messages in place where it can, else ``generic``.

    Only for the JointState and Imu definitions whose every message has exactly the fields of
    the layouts read in place (hexacal_msgs_py.cdr_messages.DEFINITIONS).
    """
    from hexacal_msgs_py.cdr_messages import DEFINITIONS, MessageDecoder

    try:
        type_name = normalize_type_name(schema.name)
    except BagSchemaError:
        return generic
    known = DEFINITIONS.get(type_name)
    if known is None or schema.encoding != SCHEMA_ENCODING:
        return generic
    fields = _definition_fields(schema.data.decode('utf-8', errors='replace'))
    top = type_name.replace('/msg/', '/')
    if fields is None or {top if k == '' else k: v for k, v in fields.items()} != known:
        return generic
    return MessageDecoder(type_name, generic)


# --------------------------------------------------------------------------- opening


def _file_order(path: Path) -> tuple[int, str]:
    # rosbag2 splits into <name>_0.mcap, <name>_1.mcap, ...: order by that index.
    match = re.search(r'_(\d+)\.mcap$', path.name)
    return (int(match.group(1)) if match else -1, path.name)


def mcap_files_in(directory: Path) -> list[Path]:
    """Return the .mcap files of a bag directory in split order."""
    return sorted((p for p in directory.glob('*.mcap') if p.is_file()), key=_file_order)


def load_metadata_yaml(path: Path) -> dict[str, Any]:
    """Return the rosbag2_bagfile_information mapping of a metadata.yaml."""
    from hexacal_msgs_py.files import load_yaml_text
    import yaml

    try:
        document = load_yaml_text(
            path.read_text(encoding='utf-8')
        )  # SafeLoader, libyaml's parser if any
        information = document['rosbag2_bagfile_information']
        if not isinstance(information, dict):
            raise TypeError('rosbag2_bagfile_information is not a mapping')
        return information
    except (
        OSError,
        UnicodeDecodeError,
        yaml.YAMLError,
        KeyError,
        TypeError,
        RecursionError,
    ) as error:  # RecursionError: YAML nested thousands deep
        raise BagMetadataError(
            f'{path} is not a readable rosbag2 metadata file '
            f'({type(error).__name__}: {error}); rebuild it with reindex'
        ) from error


def _bag_files(directory: Path) -> list[Path]:
    metadata_path = directory / METADATA_FILE_NAME
    if not metadata_path.exists():
        files = mcap_files_in(directory)
        if not files:
            raise BagMissingFileError(
                f'{directory} has neither {METADATA_FILE_NAME} nor an '
                '.mcap file: not a rosbag2 MCAP bag'
            )
        return files
    information = load_metadata_yaml(metadata_path)
    storage = information.get('storage_identifier')
    if storage != STORAGE_IDENTIFIER:
        raise BagFormatError(
            f'{directory} uses storage {storage!r}; only {STORAGE_IDENTIFIER!r} bags are supported'
        )
    relative_paths = information.get('relative_file_paths') or []
    if not isinstance(relative_paths, list) or not all(isinstance(p, str) for p in relative_paths):
        raise BagMetadataError(f'{metadata_path}: relative_file_paths is not a list of paths')
    # Older rosbag2 versions stored '<bag>/<file>'; only the file name is meaningful.
    files = [directory / Path(p).name for p in relative_paths]
    missing = [str(p) for p in files if not p.is_file()]
    if missing:
        raise BagMissingFileError(f'{metadata_path} lists files that do not exist: {missing}')
    if not files:
        raise BagMissingFileError(f'{metadata_path} lists no bag files')
    return files


def open_bag(
    path: str | os.PathLike[str], *, expect_types: Mapping[str, str] | None = None
) -> BagReader:
    """
    Open a rosbag2 MCAP bag directory or a single .mcap file.

    `expect_types` maps topic -> type name; a topic present with another type
    raises BagSchemaError naming topic, expected and found type.
    """
    bag_path = Path(path)
    if not bag_path.exists():
        raise BagNotFoundError(f'{bag_path} does not exist')
    if bag_path.is_dir():
        files = _bag_files(bag_path)
    elif bag_path.is_file():
        files = [bag_path]
    else:
        raise BagFormatError(f'{bag_path} is neither a bag directory nor a file')
    return BagReader(bag_path, [_McapFile(p) for p in files], expect_types)


def _format_size(size_bytes: int) -> str:
    size = float(size_bytes)
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if size < 1024 or unit == 'GiB':
            return f'{size:.1f} {unit}' if unit != 'B' else f'{size_bytes} B'
        size /= 1024
    return f'{size_bytes} B'


def _format_stamp(stamp_ns: int | None) -> str:
    if stamp_ns is None:
        return '-'
    import datetime

    try:
        moment = datetime.datetime.fromtimestamp(stamp_ns / 1e9, tz=datetime.timezone.utc)
    except (OverflowError, OSError, ValueError):
        return f'({stamp_ns / 1e9:.9f})'
    return f'{moment.isoformat()} ({stamp_ns / 1e9:.9f})'
