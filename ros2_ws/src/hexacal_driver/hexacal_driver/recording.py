"""
Recordings of the simulated machine without ROS: the driver's streams as arrays, and as a bag.

`simulate_recording` builds the driver node's `SimulatedMachine` from the same parameters and
walks its plan exactly as the node does (sample k at plan time k / rate_hz, stamped
`start_ns + k * round(1e9 / rate_hz)`), reading the sensors through the same `SensorStreams`
(sensor_models.py): what the node would publish, message for message, minus the samples it
publishes while waiting for a subscriber. The result carries the truth: per posture the true
platform pose and what ideal noise-free sensors read at rest, and the true parameters.

`write_recording_bag` writes the raw streams as a rosbag2 MCAP bag (hexacal_identify.bag), with
the `hexacal.collector` (namespace, model) and `hexacal.plan` metadata the collector records,
so that `hexacal calibrate BAG` re-detects the postures from it. Tests and benchmarks use both.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import os
from pathlib import Path
from typing import Any

from hexacal_driver.machine import SimulatedMachine
from hexacal_driver.parameters import parameter_problem, PARAMETERS
from hexacal_driver.plan import PosturePlan
from hexacal_driver.sensor_models import NS_PER_S, SENSOR_DEFAULTS, SensorSettings
from hexacal_driver.simulation import exact_readings, SETTLING
from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.machine.device import DEFAULT_MOUNT
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_msgs_py.readings import PostureReading
import numpy as np

DEFAULT_START_NS = 1_700_000_000 * NS_PER_S  # a plausible wall-clock time: stamps stay positive
DEFAULT_NOISE = NoiseModel(
    float(PARAMETERS['slider_noise_m'].default), float(PARAMETERS['angle_noise_rad'].default)
)


@dataclass(frozen=True)
class Recording:
    """
    The three sensor streams of a simulated plan walk, and the truth behind them (SI units).

    Stamps are the messages' header stamps (each stream's own clock with the sensor effect
    `clock`); `*_sample_ns` the true time each message was sampled (the reference clock: what a
    recorder receiving them would log). Dropped messages are absent. Per posture (plan order):
    `poses` the true platform pose, `settled_readings` what ideal noise-free sensors read there
    at rest (POSTURE_NAMES order: six actuators, alpha, beta, phi), `device_turns` the device's
    turn (rad), and `still_from_ns` .. `still_until_ns` the first and the last sample time
    (reference clock) at which the machine stood still there (both included).
    """

    model: str
    rate_hz: float
    sensors: SensorSettings
    noise: NoiseModel
    parameters: dict[str, Any]  # the driver parameter values simulated
    true_params: KinematicParameters
    mount: str
    plan: PosturePlan
    actuator_stamps_ns: np.ndarray  # (n,) int64
    actuator_sample_ns: np.ndarray  # (n,) int64
    actuator_positions: np.ndarray  # (n, 6) m
    inclinometer_stamps_ns: np.ndarray  # (m,) int64
    inclinometer_sample_ns: np.ndarray  # (m,) int64
    inclinometer_angles: np.ndarray  # (m, 2) alpha, beta rad
    inclinometer_turns: np.ndarray  # (m,) device turn of each message (rad; 0 normal mounting)
    encoder_stamps_ns: np.ndarray  # (k,) int64
    encoder_sample_ns: np.ndarray  # (k,) int64
    encoder_angles: np.ndarray  # (k, 1) phi rad
    poses: np.ndarray  # (N, 6) true platform poses
    settled_readings: np.ndarray  # (N, 9)
    device_turns: np.ndarray  # (N,)
    still_from_ns: np.ndarray  # (N,) int64
    still_until_ns: np.ndarray  # (N,) int64

    @property
    def message_count(self) -> int:
        """Return the number of messages of the three streams."""
        return len(self.actuator_stamps_ns) + len(self.inclinometer_stamps_ns) + len(
            self.encoder_stamps_ns
        )

    def settled_postures(self) -> list[PostureReading]:
        """Return the settled truth as PostureReadings, stamped at the last still sample."""
        return [
            PostureReading.from_values(int(stamp), values.tolist(), float(turn))
            for stamp, values, turn in zip(
                self.still_until_ns, self.settled_readings, self.device_turns
            )
        ]


def simulate_recording(
    *,
    true_params: KinematicParameters | str | os.PathLike[str] | None = None,
    model: str = '',
    plan: str | os.PathLike[str] = 'random',
    postures: int = 50,
    link_length: float = 0.75,
    settle_s: float = 1.0,
    dwell_s: float = 1.5,
    rate_hz: float = 100.0,
    seed: int = 0,
    noise: NoiseModel = DEFAULT_NOISE,
    sensor_effects: str = '',
    device_defects: str = '',
    device_turn: float = 0.0,
    tail_s: float = 0.0,
    start_ns: int = DEFAULT_START_NS,
    **sensor_parameters: float,
) -> Recording:
    """
    Return what the driver node publishes walking a plan once, with the truth.

    The arguments are the driver's parameters of the same names (docs/nodes.md): the true
    machine (`true_params` a KinematicParameters, a parameters YAML path, or None for the
    default machine of `model`), the plan (`plan`: 'random', 'fixed', 'mixed' or a plan file;
    `postures`, `seed`), `link_length`, `settle_s`, `dwell_s`, `rate_hz`, the uniform noise
    (`noise` half-widths; NoiseModel() none), `sensor_effects` ('' ideal sensors, 'all', or
    names) with any sensor-model parameter as a keyword (e.g. inclinometer_clock_offset_s=0.05;
    defaults sensor_models.SensorSettings), `device_defects`, `device_turn`. The walk lasts one
    pass over the plan plus `tail_s` standing at the last posture; the first sample is stamped
    `start_ns`. ValueError for a parameter the driver would refuse.
    """
    unknown = sorted(set(sensor_parameters) - set(SENSOR_DEFAULTS))
    if unknown:
        raise TypeError(
            f'unknown sensor parameter(s) {unknown}; valid: {", ".join(SENSOR_DEFAULTS)}'
        )
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values.update(
        model=model,
        plan=os.fspath(plan),
        postures=int(postures),
        link_length=float(link_length),
        settle_s=float(settle_s),
        dwell_s=float(dwell_s),
        rate_hz=float(rate_hz),
        seed=int(seed),
        slider_noise_m=float(noise.actuator_m),
        angle_noise_rad=float(noise.angle_rad),
        sensor_effects=sensor_effects,
        device_defects=device_defects,
        device_turn=float(device_turn),
        **{name: float(value) for name, value in sensor_parameters.items()},
    )
    truth = _truth(true_params, model)
    if not isinstance(true_params, KinematicParameters):  # a file, or the default machine
        values['true_params'] = os.fspath(true_params or '')
    _check(values)
    machine = SimulatedMachine(values, truth)
    return _walk(machine, values, float(tail_s), int(start_ns))


def _truth(
    true_params: KinematicParameters | str | os.PathLike[str] | None, model: str
) -> tuple[KinematicParameters, str] | None:
    """Return the in-memory true machine and mount, or None for a file (or the default)."""
    if not isinstance(true_params, KinematicParameters):
        return None
    if model and model != true_params.model:
        raise ValueError(f'model {model!r} contradicts true_params, a {true_params.model}')
    return true_params, DEFAULT_MOUNT


def _check(values: dict[str, Any]) -> None:
    """Raise ValueError for a value the driver node would refuse (range or problem)."""
    for name, value in values.items():
        spec = PARAMETERS[name]
        numeric = isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool)
        if numeric and spec.low is not None and not spec.low <= value <= spec.high:
            raise ValueError(f'{name} {value!r} is outside [{spec.low}, {spec.high}]')
        problem = parameter_problem(name, value)
        if problem:
            raise ValueError(problem)


def _walk(
    machine: SimulatedMachine, values: dict[str, Any], tail_s: float, start_ns: int
) -> Recording:
    """Walk the machine's plan as the driver node does; return the streams and the truth."""
    walker = machine.require_walker()
    rate_hz = float(values['rate_hz'])
    period_ns = int(round(NS_PER_S / rate_hz))  # as the node's
    ticks = math.ceil((walker.lap_duration_s + tail_s) * rate_hz - 1e-9)
    # Per stream: header stamps, sample times, values; and the inclinometer's device turns.
    stamps: tuple[list[int], ...] = ([], [], [])
    samples: tuple[list[int], ...] = ([], [], [])
    data: tuple[list[Any], ...] = ([], [], [])
    turns: list[float] = []
    still_from = np.full(len(walker.poses), -1, dtype=np.int64)
    still_until = still_from.copy()
    for tick in range(ticks):
        sample_ns = start_ns + tick * period_ns
        sample = walker.sample(tick / rate_hz)
        # Standing at its posture: dwelling, done, or at the start (already at the first one).
        if sample.phase != SETTLING or sample.posture_index == 0:
            if still_from[sample.posture_index] < 0:
                still_from[sample.posture_index] = sample_ns
            still_until[sample.posture_index] = sample_ns
        output, turn = machine.read_streams(sample, sample_ns)
        readings = output.readings
        channels = (
            readings.actuators_m,
            (readings.alpha_rad, readings.beta_rad),
            (readings.phi_rad,),
        )
        for stream, (stamp, value) in enumerate(zip(output.stamps_ns, channels)):
            if stamp is not None:  # else the sensor effect `drops` lost it
                stamps[stream].append(stamp)
                samples[stream].append(sample_ns)
                data[stream].append(value)
        if output.stamps_ns[1] is not None:
            turns.append(turn)
    stamp_arrays = [np.array(s, dtype=np.int64) for s in stamps]
    sample_arrays = [np.array(s, dtype=np.int64) for s in samples]
    value_arrays = [
        np.array(d, dtype=float).reshape(-1, width) for d, width in zip(data, (6, 2, 1))
    ]
    poses, settled, posture_turns = _settled_truth(machine)
    return Recording(
        model=machine.model,
        rate_hz=rate_hz,
        sensors=machine.streams.settings,
        noise=machine.sensors.noise,
        parameters=dict(values),
        true_params=machine.true_params,
        mount=machine.mount,
        plan=machine.require_plan(),
        actuator_stamps_ns=stamp_arrays[0],
        actuator_sample_ns=sample_arrays[0],
        actuator_positions=value_arrays[0],
        inclinometer_stamps_ns=stamp_arrays[1],
        inclinometer_sample_ns=sample_arrays[1],
        inclinometer_angles=value_arrays[1],
        inclinometer_turns=np.array(turns, dtype=float),
        encoder_stamps_ns=stamp_arrays[2],
        encoder_sample_ns=sample_arrays[2],
        encoder_angles=value_arrays[2],
        poses=poses,
        settled_readings=settled,
        device_turns=posture_turns,
        still_from_ns=still_from,
        still_until_ns=still_until,
    )


