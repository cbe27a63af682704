"""Unit tests of the driver's sensor models: each effect does what it says and nothing else."""

from __future__ import annotations

import math

from hexacal_driver.machine import NOISE_STREAM, SimulatedMachine
from hexacal_driver.parameters import parameter_problem, PARAMETERS, RUNTIME_PARAMETERS
from hexacal_driver.reports import finish_lines, plan_start_text
from hexacal_driver.sensor_models import (
    EFFECTS_STREAM,
    parse_effects,
    SENSOR_DEFAULTS,
    SensorEffect,
    SensorSettings,
    SensorStreams,
)
from hexacal_driver.sensor_parameters import SENSOR_PARAMETERS
from hexacal_driver.simulation import PlanWalker, SensorSimulator, WalkSample
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.model import table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
import numpy as np
import pytest

TRUE = table1_parameters()
RATE_HZ = 100.0
PERIOD_NS = 10_000_000
START_NS = 1_700_000_000_000_000_000
NOISE = NoiseModel(1e-5, 1e-5)


@pytest.fixture(scope='module')
def walk() -> list[WalkSample]:
    """Walk a plan at 100 Hz: 6 sphere postures, 0.4 s moving, 0.6 s still."""
    poses = sample_poses(TRUE, 6, np.random.default_rng(4), 'sphere')
    walker = PlanWalker(TRUE, poses, settle_s=0.4, dwell_s=0.6)
    ticks = int(walker.lap_duration_s * RATE_HZ)
    return [walker.sample(k / RATE_HZ) for k in range(ticks)]


def run(samples, effects: str, noise: NoiseModel = NoiseModel(), seed: int = 0, **numbers):
    """(streams, (n, 9) readings, (n, 3) stamps with -1 for a dropped message)."""
    settings = SensorSettings.from_values({'sensor_effects': effects, **numbers})
    streams = SensorStreams(
        SensorSimulator(noise, np.random.default_rng([seed, NOISE_STREAM])),
        settings,
        np.random.default_rng([seed, EFFECTS_STREAM]),
        1.0 / RATE_HZ,
    )
    values, stamps = [], []
    for k, sample in enumerate(samples):
        output = streams.read(sample, 0.0, START_NS + k * PERIOD_NS)
        r = output.readings
        values.append([*r.actuators_m, r.alpha_rad, r.beta_rad, r.phi_rad])
        stamps.append([-1 if s is None else s for s in output.stamps_ns])
    return streams, np.array(values), np.array(stamps, dtype=np.int64)


def reference_stamps(count: int) -> np.ndarray:
    return START_NS + np.arange(count, dtype=np.int64) * PERIOD_NS


def standing(count: int) -> list[WalkSample]:
    """Return `count` samples of a machine standing still."""
    return [WalkSample(np.array([0.1, 0.2, -0.7, 0, 0, 0]), np.zeros(6), 0, '', 0)] * count


# --------------------------------------------------------------------------- names, parameters


def test_effect_names_all_and_lists():
    assert parse_effects('') == frozenset() and parse_effects(' ') == frozenset()
    assert parse_effects('all') == frozenset(SensorEffect)
    assert parse_effects('lag, Drift') == {SensorEffect.LAG, SensorEffect.DRIFT}
    with pytest.raises(ValueError, match="unknown sensor effect 'quantization'") as caught:
        parse_effects('lag,quantization')
    for effect in SensorEffect:
        assert effect.value in str(caught.value)


def test_sensor_parameters_are_declared_checked_and_read_only():
    assert set(SENSOR_PARAMETERS) == {'sensor_effects', *SENSOR_DEFAULTS}
    assert set(SENSOR_PARAMETERS) <= set(PARAMETERS)
    assert not set(SENSOR_PARAMETERS) & set(RUNTIME_PARAMETERS)
    assert PARAMETERS['sensor_effects'].default == ''  # ideal sensors unless asked
    for name, default in SENSOR_DEFAULTS.items():
        spec = PARAMETERS[name]
        assert spec.default == default and spec.low <= default <= spec.high, name
        assert parameter_problem(name, default) is None
        assert parameter_problem(name, math.nan) == f'{name} must be finite, got nan'
    problem = parameter_problem('sensor_effects', 'lag,wobble')
    assert "sensor_effects 'lag,wobble': unknown sensor effect 'wobble'" in problem
    assert parameter_problem('sensor_effects', 'all') is None
    assert SENSOR_DEFAULTS['rotary_resolution_rad'] == 2 * math.pi / 2**20


# --------------------------------------------------------------------------- ideal sensors


def test_no_effects_reads_exactly_as_the_ideal_sensors(walk):
    simulator = SensorSimulator(NOISE, np.random.default_rng([3, NOISE_STREAM]))
    expected = [simulator.read(sample) for sample in walk]
    _, values, stamps = run(walk, '', NOISE, seed=3)
    for got, want in zip(values, expected):
        assert got.tolist() == [*want.actuators_m, want.alpha_rad, want.beta_rad, want.phi_rad]
    assert (stamps == reference_stamps(len(walk))[:, None]).all()


