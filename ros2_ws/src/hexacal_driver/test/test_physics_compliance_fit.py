"""
The compliance fit on the MuJoCo machine: a machine whose physics the identification did not write.

A Hexa Slide under gravity with a springy measuring link (the shipped 1e7 N/m, structure rigid,
no friction), walked in passive_actuator mode: the link carries part of the weight and stretches
from posture to posture.  The rigid geometric fit cannot hold that stretch (its adequacy fails);
the fit with a shared chain compliance and the link's recovers the link's compliance within its
reported standard deviations and its adequacy passes.
"""

from __future__ import annotations

from dataclasses import replace

from hexacal_driver.physics_machine import PhysicsMachine
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.compliance import ComplianceModel
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.device import DeviceModel
from hexacal_identify.core.machine.measurements import Measurements, NoiseModel
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
from hexacal_msgs_py.physical_file import default_physical
import numpy as np
import pytest

pytest.importorskip('mujoco')

NOISE = NoiseModel(actuator_m=2e-6, angle_rad=5e-6)
POSTURES = 20


def walk(model: str, physical, n: int, seed: int):
    """Return the exact readings of ``n`` passive postures of the MuJoCo machine, and releases."""
    true = architecture(model).default_parameters()
    length = DeviceModel().link_length
    poses = sample_poses(
        true, n, np.random.default_rng(seed), 'sphere', true.architecture.default_workspace()
    )
    released = np.argmin(release_conditions(true, poses, length), axis=1)
    actuators, angles, rotary = np.zeros((n, 6)), np.zeros((n, 2)), np.zeros(n)
    for i, (pose, chain) in enumerate(zip(poses, released)):
        machine = PhysicsMachine(true, physical, pose, link_length=length)
        machine.settle(1.5, speed=1e-6)
        machine.release(int(chain))
        assert machine.settle(3.0), f'posture {i} did not come to rest'
        readings = machine.readings()
        actuators[i] = readings.actuators_m
        angles[i] = readings.alpha_rad, readings.beta_rad
        rotary[i] = readings.phi_rad
    return true, actuators, angles, rotary, released


@pytest.mark.slow
def test_the_compliance_fit_recovers_the_mujoco_links_compliance():
    model = 'hexa_slide'
    # Sliders without mass keep this test to the link's compliance alone (the moving masses'
    # loads are checked in test_core_statics; bench_physics_effects measures them on MuJoCo).
    physical = replace(
        default_physical(model),
        structure_axial_stiffness=None,
        released_coulomb=0.0,
        actuator_moving_mass=0.0,
    )
    true, actuators, angles, rotary, released = walk(model, physical, POSTURES, seed=3)
    rng = np.random.default_rng(4)
    measurements = Measurements(
        actuators + rng.uniform(-NOISE.actuator_m, NOISE.actuator_m, actuators.shape),
        angles + rng.uniform(-NOISE.angle_rad, NOISE.angle_rad, angles.shape),
        rotary + rng.uniform(-NOISE.angle_rad, NOISE.angle_rad, rotary.shape),
    )
    nominal = nominal_set(2, seed=3, exact=true)
    rigid = identify(nominal, measurements, SolverOptions(noise=NOISE))
    compliance = ComplianceModel(
        'shared', MassModel.from_physical(physical), 'passive_actuator', released
    )
    compliant = identify(nominal, measurements, SolverOptions(noise=NOISE, compliance=compliance))
    link = 1.0 / physical.link_axial_stiffness
    identified, std = compliant.compliance['link'], compliant.compliance_std['link']
    assert np.isfinite(std) and std < 0.2 * link
    assert abs(identified - link) <= 3.0 * std, (identified, std, link)
    # Rigid structure: the chains' shared compliance is nothing the data can tell from zero.
    assert abs(compliant.compliance['chains']) <= 3.0 * compliant.compliance_std['chains']
    assert rigid.adequacy.failed, rigid.adequacy.lines()
    assert not compliant.adequacy.failed, compliant.adequacy.lines()
    assert compliant.variance_factor < rigid.variance_factor / 10.0
