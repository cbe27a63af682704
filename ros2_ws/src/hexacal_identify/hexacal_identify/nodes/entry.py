"""
Console-script entry points of the nodes (`ros2 run hexacal_identify collector`, ...).

The driver's is `hexacal_driver.entry:driver`, written the same way.

Each remembers SIGINT/SIGTERM before importing its node module: the imports
(rclpy, numpy, message packages) take a noticeable part of a second, and a
Ctrl-C in that time must stop the node cleanly (`nodes.runtime.run_node` acts on
the remembered signal once rclpy is up) instead of raising KeyboardInterrupt
out of an import.
"""

from __future__ import annotations

import sys

from hexacal_msgs_py.node_runtime import remember_termination_signals


def collector() -> int:
    remember_termination_signals()
    from .collector import main

    return main(sys.argv)


def identify() -> int:
    remember_termination_signals()
    from .identify import main

    return main(sys.argv)


def executor() -> int:
    remember_termination_signals()
    from .executor import main

    return main(sys.argv)


def kinematics() -> int:
    remember_termination_signals()
    from .kinematics_node import main

    return main(sys.argv)