def _settled_truth(machine: SimulatedMachine) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return per posture the true pose, what ideal sensors read there at rest, the turn."""
    walker = machine.require_walker()
    turns = machine.posture_turns()
    settled = []
    for pose, actuators, turn in zip(walker.poses, walker.posture_actuators, turns):
        exact = exact_readings(pose, actuators, machine.mount, machine.defects, float(turn))
        settled.append([*exact.actuators_m, exact.alpha_rad, exact.beta_rad, exact.phi_rad])
    return walker.poses.copy(), np.array(settled), np.asarray(turns, dtype=float)


def write_recording_bag(
    path: str | os.PathLike[str],
    recording: Recording,
    model: str | None = None,
    namespace: str = '',
) -> Path:
    """
    Write the recording's three streams as a rosbag2 MCAP bag directory `path`; return it.

    As the collector records the driver: the topics /hexacal/sliders, /hexacal/inclinometer
    (with the device_turn joint where the device is turned) and /hexacal/encoder (under
    `namespace`), sensor_msgs/JointState with the header stamps of the recording, logged at the
    true sample time, in that order; the metadata `hexacal.collector` (namespace, `model`:
    default the recording's) and `hexacal.plan` (the driver's plan parameters). No posture
    topic: `hexacal calibrate` re-detects the postures from the streams.
    """
    from hexacal_identify.bag import BagWriter
    from hexacal_identify.bag.naming import COLLECTOR_METADATA, PLAN_METADATA, PLAN_PARAMETERS
    from hexacal_msgs_py.names import (
        actuator_names,
        DEVICE_TURN_JOINT,
        ENCODER_NAMES,
        ENCODER_TOPIC,
        INCLINOMETER_NAMES,
        INCLINOMETER_TOPIC,
        JOINT_STATE_TYPE,
        SLIDERS_TOPIC,
    )

    model = model or recording.model
    space = namespace.strip('/')
    prefix = f'/{space}/' if space else '/'
    topics = [prefix + topic for topic in (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)]
    streams = (
        (recording.actuator_stamps_ns, recording.actuator_sample_ns, recording.actuator_positions),
        (
            recording.inclinometer_stamps_ns,
            recording.inclinometer_sample_ns,
            recording.inclinometer_angles,
        ),
        (recording.encoder_stamps_ns, recording.encoder_sample_ns, recording.encoder_angles),
    )
    names = (actuator_names(model), INCLINOMETER_NAMES, ENCODER_NAMES)
    # Every message in the order of its sample time, the streams in topic order at a tie.
    sample_ns = np.concatenate([stream[1] for stream in streams])
    which = np.concatenate([np.full(len(stream[1]), i) for i, stream in enumerate(streams)])
    row = np.concatenate([np.arange(len(stream[1])) for stream in streams])
    order = np.lexsort((which, sample_ns))
    path = Path(path)
    with BagWriter(path) as writer:
        writer.write_metadata(COLLECTOR_METADATA, {'namespace': f'/{space}', 'model': model})
        plan = {
            name: str(recording.parameters[name])
            for name in PLAN_PARAMETERS
            if name in recording.parameters
        }
        plan['plan_name'] = recording.plan.name
        writer.write_metadata(PLAN_METADATA, plan)
        for topic in topics:
            writer.add_topic(topic, JOINT_STATE_TYPE)
        for index, k in zip(which[order].tolist(), row[order].tolist()):
            stamps, samples, values = streams[index]
            joints, positions = names[index], values[k].tolist()
            if index == 1 and recording.inclinometer_turns[k] != 0.0:
                joints = (*joints, DEVICE_TURN_JOINT)
                positions.append(float(recording.inclinometer_turns[k]))
            writer.write(
                topics[index], _joint_state(int(stamps[k]), joints, positions), int(samples[k])
            )
    return path


def _joint_state(stamp_ns: int, names: tuple[str, ...], positions: list[float]) -> dict:
    """Return a sensor_msgs/JointState as the bag writer takes it."""
    seconds, nanoseconds = divmod(stamp_ns, NS_PER_S)
    return {
        'header': {'stamp': {'sec': seconds, 'nanosec': nanoseconds}, 'frame_id': ''},
        'name': list(names),
        'position': positions,
        'velocity': [],
        'effort': [],
    }
