"""
Write rosbag2 bags that look like the collector's, straight from the core simulation.

No ROS graph.  Raw streams at ``rate_hz``: each posture is held for ``dwell_s`` (readings
with fresh noise) and reached by a ``move_s`` linear move of the sliders and angles; the
posture topic carries the mean of each dwell, stamped at its end.  Used to test
the offline tools on bags of known content.  ``model`` names the actuator joints
(Hexa Slide: slider_1..6, the default; Gough-Stewart: leg_1..6) and, with
``record_model``, is written to the bag's ``hexacal.collector`` metadata as the
collector does.  With ``scatter`` each posture message also carries the dwell's scatter as
the collector records it: the standard error of each channel's mean in ``velocity``, the
number of samples in ``effort``.  When ``exact`` has ``link_lengths`` (the lvdt measuring
mode) the link length is a fourth raw stream (hexacal/link, joint link_length) and each
posture carries its mean as the optional joint link_length; ``measuring`` is written as the
``hexacal.measuring`` metadata record.
"""

from __future__ import annotations

from pathlib import Path

from hexacal_identify.bag import BagWriter
from hexacal_identify.core.machine.measurements import Measurements
from hexacal_msgs_py.names import (
    actuator_names,
    ENCODER_NAMES,
    ENCODER_TOPIC,
    INCLINOMETER_NAMES,
    INCLINOMETER_TOPIC,
    LINK_LENGTH_JOINT,
    LINK_TOPIC,
    posture_names,
    POSTURE_TOPIC,
    SLIDERS_TOPIC,
)
import numpy as np

JOINT_STATE = 'sensor_msgs/msg/JointState'


def _joint_state(stamp_ns: int, names, values, velocity=(), effort=()) -> dict:
    return {
        'header': {
            'stamp': {'sec': stamp_ns // 1_000_000_000, 'nanosec': stamp_ns % 1_000_000_000},
            'frame_id': '',
        },
        'name': list(names),
        'position': [float(v) for v in values],
        'velocity': [float(v) for v in velocity],
        'effort': [float(v) for v in effort],
    }


def write_recording(
    directory: Path,
    exact: Measurements,
    *,
    noise_m: float = 1e-5,
    noise_rad: float = 1e-5,
    rate_hz: float = 100.0,
    dwell_s: float = 1.0,
    move_s: float = 0.6,
    seed: int = 0,
    raw: bool = True,
    postures: bool = True,
    extra_topic: str | None = None,
    drop_topic: str | None = None,
    namespace: str = '',
    nan_every: int = 0,
    model: str | None = None,
    record_model: str | None = None,
    scatter: bool = False,
    measuring: dict | None = None,
) -> Path:
    rng = np.random.default_rng(seed)
    slider_names, names = actuator_names(model), posture_names(model)
    period = int(1e9 / rate_hz)
    # (N, 9)
    values = np.column_stack([exact.actuator_positions, exact.inclinometer, exact.rotary])
    half_widths = np.array([noise_m] * 6 + [noise_rad] * 3)
    link = exact.link_lengths is not None
    if link:  # the link length rides as a tenth column, with the actuators' noise
        values = np.column_stack([values, exact.link_lengths])
        half_widths = np.append(half_widths, noise_m)
    prefix = f'/{namespace.strip("/")}/' if namespace else '/'
    with BagWriter(directory) as writer:
        if record_model is not None:
            writer.write_metadata('hexacal.collector', {'namespace': '/', 'model': record_model})
        if measuring is not None:
            writer.write_metadata('hexacal.measuring', measuring)
        topics = {
            SLIDERS_TOPIC: slider_names,
            INCLINOMETER_TOPIC: INCLINOMETER_NAMES,
            ENCODER_TOPIC: ENCODER_NAMES,
        }
        if raw:
            for topic in topics:
                if topic != drop_topic:
                    writer.add_topic(prefix + topic, JOINT_STATE)
            if link:
                writer.add_topic(prefix + LINK_TOPIC, JOINT_STATE)
        if postures:
            writer.add_topic(prefix + POSTURE_TOPIC, JOINT_STATE)
        if extra_topic:
            writer.add_topic(extra_topic, 'std_msgs/msg/String')
        stamp = 1_700_000_000 * 1_000_000_000
        previous = values[0]
        for target in values:
            moving = int(move_s * rate_hz)
            samples = [previous + (target - previous) * (k + 1) / moving for k in range(moving)]
            shape = (int(dwell_s * rate_hz), len(target))
            dwell = target + rng.uniform(-1, 1, shape) * half_widths
            for count, sample in enumerate(samples + list(dwell)):
                stamp += period
                if nan_every and count % nan_every == nan_every - 1:
                    sample = np.where(
                        np.arange(len(sample)) == 2, np.nan, sample
                    )  # a glitched slider_3 reading
                if raw:
                    _write_raw(writer, stamp, sample[:9], drop_topic, prefix, slider_names)
                    if link:
                        writer.write(
                            prefix + LINK_TOPIC,
                            _joint_state(stamp, [LINK_LENGTH_JOINT], sample[9:]),
                            stamp,
                        )
                if extra_topic and stamp % (10 * period) == 0:
                    writer.write(extra_topic, {'data': 'not hexacal'}, stamp)
            if postures:
                spread = {}
                joints = list(names) + ([LINK_LENGTH_JOINT] if link else [])
                if scatter:  # standard errors of the means, and the samples averaged
                    spread = {
                        'velocity': dwell.std(axis=0, ddof=1) / np.sqrt(len(dwell)),
                        'effort': [len(dwell)] * len(joints),
                    }
                writer.write(
                    prefix + POSTURE_TOPIC,
                    _joint_state(stamp, joints, dwell.mean(axis=0), **spread),
                    stamp,
                )
            previous = target
    return directory


def _write_raw(
    writer: BagWriter,
    stamp: int,
    sample: np.ndarray,
    drop_topic: str | None,
    prefix: str,
    slider_names=actuator_names(),
) -> None:
    parts = (
        (SLIDERS_TOPIC, slider_names, sample[:6]),
        (INCLINOMETER_TOPIC, INCLINOMETER_NAMES, sample[6:8]),
        (ENCODER_TOPIC, ENCODER_NAMES, sample[8:]),
    )
    for topic, names, values in parts:
        if topic != drop_topic:
            writer.write(prefix + topic, _joint_state(stamp, names, values), stamp)
