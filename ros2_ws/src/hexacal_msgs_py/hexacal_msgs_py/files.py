"""Atomic file writes (ROS-free): readers see the old file or the new one, never a partial one."""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
import stat
import tempfile

DEFAULT_FILE_MODE = 0o644


def atomic_write(target: Path | str, content: str | bytes) -> Path:
    """Write via a temp file in the same directory, fsync, os.replace, fsync of the directory.

    An existing file keeps its permissions; a new one gets DEFAULT_FILE_MODE.
    OSError propagates (the caller names the file in its own error); no temp file is left behind.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    try:
        mode = stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        mode = DEFAULT_FILE_MODE
    descriptor, temp_name = tempfile.mkstemp(prefix=f'.{target.name}.', suffix='.tmp', dir=target.parent)
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
