"""
ROS-free rosbag2 (MCAP storage) bag layer: write, read, recover and describe bags.

The names below are imported from their submodules on first use (PEP 562): the
errors alone do not load the MCAP reader and writer.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

_EXPORTS = {
    'errors': (
        'BagCorruptError',
        'BagDecodeError',
        'BagEmptyError',
        'BagEncodeError',
        'BagError',
        'BagFormatError',
        'BagMetadataError',
        'BagMissingFileError',
        'BagNotFoundError',
        'BagSchemaError',
        'BagWriteError',
        'MessageDefinitionNotFoundError',
    ),
    'bag_info': ('BagInfo', 'FileInfo', 'MetadataRecord', 'TopicInfo'),
    'reader': ('BagMessage', 'BagReader', 'open_bag'),
    'qos_yaml': ('DEFAULT_QOS_PROFILES_YAML', 'qos_profiles_yaml', 'read_qos_profiles'),
    'reindex': ('reindex',),
    'schemas': ('message_definition', 'normalize_type_name'),
    'writer': (
        'ROSBAG2_METADATA_VERSION',
        'STORAGE_PRESETS',
        'BagWriter',
    ),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [
    'BagCorruptError',
    'BagDecodeError',
    'BagEmptyError',
    'BagEncodeError',
    'BagError',
    'BagFormatError',
    'BagInfo',
    'BagMessage',
    'BagMetadataError',
    'BagMissingFileError',
    'BagNotFoundError',
    'BagReader',
    'BagSchemaError',
    'BagWriteError',
    'BagWriter',
    'DEFAULT_QOS_PROFILES_YAML',
    'FileInfo',
    'MessageDefinitionNotFoundError',
    'MetadataRecord',
    'ROSBAG2_METADATA_VERSION',
    'STORAGE_PRESETS',
    'TopicInfo',
    'message_definition',
    'normalize_type_name',
    'open_bag',
    'qos_profiles_yaml',
    'read_qos_profiles',
    'reindex',
]


def __getattr__(name: str):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:
    from .bag_info import BagInfo, FileInfo, MetadataRecord, TopicInfo
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
    from .reader import BagMessage, BagReader, open_bag
    from .qos_yaml import DEFAULT_QOS_PROFILES_YAML, qos_profiles_yaml, read_qos_profiles
    from .reindex import reindex
    from .schemas import message_definition, normalize_type_name
    from .writer import (
        BagWriter,
        ROSBAG2_METADATA_VERSION,
        STORAGE_PRESETS,
    )
