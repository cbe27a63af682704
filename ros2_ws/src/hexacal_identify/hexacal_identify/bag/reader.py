"""
Read rosbag2 MCAP bags (a bag directory or a single .mcap file) without ROS.

A complete MCAP file (valid footer and summary CRC) is indexed from its
summary; any damaged record in it raises `BagCorruptError`. A file without a
valid footer (the recorder was killed, the disk filled up) is read by a
forward scan that keeps every complete record and chunk and stops cleanly at
the first incomplete or damaged one; the file is then reported as truncated.
Every problem with the input surfaces as a `BagError` subclass.

The parts: ``mcap_records`` (records, chunks, the forward scan), ``mcap_file`` (one file,
indexed from its summary or a scan), ``bag_info`` (what ``bag-info`` prints); this module
opens a bag and reads its messages.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import io
import os
from pathlib import Path
import re
from typing import Any, Callable, Iterable, Iterator, Mapping, NamedTuple

from mcap.records import Channel, Schema

from .bag_info import (
    BagInfo,
    FileInfo,
    METADATA_FILE_NAME,
    MetadataRecord,
    STORAGE_IDENTIFIER,
    TopicInfo,
)
from .errors import (
    BagDecodeError,
    BagError,
    BagFormatError,
    BagMetadataError,
    BagMissingFileError,
    BagNotFoundError,
    BagSchemaError,
)
from .mcap_file import McapFile
from .mcap_records import MCAP_MAGIC, RawMessage
from .schemas import field_signature, MESSAGE_ENCODING, normalize_type_name, SCHEMA_ENCODING

_DECODABLE_SCHEMA_ENCODINGS = (SCHEMA_ENCODING, 'ros2idl')


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
        self, path: Path, files: list[McapFile], expect_types: Mapping[str, str] | None = None
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

    def _validated_topic(self, mcap_file: McapFile, channel: Channel) -> _Topic:
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
            decoders = {
                cid: self._lazy_decoder(file_index, mcap_file, cid) for cid in selected
            }  # once per channel, not per message
            for record in scan.records(skip_chunks, ignore_channels):
                if not isinstance(record, RawMessage):
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
                    decoders[record.channel_id],
                )

    def _lazy_decoder(
        self, file_index: int, mcap_file: McapFile, channel_id: int
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
    return BagReader(bag_path, [McapFile(p) for p in files], expect_types)


__all__ = [
    'BagInfo',
    'BagMessage',
    'BagReader',
    'FileInfo',
    'MCAP_MAGIC',
    'METADATA_FILE_NAME',
    'MetadataRecord',
    'STORAGE_IDENTIFIER',
    'TopicInfo',
    'load_metadata_yaml',
    'mcap_files_in',
    'open_bag',
]
