#!/usr/bin/env python3
"""
The MuJoCo machine (hexacal_driver.physics_machine): agreement at rest and speed.

In one run:

- agreement: gravity off, rigid structure, each built-in model in each measuring mode, the
  machine moved from one posture to another and settled; the largest difference (nm) of its
  pose (angles times L), encoders and joint gaps from the geometric model (passive_actuator:
  core.passive_actuator.solve_passive; lvdt: the commanded pose; compliant:
  core.compliant.device_constrained_pose), with the stiff constraint settings and with
  MuJoCo's defaults (``stiff=False``);
- speed: simulated seconds per CPU second (and per wall second) at the 1e-4 s timestep on
  this process's one core, the shipped physical description (gravity, springs), moves of 0.5 s and dwells of 0.5 s
  over ``--postures`` postures with one actuator released; prints "met" / "NOT met" against
  real time.

Run: ``.venv/bin/python benchmarks/bench_physics_machine.py [--postures N] [--json]``.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import json
import time

from hexacal_driver.physics_machine import PhysicsMachine
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.machine.device import sphere_z
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.modes.compliant import device_constrained_pose
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_msgs_py.physical_file import default_physical
import numpy as np

L = 0.75
MODELS = ('hexa_slide', 'gough_stewart')
MODES = ('passive_actuator', 'lvdt', 'compliant')


def sphere_pose(x, y, angles, length=L):
    return np.array([x, y, sphere_z(np.array([[x, y]]), length)[0], *angles])


START = sphere_pose(0.02, -0.01, [0.01, 0.0, 0.02])
TARGET = sphere_pose(0.06, 0.03, [-0.02, 0.015, -0.03])


def agreement(model: str, mode: str, stiff: bool) -> dict:
    params = architecture(model).default_parameters()
    physical = replace(
        default_physical(model).weightless().made_rigid(), released_coulomb=0.0
    )
    machine = PhysicsMachine(params, physical, START, link_length=L, mode=mode, stiff=stiff)
    setpoints = inverse_kinematics(params, TARGET[None])[0]
    if mode == 'passive_actuator':
        machine.release(2)
        setpoints[0] += 20e-6
        expected = solve_passive(params, setpoints[None], 2, TARGET[None], L)
        pose, actuators = expected.poses[0], expected.actuators[0]
    elif mode == 'lvdt':
        pose = sphere_pose(0.05, -0.02, [0.01, 0.02, -0.01], L + 0.002)
        setpoints = actuators = inverse_kinematics(params, pose[None])[0]
    else:
        setpoints = setpoints + np.array([30e-6, -10e-6, 0.0, 15e-6, 0.0, -20e-6])
        pose, actuators = device_constrained_pose(params, setpoints, TARGET, L)
    machine.command(setpoints, 0.15)
    machine.advance(0.15)
    settled = machine.settle(2.0, speed=1e-9)
    got = machine.pose()
    return {
        'model': model,
        'mode': mode,
        'stiff': stiff,
        'settled': settled,
        'pose_nm': 1e9
        * max(np.abs(got[:3] - pose[:3]).max(), L * np.abs(got[3:] - pose[3:]).max()),
        'encoders_nm': 1e9 * float(np.abs(machine.encoders() - actuators).max()),
        'joint_gaps_nm': 1e9 * float(machine.joint_gaps().max()),
    }


def speed(model: str, postures: int) -> dict:
    params = architecture(model).default_parameters()
    rng = np.random.default_rng(3)
    poses = [
        sphere_pose(*rng.uniform(-0.08, 0.08, 2), rng.uniform(-0.04, 0.04, 3))
        for _ in range(postures)
    ]
    machine = PhysicsMachine(params, default_physical(model), poses[0], link_length=L)
    started, cpu_started = time.perf_counter(), time.process_time()
    for index, pose in enumerate(poses[1:]):
        machine.lock()
        released = index % 6
        setpoints = inverse_kinematics(params, pose[None])[0]
        machine.command(setpoints, 0.5)
        machine.advance(0.5)
        machine.release(released)
        machine.advance(0.5)
    wall = time.perf_counter() - started
    cpu = time.process_time() - cpu_started
    return {
        'model': model,
        'simulated_s': machine.time_s,
        'wall_s': wall,
        'cpu_s': cpu,
        'real_time_factor': machine.time_s / wall,
        'cpu_real_time_factor': machine.time_s / cpu,
        'faults': len(machine.faults),
        'max_joint_gap_nm': 1e9 * float(machine.joint_gaps().max()),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--postures', type=int, default=10)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    rows = [agreement(m, mode, stiff) for m in MODELS for mode in MODES for stiff in (True, False)]
    speeds = [speed(m, args.postures) for m in MODELS]
    if args.json:
        print(json.dumps({'agreement': rows, 'speed': speeds}, indent=2))
        return 0
    print('At rest, gravity off, rigid: largest difference from the geometric model (nm)')
    print(f'{"model":14s} {"mode":17s} {"settings":9s} {"pose":>12s} {"encoders":>12s} '
          f'{"joint gaps":>12s}')
    for row in rows:
        print(f'{row["model"]:14s} {row["mode"]:17s} {"stiff" if row["stiff"] else "default":9s} '
              f'{row["pose_nm"]:12.3g} {row["encoders_nm"]:12.3g} {row["joint_gaps_nm"]:12.3g}')
    print('\nSpeed at 1e-4 s, shipped physics (gravity, springs), one actuator released')
    for row in speeds:
        verdict = 'met' if row['cpu_real_time_factor'] >= 1.0 else 'NOT met'
        print(f'{row["model"]:14s} {row["simulated_s"]:.1f} s simulated in {row["cpu_s"]:.1f} s '
              f'CPU: {row["cpu_real_time_factor"]:.2f}x real time on one core ({verdict}); '
              f'{row["wall_s"]:.1f} s wall on this shared machine '
              f'({row["real_time_factor"]:.2f}x); {row["faults"]} faults')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
