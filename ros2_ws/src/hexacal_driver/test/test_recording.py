"""Unit tests of recording.py: the driver's streams walked without ROS, and written as a bag."""

from __future__ import annotations

import math

from hexacal_driver.machine import SimulatedMachine
from hexacal_driver.parameters import PARAMETERS
from hexacal_driver.recording import (
    DEFAULT_START_NS,
    simulate_recording,
    write_recording_bag,
)
from hexacal_identify.bag import open_bag
from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np
import pytest

QUIET = NoiseModel()
SHORT = {'postures': 5, 'plan': 'mixed', 'settle_s': 0.5, 'dwell_s': 1.0, 'seed': 2}
TICKS = 5 * 150  # 5 postures of 1.5 s at 100 Hz


def test_ideal_streams_are_the_nodes_samples_with_one_stamp():
    recording = simulate_recording(**SHORT)
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values.update(SHORT)
    machine = SimulatedMachine(values)  # what the node builds from the same parameters
    assert len(recording.actuator_stamps_ns) == TICKS
    stamps = DEFAULT_START_NS + np.arange(TICKS, dtype=np.int64) * 10_000_000
    for name in ('actuator', 'inclinometer', 'encoder'):
        assert np.array_equal(getattr(recording, f'{name}_stamps_ns'), stamps)
        assert np.array_equal(getattr(recording, f'{name}_sample_ns'), stamps)
    assert recording.actuator_positions.shape == (TICKS, 6)
    assert recording.inclinometer_angles.shape == (TICKS, 2)
    assert recording.encoder_angles.shape == (TICKS, 1)
    # The node's tick: sample k of the walk at plan time k / rate_hz, through read_streams.
    node = []
    for tick in range(TICKS):
        output, _ = machine.read_streams(machine.walker.sample(tick / 100.0), int(stamps[tick]))
        readings = output.readings
        node.append([*readings.actuators_m, readings.alpha_rad, readings.beta_rad])
    walked = np.column_stack([recording.actuator_positions, recording.inclinometer_angles])
    assert np.array_equal(walked, np.array(node))
    assert recording.message_count == 3 * TICKS
    assert recording.plan.name == 'mixed-5-seed2' and recording.model == 'hexa_slide'


def test_the_truth_is_what_still_ideal_sensors_read():
    recording = simulate_recording(**SHORT, noise=QUIET)
    np.testing.assert_array_equal(recording.poses, recording.plan.poses)
    assert recording.settled_readings.shape == (5, 9)
    values = np.column_stack(
        [recording.actuator_positions, recording.inclinometer_angles, recording.encoder_angles]
    )
    stamps = recording.actuator_stamps_ns
    for index in range(5):
        still = (stamps >= recording.still_from_ns[index]) & (
            stamps <= recording.still_until_ns[index]
        )
        assert still.sum() >= 100  # 1 s of dwell at 100 Hz
        assert (values[still] == recording.settled_readings[index]).all(), index
        moving = stamps == recording.still_from_ns[index] - 10_000_000
        if index:
            assert not (values[moving] == recording.settled_readings[index]).all()
    postures = recording.settled_postures()
    assert [p.stamp_ns for p in postures] == recording.still_until_ns.tolist()
    assert postures[2].actuator_positions == tuple(recording.settled_readings[2, :6])
    assert np.array_equal(recording.true_params.vector, default_parameters().vector)


def test_true_params_in_memory_or_from_a_file_give_the_same_recording(tmp_path):
    truth = default_parameters('gough_stewart')
    path = tmp_path / 'gs.yaml'
    save_parameters(path, truth.vector, model='gough_stewart')
    in_memory = simulate_recording(**SHORT, true_params=truth)
    from_file = simulate_recording(**SHORT, true_params=path)
    assert in_memory.model == from_file.model == 'gough_stewart'
    assert np.array_equal(in_memory.actuator_positions, from_file.actuator_positions)
    with pytest.raises(ValueError, match="model 'hexa_slide' contradicts"):
        simulate_recording(**SHORT, true_params=truth, model='hexa_slide')


