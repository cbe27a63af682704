"""
The MuJoCo machine (physics_machine.py) against the geometric model it must agree with at rest.

Gravity off and a rigid structure: every built-in model in every measuring mode stands where
the core's kinematics says, to nanometres (nanoradians: the rotary hexapod's cranks); with
gravity on the accelerometer reads eq. 4's angles of the link; with springs, gravity deflects
the chains by what statics predicts.
"""

from __future__ import annotations

from dataclasses import replace

from hexacal_driver.physics_machine import PhysicsError, PhysicsMachine
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.machine.device import DeviceDefects, inclinometer_readings, sphere_z
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.modes.compliant import device_constrained_pose
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_msgs_py.physical_file import default_physical
import numpy as np
import pytest

mujoco = pytest.importorskip('mujoco')

L = 0.75
NM = 1e-9
MODELS = ('hexa_slide', 'gough_stewart', 'rotary_hexapod')


def sphere_pose(x: float, y: float, angles, length: float = L) -> np.ndarray:
    return np.array([x, y, sphere_z(np.array([[x, y]]), length)[0], *angles])


START = sphere_pose(0.02, -0.01, [0.01, 0.0, 0.02])
TARGET = sphere_pose(0.06, 0.03, [-0.02, 0.015, -0.03])


def weightless_rigid(model: str):
    """Gravity off, no springs, a frictionless released actuator."""
    physical = default_physical(model).weightless().made_rigid()
    return architecture(model).default_parameters(), replace(physical, released_coulomb=0.0)


def settle(machine: PhysicsMachine, setpoints: np.ndarray, seconds: float = 0.15) -> None:
    machine.command(setpoints, seconds)
    machine.advance(seconds)
    machine.settle(1.5, speed=1e-9)
    assert not machine.faults


def pose_error_m(pose: np.ndarray, expected: np.ndarray) -> float:
    """Return the largest position error and angle error times L (m)."""
    return max(np.abs(pose[:3] - expected[:3]).max(), L * np.abs(pose[3:] - expected[3:]).max())


@pytest.mark.parametrize('model', MODELS)
def test_passive_actuator_at_rest_agrees_with_the_closure(model):
    params, physical = weightless_rigid(model)
    machine = PhysicsMachine(params, physical, START, link_length=L)
    released = 2
    machine.release(released)
    assert 0.0 < machine.release_left_s() <= physical.release_ramp_s
    machine.advance(machine.release_left_s())  # the drive lets go before the others move
    assert machine.release_left_s() == 0.0
    start = machine.encoders()[released]
    setpoints = inverse_kinematics(params, TARGET[None])[0]
    setpoints[0] += 20e-6  # setpoints off the target: the closure, not the target, decides
    settle(machine, setpoints)
    solution = solve_passive(params, setpoints[None], released, TARGET[None], L)
    solution.raise_if_failed()
    assert pose_error_m(machine.pose(), solution.poses[0]) < 10 * NM
    encoders = machine.encoders()
    assert abs(encoders[released] - solution.released_positions[0]) < 10 * NM
    assert abs(encoders[released] - start) > 1e-3  # the closure moved the released actuator
    assert np.abs(encoders - solution.actuators[0]).max() < 10 * NM
    assert machine.joint_gaps().max() < 10 * NM
    status = machine.status()
    assert status['at_rest'] and status['released_chain'] == released
    assert status['max_joint_gap_m'] < 10 * NM


@pytest.mark.parametrize('model', MODELS)
def test_lvdt_at_rest_agrees_with_the_inverse_kinematics(model):
    params, physical = weightless_rigid(model)
    machine = PhysicsMachine(params, physical, START, link_length=L, mode='lvdt')
    off_sphere = sphere_pose(0.05, -0.02, [0.01, 0.02, -0.01], L + 0.002)
    settle(machine, inverse_kinematics(params, off_sphere[None])[0])
    assert pose_error_m(machine.pose(), off_sphere) < 10 * NM
    assert abs(machine.readings().link_length_m - np.linalg.norm(off_sphere[:3])) < 10 * NM
    assert machine.joint_gaps().max() < 10 * NM


@pytest.mark.parametrize('model', MODELS)
def test_compliant_servos_settle_where_the_least_squares_pose_is(model):
    params, physical = weightless_rigid(model)
    machine = PhysicsMachine(params, physical, START, link_length=L, mode='compliant')
    setpoints = inverse_kinematics(params, TARGET[None])[0] + np.array(
        [30e-6, -10e-6, 0.0, 15e-6, 0.0, -20e-6]
    )
    settle(machine, setpoints)
    pose, actuators = device_constrained_pose(params, setpoints, TARGET, L)
    assert pose_error_m(machine.pose(), pose) < 10 * NM
    assert np.abs(machine.encoders() - actuators).max() < 10 * NM


