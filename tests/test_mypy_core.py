"""
Type-check the ROS-free core with mypy, as CI does (`make test`; `make lint` runs it alone).

The configuration is the repository's mypy.ini (missing stubs of third-party imports are
ignored); mypy runs in a subprocess, like ament's linters, so its result does not depend on
what this test session has imported.
"""

from pathlib import Path
import subprocess
import sys

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]
CORE = REPOSITORY / 'ros2_ws' / 'src' / 'hexacal_identify' / 'hexacal_identify' / 'core'


@pytest.mark.linter
@pytest.mark.mypy
@pytest.mark.slow
def test_mypy_core() -> None:
    """Check core/ against mypy.ini: no type errors."""
    completed = subprocess.run(
        [sys.executable, '-m', 'mypy', '--config-file', str(REPOSITORY / 'mypy.ini'), str(CORE)],
        cwd=REPOSITORY,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
