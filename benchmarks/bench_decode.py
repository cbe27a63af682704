#!/usr/bin/env python3
"""
Decoding benchmark (issue #19 item 4): JointState/Imu messages per second, generic vs in place.

Writes, into a temporary directory, a recording of raw sensor streams only (no posture
topic: `hexacal calibrate` re-detects the postures) with the project's bag writer
(tests/synthetic_recording.py: ``--postures`` dwells at ``--rate-hz`` per stream, at least
75 000 messages), and an Imu stream of ``--imu`` messages. Then, in the same run:

- decoder: every message's CDR bytes decoded by today's generic decoder (mcap_ros2, one
  decoder per schema as the bag reader builds it) and by the in-place decoder around it
  (hexacal_msgs_py.cdr_messages.MessageDecoder), best of ``--repeats``;
- reader: reading the bag and ``BagMessage.decoded`` of every message, as re-detection does
  (MCAP scanning included), with ``BagReader.fast_decoding`` off and on;
- reference: rclpy's compiled deserializer on the JointStates (not used: its sequences are
  array.array where the generic decoder gives lists, and the bag layer is ROS-free);
- end to end: the wall time of ``hexacal calibrate`` on the recording (a new process each, the
  re-detection path), generic then in place; their parameter files must be byte-identical.

Every decoded message of the in-place decoder is checked against the generic one (types and
float bits). Prints "met" / "NOT met" against 100 000 messages/s (decoder and reader).
Run: ``.venv/bin/python benchmarks/bench_decode.py [--json]``.
"""

from __future__ import annotations

import argparse
import gc
import json
import math
from pathlib import Path
import struct
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / 'tests'))

from hexacal_identify.bag import BagReader, BagWriter, open_bag  # noqa: E402, I100
from hexacal_identify.core import (  # noqa: E402
    sample_poses,
    simulate_measurements,
    table1_parameters,
)
from hexacal_identify.core.machine.model import nominal_set  # noqa: E402
from hexacal_msgs_py.cdr_messages import IMU_TYPE, MessageDecoder  # noqa: E402
from hexacal_msgs_py.parameters_file import save_parameters  # noqa: E402
from mcap.records import Schema  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402
import numpy as np  # noqa: E402
from synthetic_recording import write_recording  # noqa: E402

TARGET_PER_S = 100_000
MIN_MESSAGES = 75_000
_CALIBRATE = (
    'import sys\n'
    'from hexacal_identify.bag import BagReader\n'
    'from hexacal_identify.cli.commands import main\n'
    'BagReader.fast_decoding = sys.argv[1] == "fast"\n'
    'sys.exit(main(sys.argv[2:]))\n'
)


def _fields(value):
    if isinstance(value, float):
        return struct.pack('<d', value)
    if isinstance(value, list):
        return [_fields(v) for v in value]
    if isinstance(value, (int, str)):
        return value
    return (type(value).__name__, [_fields(getattr(value, s)) for s in value.__slots__])


