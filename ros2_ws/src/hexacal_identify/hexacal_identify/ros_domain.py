"""
Claim a ROS domain id that no other hexacal test session, demo or benchmark uses (ROS-free).

A claim is an exclusive ``flock`` on ``hexacal-test-ros-domain-<id>.lock`` in the temp
directory, held until the process exits (the lock files are shared by tests/conftest.py,
``hexacal demo`` and the benchmarks, so no two of them pick the same domain).
"""

from __future__ import annotations

import atexit
import fcntl
import os
from pathlib import Path
import tempfile
from typing import IO

# 0 is ROS's default domain; 101 is the largest id that is safe on Linux.
DOMAIN_ID_RANGE = range(1, 101)
LOCK_PATTERN = 'hexacal-test-ros-domain-{}.lock'

# Open lock files: a lock lasts as long as its file stays open, i.e. until the process exits.
_held: list[IO[str]] = []


class NoFreeDomainError(RuntimeError):
    """Raise when every domain id of DOMAIN_ID_RANGE is locked by another process."""


def lock_path(domain_id: int, directory: str | os.PathLike[str] | None = None) -> Path:
    """Return the lock file of `domain_id` (in `directory`, default the temp directory)."""
    return Path(directory or tempfile.gettempdir()) / LOCK_PATTERN.format(domain_id)


def claim_domain_id(
    override_env: str = '',
    start: int | None = None,
    directory: str | os.PathLike[str] | None = None,
) -> int:
    """
    Return a domain id locked for this process, trying ids from `start` (default: the pid).

    A non-empty environment variable `override_env` names the id instead (nothing is locked).
    Raise NoFreeDomainError naming `override_env` when every id is taken.
    """
    if override_env and os.environ.get(override_env):
        return int(os.environ[override_env])
    first = (os.getpid() if start is None else start) % len(DOMAIN_ID_RANGE)
    for offset in range(len(DOMAIN_ID_RANGE)):
        domain_id = DOMAIN_ID_RANGE[(first + offset) % len(DOMAIN_ID_RANGE)]
        lock = open(lock_path(domain_id, directory), 'a')  # noqa: SIM115 - held until exit
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        if not _held:
            atexit.register(_release_all)
        _held.append(lock)
        return domain_id
    hint = f'; set {override_env}' if override_env else ''
    raise NoFreeDomainError(
        f'every ROS domain id {DOMAIN_ID_RANGE.start}..{DOMAIN_ID_RANGE.stop - 1} is in use '
        f'by another hexacal test session, demo or benchmark{hint}'
    )


def _release_all() -> None:
    """Close the lock files at exit (the claims end with the process anyway)."""
    while _held:
        _held.pop().close()
