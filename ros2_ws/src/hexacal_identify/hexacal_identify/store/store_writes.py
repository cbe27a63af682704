"""
Crash-safe writes of a store: whole entries, new event files, the writers' lock.

Every write goes to a name starting with TEMP_PREFIX, is fsynced, and becomes visible by one
rename (an entry directory) or one hard link (an event file, which must not replace another
writer's event of the same number); the directory is fsynced after.  A kill at any moment
leaves the whole entry or event, or nothing but a temporary name, which readers ignore and the
next writer removes under the lock (only a dead writer's can be left: writers hold the lock
while their temporary names exist).
"""

from __future__ import annotations

from collections.abc import Iterator
import contextlib
import fcntl
import json
import os
from pathlib import Path
import secrets
import shutil
from typing import Any

from hexacal_msgs_py.files import fsync_directory
from hexacal_msgs_py.store_format import LOCK_FILE, TEMP_PREFIX

from .store_entry import StoreError

# Test hook: called with a stage name between the steps of a write (simulated crashes).
_CRASH_HOOK = None


def _stage(name: str) -> None:
    if _CRASH_HOOK is not None:
        _CRASH_HOOK(name)


def json_text(payload: Any) -> str:
    """Return the JSON text the store writes (sorted keys, strict numbers, newline)."""
    return json.dumps(payload, indent=2, sort_keys=True, allow_nan=False) + '\n'


def read_json(path: Path) -> Any:
    """Read a store JSON file; StoreError names the file when it is not JSON."""
    try:
        return json.loads(path.read_text(encoding='utf-8'))
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise StoreError(f'{path}: unreadable store file ({error})') from None


def _write_synced(path: Path, data: bytes) -> None:
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    with os.fdopen(descriptor, 'wb') as stream:
        stream.write(data)
        stream.flush()
        os.fsync(stream.fileno())


def temp_name(stem: str) -> str:
    """Return a fresh temporary name (TEMP_PREFIX, the stem, a random tag)."""
    return f'{TEMP_PREFIX}{stem}-{os.getpid()}-{secrets.token_hex(4)}'


def write_directory(target: Path, files: dict[str, bytes]) -> Path:
    """
    Create directory `target` holding `files` (name -> bytes), all or nothing.

    StoreError if `target` exists (nothing is overwritten).
    """
    parent = target.parent
    temp = parent / temp_name(target.name)
    temp.mkdir()
    try:
        for name, data in files.items():
            _write_synced(temp / name, data)
            _stage(f'wrote {name}')
        fsync_directory(temp)
        _stage('before rename')
        if target.exists():
            raise StoreError(f'{target} exists already; a store never overwrites an entry')
        os.rename(temp, target)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    _stage('after rename')
    fsync_directory(parent)
    return target


def write_new_file(target: Path, data: bytes) -> bool:
    """
    Create file `target` with `data`, all or nothing; False if `target` exists (left as is).

    The hard link makes the name appear with the whole content and fails on an existing name,
    where a rename would replace it.
    """
    temp = target.parent / temp_name(target.name)
    try:
        _write_synced(temp, data)
        _stage('before link')
        try:
            os.link(temp, target)
        except FileExistsError:
            return False
        _stage('after link')
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp)
    fsync_directory(target.parent)
    return True


def replace_file(target: Path, data: bytes) -> None:
    """Replace `target` by a new file (new inode) holding `data` (the derived active marker)."""
    temp = target.parent / temp_name(target.name)
    try:
        _write_synced(temp, data)
        os.replace(temp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp)
        raise
    fsync_directory(target.parent)


def remove_leftovers(*directories: Path) -> list[Path]:
    """Remove temporary names (a crashed writer's); call under the writers' lock only."""
    removed = []
    for directory in directories:
        if not directory.is_dir():
            continue
        for path in directory.iterdir():
            if not path.name.startswith(TEMP_PREFIX):
                continue
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()
            removed.append(path)
    return removed


@contextlib.contextmanager
def writer_lock(root: Path) -> Iterator[None]:
    """Hold the store's exclusive writers' lock (released by the kernel if the process dies)."""
    descriptor = os.open(root / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX)
        yield
    finally:
        os.close(descriptor)
