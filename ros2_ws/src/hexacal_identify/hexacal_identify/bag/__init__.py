"""ROS-free rosbag2 (MCAP storage) bag layer: write, read, recover and describe bags."""
from .errors import (
    BagCorruptError,
    BagDecodeError,
    BagEmptyError,
    BagEncodeError,
    BagError,
    BagFormatError,
    BagMetadataError,
    BagMissingFileError,
    BagNotFoundError,
    BagSchemaError,
    BagWriteError,
    MessageDefinitionNotFoundError,
)
from .reader import BagInfo, BagMessage, BagReader, FileInfo, MetadataRecord, TopicInfo, open_bag
from .reindex import reindex
from .schemas import message_definition, normalize_type_name
from .writer import DEFAULT_QOS_PROFILES_YAML, ROSBAG2_METADATA_VERSION, STORAGE_PRESETS, BagWriter

__all__ = [
    "BagCorruptError", "BagDecodeError", "BagEmptyError", "BagEncodeError", "BagError",
    "BagFormatError", "BagInfo", "BagMessage", "BagMetadataError", "BagMissingFileError",
    "BagNotFoundError", "BagReader", "BagSchemaError", "BagWriteError", "BagWriter",
    "DEFAULT_QOS_PROFILES_YAML", "FileInfo", "MessageDefinitionNotFoundError", "MetadataRecord",
    "ROSBAG2_METADATA_VERSION", "STORAGE_PRESETS", "TopicInfo", "message_definition",
    "normalize_type_name", "open_bag", "reindex",
]
