"""What a bag holds, as ``hexacal bag-info`` prints it: its files, topics and metadata."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

METADATA_FILE_NAME = 'metadata.yaml'
STORAGE_IDENTIFIER = 'mcap'


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
