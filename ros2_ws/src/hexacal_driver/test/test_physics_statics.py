"""
The static loads of the core (core/fit/statics.py) against the MuJoCo machine at rest.

The fit's compliance model predicts the chains' and the link's loads from the weights; the
MuJoCo machine, which hexacal did not write, holds the same weights by its constraints.  At
rest in passive_actuator mode (the released drive free, without friction) the drives' forces,
the chains' springs and the link's force must be the statics'.
"""

from __future__ import annotations

from dataclasses import replace

from hexacal_driver.physics_machine import PhysicsMachine
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.statics import LoadSharing, MassModel, static_loads
from hexacal_identify.core.machine.device import sphere_z
from hexacal_msgs_py.physical_file import default_physical
import numpy as np
import pytest

mujoco = pytest.importorskip('mujoco')

L = 0.75


def _at_rest(model, physical, pose, released):
    """Return the machine settled at ``pose`` with chain ``released`` free."""
    params = architecture(model).default_parameters()
    machine = PhysicsMachine(params, physical, pose, link_length=L)
    machine.settle(1.0, speed=1e-6)
    machine.release(released)
    assert machine.settle(3.0)
    return params, machine


@pytest.mark.parametrize(
    'model, xy, angles, released',
    [
        ('gough_stewart', (0.03, -0.02), (0.02, -0.01, 0.03), 0),
        ('gough_stewart', (-0.05, 0.04), (-0.03, 0.02, -0.02), 4),
        ('hexa_slide', (0.03, -0.02), (0.02, -0.01, 0.03), 2),
        ('hexa_slide', (-0.05, 0.04), (-0.03, 0.02, -0.02), 5),
        ('rotary_hexapod', (0.03, -0.02), (0.02, -0.01, 0.03), 1),
    ],
)
def test_loads_at_rest_are_the_statics(model, xy, angles, released):
    # The shipped masses (platform, legs, sliders / rods / cranks, a 1.5 kg link), rigid link,
    # the legs' springs on.  A Gough-Stewart housing's axial weight goes to the base, not
    # through the released drive to the platform and the link; a Hexa Slide leg's (a rotary
    # hexapod rod's) base-side share rides on its slider (crank tip), along a released rail
    # (about a released motor's axis) held by the leg and the link.
    physical = replace(default_physical(model), link_axial_stiffness=None, released_coulomb=0.0)
    pose = np.array([*xy, sphere_z(np.array([xy]), L)[0], *angles])
    params, machine = _at_rest(model, physical, pose, released)
    at = machine.pose()
    masses = MassModel.from_physical(physical)
    loads = static_loads(params, at[None], masses, 'passive_actuator', np.array([released]))
    # The link's force at its platform joint: its axial force less the axial share of its
    # weight lumped at the platform end (which the joint carries to the platform).
    direction = at[:3] / np.linalg.norm(at[:3])
    share = masses.link_com_fraction * masses.link_mass * np.asarray(masses.gravity) @ direction
    assert abs(loads.link[0]) > 100.0 and abs(share) > 5.0
    assert machine.link_force() == pytest.approx(loads.link[0] - share, abs=0.5)
    np.testing.assert_allclose(machine.data.actuator_force, loads.thrust[0], atol=0.5)
    springs = [machine.model.joint(name).id for name in machine.mjcf.names.spring_joints]
    # qfrc_spring pushes the housing back towards the base: a compressed leg's force.
    spring_forces = -np.asarray(machine.data.qfrc_spring)[machine.model.jnt_dofadr[springs]]
    if model == 'rotary_hexapod':
        # A crank's chain force is signed as its torque, which pushes or pulls its rod as the
        # rod leaves the crank's tip: the size is the spring's.
        np.testing.assert_allclose(np.abs(spring_forces), np.abs(loads.chains[0]), atol=0.5)
    else:
        np.testing.assert_allclose(spring_forces, -loads.chains[0], atol=0.5)


@pytest.mark.parametrize(
    'model, xy, angles',
    [
        ('hexa_slide', (0.03, -0.02), (0.02, -0.01, 0.03)),
        ('gough_stewart', (-0.05, 0.04), (-0.03, 0.02, -0.02)),
    ],
)
def test_compliant_loads_at_rest_are_shared_by_stiffness(model, xy, angles):
    # All six drives powered, the shipped springs: legs 5e7 N/m, the link 1e7 N/m, servos
    # 1e8 N/m (Hexa Slide) or 1e7 N/m (Gough-Stewart).  The rule of equal drives and a rigid
    # link gave the link 150-370 N more than the machine carries.
    physical = replace(default_physical(model), released_coulomb=0.0)
    params = architecture(model).default_parameters()
    pose = np.array([*xy, sphere_z(np.array([xy]), L)[0], *angles])
    machine = PhysicsMachine(params, physical, pose, link_length=L, mode='compliant')
    assert machine.settle(3.0)
    masses = MassModel.from_physical(physical)
    sharing = LoadSharing.of(
        physical.drive_kp, 1.0 / np.asarray(physical.structure_axial_stiffness),
        1.0 / physical.link_axial_stiffness,
    )
    loads = static_loads(params, pose[None], masses, 'compliant', sharing=sharing)
    rule = static_loads(params, pose[None], masses, 'compliant')
    direction = pose[:3] / np.linalg.norm(pose[:3])
    share = masses.link_com_fraction * masses.link_mass * np.asarray(masses.gravity) @ direction
    # Within 10 N of 14.7 N of the link's weight: the MJCF's sprung link slides as one body on
    # its spring at the base (6-7 N here), where the statics lump it at its two ends.
    assert machine.link_force() == pytest.approx(loads.link[0] - share, abs=10.0)
    assert abs(machine.link_force() - (rule.link[0] - share)) > 100.0
    np.testing.assert_allclose(machine.data.actuator_force, loads.thrust[0], atol=2.0)
