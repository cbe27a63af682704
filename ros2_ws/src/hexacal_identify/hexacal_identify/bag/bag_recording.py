"""
A recording: the bag being written, opened and closed on demand, stopped by its first error.

The collector records into one bag at a time. Every write goes through here: a BagError
(e.g. disk full) stops the recording, is remembered (`error`) and handed to `on_failure`,
and the bag stays readable (BagWriter cuts it back to its last flush).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from .errors import BagError
from .writer import BagWriter


class Recording:
    """The current bag of a recorder (None when not recording) and its counts."""

    def __init__(self, on_failure: Callable[[BagError], None]) -> None:
        self.on_failure = on_failure  # called after a write error, the recording stopped
        self.writer: BagWriter | None = None
        self.postures = 0  # postures written in the current bag
        self.error: str | None = None  # the error that stopped the last recording
        self._topics_added: set[str] = set()  # topics registered on first message

    @property
    def directory(self) -> Path | None:
        """Return the directory of the current bag, None when not recording."""
        return self.writer.directory if self.writer is not None else None

    def start(
        self,
        directory: Path,
        custom_data: Mapping[str, str],
        topics: Iterable[tuple[str, str, str]],
        metadata: Mapping[str, Mapping[str, str]],
    ) -> None:
        """
        Start a bag with these topics (name, type, QoS YAML) and metadata records.

        A BagError is raised (no bag is left open) and not handed to on_failure.
        """
        writer = BagWriter(directory, custom_data=custom_data)
        try:
            for name, type_name, qos_yaml in topics:
                writer.add_topic(name, type_name, qos_yaml)
            for name, mapping in metadata.items():
                writer.write_metadata(name, mapping)
        except BagError:
            try:
                writer.close()
            except BagError:
                pass  # the first error is the one to report
            raise
        self.writer, self.postures, self.error = writer, 0, None
        self._topics_added = set()

    def close(self) -> str | None:
        """Finish the bag (metadata.yaml); return what happened, None if not recording."""
        writer, self.writer = self.writer, None
        if writer is None:
            return None
        try:
            writer.close()
        except BagError as error:
            return f'closing {writer.directory}: {error}'
        return (
            f'closed bag {writer.directory}: {writer.message_count} messages, '
            f'{self.postures} postures'
        )

    def write(
        self, name: str, data: Any, log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """Write CDR bytes as received, or encode a message, on the bag topic `name`."""
        if self.writer is None:
            return
        try:
            if isinstance(data, bytes):
                self.writer.write_raw(name, data, log_time_ns, publish_time_ns)
            else:
                self.writer.write(name, data, log_time_ns)
        except BagError as error:
            self._failed(error)

    def add_topic_once(self, name: str, type_name: str, qos_yaml: str) -> bool:
        """Register a topic in the current bag on its first message; False if not recording."""
        if self.writer is None:
            return False
        if name not in self._topics_added:
            try:
                self.writer.add_topic(name, type_name, qos_yaml)
            except BagError as error:
                self._failed(error)
                return False
            self._topics_added.add(name)
        return True

    def flush(self) -> None:
        """Make what was written durable, if anything was written since the last flush."""
        writer = self.writer
        if writer is None or writer.message_count == writer.flushed_message_count:
            return
        try:
            writer.flush()
        except BagError as error:
            self._failed(error)

    def write_metadata(self, writer: BagWriter, name: str, mapping: Mapping[str, str]) -> bool:
        """Add a metadata record to `writer` if it is still the current bag; True if written."""
        if writer is not self.writer:
            return False
        try:
            writer.write_metadata(name, mapping)
        except BagError as error:
            self._failed(error)
            return False
        return True

    def _failed(self, error: BagError) -> None:
        self.error = f'{error.reason}: {error}'
        self.on_failure(error)
