"""The ROS domain a benchmark with real nodes runs in: one no test session, demo or other benchmark holds.

Same lock files as tests/conftest.py and `hexacal demo` (hexacal-test-ros-domain-<id>.lock in the temp
directory), held for the benchmark's whole run; HEXACAL_TEST_DOMAIN_ID picks one explicitly.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
import tempfile


def claim_domain_id() -> int:
    """A ROS domain no test session or other benchmark uses."""
    if os.environ.get('HEXACAL_TEST_DOMAIN_ID'):
        return int(os.environ['HEXACAL_TEST_DOMAIN_ID'])
    for offset in range(100):
        domain_id = 1 + (os.getpid() + offset) % 100
        lock = open(Path(tempfile.gettempdir()) / f'hexacal-test-ros-domain-{domain_id}.lock', 'a')  # noqa: SIM115 (held open for the whole run)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        claim_domain_id.lock = lock  # type: ignore[attr-defined]
        return domain_id
    raise RuntimeError('no free ROS domain id in 1..100')
