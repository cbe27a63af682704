"""
ros2msg schema text for MCAP files, built from the installed .msg files.

rosbag2's MCAP storage stores, per message type, the type's own .msg text
followed by every (transitive) dependency, each introduced by a line of 80
'=' and a line ``MSG: pkg/Type``. Dependencies are found with the same field
regex rosbag2 uses, visited depth-first in sorted order, each one only once,
so the text produced here matches what ``ros2 bag record`` writes.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
import re
import sys

from .errors import BagSchemaError, MessageDefinitionNotFoundError

SCHEMA_ENCODING = 'ros2msg'
MESSAGE_ENCODING = 'cdr'

# 'pkg/Type' or 'pkg/msg/Type' (also srv), as accepted by rosbag2.
_TYPE_NAME_RE = re.compile(r'^([a-zA-Z][a-zA-Z0-9_]*)/((?:msg|srv)/)?([a-zA-Z][a-zA-Z0-9_]*)$')
# The field type at the start of a .msg line, e.g. 'std_msgs/Header' in 'std_msgs/Header header'.
_FIELD_TYPE_RE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
# 'TYPE name [default]' or 'TYPE NAME = value' (a constant) in one .msg line.
_FIELD_LINE_RE = re.compile(r'^\s*(\S+)\s+([A-Za-z][A-Za-z0-9_]*)\s*(=)?')
_PRIMITIVE_TYPES = frozenset(
    {
        'bool',
        'byte',
        'char',
        'float32',
        'float64',
        'int8',
        'uint8',
        'int16',
        'uint16',
        'int32',
        'uint32',
        'int64',
        'uint64',
        'string',
    }
)
_DELIMITER_LINE = '=' * 80 + '\n'
_MAX_DEPTH = 50


def normalize_type_name(type_name: str) -> str:
    """'sensor_msgs/JointState' or 'sensor_msgs/msg/JointState' -> 'sensor_msgs/msg/JointState'."""
    match = _TYPE_NAME_RE.match(type_name or '')
    if match is None:
        raise BagSchemaError(
            f'message type name {type_name!r} is not of the form pkg/msg/Type',
            found=str(type_name),
        )
    package, namespace, name = match.groups()
    return f'{package}/{(namespace or "msg/")}{name}'


def _prefixes() -> list[Path]:
    """Install prefixes to search: AMENT_PREFIX_PATH entries, then this interpreter's prefix."""
    entries = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes: list[Path] = []
    for entry in [*entries, sys.prefix]:
        path = Path(entry)
        if path not in prefixes:
            prefixes.append(path)
    return prefixes


def _share_directories(package: str) -> list[Path]:
    shares: list[Path] = []
    if os.environ.get('AMENT_PREFIX_PATH'):
        try:
            from ament_index_python.packages import get_package_share_directory

            shares.append(Path(get_package_share_directory(package, print_warning=False)))
        except Exception:  # noqa: BLE001 - not importable or not in the index: search prefixes
            pass
    # pip-installed ROS wheels put share/ under sys.prefix without AMENT_PREFIX_PATH.
    shares.extend(prefix / 'share' / package for prefix in _prefixes())
    return shares


def find_definition_file(type_name: str) -> Path:
    """Path of the installed .msg file of `type_name`."""
    normalized = normalize_type_name(type_name)
    package, namespace, name = normalized.split('/')
    searched = []
    for share in _share_directories(package):
        candidate = share / namespace / f'{name}.msg'
        if candidate.is_file():
            return candidate
        searched.append(str(candidate))
    raise MessageDefinitionNotFoundError(
        f'no .msg file for {normalized}; searched {searched}', found=normalized
    )


def _dependencies(text: str, package: str) -> list[str]:
    deps: set[str] = set()
    for match in _FIELD_TYPE_RE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVE_TYPES:
            continue
        deps.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(deps)  # rosbag2 keeps them in a std::set


@functools.lru_cache(maxsize=256)
def _definition_text(type_name: str, search_key: tuple[str, ...]) -> str:
    del search_key  # only part of the cache key, so a changed environment is re-searched
    seen: set[str] = set()

    def append_recursive(name: str, depth: int) -> str:
        if depth <= 0:
            raise BagSchemaError(
                f'dependencies of {type_name} nest deeper than {_MAX_DEPTH}', found=type_name
            )
        path = find_definition_file(name)
        try:
            text = path.read_text(encoding='utf-8')
        except (OSError, UnicodeDecodeError) as error:
            raise MessageDefinitionNotFoundError(
                f'cannot read {path}: {error}', found=name
            ) from error
        package = normalize_type_name(name).split('/')[0]
        for dep in _dependencies(text, package):
            if dep not in seen:
                seen.add(dep)
                text += '\n' + _DELIMITER_LINE + f'MSG: {dep}\n' + append_recursive(dep, depth - 1)
        return text

    return append_recursive(type_name, _MAX_DEPTH)


def field_names(type_name: str) -> tuple[str, ...]:
    """Names of the fields (not constants) of `type_name`, from its own .msg text."""
    text = message_definition(type_name).split('\n' + _DELIMITER_LINE, 1)[0]
    names = []
    for line in text.splitlines():
        match = _FIELD_LINE_RE.match(line.split('#', 1)[0])
        if match and not match.group(3):  # 'TYPE NAME=VALUE' is a constant
            names.append(match.group(2))
    return tuple(names)


def field_signature(definition: str) -> tuple[tuple[str, str], ...]:
    """
    (type, name) of each field (not constant) of the top-level message of a ros2msg text.

    Comments, blank lines, default values and the spelling 'pkg/msg/Type' versus
    'pkg/Type' do not matter; a field added, removed, renamed or retyped does:
    two texts with the same signature decode the same CDR bytes the same way.
    """
    own = re.split(r'^={80}\s*$', definition, maxsplit=1, flags=re.MULTILINE)[0]
    fields = []
    for line in own.splitlines():
        match = _FIELD_LINE_RE.match(line.split('#', 1)[0])
        if match and not match.group(3):  # 'TYPE NAME=VALUE' is a constant
            fields.append((match.group(1).replace('/msg/', '/'), match.group(2)))
    return tuple(fields)


def message_definition(type_name: str) -> str:
    """Concatenated ros2msg definition of `type_name`, as rosbag2 stores it in an MCAP schema."""
    normalized = normalize_type_name(type_name)
    search_key = (os.environ.get('AMENT_PREFIX_PATH', ''), sys.prefix)
    return _definition_text(normalized, search_key)
