"""
The architectures' mechanisms and the MJCF writer (physics/mjcf.py).

The mechanism of each chain must close at the pose exactly as the architecture's IK says, and
the MJCF must compile in MuJoCo with the names the simulated machine reads.
"""

from __future__ import annotations

import subprocess
import sys

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.architectures.base import ACTUATED, COMPLIANCE, HINGE, PASSIVE, SLIDE
from hexacal_identify.core.machine.device import sphere_z
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.physics.mjcf import device_readings_at, machine_mjcf
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.physical_file import default_physical, write_physical_file
import numpy as np
import pytest

L = 0.75
BUILT_IN = ('hexa_slide', 'gough_stewart', 'rotary_hexapod')


def sphere_pose(x: float, y: float, angles) -> np.ndarray:
    return np.array([x, y, sphere_z(np.array([[x, y]]), L)[0], *angles])


POSE = sphere_pose(0.04, -0.03, [0.02, -0.015, 0.03])


@pytest.mark.parametrize('model', BUILT_IN)
def test_mechanism_closes_every_chain_at_the_pose(model):
    arch = architecture(model)
    params = arch.default_parameters()
    chains = arch.mechanism(params, POSE)
    sliders = inverse_kinematics(params, POSE[None])[0]
    joints = arch.drawing(params, POSE)['platform_joints']
    assert len(chains) == 6
    for c, chain in enumerate(chains):
        assert chain.actuator == pytest.approx(sliders[c], abs=1e-12)
        np.testing.assert_allclose(chain.platform_joint, joints[c], atol=1e-12)
        np.testing.assert_allclose(chain.bodies[-1].segment[1], joints[c], atol=1e-12)
        roles = [joint.role for body in chain.bodies for joint in body.joints]
        assert roles.count(ACTUATED) == 1 and roles.count(COMPLIANCE) == 1
        for body in chain.bodies:
            for joint in body.joints:
                assert np.linalg.norm(joint.axis) == pytest.approx(1.0)
                assert joint.kind in (SLIDE, HINGE)
        # The universal joint's hinges are normal to the leg, the spring along it.
        leg = chain.platform_joint - [j.anchor for b in chain.bodies for j in b.joints
                                      if j.kind == HINGE and j.role == PASSIVE][0]
        for body in chain.bodies:
            for joint in body.joints:
                if joint.kind == HINGE and joint.role == PASSIVE:
                    assert abs(joint.axis @ leg) < 1e-12
                if joint.role == COMPLIANCE:
                    assert abs(joint.axis @ leg) == pytest.approx(np.linalg.norm(leg))


def test_the_hexa_slide_actuated_joint_runs_along_the_rail_from_A0():
    arch = architecture('hexa_slide')
    params = arch.default_parameters()
    for c, chain in enumerate(arch.mechanism(params, POSE)):
        slide = chain.bodies[0].joints[0]
        np.testing.assert_allclose(slide.axis, params.rail_directions[c])
        np.testing.assert_allclose(
            slide.anchor, params.base_points[c] + chain.actuator * params.rail_directions[c]
        )
        leg = np.linalg.norm(chain.platform_joint - slide.anchor)
        assert leg == pytest.approx(params.leg_lengths[c], abs=1e-12)


def test_the_rotary_hexapod_crank_turns_about_the_motor_axis_from_its_zero():
    arch = architecture('rotary_hexapod')
    params = arch.default_parameters()
    for c, chain in enumerate(arch.mechanism(params, POSE)):
        crank, rod = chain.bodies
        hinge = crank.joints[0]
        assert (hinge.kind, hinge.role) == (HINGE, ACTUATED)
        np.testing.assert_allclose(hinge.axis, params.axis_directions[c], atol=1e-15)
        np.testing.assert_allclose(hinge.anchor, params.base_points[c], atol=1e-15)
        # The crank points along c(lambda + alpha0): the hinge's zero is the crank zero.
        tip = params.base_points[c] + params.crank_lengths[c] * params.crank_directions(
            np.full(6, chain.actuator)
        )[c]
        np.testing.assert_allclose(crank.segment[1], tip, atol=1e-12)
        np.testing.assert_allclose(rod.joints[0].anchor, tip, atol=1e-12)
        rod_length = np.linalg.norm(chain.platform_joint - tip)
        assert rod_length == pytest.approx(params.rod_lengths[c], abs=1e-12)


