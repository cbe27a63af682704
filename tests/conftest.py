"""
System-test configuration: isolate this test session's ROS graph.

Runs at import time, before any test creates a ROS context, so that every
node of this session (in-process or started with rosproc) shares a DDS domain
that no other session on the machine uses, and discovery stays on localhost.
"""

from __future__ import annotations

import atexit
import os
from pathlib import Path
import shutil
import tempfile

from hexacal_identify.ros_domain import claim_domain_id
import pytest
from rosproc import RosProcesses

# The lock is held for the whole session; HEXACAL_TEST_DOMAIN_ID picks the domain instead.
ROS_DOMAIN_ID = claim_domain_id('HEXACAL_TEST_DOMAIN_ID')
os.environ['ROS_DOMAIN_ID'] = str(ROS_DOMAIN_ID)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_STATIC_PEERS', None)
# Calibrations of this session (`hexacal calibrate`, identify nodes) go to a temporary store
# directory, never the user's (hexacal_identify.store.default_store_dir).
_STORES = tempfile.mkdtemp(prefix='hexacal-test-stores-')
os.environ['HEXACAL_STORE'] = _STORES
atexit.register(shutil.rmtree, _STORES, True)


def pytest_report_header(config: pytest.Config) -> str:
    return f'ROS_DOMAIN_ID={ROS_DOMAIN_ID} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST'


@pytest.fixture(scope='session')
def ros_domain_id() -> int:
    """Return the DDS domain of this test session (also in os.environ['ROS_DOMAIN_ID'])."""
    return ROS_DOMAIN_ID


@pytest.fixture
def ros_processes(tmp_path: Path):
    """Start node processes with ros_processes.start(argv); all are stopped at teardown."""
    processes = RosProcesses(tmp_path / 'logs')
    try:
        yield processes
    finally:
        processes.stop_all()
