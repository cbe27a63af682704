"""
run_node logs what a node keeps while it stops after the node is gone: no rosout error.

A real rclpy node in its own process (this session's ROS domain, conftest.py) shuts its
context down as a signal does; its `finish` returns a ShutdownLog's lines, which come out at
their severity with no `Failed to publish log message to rosout`.
"""

import subprocess
import sys
import textwrap


def test_run_node_logs_the_kept_lines_after_the_node_is_destroyed():
    # A node whose finish logs at two severities: both lines come out, after the node is gone,
    # with no rosout error (its own process, so that rclpy.init is its own).
    program = textwrap.dedent(
        """
        from rclpy.node import Node
        from hexacal_msgs_py.node_runtime import run_node, ShutdownLog

        class Stopping(Node):
            def __init__(self):
                super().__init__('stopping')
                self.create_timer(0.01, self.context.try_shutdown)

        def finish(node):
            log = ShutdownLog()
            log.info('kept line one')
            log.warning('kept line two')
            return [*log.lines, 'plain line']

        raise SystemExit(run_node('stopping', Stopping, finish=finish))
        """
    )
    completed = subprocess.run(
        [sys.executable, '-c', program], capture_output=True, text=True, timeout=120
    )
    output = completed.stdout + completed.stderr
    assert completed.returncode == 0, output
    assert '[INFO]' in output and 'kept line one' in output, output
    assert '[WARN]' in output and 'kept line two' in output, output
    assert 'plain line' in output and 'Failed to publish' not in output, output