def test_the_machine_reads_the_noise_stream_of_before():
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values.update(postures=3, seed=7)
    machine = SimulatedMachine(values)
    simulator = SensorSimulator(
        machine.sensors.noise, np.random.default_rng([7, NOISE_STREAM]), machine.mount
    )
    for k in range(300):
        sample = machine.walker.sample(k / RATE_HZ)
        output, turn = machine.read_streams(sample, 1000 + k)
        want = simulator.read(sample, turn)
        assert output.readings.actuators_m.tolist() == want.actuators_m.tolist()
        assert (output.readings.alpha_rad, output.readings.beta_rad) == (
            want.alpha_rad,
            want.beta_rad,
        )
        assert output.readings.phi_rad == want.phi_rad
        assert output.stamps_ns == (1000 + k,) * 3


def test_effects_draw_from_their_own_stream_so_the_noise_is_unchanged(walk):
    _, ideal, _ = run(walk, '', NOISE)
    _, clocked, stamps = run(walk, 'clock,drops', NOISE)
    assert np.array_equal(ideal, clocked)  # neither changes a value: the same noise draws
    assert (stamps != reference_stamps(len(walk))[:, None]).any()


# --------------------------------------------------------------------------- each effect


def test_lag_step_response_reaches_1_minus_1_over_e_after_tau(walk):
    tau = 0.1
    first = next(s for s in walk if s.posture_index == 1)  # a point in motion
    last = walk[-1]
    samples = [first] * 5 + [last] * 60
    _, ideal, _ = run(samples, '')
    streams, lagged, stamps = run(samples, 'lag', inclinometer_time_constant_s=tau)
    assert np.array_equal(lagged[:5], ideal[:5])  # settled at the first sample
    step = ideal[5, 6:8] - ideal[0, 6:8]
    assert np.abs(step).min() > 1e-3
    steps_per_tau = round(tau * RATE_HZ)
    reached = (lagged[4 + steps_per_tau, 6:8] - ideal[0, 6:8]) / step
    np.testing.assert_allclose(reached, 1.0 - math.exp(-1.0), rtol=1e-9)
    # Exactly first order: each sample closes the same fraction of what is left.
    left = np.abs(lagged[5:, 6:8] - ideal[5:, 6:8])
    np.testing.assert_allclose(left[1:] / left[:-1], math.exp(-0.01 / tau), rtol=1e-6)
    # Nothing else: the actuators, the rotary angle and the stamps are the ideal ones.
    assert np.array_equal(lagged[:, [0, 1, 2, 3, 4, 5, 8]], ideal[:, [0, 1, 2, 3, 4, 5, 8]])
    assert (stamps == reference_stamps(len(samples))[:, None]).all()
    assert streams.dropped == [0, 0, 0] and streams.spikes == 0


def test_quantisation_rounds_every_channel_to_its_resolution(walk):
    resolutions = {
        'actuator_resolution_m': 1e-6,
        'inclinometer_resolution_rad': 5e-6,
        'rotary_resolution_rad': 2 * math.pi / 2**20,
    }
    _, noisy, _ = run(walk, '', NOISE)
    _, values, stamps = run(walk, 'quantisation', NOISE, **resolutions)
    per_channel = np.array(
        [resolutions['actuator_resolution_m']] * 6
        + [resolutions['inclinometer_resolution_rad']] * 2
        + [resolutions['rotary_resolution_rad']]
    )
    counts = values / per_channel
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    # The nearest multiple of the noisy reading (quantisation comes after the noise).
    assert (np.abs(values - noisy) <= per_channel / 2 * (1 + 1e-9)).all()
    assert len(np.unique(values[:, 0])) < len(np.unique(noisy[:, 0]))
    assert (stamps == reference_stamps(len(walk))[:, None]).all()


@pytest.mark.slow
def test_clock_stamps_each_stream_by_its_own_clock():
    samples = standing(20000)
    offsets = {'inclinometer_clock_offset_s': 0.03, 'encoder_clock_offset_s': -0.004}
    jitter = 0.001
    _, ideal, _ = run(samples, '', NOISE)
    _, values, stamps = run(samples, 'clock', NOISE, clock_jitter_s=jitter, **offsets)
    assert np.array_equal(values, ideal)  # the clocks change no reading
    errors_s = (stamps - reference_stamps(len(samples))[:, None]) / 1e9
    expected = np.array([0.0, 0.03, -0.004])
    bound = 4 * jitter / math.sqrt(len(samples))
    assert np.abs(errors_s.mean(axis=0) - expected).max() < bound
    np.testing.assert_allclose(errors_s.std(axis=0), jitter, rtol=0.05)
    # Between streams: the offset within the jitter of both.
    difference = errors_s[:, 1] - errors_s[:, 0]
    assert np.abs(difference - 0.03).max() < 6 * math.sqrt(2) * jitter
    assert (np.diff(stamps, axis=0) > 0).all()


