"""System-test configuration: isolate this test session's ROS graph.

Runs at import time, before any test creates a ROS context, so that every
node of this session (in-process or started with rosproc) shares a DDS domain
that no other session on the machine uses, and discovery stays on localhost.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
import tempfile
from typing import IO

import pytest
from rosproc import RosProcesses

DOMAIN_ID_RANGE = range(1, 101)  # 0 is ROS's default; 101 is the Linux-safe maximum
_domain_lock: IO[str] | None = None  # held for the whole session


def _claim_domain_id() -> int:
    """Lock a domain id free among concurrent test sessions, starting from the pid."""
    global _domain_lock
    start = os.getpid() % len(DOMAIN_ID_RANGE)
    for offset in range(len(DOMAIN_ID_RANGE)):
        domain_id = DOMAIN_ID_RANGE[(start + offset) % len(DOMAIN_ID_RANGE)]
        path = Path(tempfile.gettempdir()) / f'hexacal-test-ros-domain-{domain_id}.lock'
        lock = open(path, 'a')  # noqa: SIM115 (kept open to hold the lock)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _domain_lock = lock
        return domain_id
    raise RuntimeError(
        f'all ROS domain ids {DOMAIN_ID_RANGE.start}..{DOMAIN_ID_RANGE.stop - 1} are in use '
        'by other test sessions; set HEXACAL_TEST_DOMAIN_ID'
    )


if os.environ.get('HEXACAL_TEST_DOMAIN_ID'):
    ROS_DOMAIN_ID = int(os.environ['HEXACAL_TEST_DOMAIN_ID'])
else:
    ROS_DOMAIN_ID = _claim_domain_id()
os.environ['ROS_DOMAIN_ID'] = str(ROS_DOMAIN_ID)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)


def pytest_report_header(config: pytest.Config) -> str:
    return f'ROS_DOMAIN_ID={ROS_DOMAIN_ID} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST'


@pytest.fixture(scope='session')
def ros_domain_id() -> int:
    """The DDS domain of this test session (also in os.environ['ROS_DOMAIN_ID'])."""
    return ROS_DOMAIN_ID


@pytest.fixture
def ros_processes(tmp_path: Path):
    """Start node processes with ros_processes.start(argv); all are stopped at teardown."""
    processes = RosProcesses(tmp_path / 'logs')
    try:
        yield processes
    finally:
        processes.stop_all()
