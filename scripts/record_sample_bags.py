#!/usr/bin/env python3
"""Record the sample bags of bags/ with the real nodes: the simulated driver and the collector.

Each bag: `driver` (Table 1 machine, the given plan, noise and seed) and
`collector` (recording into bags/<name>) run in a private ROS domain; this
script counts the postures the collector publishes, and once the plan is done
stops the driver, then the collector (SIGINT), which closes the bag.

    .venv/bin/python scripts/record_sample_bags.py            # all samples
    .venv/bin/python scripts/record_sample_bags.py --only sphere50_noise10
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time

BAGS = Path(__file__).resolve().parent.parent / 'bags'


@dataclass(frozen=True)
class Sample:
    name: str
    plan: str  # driver plan: random (sphere), fixed, mixed (3 sphere : 1 fixed)
    postures: int
    noise_m: float  # slider noise half-width, m; the angle noise is the same number in rad
    seed: int
    model: str = 'hexa_slide'  # machine model simulated (its default machine) and recorded


SAMPLES = (
    Sample('sphere50_noise10', 'random', 50, 10e-6, 1),
    Sample('sphere60_fixed20_noise10', 'mixed', 80, 10e-6, 2),
    Sample('sphere30_nonoise', 'random', 30, 0.0, 3),
    Sample('gs_sphere50_noise10', 'random', 50, 10e-6, 4, 'gough_stewart'),
    # Crank angles: the noise half-width is 10 urad on the cranks, 10 urad on the angles.
    Sample('rh_sphere60_noise10', 'random', 60, 10e-6, 5, 'rotary_hexapod'),
)
DRIVER = {'rate_hz': 50.0, 'settle_s': 0.6, 'dwell_s': 1.2}


def _ros_args(params: dict) -> list[str]:
    args = ['--ros-args']
    for name, value in params.items():
        args += ['-p', f'{name}:={value}']
    return args


def record(sample: Sample, domain: int) -> Path:
    from hexacal_msgs_py.names import POSTURE_TOPIC
    from hexacal_msgs_py.qos import POSTURE_QOS
    import rclpy
    from sensor_msgs.msg import JointState

    target = BAGS / sample.name
    shutil.rmtree(target, ignore_errors=True)
    env = {
        **os.environ,
        'ROS_DOMAIN_ID': str(domain),
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
    }
    os.environ.update(env)
    bin_dir = Path(sys.executable).parent
    collector = subprocess.Popen(
        [
            str(bin_dir / 'collector'),
            *_ros_args({'output_dir': str(BAGS), 'bag_name': sample.name, 'model': sample.model}),
        ],
        env=env,
        start_new_session=True,
    )
    rclpy.init()
    node = rclpy.create_node('sample_recorder')
    received: list[JointState] = []
    node.create_subscription(JointState, '/' + POSTURE_TOPIC, received.append, POSTURE_QOS)
    driver = subprocess.Popen(
        [
            str(bin_dir / 'driver'),
            *_ros_args(
                {
                    'plan': sample.plan,
                    'postures': sample.postures,
                    'seed': sample.seed,
                    'slider_noise_m': sample.noise_m,
                    'angle_noise_rad': sample.noise_m,
                    'model': sample.model,
                    **DRIVER,
                }
            ),
        ],
        env=env,
        start_new_session=True,
    )
    deadline = time.monotonic() + sample.postures * 5 + 60
    try:
        shown = -1
        while len(received) < sample.postures and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
            if len(received) != shown:
                shown = len(received)
                print(f'{sample.name}: {shown}/{sample.postures} postures', file=sys.stderr)
        if len(received) < sample.postures:
            raise RuntimeError(
                f'{sample.name}: only {len(received)} of {sample.postures} postures arrived'
            )
    finally:
        for process in (driver, collector):  # driver first: the collector records to the end
            os.killpg(process.pid, signal.SIGINT)
            process.wait(timeout=30)
        node.destroy_node()
        rclpy.try_shutdown()
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        '--only', choices=[s.name for s in SAMPLES], help='record just this sample'
    )
    parser.add_argument(
        '--domain', type=int, default=77, help='ROS_DOMAIN_ID to record in (default 77)'
    )
    args = parser.parse_args(argv)
    for sample in SAMPLES:
        if args.only in (None, sample.name):
            path = record(sample, args.domain)
            size = sum(p.stat().st_size for p in path.iterdir())
            print(f'recorded {path} ({size / 1e6:.2f} MB)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
