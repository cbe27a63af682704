"""One MCAP file of a bag: schemas, channels, counts and metadata, from its summary or a scan."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any
import zlib

from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Footer,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
)

from .bag_info import FileInfo, MetadataRecord
from .errors import BagCorruptError, BagEmptyError, BagFormatError, BagNotFoundError
from .mcap_records import (
    chunk_index_channels,
    FOOTER_BODY,
    FOOTER_RECORD_SIZE,
    MCAP_MAGIC,
    parse_record,
    RawMessage,
    RECORD_HEADER,
    RecordDamage,
    RecordScan,
)


class McapFile:
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

    def scan(self) -> RecordScan:
        return RecordScan(self.path, self.size, strict=self.complete)

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
        tail_size = FOOTER_RECORD_SIZE + len(MCAP_MAGIC)
        size = os.fstat(handle.fileno()).st_size
        if size < 2 * len(MCAP_MAGIC) + FOOTER_RECORD_SIZE:
            return None
        handle.seek(size - tail_size)
        tail = handle.read(tail_size)
        opcode, length = RECORD_HEADER.unpack_from(tail)
        if (
            opcode != Opcode.FOOTER
            or length != FOOTER_BODY.size
            or tail[-len(MCAP_MAGIC):] != MCAP_MAGIC
        ):
            return None
        summary_start, summary_offset_start, summary_crc = FOOTER_BODY.unpack_from(
            tail, RECORD_HEADER.size
        )
        footer_offset = size - tail_size
        if summary_start and not len(MCAP_MAGIC) <= summary_start <= footer_offset:
            return None
        if summary_crc:
            crc = 0
            if summary_start:
                handle.seek(summary_start)
                crc = zlib.crc32(handle.read(footer_offset - summary_start))
            crc = zlib.crc32(tail[: RECORD_HEADER.size + 16], crc)
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
                    if len(data) - position < RECORD_HEADER.size:
                        raise RecordDamage('summary ends inside a record header')
                    opcode, length = RECORD_HEADER.unpack_from(data, position)
                    position += RECORD_HEADER.size
                    if length > len(data) - position:
                        raise RecordDamage('summary record overruns the summary section')
                    if opcode == Opcode.CHUNK_INDEX:
                        if chunk_channels is not None:
                            try:
                                offset, channel_ids = chunk_index_channels(
                                    data[position:position + length]
                                )
                                chunk_channels[offset] = channel_ids
                            except RecordDamage:
                                chunk_channels = None  # not used: every chunk is read
                        position += length
                        continue
                    record = parse_record(opcode, data[position:position + length])
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
                    if len(raw) != index.length or index.length < RECORD_HEADER.size:
                        raise RecordDamage(
                            f'metadata index points outside the file ({index.offset})'
                        )
                    opcode, length = RECORD_HEADER.unpack_from(raw)
                    if opcode != Opcode.METADATA or length != index.length - RECORD_HEADER.size:
                        raise RecordDamage('metadata index points at a non-metadata record')
                    record = parse_record(opcode, raw[RECORD_HEADER.size:])
                    self.metadata.append(MetadataRecord(record.name, dict(record.metadata)))
            except RecordDamage as damage:
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
            if isinstance(record, RawMessage):
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
