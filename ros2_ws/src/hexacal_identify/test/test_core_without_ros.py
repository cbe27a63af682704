"""The core must import and run where rclpy and the ROS message packages are absent."""

import subprocess
import sys
import textwrap


def test_core_runs_with_rclpy_unimportable():
    script = textwrap.dedent("""
        import sys
        for name in ("rclpy", "sensor_msgs", "std_msgs", "std_srvs", "diagnostic_msgs",
                     "builtin_interfaces"):
            sys.modules[name] = None  # any import of these now raises ImportError
        import numpy as np
        from hexacal_identify.core import (
            identify, nominal_set, sample_poses, simulate_measurements, table1_parameters)
        true = table1_parameters()
        poses = sample_poses(true, 20, np.random.default_rng(0))
        result = identify(nominal_set(1), simulate_measurements(true, poses))
        print(result.reason, float(np.abs(result.parameters.vector - true.vector).max()))
        assert not any(name.startswith("rclpy") for name in sys.modules
                       if sys.modules[name] is not None)
    """)
    completed = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
    reason, error = completed.stdout.split()
    assert reason == 'converged' and float(error) < 1e-9
