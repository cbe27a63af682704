"""
Named errors of the bag layer: each says what is wrong and with which file or topic.

Every failure on malformed input surfaces as a `BagError` subclass, so callers
(the bag-info command, the offline identification) can catch one base class.
"""

from __future__ import annotations


class BagError(Exception):
    """Base class of every error the bag layer raises."""

    reason = 'bag-error'


class BagNotFoundError(BagError):
    """The path given as a bag does not exist."""

    reason = 'not-found'


class BagFormatError(BagError):
    """The file is not an MCAP file / the directory is not a rosbag2 bag."""

    reason = 'not-a-bag'


class BagEmptyError(BagFormatError):
    """The MCAP file has zero bytes (e.g. the recorder died before writing anything)."""

    reason = 'empty'


class BagMissingFileError(BagError):
    """A bag directory has no MCAP file, or metadata.yaml names one that is missing."""

    reason = 'missing-file'


class BagMetadataError(BagError):
    """Metadata.yaml cannot be parsed; `reindex` can rebuild it from the MCAP files."""

    reason = 'bad-metadata'


class BagCorruptError(BagError):
    """A complete MCAP file (with footer) has a damaged record: bad CRC, bad length, ..."""

    reason = 'corrupt'

    def __init__(self, message: str, path: str = '', offset: int = -1):
        super().__init__(message)
        self.path = path
        self.offset = offset


class BagSchemaError(BagError):
    """A schema is unusable: wrong encoding, unparsable, not found, or not the expected type."""

    reason = 'schema'

    def __init__(self, message: str, topic: str = '', expected: str = '', found: str = ''):
        super().__init__(message)
        self.topic = topic
        self.expected = expected
        self.found = found


class MessageDefinitionNotFoundError(BagSchemaError):
    """No installed .msg file defines the requested type (or one of its dependencies)."""

    reason = 'definition-not-found'


class BagDecodeError(BagError):
    """A message's CDR bytes do not decode with its topic's schema."""

    reason = 'decode'

    def __init__(self, message: str, topic: str = '', log_time_ns: int = -1):
        super().__init__(message)
        self.topic = topic
        self.log_time_ns = log_time_ns


class BagEncodeError(BagError):
    """A message object/dict cannot be encoded to CDR with its topic's schema."""

    reason = 'encode'


class BagWriteError(BagError):
    """An OS error (disk full, I/O error) while writing; data up to the last flush is kept."""

    reason = 'write'

    def __init__(self, message: str, path: str = '', os_error: OSError | None = None):
        super().__init__(message)
        self.path = path
        self.os_error = os_error
