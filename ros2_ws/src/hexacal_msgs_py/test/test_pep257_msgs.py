"""
Run ament_pep257 on the hexacal_msgs_py package, as `colcon test` does (test_pep257.py).

The basename carries the package's name: pytest imports test modules from the repository
root in prepend mode, where basenames must be unique across the test directories.
"""

from pathlib import Path

from ament_pep257.main import main
import pytest

PACKAGE = Path(__file__).resolve().parents[1]  # explicit: pytest runs from the repository root


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257() -> None:
    """Check the package's docstrings against the ROS 2 pep257 configuration."""
    rc = main(argv=[str(PACKAGE)])
    assert rc == 0, 'Found code style errors / warnings'