def test_the_links_force_is_its_spring_and_its_weight():
    params = architecture('hexa_slide').default_parameters()
    shipped = default_physical('hexa_slide')
    # Gravity off: the link's force at its platform joint is its spring's tension.
    machine = PhysicsMachine(params, shipped.weightless(), START, link_length=L)
    setpoints = inverse_kinematics(params, TARGET[None])[0]
    machine.release(2)
    setpoints[0] += 20e-6  # the released actuator follows; the link bears the rest
    settle(machine, setpoints)
    stretch = machine.link_length() - L
    assert abs(stretch) > 1e-7
    tension = shipped.link_axial_stiffness * stretch
    assert abs(machine.link_force() - tension) < 1e-6 * abs(tension) + 1e-6
    # An LVDT without spring under gravity: only the sliding link's weight along its axis.
    machine = PhysicsMachine(params, shipped, START, link_length=L, mode='lvdt')
    assert machine.settle(1.5, speed=1e-6)
    direction = machine.pose()[:3] / np.linalg.norm(machine.pose()[:3])
    weight = shipped.link_mass * np.asarray(shipped.gravity) @ direction  # > 0: pulls it down
    assert abs(machine.link_force() + weight) < 1e-3 * weight


@pytest.mark.parametrize('turn', [0.0, np.pi / 2])
def test_the_accelerometer_reads_eq4s_angles_at_rest(turn):
    model = 'hexa_slide'
    params = architecture(model).default_parameters()
    physical = replace(default_physical(model).made_rigid(), released_coulomb=0.0)
    defects = DeviceDefects(alpha0=1e-4, beta0=-2e-4, gamma=3e-4, phi0=5e-4)
    machine = PhysicsMachine(
        params, physical, TARGET, link_length=L, defects=defects, device_turn=turn
    )
    machine.release(4)
    machine.settle(1.5, speed=1e-9)
    readings = machine.readings()
    pose = machine.pose()
    assert abs(np.linalg.norm(pose[:3]) - L) < 10 * NM  # on the link's sphere
    alpha, beta = inclinometer_readings(pose[None, :3], defects, device_turn=turn)
    assert abs(readings.alpha_rad - alpha[0]) < 10e-9
    assert abs(readings.beta_rad - beta[0]) < 10e-9
    assert readings.phi_rad == pytest.approx(pose[5] - turn + defects.phi0, abs=1e-12)
    # Gravity loaded the stiff servos: the platform moved off its assembly, measurably.
    assert pose_error_m(pose, TARGET) > 1e-7


@pytest.mark.slow
@pytest.mark.parametrize('model', MODELS)
def test_gravity_deflects_the_chain_springs_as_statics_says(model):
    # A heavy platform (its weight dominates the legs'), the link unloaded (an LVDT without
    # spring), every chain with its axial spring: each spring carries the leg's axial load.
    params = architecture(model).default_parameters()
    physical = replace(
        default_physical(model), platform_mass=300.0, link_mass=0.2, released_coulomb=0.0
    )
    home = np.array([0.0, 0.0, -L, 0.0, 0.0, 0.0])
    machine = PhysicsMachine(params, physical, home, link_length=L, mode='lvdt')
    machine.settle(2.0, speed=1e-8)
    # Statics of massless two-force legs: sum f_c u_c + m g = 0, sum (B_c - P) x f_c u_c = 0,
    # f_c > 0 pushing the platform away from the base-side joint (compression).
    chains = architecture(model).mechanism(params, home)
    columns = []
    for chain in chains:
        # The leg (rod) is the two-force member between its passive hinges and the platform.
        hinge = next(
            j.anchor for b in chain.bodies for j in b.joints
            if j.kind == 'hinge' and j.role == 'passive'
        )
        unit = (chain.platform_joint - hinge) / np.linalg.norm(chain.platform_joint - hinge)
        columns.append(np.concatenate([unit, np.cross(chain.platform_joint - home[:3], unit)]))
    weight = physical.platform_mass * np.array(physical.gravity)
    forces = np.linalg.solve(np.array(columns).T, -np.concatenate([weight, np.zeros(3)]))
    expected = -forces / np.array(physical.structure_axial_stiffness)  # spring extension, m
    springs = [
        machine.data.qpos[machine.model.jnt_qposadr[machine.model.joint(name).id]]
        for name in machine.mjcf.names.spring_joints
    ]
    assert np.abs(expected).max() > 1e-6  # micrometres: what a calibration must see
    np.testing.assert_allclose(springs, expected, rtol=0.15, atol=0.05 * np.abs(expected).max())
    assert machine.pose()[2] < home[2]  # the hanging platform sags


def test_instability_is_an_error_not_a_reset(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo writes its warnings to MUJOCO_LOG.TXT here
    model = 'gough_stewart'
    params = architecture(model).default_parameters()
    # Servos far too stiff for the timestep: the explicit spring blows up.
    physical = replace(default_physical(model), drive_kp=(1e13,) * 6)
    machine = PhysicsMachine(params, physical, START, link_length=L)
    with pytest.raises(PhysicsError, match='unstable|non-finite'):
        machine.command(machine.setpoints + 1e-3)
        machine.advance(0.05)


def test_a_following_error_beyond_the_limit_is_a_fault():
    model = 'hexa_slide'
    params = architecture(model).default_parameters()
    machine = PhysicsMachine(params, default_physical(model), START, link_length=L)
    machine.release(0)
    setpoints = machine.setpoints
    setpoints[3] += 0.01  # a 10 mm step: the servo cannot follow within 1 mm at once
    machine.command(setpoints)
    machine.advance(0.002)
    assert [fault.chain for fault in machine.faults] == [3]
    limit = default_physical(model).following_error_limit
    assert machine.status()['faults'][0]['limit_m'] == limit
