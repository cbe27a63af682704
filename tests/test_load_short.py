"""Load (issue #7), short version of benchmarks/bench_load.py: 1 kHz per stream for 20 s.

A real driver publishes its three sensor streams at 1 kHz into a real collector
that detects postures and records the bag. Nothing may be lost between what the
driver published and what the bag holds, every dwell must give its posture, and
the collector's memory must not grow. The 10-minute run is the benchmark.
"""
from __future__ import annotations

from pathlib import Path
import sys

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))

from bench_load import STREAMS, run_load  # noqa: E402

SECONDS = 20.0
WARM_UP_S = 8.0


@pytest.mark.slow
def test_one_khz_per_stream_loses_nothing_and_keeps_memory_flat(tmp_path):
    result = run_load(SECONDS, tmp_path / 'load', rate_hz=1000.0, sample_s=1.0)
    report = result.table(WARM_UP_S)
    assert result.achieved_rate_hz > 800.0, report  # the driver really ran near 1 kHz
    assert result.published > 0.8 * 1000.0 * SECONDS, report
    assert result.lost == dict.fromkeys(STREAMS, 0), report
    for stream in STREAMS:  # received counts also what arrived while the driver held still
        assert result.received[stream] >= result.published, report
    # One posture per dwell; the dwell the driver's stop cut short is dropped, not published.
    assert result.postures_walked >= 6, report
    assert result.postures_walked - 1 <= result.postures_detected <= result.postures_walked, report
    assert result.postures_in_bag == result.postures_detected, report
    assert result.problems == [], report
    assert len(result.memory) >= SECONDS - 2, report
    assert abs(result.memory_growth_mib(WARM_UP_S)) < 3.0, report