def test_the_rotary_hexapod_hinge_value_is_the_crank_reading():
    # Turning the MJCF's actuated hinge to any value puts the crank tip where the architecture
    # puts it for that reading.
    mujoco = pytest.importorskip('mujoco')
    params = architecture('rotary_hexapod').default_parameters()
    mjcf = machine_mjcf(params, default_physical('rotary_hexapod'), POSE, link_length=L)
    m = mujoco.MjModel.from_xml_string(mjcf.xml)
    d = mujoco.MjData(m)
    readings = inverse_kinematics(params, POSE[None])[0] + np.linspace(-0.4, 0.5, 6)
    for c, name in enumerate(mjcf.names.actuated_joints):
        assert m.jnt_type[m.joint(name).id] == mujoco.mjtJoint.mjJNT_HINGE
        d.qpos[m.jnt_qposadr[m.joint(name).id]] = readings[c]
    mujoco.mj_kinematics(m, d)
    tips = params.base_points + params.crank_lengths[:, None] * params.crank_directions(readings)
    for c in range(6):
        rod = m.body(f'chain_{c + 1}_rod').id  # its frame origin is the crank tip's U joint
        np.testing.assert_allclose(d.xpos[rod], tips[c], atol=1e-12)


def test_device_readings_at_are_eq4s_angles():
    alpha, beta = device_readings_at(POSE[:3])
    expected = L * np.array(
        [np.cos(alpha) * np.sin(beta), -np.sin(alpha), -np.cos(alpha) * np.cos(beta)]
    )
    np.testing.assert_allclose(expected, POSE[:3], atol=1e-12)


@pytest.mark.parametrize('model', BUILT_IN)
def test_mjcf_names_and_options(model):
    params = architecture(model).default_parameters()
    physical = default_physical(model)
    mjcf = machine_mjcf(params, physical, POSE, link_length=L)
    assert mjcf.names.actuators == MODELS[model].actuator_names
    assert all(name is not None for name in mjcf.names.spring_joints)
    assert mjcf.names.link_spring_joint is not None
    assert 'solver="Newton"' in mjcf.xml and 'contact="disable"' in mjcf.xml
    assert 'solref="0.0002 1.0"' in mjcf.xml
    rigid = machine_mjcf(params, physical.made_rigid(), POSE, link_length=L)
    assert rigid.names.spring_joints == (None,) * 6 and rigid.names.link_spring_joint is None
    assert 'stiffness' not in rigid.xml
    with pytest.raises(ValueError, match='physical description'):
        other = 'gough_stewart' if model == 'hexa_slide' else 'hexa_slide'
        machine_mjcf(params, default_physical(other), POSE)


@pytest.mark.parametrize('model', BUILT_IN)
def test_mjcf_compiles_at_the_assembly_with_closed_chains(model):
    mujoco = pytest.importorskip('mujoco')
    params = architecture(model).default_parameters()
    mjcf = machine_mjcf(params, default_physical(model), POSE, link_length=L)
    m = mujoco.MjModel.from_xml_string(mjcf.xml)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key('assembly').id)
    mujoco.mj_forward(m, d)
    assert m.nu == 6 and m.neq == 7
    np.testing.assert_allclose(d.xpos[m.body('platform').id], POSE[:3], atol=1e-12)
    assert np.max(np.abs(d.efc_pos[: d.ne])) < 1e-12  # every connect closed at the assembly
    actuated = [m.jnt_qposadr[m.joint(j).id] for j in mjcf.names.actuated_joints]
    np.testing.assert_allclose(d.qpos[actuated], inverse_kinematics(params, POSE[None])[0])


def test_the_writer_imports_no_mujoco():
    code = (
        'import sys; import hexacal_identify.physics.mjcf; '
        'sys.exit(1 if "mujoco" in sys.modules else 0)'
    )
    assert subprocess.run([sys.executable, '-c', code], check=False).returncode == 0


def test_export_mjcf_writes_the_machine_with_its_physics(tmp_path, capsys):
    mujoco = pytest.importorskip('mujoco')
    from hexacal_identify.cli import main
    from hexacal_msgs_py.parameters_file import save_parameters

    model = 'gough_stewart'
    params = architecture(model).default_parameters()
    parameters = tmp_path / 'calibrated.yaml'
    save_parameters(parameters, params.vector, model=model)
    physical = tmp_path / 'physical.yaml'
    write_physical_file(physical, default_physical(model))
    out = tmp_path / 'machine.xml'
    assert main(['export', str(parameters), '--format', 'mjcf', '--physical', str(physical),
                 '--out', str(out)]) == 0
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.body('platform').mass[0] == pytest.approx(default_physical(model).platform_mass)
    assert m.nu == 6
    # --physical belongs to mjcf; a physical file of the other model is refused.
    assert main(['export', str(parameters), '--format', 'yaml', '--physical', str(physical),
                 '--out', str(tmp_path / 'x.yaml')]) == 2
    write_physical_file(physical, default_physical('hexa_slide'))
    assert main(['export', str(parameters), '--format', 'mjcf', '--physical', str(physical),
                 '--out', str(out)]) == 2
    assert 'describes a hexa_slide' in capsys.readouterr().err
