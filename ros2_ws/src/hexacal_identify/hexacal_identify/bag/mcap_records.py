"""
The records of an MCAP file: parse them, expand chunks, and scan a data section forward.

A record that does not parse raises ``RecordDamage``; ``RecordScan`` turns it into a
``BagCorruptError`` in a complete file and into a truncation point in one without a valid
footer.
"""

from __future__ import annotations

from io import BytesIO
from pathlib import Path
import struct
from typing import Any, Callable, Iterator, NamedTuple
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

from .errors import BagCorruptError, BagNotFoundError

MCAP_MAGIC = b'\x89MCAP0\r\n'

RECORD_HEADER = struct.Struct('<BQ')
_MESSAGE_PREFIX = struct.Struct('<HIQQ')  # channel_id, sequence, log_time, publish_time
FOOTER_BODY = struct.Struct('<QQI')  # summary_start, summary_offset_start, summary_crc
FOOTER_RECORD_SIZE = RECORD_HEADER.size + FOOTER_BODY.size
_CHANNEL_ID = struct.Struct('<H')
# Chunk index: message_start_time, message_end_time, chunk_start_offset, chunk_length, then the
# byte length of the message_index_offsets map of (channel id u16, offset u64) entries.
_CHUNK_INDEX_PREFIX = struct.Struct('<QQQQI')
_CHUNK_INDEX_ENTRY_SIZE = 10
# A corrupt length field must not make us allocate gigabytes.
_MAX_UNCOMPRESSED_CHUNK_BYTES = 1 << 30


class RecordDamage(Exception):
    """A record that cannot be parsed (internal; becomes a truncation stop or BagCorruptError)."""


class _StrictStream(ReadDataStream):
    """ReadDataStream that treats a short read as the end of data instead of returning less."""

    def read(self, length: int) -> bytes:
        data = super().read(length) if length else b''
        if len(data) != length:
            raise EndOfFile()
        return data


class RawMessage(NamedTuple):
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


def parse_record(opcode: int, body: bytes) -> Any:
    """Parse one record body, or None for record kinds this reader does not need."""
    if opcode == Opcode.MESSAGE:
        if len(body) < _MESSAGE_PREFIX.size:
            raise RecordDamage(f'message record of {len(body)} bytes is too short')
        channel_id, sequence, log_time, publish_time = _MESSAGE_PREFIX.unpack_from(body)
        return RawMessage(
            channel_id, sequence, log_time, publish_time, body[_MESSAGE_PREFIX.size:]
        )
    parser = _PARSERS.get(opcode)
    if parser is None:
        return None
    try:
        return parser(_StrictStream(BytesIO(body)))
    except Exception as error:  # noqa: BLE001 - any failure of mcap's parsers means damage
        raise RecordDamage(
            f'{Opcode(opcode).name} record does not parse: {type(error).__name__} {error}'
        ) from error


def _decompress(chunk: Chunk) -> bytes:
    if chunk.uncompressed_size > _MAX_UNCOMPRESSED_CHUNK_BYTES:
        raise RecordDamage(f'chunk claims {chunk.uncompressed_size} uncompressed bytes')
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
            raise RecordDamage(f'unsupported chunk compression {chunk.compression!r}')
    except RecordDamage:
        raise
    except Exception as error:  # noqa: BLE001 - codec errors have library-specific types
        raise RecordDamage(f'{chunk.compression} chunk does not decompress: {error}') from error
    if len(data) != chunk.uncompressed_size:
        raise RecordDamage(
            f'chunk decompresses to {len(data)} bytes, header says {chunk.uncompressed_size}'
        )
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise RecordDamage('chunk CRC mismatch')
    return data


