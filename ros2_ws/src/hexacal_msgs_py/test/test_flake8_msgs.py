"""
Run ament_flake8 on the hexacal_msgs_py package, as `colcon test` does (test_flake8.py).

The basename carries the package's name: pytest imports test modules from the repository
root in prepend mode, where basenames must be unique across the test directories.
"""

from pathlib import Path

from ament_flake8.main import main_with_errors
import pytest

PACKAGE = Path(__file__).resolve().parents[1]  # explicit: pytest runs from the repository root


@pytest.mark.slow
@pytest.mark.flake8
@pytest.mark.linter
def test_flake8() -> None:
    """Check the package against the ROS 2 flake8 configuration."""
    rc, errors = main_with_errors(argv=[str(PACKAGE)])
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)
