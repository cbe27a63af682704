"""
Type-check the three packages with mypy, as CI does (`make test`; `make lint` runs it alone).

The configuration is the repository's mypy.ini (missing stubs of third-party imports are
ignored); mypy runs in a subprocess, like ament's linters, so its result does not depend on
what this test session has imported.
"""

from pathlib import Path
import subprocess
import sys

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]
SOURCES = REPOSITORY / 'ros2_ws' / 'src'
# Each package's code: the contract, the ROS-free core with its CLI and nodes, the driver.
PACKAGES = [
    SOURCES / 'hexacal_msgs_py' / 'hexacal_msgs_py',
    SOURCES / 'hexacal_identify' / 'hexacal_identify',
    SOURCES / 'hexacal_driver' / 'hexacal_driver',
]


@pytest.mark.linter
@pytest.mark.mypy
@pytest.mark.slow
def test_mypy_core() -> None:
    """Check every package against mypy.ini: no type errors."""
    completed = subprocess.run(
        [
            sys.executable, '-m', 'mypy', '--config-file', str(REPOSITORY / 'mypy.ini'),
            *map(str, PACKAGES),
        ],
        cwd=REPOSITORY,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
