"""A stopping node's lines are kept with their severity and logged once it is gone (no DDS)."""

from hexacal_msgs_py.node_runtime import ShutdownLog


def test_the_shutdown_log_keeps_every_line_with_its_severity():
    log = ShutdownLog()
    log.info('calibration report written: r.html')
    log.warning('calibration report not written: disk full', throttle_duration_sec=5.0)
    log.error('calibration failed')
    assert log.lines == [
        ('info', 'calibration report written: r.html'),
        ('warning', 'calibration report not written: disk full'),
        ('error', 'calibration failed'),
    ]
