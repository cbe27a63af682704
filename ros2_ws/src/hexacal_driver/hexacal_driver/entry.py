"""
Console-script entry point of the driver (`ros2 run hexacal_driver driver`).

SIGINT/SIGTERM are remembered before the node module's imports, as for every
hexacal node (see hexacal_identify.nodes.entry).
"""

from __future__ import annotations

import sys

from hexacal_msgs_py.node_runtime import remember_termination_signals


def driver() -> int:
    remember_termination_signals()
    from .driver_node import main

    return main(sys.argv)
