"""
The simulated driver with real sensors' effects, on the real topics (a real driver process).

The driver runs with `sensor_effects:=all` in its own process; a probe node subscribes to its
three streams. Each stream is stamped by its own clock: a message's stamp is the sliders' stamp
of the same sample (the reference clock) plus `inclinometer_clock_offset_s` or
`encoder_clock_offset_s`, within the jitter; every value is a multiple of its channel's
resolution; the start-up line names the effects.

Stamps alone cannot tell an offset from one a whole number of periods away, so the messages of
one sample are paired by their values: without noise and drift every moving sample's values
are unique and exactly those of `simulate_recording` with the same parameters (the same code
walks the same plan), which gives each message's sample index. The effects' arithmetic is
unit-tested in ros2_ws/src/hexacal_driver/test/test_sensor_models.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from system_support import node_argv, NODE_START_TIMEOUT_S, Probe

INCLINOMETER_OFFSET_S = 0.033  # neither is a whole number of 10 ms periods
ENCODER_OFFSET_S = -0.017
JITTER_S = 0.0005
RESOLUTIONS = {
    'actuator_resolution_m': 1e-6,
    'inclinometer_resolution_rad': 5e-6,
    'rotary_resolution_rad': 2 * math.pi / 2**20,
}
PLAN = {'plan': 'mixed', 'postures': 4, 'settle_s': 0.3, 'dwell_s': 0.7, 'seed': 1}
SENSORS = {
    'sensor_effects': 'all',
    'inclinometer_clock_offset_s': INCLINOMETER_OFFSET_S,
    'encoder_clock_offset_s': ENCODER_OFFSET_S,
    'clock_jitter_s': JITTER_S,
    'inclinometer_drift_rad_per_s': 0.0,  # values stay those of the recording (no time term)
    **RESOLUTIONS,
}
STREAMS = ('sliders', 'inclinometer', 'encoder')


@pytest.fixture
def listener():
    """Return an in-process node (system_support.Probe); closed at teardown."""
    node = Probe()
    try:
        yield node
    finally:
        node.close()


def subscribe(probe: Probe) -> dict[str, list]:
    """Collect (stamp ns, positions) of the three streams, in arrival order."""
    from hexacal_msgs_py.qos import SENSOR_QOS
    from sensor_msgs.msg import JointState

    received: dict[str, list] = {name: [] for name in STREAMS}
    for name, messages in received.items():

        def on_message(message: JointState, messages=messages) -> None:
            stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
            messages.append((stamp, tuple(message.position)))

        probe.node.create_subscription(JointState, f'hexacal/{name}', on_message, SENSOR_QOS)
    return received


def sample_of(values: np.ndarray, sample_ns: np.ndarray) -> dict[tuple, int]:
    """Return the sample (its time) of each row of values that occurs once (a moving sample)."""
    rows = [tuple(row) for row in values.tolist()]
    counts: dict[tuple, int] = {}
    for row in rows:
        counts[row] = counts.get(row, 0) + 1
    return {row: int(t) for row, t in zip(rows, sample_ns) if counts[row] == 1}


def assert_multiples(values: np.ndarray, resolution: float, what: str) -> None:
    """Assert that every value is a whole number of `resolution` steps."""
    counts = values / resolution
    worst = float(np.abs(counts - np.round(counts)).max())
    assert worst < 1e-6, f'{what}: {worst} of a step off a multiple of {resolution}'


def test_driver_streams_carry_their_own_clocks_and_resolutions(ros_processes, listener):
    from hexacal_driver.recording import simulate_recording
    from hexacal_identify.core.machine.measurements import NoiseModel

    probe = listener
    received = subscribe(probe)
    parameters = {**PLAN, **SENSORS, 'slider_noise_m': 0.0, 'angle_noise_rad': 0.0}
    driver = ros_processes.start(node_argv('driver', parameters))
    probe.wait_for_node('driver', process=driver)
    # The driver holds the first posture until our three subscriptions match, then walks.
    probe.spin_until(
        lambda: 'end of plan' in driver.log_text(),
        NODE_START_TIMEOUT_S + 60.0,  # a 4 s plan; generous: two cores shared under load
        'the end of the plan',
        driver.describe,
    )
    log = driver.log_text()
    assert 'sensor effects: lag (tau 0.1 s), drift (0 rad/s), spikes' in log
    assert 'clock (offsets 0.033 s inclinometer, -0.017 s encoder, jitter 0.0005 s)' in log

    recording = simulate_recording(**PLAN, **SENSORS, noise=NoiseModel())
    # The recording's own drops leave samples out: they are keyed by their sample time.
    tables = {
        'sliders': sample_of(recording.actuator_positions, recording.actuator_sample_ns),
        'inclinometer': sample_of(
            recording.inclinometer_angles, recording.inclinometer_sample_ns
        ),
        'encoder': sample_of(recording.encoder_angles, recording.encoder_sample_ns),
    }
    stamps_of: dict[str, dict[int, int]] = {}
    for name in STREAMS:
        stamps = np.array([stamp for stamp, _ in received[name]])
        # Each clock's stamps strictly increase (SENSOR_QOS keeps order on one host).
        assert (np.diff(stamps) > 0).all(), name
        width = 1 if name == 'encoder' else 2 if name == 'inclinometer' else 6
        stamps_of[name] = {
            tables[name][values[:width]]: stamp
            for stamp, values in received[name]
            if values[:width] in tables[name]
        }
    sliders = stamps_of['sliders']
    assert len(sliders) > 60, 'the moving samples of the sliders were not recognised'
    for name, offset in (('inclinometer', INCLINOMETER_OFFSET_S), ('encoder', ENCODER_OFFSET_S)):
        common = sorted(set(stamps_of[name]) & set(sliders))
        assert len(common) > 40, (name, len(common))
        offsets = np.array([stamps_of[name][k] - sliders[k] for k in common]) / 1e9
        # The difference of two stamps jittered independently: 5 sigma is sqrt(2) 5 jitter.
        worst = float(np.abs(offsets - offset).max())
        assert worst <= 5 * math.sqrt(2) * JITTER_S, (name, worst)
        assert abs(float(offsets.mean()) - offset) < JITTER_S / 2, name

    sliders_values = np.array([values for _, values in received['sliders']])
    inclinometer = np.array([values[:2] for _, values in received['inclinometer']])
    rotary = np.array([values[0] for _, values in received['encoder']])
    assert_multiples(sliders_values, RESOLUTIONS['actuator_resolution_m'], 'sliders')
    assert_multiples(inclinometer, RESOLUTIONS['inclinometer_resolution_rad'], 'inclinometer')
    assert_multiples(rotary, RESOLUTIONS['rotary_resolution_rad'], 'rotary')