def test_effects_and_their_settings_reach_the_streams():
    recording = simulate_recording(
        **SHORT,
        sensor_effects='clock,drops',
        inclinometer_clock_offset_s=0.05,
        drop_probability=0.1,
        clock_jitter_s=0.0,
    )
    lengths = [
        len(recording.actuator_stamps_ns),
        len(recording.inclinometer_stamps_ns),
        len(recording.encoder_stamps_ns),
    ]
    assert all(TICKS * 0.8 < length < TICKS for length in lengths), lengths
    offset = recording.inclinometer_stamps_ns - recording.inclinometer_sample_ns
    assert (offset == 50_000_000).all()
    assert (recording.encoder_stamps_ns - recording.encoder_sample_ns == 5_000_000).all()
    assert recording.sensors.describe().startswith('sensor effects: clock')


def test_parameters_the_driver_refuses_are_refused():
    with pytest.raises(ValueError, match="unknown sensor effect 'wobble'"):
        simulate_recording(**SHORT, sensor_effects='wobble')
    with pytest.raises(TypeError, match="unknown sensor parameter.*'spike_hz'"):
        simulate_recording(**SHORT, spike_hz=1.0)
    with pytest.raises(ValueError, match='rate_hz 0.5 is outside'):
        simulate_recording(**SHORT | {'rate_hz': 0.5})
    with pytest.raises(ValueError, match=r'drop_probability nan is outside \[0.0, 0.9\]'):
        simulate_recording(**SHORT, drop_probability=math.nan)


def test_the_bag_holds_the_streams_and_calibrate_re_detects_the_postures(tmp_path):
    recording = simulate_recording(**SHORT, sensor_effects='quantisation,clock')
    bag = write_recording_bag(tmp_path / 'bag', recording)
    with open_bag(bag) as reader:
        metadata = {record.name: record.data for record in reader.metadata()}
        messages = list(reader.messages(['/hexacal/inclinometer']))
    assert metadata['hexacal.collector']['model'] == 'hexa_slide'
    assert metadata['hexacal.plan']['plan_name'] == 'mixed-5-seed2'
    assert metadata['hexacal.plan']['settle_s'] == '0.5'
    stamps = [
        m.decoded.header.stamp.sec * 10**9 + m.decoded.header.stamp.nanosec for m in messages
    ]
    assert stamps == recording.inclinometer_stamps_ns.tolist()
    assert [m.log_time_ns for m in messages] == recording.inclinometer_sample_ns.tolist()
    assert [tuple(m.decoded.position) for m in messages[:3]] == [
        tuple(row) for row in recording.inclinometer_angles[:3]
    ]
    found = postures_from_bag(bag)
    assert found.source == 'raw streams (re-detected)' and found.model == 'hexa_slide'
    assert len(found.postures) == 5
    detected = np.array([p.values() for p in found.postures])
    assert np.abs(detected - recording.settled_readings).max() < 2e-5


def test_a_turned_device_writes_its_joint_and_a_namespace_its_topics(tmp_path):
    recording = simulate_recording(**SHORT, device_turn=math.pi, noise=QUIET)
    assert (recording.inclinometer_turns == math.pi).all()
    assert (recording.device_turns == math.pi).all()
    bag = write_recording_bag(tmp_path / 'bag', recording, namespace='cell_2')
    with open_bag(bag) as reader:
        assert set(reader.topics()) == {
            '/cell_2/hexacal/sliders',
            '/cell_2/hexacal/inclinometer',
            '/cell_2/hexacal/encoder',
        }
        first = next(iter(reader.messages(['/cell_2/hexacal/inclinometer']))).decoded
    assert list(first.name)[-1] == 'device_turn' and first.position[-1] == math.pi


def test_a_tail_stands_at_the_last_posture():
    recording = simulate_recording(**SHORT, tail_s=0.5, noise=QUIET)
    assert len(recording.actuator_stamps_ns) == TICKS + 50
    assert recording.still_until_ns[-1] == recording.actuator_stamps_ns[-1]
    last = recording.actuator_stamps_ns >= recording.still_from_ns[-1]
    assert last.sum() == 100 + 50  # its dwell, then the tail
    assert (recording.actuator_positions[last] == recording.settled_readings[-1, :6]).all()