def test_clock_stamps_stay_strictly_increasing_under_any_jitter():
    samples = standing(3000)
    _, _, stamps = run(samples, 'clock', clock_jitter_s=0.05)  # 5 periods of jitter
    assert (np.diff(stamps, axis=0) > 0).all()
    assert (np.diff(stamps, axis=0) == 1).any()  # ... held back by a nanosecond where needed


def test_drops_lose_messages_at_their_rate_independently_per_stream():
    count, p = 12000, 0.05
    samples = standing(count)
    streams, values, stamps = run(samples, 'drops', NOISE, drop_probability=p)
    dropped = (stamps == -1).sum(axis=0)
    assert dropped.tolist() == streams.dropped
    sigma = math.sqrt(count * p * (1 - p))
    assert (np.abs(dropped - count * p) < 5 * sigma).all(), dropped
    together = (stamps == -1).all(axis=1).sum()
    assert together < 10  # independent: all three ~ count p**3 = 1.5
    kept = stamps[stamps[:, 0] != -1, 0]
    assert (kept == reference_stamps(count)[stamps[:, 0] != -1]).all()
    _, ideal, _ = run(samples, '', NOISE)
    assert np.array_equal(values, ideal)  # a dropped message takes no reading with it


@pytest.mark.slow
def test_spikes_come_at_their_rate_with_their_size_on_the_inclinometer():
    count, rate, size = 20000, 2.0, 5e-4  # 200 s
    samples = standing(count)
    _, ideal, _ = run(samples, '')
    streams, values, stamps = run(samples, 'spikes', spike_rate_hz=rate, spike_size_rad=size)
    off = values - ideal
    spiked = np.abs(off[:, 6]) > 0
    assert (spiked == (np.abs(off[:, 7]) > 0)).all()  # both angles at once
    np.testing.assert_allclose(np.abs(off[spiked, 6:8]), size, rtol=1e-9)
    assert 0.3 < (off[spiked, 6] > 0).mean() < 0.7  # either sign
    expected = rate * count / RATE_HZ  # 400, Poisson
    assert abs(spiked.sum() - expected) < 5 * math.sqrt(expected)
    assert spiked.sum() == streams.spikes
    assert not off[:, [0, 1, 2, 3, 4, 5, 8]].any()  # the encoders see no vibration
    assert (stamps == reference_stamps(count)[:, None]).all()


def test_drift_moves_the_inclinometer_zero_linearly_from_the_first_sample(walk):
    rate = 2e-6
    _, ideal, _ = run(walk, '')
    _, values, _ = run(walk, 'drift', inclinometer_drift_rad_per_s=rate)
    time_s = np.arange(len(walk)) / RATE_HZ
    np.testing.assert_allclose(values[:, 6] - ideal[:, 6], rate * time_s, rtol=0, atol=1e-15)
    np.testing.assert_allclose(values[:, 7] - ideal[:, 7], rate * time_s, rtol=0, atol=1e-15)
    assert np.array_equal(values[:, [0, 1, 2, 3, 4, 5, 8]], ideal[:, [0, 1, 2, 3, 4, 5, 8]])


def test_all_effects_together_in_their_order(walk):
    streams, values, stamps = run(walk, 'all', NOISE)
    settings = streams.settings
    assert settings.effects == frozenset(SensorEffect)
    counts = values[:, 6:8] / settings.inclinometer_resolution_rad
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)  # quantised last
    for column in range(3):
        kept = stamps[stamps[:, column] != -1, column]
        assert (np.diff(kept) > 0).all()


# --------------------------------------------------------------------------- what is logged


def test_the_start_line_names_the_active_effects_and_the_end_the_drops():
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values.update(postures=3)
    ideal = plan_start_text(SimulatedMachine(values), 'Table 1', 100.0)
    assert 'sensor effects' not in ideal and ideal.endswith('noise +-1e-05 m / +-1e-05 rad')
    values.update(sensor_effects='lag,drops')
    text = plan_start_text(SimulatedMachine(values), 'Table 1', 100.0)
    assert text.endswith('noise +-1e-05 m / +-1e-05 rad; sensor effects: lag (tau 0.1 s), '
                         'drops (0.01)')
    line = finish_lines(100, 10, 5, None, (1, 2, 0))[0]
    assert line.endswith('the sensor model dropped 1, 2, 0 of them (sliders, inclinometer, '
                         'encoder)')
    assert 'dropped' not in finish_lines(100, 10, 5, None, (0, 0, 0))[0]
