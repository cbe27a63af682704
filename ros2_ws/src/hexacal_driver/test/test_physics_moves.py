"""
A passive move on the MuJoCo machine: the executor's eased command against full speed at once.

With one actuator released the link is a load-bearing member (test_physics_statics.py).  A move
timed at full speed from its first point (platform_paths.point_times) asks the stiff servos for
a step in speed: the platform's inertia then loads the link far beyond its static load.  The
executor's eased command (platform_paths.eased_command: starts and stops at rest) keeps the
link near the statics all along the way.
"""

from __future__ import annotations

from dataclasses import replace

from hexacal_driver.physics_machine import PhysicsMachine
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.device import sphere_z
from hexacal_identify.core.modes.link_load import released_link_forces
from hexacal_identify.core.walk.platform_paths import eased_command, route_command
from hexacal_msgs_py.physical_file import default_physical
import numpy as np
import pytest

mujoco = pytest.importorskip('mujoco')

L = 0.75
SPEED = 0.5  # the demo executor's m/s
STROKE = (-np.inf, np.inf)
RELEASED = 2


def _pose(xy, angles):
    return np.array([*xy, sphere_z(np.array([xy]), L)[0], *angles])


def _peak_link_force(params, physical, start, command):
    """Walk `command` from rest at `start` (chain RELEASED free); return the largest |force|."""
    machine = PhysicsMachine(params, physical, start, link_length=L)
    machine.settle(1.0, speed=1e-6)
    machine.release(RELEASED)
    assert machine.settle(2.0)
    peak, before = abs(machine.link_force()), 0.0
    for point, time_s in zip(command.points, command.times):
        machine.command(point, time_s - before, linear=True)  # the drive's linear interpolation
        steps = max(1, round((time_s - before) / 2e-3))
        for _ in range(steps):
            machine.advance((time_s - before) / steps)
            peak = max(peak, abs(machine.link_force()))
        before = time_s
    return peak


def test_an_eased_passive_move_keeps_the_link_near_its_static_load():
    physical = default_physical('hexa_slide')
    arch = architecture('hexa_slide')
    params = arch.default_parameters()
    start = _pose((-0.05, 0.04), (-0.03, 0.02, -0.02))
    end = _pose((0.06, -0.03), (0.03, -0.02, 0.04))
    command = route_command(params, np.zeros(6), start, end, STROKE, SPEED, L, 0.02)
    setpoints = arch.legs(arch.chains(params), start[None]).actuators[0]
    eased = eased_command(command, setpoints, SPEED)
    # The statics with the released chain along the way (the move's sphere path).
    along = np.array([start + s * (end - start) for s in np.linspace(0.0, 1.0, 21)])
    along[:, 2] = sphere_z(along[:, :2], L)
    masses = MassModel.from_physical(physical)
    static = released_link_forces(params, along, masses)[:, RELEASED].max()
    full_speed = _peak_link_force(params, physical, start, command)
    gentle = _peak_link_force(params, physical, start, eased)
    # Measured: static 460 N, full speed 2.8 kN, eased 0.64 kN.
    assert full_speed > 3.0 * static, (full_speed, static)
    assert gentle < 1.5 * static + 50.0, (gentle, static)


def test_a_release_ramped_down_hands_the_link_its_load_without_a_jolt():
    # The physical description's drives.release_ramp_s: the released drive's force goes to
    # zero over 0.3 s by default; cut at once, the link takes its load as a step.
    physical = default_physical('hexa_slide')
    params = architecture('hexa_slide').default_parameters()
    pose = _pose((0.03, -0.02), (0.02, -0.01, 0.03))
    chain = 3
    static = released_link_forces(params, pose[None], MassModel.from_physical(physical))[0, chain]

    def peak(ramp_s: float) -> tuple[float, float]:
        """Return the link's largest |force| over 0.6 s after the release, and where it settles."""
        machine = PhysicsMachine(params, replace(physical, release_ramp_s=ramp_s), pose,
                                 link_length=L)
        machine.settle(1.0, speed=1e-6)
        machine.release(chain)
        largest = 0.0
        for _ in range(600):
            machine.advance(1e-3)
            largest = max(largest, abs(machine.link_force()))
        machine.settle(1.0)
        return largest, abs(machine.link_force())

    # Measured: static 303 N; at once a 466 N peak; ramped, 251 N and no overshoot (the released
    # slider's 10 N stiction stops it short of the frictionless statics). The drive's gains
    # scaled down instead of its force peaked at 364 N.
    assert physical.release_ramp_s == 0.3
    assert peak(0.0)[0] > 1.35 * static > 1.35 * 250.0
    ramped, settled = peak(physical.release_ramp_s)
    assert ramped < 1.02 * settled, (ramped, settled)
    assert abs(settled - static) < 0.25 * static, (settled, static)