def write_imu(directory: Path, count: int) -> Path:
    with BagWriter(directory) as writer:
        writer.add_topic('/imu', IMU_TYPE)
        for index in range(count):
            angle = 1e-4 * index
            stamp = 1_700_000_000_000_000_000 + index * 1_000_000
            writer.write(
                '/imu',
                {
                    'header': {
                        'stamp': {'sec': stamp // 10**9, 'nanosec': stamp % 10**9},
                        'frame_id': 'imu_link',
                    },
                    'orientation': dict(zip('xyzw', (math.sin(angle), 0.0, 0.0, math.cos(angle)))),
                    'orientation_covariance': [1e-8] * 9,
                    'angular_velocity': {'x': 0.0, 'y': 0.0, 'z': 0.0},
                    'angular_velocity_covariance': [-1.0] + [0.0] * 8,
                    'linear_acceleration': {'x': 0.0, 'y': 0.0, 'z': 9.81},
                    'linear_acceleration_covariance': [0.0] * 9,
                },
                stamp,
            )
    return directory


def _by_schema(bag: Path) -> list[tuple[Schema, list[bytes]]]:
    """Return each topic's schema (as the reader builds decoders from) and message bytes."""
    reader = open_bag(bag)
    out = []
    for topic, info in reader.topics().items():
        encoding, text = reader.schemas(topic)[0]
        schema = Schema(id=1, name=info.type_name, encoding=encoding, data=text.encode())
        out.append((schema, [m.data_bytes for m in reader.messages([topic])]))
    return out


def _timed(decode, datas: list[bytes]) -> float:
    gc.collect()
    start = time.perf_counter()
    for data in datas:
        decode(data)
    return time.perf_counter() - start


def decoder_rates(bag: Path, repeats: int) -> dict[str, float]:
    """Return messages/s of the generic and the in-place decoder; check every message."""
    streams = _by_schema(bag)
    total = sum(len(datas) for _, datas in streams)
    seconds = {'generic': math.inf, 'in_place': math.inf}
    for _ in range(repeats):
        for name in seconds:
            elapsed = 0.0
            for schema, datas in streams:
                generic = DecoderFactory().decoder_for('cdr', schema)
                decode = MessageDecoder(schema.name, generic) if name == 'in_place' else generic
                elapsed += _timed(decode, datas)
            seconds[name] = min(seconds[name], elapsed)
    for schema, datas in streams:
        generic = DecoderFactory().decoder_for('cdr', schema)
        fast = MessageDecoder(schema.name, generic)
        for data in datas:
            if _fields(fast(data)) != _fields(generic(data)):
                raise SystemExit(f'in-place decoding differs from the generic on {schema.name}')
    return {name: total / s for name, s in seconds.items()} | {'messages': total}


def rclpy_rate(bag: Path, repeats: int) -> float | None:
    """Return messages/s of rclpy's compiled deserializer on the JointStates (None: no rclpy)."""
    try:
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import JointState
    except ImportError:
        return None
    datas = [data for _, stream in _by_schema(bag) for data in stream]
    best = min(_timed(lambda d: deserialize_message(d, JointState), datas) for _ in range(repeats))
    return len(datas) / best


def reader_rates(bag: Path, repeats: int) -> dict[str, float]:
    """Return messages/s of reading a bag and decoding each message, as re-detection does."""
    rates = {}
    for name, fast in (('generic', False), ('in_place', True)):
        best, count = math.inf, 0
        for _ in range(repeats):
            BagReader.fast_decoding = fast
            reader = open_bag(bag)
            gc.collect()
            start = time.perf_counter()
            count = 0
            for message in reader.messages():
                message.decoded
                count += 1
            best = min(best, time.perf_counter() - start)
        rates[name] = count / best
    BagReader.fast_decoding = True
    return rates


def calibrate_seconds(bag: Path, nominal: Path, directory: Path) -> dict[str, object]:
    """Return the wall time of `hexacal calibrate` on ``bag``, generic then in place."""
    out: dict[str, object] = {}
    outputs = {}
    for name in ('generic', 'fast'):
        output = directory / f'calibrated_{name}.yaml'
        command = [sys.executable, '-c', _CALIBRATE, name, 'calibrate', str(bag)]
        command += ['--nominal', str(nominal), '--output', str(output), '--json']
        start = time.perf_counter()
        completed = subprocess.run(command, capture_output=True, text=True, timeout=600)
        out[f'{name}_s'] = time.perf_counter() - start
        if completed.returncode != 0:
            raise SystemExit(f'hexacal calibrate failed ({name}): {completed.stderr}')
        result = json.loads(completed.stdout)
        out['postures'] = result['bag']['postures']
        out['source'] = result['bag']['source']
        outputs[name] = output.read_bytes()
    out['identical'] = outputs['generic'] == outputs['fast']
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--postures', type=int, default=50)
    parser.add_argument('--rate-hz', type=float, default=320.0)
    parser.add_argument('--imu', type=int, default=20_000)
    parser.add_argument('--repeats', type=int, default=3)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    true = table1_parameters()
    exact = simulate_measurements(
        true, sample_poses(true, args.postures, np.random.default_rng(7))
    )
    with tempfile.TemporaryDirectory(prefix='bench_decode_') as temporary:
        directory = Path(temporary)
        start = time.perf_counter()
        bag = write_recording(
            directory / 'raw', exact, rate_hz=args.rate_hz, postures=False, seed=7
        )
        imu = write_imu(directory / 'imu', args.imu)
        written_s = time.perf_counter() - start
        nominal = directory / 'nominal.yaml'
        save_parameters(nominal, nominal_set(2).vector)
        joint_states = decoder_rates(bag, args.repeats)
        if joint_states['messages'] < MIN_MESSAGES:
            raise SystemExit(f'only {joint_states["messages"]} messages; raise --rate-hz')
        results = {
            'recording_messages': joint_states['messages'],
            'recording_written_s': written_s,
            'decoder_joint_state': joint_states,
            'decoder_imu': decoder_rates(imu, args.repeats),
            'reader': reader_rates(bag, args.repeats),
            'rclpy_joint_state': rclpy_rate(bag, args.repeats),
            'calibrate': calibrate_seconds(bag, nominal, directory),
        }
    verdicts = {
        key: results[key]['in_place'] >= TARGET_PER_S
        for key in ('decoder_joint_state', 'decoder_imu', 'reader')
    }
    results['target_per_s'] = TARGET_PER_S
    results['met'] = all(verdicts.values())
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print(
        f'recording: {results["recording_messages"]} JointState messages (3 raw streams, no '
        f'posture topic), {args.imu} Imu; written in {written_s:.1f} s'
    )
    for key, label in (
        ('decoder_joint_state', 'decoder, JointState'),
        ('decoder_imu', 'decoder, Imu'),
        ('reader', 'reader + decoding'),
    ):
        rates = results[key]
        print(
            f'{label:22s} generic {rates["generic"]:>10,.0f} msg/s   in place '
            f'{rates["in_place"]:>10,.0f} msg/s   x{rates["in_place"] / rates["generic"]:.1f}   '
            f'{"met" if verdicts[key] else "NOT met"} (>= {TARGET_PER_S:,} msg/s)'
        )
    if results['rclpy_joint_state'] is not None:
        print(
            f'{"rclpy, JointState":22s} deserialize_message {results["rclpy_joint_state"]:>10,.0f}'
            ' msg/s (reference, not used: array.array sequences, not the generic lists)'
        )
    calibrate = results['calibrate']
    print(
        f'hexacal calibrate (re-detection, {calibrate["postures"]} postures from the '
        f'{calibrate["source"]}): generic {calibrate["generic_s"]:.2f} s, in place '
        f'{calibrate["fast_s"]:.2f} s; parameter files '
        f'{"identical" if calibrate["identical"] else "DIFFER"}'
    )
    print('met' if results['met'] else 'NOT met')
    return 0 if calibrate['identical'] else 1


if __name__ == '__main__':
    sys.exit(main())
