"""
Atomic file writes (ROS-free): readers see the old file or the new one, never a partial one.

Also the one YAML text loader (parameters files, posture plans, bag metadata):
libyaml's parser when PyYAML has it, else PyYAML's pure-Python one.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
import stat
import tempfile
from typing import Any

DEFAULT_FILE_MODE = 0o644
# libyaml's parser composes nested collections by C recursion: tens of thousands of levels crash
# the interpreter, where the pure-Python parser raises RecursionError at about a thousand.  Nesting
# needs one indicator character per level, so text with fewer of them than this goes to libyaml.
MAX_LIBYAML_INDICATORS = 1000
_NESTING_INDICATORS = '[{-:?'


def load_yaml_text(text: str, loader: type | None = None, fast_loader: type | None = None) -> Any:
    """
    Load YAML text, through libyaml when safe.

    ``yaml.load(text, Loader=loader)``, through ``fast_loader`` (a libyaml twin of it) when safe.

    Default: ``yaml.SafeLoader`` and ``yaml.CSafeLoader``.  The fast loader is
    used when PyYAML has libyaml and the text cannot nest more than about
    MAX_LIBYAML_INDICATORS deep; else the pure-Python loader (a RecursionError
    for absurd nesting).  yaml.YAMLError and RecursionError
    propagate: callers name the file.
    """
    import yaml

    if loader is None:
        loader, fast_loader = yaml.SafeLoader, getattr(yaml, 'CSafeLoader', None)
    if (
        fast_loader is not None
        and sum(text.count(c) for c in _NESTING_INDICATORS) < MAX_LIBYAML_INDICATORS
    ):
        loader = fast_loader
    # A safe loader (SafeLoader, CSafeLoader or subclasses).
    return yaml.load(text, Loader=loader)  # noqa: S506


def atomic_write(target: Path | str, content: str | bytes) -> Path:
    """
    Write via a temp file in the same directory, fsync, os.replace, fsync of the directory.

    An existing file keeps its permissions; a new one gets DEFAULT_FILE_MODE.
    OSError propagates (the caller names the file in its own error); no temp file is left behind.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        mode = stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        mode = DEFAULT_FILE_MODE
    descriptor, temp_name = tempfile.mkstemp(
        prefix=f'.{target.name}.', suffix='.tmp', dir=target.parent
    )
    try:
        with os.fdopen(descriptor, 'wb') as stream:
            stream.write(content.encode('utf-8') if isinstance(content, str) else content)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temp_name, mode)
        os.replace(temp_name, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp_name)
        raise
    fsync_directory(target.parent)
    return target


def fsync_directory(directory: Path) -> None:
    """Make a rename durable; not all file systems allow opening a directory."""
    try:
        descriptor = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)
