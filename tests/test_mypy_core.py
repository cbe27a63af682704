"""
mypy on the ROS-free core passes with the repository's configuration (issue #17).

mypy.ini at the repository root names what is checked (core/ and the contract
modules it imports), so this test and a bare `mypy` from the root agree.
"""

from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # a cold mypy run of core/ takes about 5 s
def test_mypy_passes_on_core(tmp_path: Path) -> None:
    pytest.importorskip('mypy', reason='mypy is not installed (see requirements-dev.txt)')
    # A fresh cache directory: the result cannot come from an earlier run's state.
    result = subprocess.run(
        [
            sys.executable,
            '-m',
            'mypy',
            '--config-file',
            'mypy.ini',
            '--cache-dir',
            str(tmp_path / 'mypy_cache'),
        ],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'Success: no issues found' in result.stdout