def _chunk_records(chunk: Chunk, ignore_channels: frozenset[int] = frozenset()) -> list[Any]:
    """
    All schema, channel and message records of a chunk (all or nothing).

    Messages on ``ignore_channels`` are left out (bodies not copied; still checked for length).
    """
    data = _decompress(chunk)
    records: list[Any] = []
    # Messages are nearly every record: unpacked here, with plain ints and bound methods (the
    # per-record cost is most of reading a bag; parse_record would slice each body twice).
    message, others = int(Opcode.MESSAGE), (int(Opcode.SCHEMA), int(Opcode.CHANNEL))
    header, header_size = RECORD_HEADER.unpack_from, RECORD_HEADER.size
    prefix, prefix_size = _MESSAGE_PREFIX.unpack_from, _MESSAGE_PREFIX.size
    append, size, position = records.append, len(data), 0
    while position < size:
        if size - position < header_size:
            raise RecordDamage('chunk ends inside a record header')
        opcode, length = header(data, position)
        position += header_size
        end = position + length
        if end > size:
            raise RecordDamage(f'record of {length} bytes overruns its chunk')
        if opcode == message:
            if length < prefix_size:
                raise RecordDamage(f'message record of {length} bytes is too short')
            channel_id, sequence, log_time, publish_time = prefix(data, position)
            if channel_id not in ignore_channels:
                append(RawMessage(
                    channel_id, sequence, log_time, publish_time, data[position + prefix_size:end]
                ))
        elif opcode in others:
            append(parse_record(opcode, data[position:end]))
        position = end
    return records


def chunk_index_channels(body: bytes) -> tuple[int, frozenset[int]]:
    """
    Return the chunk start offset and channel ids of a chunk index record.

    (chunk_start_offset, ids of the channels with messages in the chunk) of a chunk index record.
    """
    if len(body) < _CHUNK_INDEX_PREFIX.size:
        raise RecordDamage(f'chunk index record of {len(body)} bytes is too short')
    _, _, chunk_offset, _, map_length = _CHUNK_INDEX_PREFIX.unpack_from(body)
    start = _CHUNK_INDEX_PREFIX.size
    if map_length % _CHUNK_INDEX_ENTRY_SIZE or map_length > len(body) - start:
        raise RecordDamage("chunk index's message index offsets overrun the record")
    return chunk_offset, frozenset(
        _CHANNEL_ID.unpack_from(body, position)[0]
        for position in range(start, start + map_length, _CHUNK_INDEX_ENTRY_SIZE)
    )


class RecordScan:
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
                head = handle.read(RECORD_HEADER.size)
                if len(head) < RECORD_HEADER.size:
                    self.stop(
                        offset,
                        'file ends before the footer'
                        if not head
                        else 'file ends inside a record header',
                    )
                    return
                opcode, length = RECORD_HEADER.unpack(head)
                available = self.size - offset - RECORD_HEADER.size
                if length > available:
                    self.stop(
                        offset,
                        f'{_opcode_name(opcode)} record of {length} bytes, '
                        f'only {available} left in the file',
                    )
                    return
                if opcode == Opcode.CHUNK and offset in skip_chunks:
                    offset += RECORD_HEADER.size + length
                    handle.seek(offset)
                    continue
                body = handle.read(length)
                if len(body) < length:
                    self.stop(offset, 'file shrank while reading')
                    return
                try:
                    if offset == len(MCAP_MAGIC) and opcode != Opcode.HEADER:
                        raise RecordDamage('first record is not an MCAP header')
                    if opcode == Opcode.CHUNK:
                        parsed = _chunk_records(parse_record(opcode, body), ignore_channels)
                    else:
                        record = parse_record(opcode, body)
                        parsed = [] if record is None else [record]
                except RecordDamage as damage:
                    self.stop(offset, str(damage))
                    return
                yield from parsed
                offset += RECORD_HEADER.size + length
                if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    self.reached_end = True
                    return


def _opcode_name(opcode: int) -> str:
    try:
        return Opcode(opcode).name
    except ValueError:
        return f'unknown (opcode {opcode:#x})'
