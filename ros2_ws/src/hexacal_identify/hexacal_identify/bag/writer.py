"""
Write rosbag2-compatible MCAP bags (ROS 2 Jazzy layout, metadata version 9) without ROS.

Layout: ``<dir>/<dirname>_0.mcap`` (MCAP profile ``ros2``, schemas ``ros2msg``,
messages ``cdr``, channel metadata ``offered_qos_profiles``) and, on close,
``<dir>/metadata.yaml``.

Durability: bytes go to an in-memory buffer; `flush()` closes the open MCAP
chunk, writes everything and fsyncs, so a SIGKILL loses at most what was
written after the last flush. On an OSError the writer stops, and `close()`
cuts the file back to the last flush so it stays readable (see reader.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path
import time
from typing import Any, Callable, cast, IO, Mapping

from hexacal_msgs_py.files import atomic_write
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
import yaml

from .bag_info import BagInfo, FileInfo, METADATA_FILE_NAME, STORAGE_IDENTIFIER, TopicInfo
from .errors import BagEncodeError, BagError, BagSchemaError, BagWriteError
from .qos_yaml import DEFAULT_QOS_PROFILES_YAML, read_qos_profiles
from .schemas import (
    field_names,
    message_definition,
    MESSAGE_ENCODING,
    normalize_type_name,
    SCHEMA_ENCODING,
)

# Jazzy's rosbag2_storage writes version 9: offered_qos_profiles is a YAML list
# with policies as strings ('reliable'), not the integer enums of version 8.
ROSBAG2_METADATA_VERSION = 9
ROS_DISTRO = 'jazzy'
MCAP_PROFILE = 'ros2'
LIBRARY_IDENTIFIER = 'hexacal_identify.bag'
# rosbag2's MCAP storage stores its BagMetadata in a metadata record of this name.
ROSBAG2_METADATA_RECORD = 'rosbag2'


@dataclass(frozen=True)
class _StoragePreset:
    chunked: bool
    chunk_size_bytes: int
    compression: CompressionType


# Names of rosbag2's MCAP storage presets. Chunks are smaller than rosbag2's
# (768 KiB) because a chunk is the unit that a crash without flush loses.
STORAGE_PRESETS: dict[str, _StoragePreset] = {
    'none': _StoragePreset(True, 256 * 1024, CompressionType.NONE),
    'fastwrite': _StoragePreset(False, 0, CompressionType.NONE),
    'zstd_fast': _StoragePreset(True, 256 * 1024, CompressionType.ZSTD),
    'zstd_small': _StoragePreset(True, 4 * 1024 * 1024, CompressionType.ZSTD),
}


def metadata_document(
    info: BagInfo, *, custom_data: Mapping[str, str] | None = None, ros_distro: str = ROS_DISTRO
) -> dict[str, Any]:
    """Return the rosbag2_bagfile_information mapping (version 9) describing `info`."""
    start_ns = info.start_time_ns if info.start_time_ns is not None else 0
    return {
        'version': ROSBAG2_METADATA_VERSION,
        'storage_identifier': STORAGE_IDENTIFIER,
        'duration': {'nanoseconds': info.duration_ns},
        'starting_time': {'nanoseconds_since_epoch': start_ns},
        'message_count': info.message_count,
        'topics_with_message_count': [
            {
                'topic_metadata': {
                    'name': name,
                    'type': topic.type_name,
                    'serialization_format': MESSAGE_ENCODING,
                    'offered_qos_profiles': read_qos_profiles(topic.qos_profiles),
                    'type_description_hash': '',
                },
                'message_count': topic.count,
            }
            for name, topic in info.topics.items()
        ],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [Path(f.path).name for f in info.files],
        'files': [
            {
                'path': Path(f.path).name,
                'starting_time': {'nanoseconds_since_epoch': f.start_time_ns or 0},
                'duration': {'nanoseconds': (f.end_time_ns or 0) - (f.start_time_ns or 0)},
                'message_count': f.message_count,
            }
            for f in info.files
        ],
        'custom_data': dict(custom_data or {}),
        'ros_distro': ros_distro,
    }


def write_metadata_yaml(directory: Path, document: Mapping[str, Any]) -> Path:
    """Write <directory>/metadata.yaml atomically (temp file, fsync, rename, fsync dir)."""
    text = yaml.safe_dump({'rosbag2_bagfile_information': dict(document)}, sort_keys=False)
    return atomic_write(
        directory / METADATA_FILE_NAME, text
    )  # e.g. disk full: no half-written file


class _DurableFile:
    """
    Write-behind buffer over a file descriptor that knows exactly which bytes are on disk.

    The mcap Writer only needs write/tell/flush. A Python BufferedWriter would
    retry its buffer on close after an ENOSPC and append garbage; here a failed
    writer can cut the file back to the last fsync'd offset instead.
    """

    def __init__(self, path: Path, spill_bytes: int = 1 << 20):
        self.path = path
        self._descriptor = os.open(
            path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644
        )
        self._buffer = bytearray()
        self._in_file = 0
        self._spill_bytes = spill_bytes

    def write(self, data: bytes | bytearray | memoryview) -> int:
        self._buffer += data
        if len(self._buffer) >= self._spill_bytes:
            self._drain()
        return len(data)

    def tell(self) -> int:
        return self._in_file + len(self._buffer)

    def flush(self) -> None:
        self._drain()

    def sync(self) -> int:
        """Write the buffer and fsync; returns the file size that is now durable."""
        self._drain()
        os.fsync(self._descriptor)
        return self._in_file

    def truncate(self, size: int) -> None:
        self._buffer.clear()
        os.ftruncate(self._descriptor, size)
        self._in_file = size

    def close(self) -> None:
        if self._descriptor >= 0:
            descriptor, self._descriptor = self._descriptor, -1
            os.close(descriptor)

    def _drain(self) -> None:
        view = memoryview(self._buffer)
        written = 0
        try:
            while written < len(view):
                written += os.write(self._descriptor, view[written:])
        finally:
            self._in_file += written
            view.release()
            del self._buffer[:written]


@dataclass
class _TopicState:
    type_name: str
    qos_profiles_yaml: str
    channel_id: int
    count: int = 0
    durable_count: int = 0


@dataclass
class _Stamps:
    start_ns: int | None = None
    end_ns: int | None = None

    def add(self, stamp_ns: int) -> None:
        self.start_ns = stamp_ns if self.start_ns is None else min(self.start_ns, stamp_ns)
        self.end_ns = stamp_ns if self.end_ns is None else max(self.end_ns, stamp_ns)


@dataclass
class _DurableState:
    size_bytes: int = 0
    stamps: _Stamps = field(default_factory=_Stamps)


class BagWriter:
    """Writes one rosbag2 MCAP bag directory; use as a context manager or call close()."""

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        storage_preset: str = 'none',
        chunk_size_bytes: int | None = None,
        flush_period_s: float | None = None,
        custom_data: Mapping[str, str] | None = None,
        ros_distro: str = ROS_DISTRO,
    ):
        if storage_preset not in STORAGE_PRESETS:
            raise BagError(
                f'unknown storage preset {storage_preset!r}; valid: {sorted(STORAGE_PRESETS)}'
            )
        preset = STORAGE_PRESETS[storage_preset]
        self.directory = Path(directory)
        self.mcap_path = self.directory / f'{self.directory.resolve().name}_0.mcap'
        self._custom_data = dict(custom_data or {})
        self._ros_distro = ros_distro
        self._flush_period_s = flush_period_s
        self._topics: dict[str, _TopicState] = {}
        self._schema_ids: dict[str, int] = {}
        self._encoders: dict[str, Callable[[Any], bytes]] = {}
        self._stamps = _Stamps()
        self._durable = _DurableState()
        self._failure: BagWriteError | None = None
        self._closed = False
        self._prepare_directory()
        try:
            self._file = _DurableFile(self.mcap_path)
        except OSError as error:
            raise BagWriteError(
                f'cannot create {self.mcap_path}: {error}',
                path=str(self.mcap_path),
                os_error=error,
            ) from error
        self._mcap = McapWriter(
            # mcap's stub asks for a file object; the Writer uses only write/tell/flush.
            cast(IO[Any], self._file),
            chunk_size=chunk_size_bytes or preset.chunk_size_bytes or 1,
            compression=preset.compression,
            use_chunking=preset.chunked,
            enable_crcs=True,
        )
        self._last_flush = time.monotonic()
        try:
            self._guarded(
                'start the MCAP file', self._mcap.start, MCAP_PROFILE, LIBRARY_IDENTIFIER
            )
            # Early rosbag2 record: a file cut short still says its QoS text is version 9.
            self._add_rosbag2_record()
            self.flush()
        except BagWriteError:
            self._close_after_failure()
            raise

    # ------------------------------------------------------------------ public API

    def add_topic(
        self, topic: str, type_name: str, qos_profiles_yaml: str = DEFAULT_QOS_PROFILES_YAML
    ) -> None:
        """Register a topic (schema from the installed .msg files, channel with its QoS)."""
        self._check_open()
        if not isinstance(topic, str) or not topic:
            raise BagError(f'topic name must be a non-empty string, got {topic!r}')
        normalized = normalize_type_name(type_name)
        read_qos_profiles(qos_profiles_yaml, strict=True)
        known = self._topics.get(topic)
        if known is not None:
            if known.type_name != normalized:
                raise BagError(
                    f'topic {topic!r} was added as {known.type_name}, '
                    f'cannot add it again as {normalized}'
                )
            return
        schema_id = self._schema_ids.get(normalized)
        if schema_id is None:
            text = message_definition(normalized)
            schema_id = self._guarded(
                'register a schema',
                self._mcap.register_schema,
                normalized,
                SCHEMA_ENCODING,
                text.encode('utf-8'),
            )
            self._schema_ids[normalized] = schema_id
        channel_id = self._guarded(
            'register a channel',
            self._mcap.register_channel,
            topic,
            MESSAGE_ENCODING,
            schema_id,
            {'offered_qos_profiles': qos_profiles_yaml, 'topic_type_hash': ''},
        )
        self._topics[topic] = _TopicState(normalized, qos_profiles_yaml, channel_id)

    def write_raw(
        self,
        topic: str,
        cdr_bytes: bytes | bytearray | memoryview,
        log_time_ns: int,
        publish_time_ns: int | None = None,
    ) -> None:
        """Write CDR bytes (from rclpy serialize_message or a raw subscription)."""
        self._check_open()
        state = self._topics.get(topic)
        if state is None:
            raise BagError(f'topic {topic!r} was not added with add_topic')
        log_time = _stamp(log_time_ns, 'log_time_ns')
        publish_time = (
            log_time if publish_time_ns is None else _stamp(publish_time_ns, 'publish_time_ns')
        )
        try:
            data = bytes(cdr_bytes)
        except TypeError as error:
            raise BagEncodeError(
                f'topic {topic!r}: message data must be bytes, got {type(cdr_bytes).__name__}'
            ) from error
        self._guarded(
            'write a message',
            self._mcap.add_message,
            state.channel_id,
            log_time,
            data,
            publish_time,
            state.count % 2**32,
        )
        state.count += 1
        self._stamps.add(log_time)
        if (
            self._flush_period_s is not None
            and time.monotonic() - self._last_flush >= self._flush_period_s
        ):
            self.flush()

    def write(
        self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """
        Encode a dict (or a message object) with the topic's schema and write it.

        A topic not added yet is added when `message` is a generated ROS
        message object (its type is read from its class); dicts need add_topic.
        """
        self._check_open()
        state = self._topics.get(topic)
        if state is None:
            type_name = _type_name_of(message)
            if type_name is None:
                raise BagError(f'topic {topic!r} was not added with add_topic')
            self.add_topic(topic, type_name)
            state = self._topics[topic]
        encoder = self._encoder(state.type_name)
        if isinstance(message, Mapping):
            # The encoder silently ignores unknown keys: a typo would record default values.
            unknown = sorted(set(message) - set(field_names(state.type_name)))
            if unknown:
                raise BagEncodeError(
                    f'cannot encode a dict for topic {topic!r}: '
                    f'{state.type_name} has no field(s) {unknown}'
                )
        try:
            data = encoder(message)
        except Exception as error:  # noqa: BLE001 - the encoder raises many types
            raise BagEncodeError(
                f'cannot encode a {type(message).__name__} for topic {topic!r} '
                f'as {state.type_name}: {type(error).__name__}: {error}'
            ) from error
        self.write_raw(topic, data, log_time_ns, publish_time_ns)

    def write_metadata(self, key: str, data: Mapping[str, str]) -> None:
        """Write an MCAP metadata record (e.g. the posture plan followed) and flush it."""
        self._check_open()
        if not isinstance(key, str) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in data.items()
        ):
            raise BagError(f'metadata {key!r} must map str to str')
        self._guarded('write metadata', self._mcap.add_metadata, key, dict(data))
        self.flush()

    def flush(self) -> None:
        """Close the open chunk, write everything so far and fsync it."""
        self._check_open()
        self._guarded('close the current chunk', self._mcap.flush)
        size = self._guarded('fsync the bag file', self._file.sync)
        self._durable = _DurableState(size, _Stamps(self._stamps.start_ns, self._stamps.end_ns))
        for state in self._topics.values():
            state.durable_count = state.count
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """
        Finish the MCAP (summary, footer) and write metadata.yaml atomically.

        After a BagWriteError, close() cuts the file back to the last flush and
        writes metadata.yaml for that part if the disk lets it; it does not
        raise again (the error was already raised to the caller).
        """
        if self._closed:
            return
        if self._failure is not None:
            self._close_after_failure()
            return
        try:
            self._add_rosbag2_record()
            self._guarded('finish the MCAP file', self._mcap.finish)
            size = self._guarded('fsync the bag file', self._file.sync)
        except BagWriteError:
            self._close_after_failure()
            raise
        self._file.close()
        self._closed = True
        for state in self._topics.values():
            state.durable_count = state.count
        self._durable = _DurableState(size, self._stamps)
        try:
            write_metadata_yaml(self.directory, self._metadata_document())
        except OSError as error:
            raise BagWriteError(
                f'cannot write {self.directory / METADATA_FILE_NAME}: {error}',
                path=str(self.directory / METADATA_FILE_NAME),
                os_error=error,
            ) from error

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, traceback: object) -> None:
        if exc_type is None:
            self.close()
            return
        try:
            self.close()
        except BagError:
            pass  # the exception already propagating is the one to report

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def failure(self) -> BagWriteError | None:
        """Return the write error that stopped this writer, if any."""
        return self._failure

    @property
    def message_count(self) -> int:
        return sum(state.count for state in self._topics.values())

    @property
    def flushed_message_count(self) -> int:
        """Messages made durable by the last flush (what survives a SIGKILL now)."""
        return sum(state.durable_count for state in self._topics.values())

    # ------------------------------------------------------------------ internals

    def _prepare_directory(self) -> None:
        if self.directory.exists():
            if not self.directory.is_dir():
                raise BagError(f'bag path {self.directory} exists and is not a directory')
            if any(self.directory.iterdir()):
                raise BagError(f'bag directory {self.directory} already exists and is not empty')
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise BagWriteError(
                f'cannot create bag directory {self.directory}: {error}',
                path=str(self.directory),
                os_error=error,
            ) from error

    def _check_open(self) -> None:
        if self._failure is not None:
            raise BagWriteError(
                f'bag writer for {self.mcap_path} stopped after an earlier error: {self._failure}',
                path=str(self.mcap_path),
                os_error=self._failure.os_error,
            )
        if self._closed:
            raise BagError(f'bag writer for {self.mcap_path} is closed')

    def _guarded(self, action: str, function: Callable[..., Any], *args: Any) -> Any:
        try:
            return function(*args)
        except OSError as error:
            self._failure = BagWriteError(
                f'cannot {action} in {self.mcap_path}: {error}; the bag keeps what was written '
                f'up to the last flush',
                path=str(self.mcap_path),
                os_error=error,
            )
            raise self._failure from error

    def _close_after_failure(self) -> None:
        self._closed = True
        try:
            self._file.truncate(self._durable.size_bytes)
        except OSError:
            pass  # the reader still stops at the first incomplete record
        self._file.close()
        for state in self._topics.values():
            state.count = state.durable_count
        self._stamps = self._durable.stamps
        try:
            write_metadata_yaml(self.directory, self._metadata_document())
        except OSError:
            pass  # reindex() rebuilds it once there is space

    def _info(self) -> BagInfo:
        counts = sum(state.count for state in self._topics.values())
        file_info = FileInfo(
            str(self.mcap_path),
            self._durable.size_bytes,
            counts,
            self._stamps.start_ns,
            self._stamps.end_ns,
            truncated=self._failure is not None,
        )
        return BagInfo(
            path=str(self.directory),
            storage_identifier=STORAGE_IDENTIFIER,
            files=(file_info,),
            topics={
                name: TopicInfo(state.type_name, state.count, state.qos_profiles_yaml)
                for name, state in self._topics.items()
            },
            message_count=counts,
            start_time_ns=self._stamps.start_ns,
            end_time_ns=self._stamps.end_ns,
            size_bytes=self._durable.size_bytes,
        )

    def _metadata_document(self) -> dict[str, Any]:
        return metadata_document(
            self._info(), custom_data=self._custom_data, ros_distro=self._ros_distro
        )

    def _add_rosbag2_record(self) -> None:
        serialized = yaml.safe_dump(self._metadata_document(), sort_keys=False)
        self._guarded(
            'write metadata',
            self._mcap.add_metadata,
            ROSBAG2_METADATA_RECORD,
            {'serialized_metadata': serialized},
        )

    def _encoder(self, type_name: str) -> Callable[[Any], bytes]:
        encoder = self._encoders.get(type_name)
        if encoder is None:
            from mcap_ros2._dynamic import serialize_dynamic

            try:
                encoder = serialize_dynamic(type_name, message_definition(type_name))[type_name]
            except BagError:
                raise
            except Exception as error:  # noqa: BLE001 - schema parser errors have many types
                raise BagSchemaError(
                    f'cannot build a CDR encoder for {type_name}: {error}', found=type_name
                ) from error
            self._encoders[type_name] = encoder
        return encoder


def _stamp(value: Any, name: str) -> int:
    try:
        stamp = int(value.__index__())
    except (AttributeError, TypeError) as error:
        raise BagError(f'{name} must be an integer number of ns, got {value!r}') from error
    if not 0 <= stamp < 2**64:
        raise BagError(f'{name} must be in [0, 2**64) ns, got {stamp}')
    return stamp


def _type_name_of(message: Any) -> str | None:
    """'sensor_msgs/msg/JointState' for a generated ROS message object, else None."""
    if isinstance(message, Mapping):
        return None
    module = type(message).__module__.split('.')
    if len(module) >= 2 and module[1] == 'msg':
        return f'{module[0]}/msg/{type(message).__name__}'
    return None
