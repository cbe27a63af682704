"""Statics of the weights: the chains' and the link's loads balance the wrench, every mode."""

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.statics import MassModel, static_loads, weight_gradient
from hexacal_identify.core.machine.kinematics import rotation_matrices
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.measuring_modes import MeasuringMode
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')
MASSES = MassModel(
    platform_mass=20.0,
    platform_com=(0.01, -0.02, 0.03),
    payload_mass=5.0,
    payload_com=(0.05, 0.0, 0.08),
    leg_mass=2.0,
    leg_com_fraction=0.4,
    link_mass=1.5,
    link_com_fraction=0.5,
)


def _machine(model, n=12, seed=3):
    arch = architecture(model)
    params = arch.default_parameters()
    rng = np.random.default_rng(seed)
    poses = sample_poses(params, n, rng, 'sphere', arch.default_workspace())
    return params, poses


def _potential(params, poses, masses):
    """U = -sum m g . p of the platform-side weights, from the points themselves."""
    rotation = rotation_matrices(poses[:, 3:6])
    gravity = np.asarray(masses.gravity)
    points = [
        (masses.platform_mass, np.asarray(masses.platform_com)),
        (masses.payload_mass, np.asarray(masses.payload_com)),
        (masses.link_com_fraction * masses.link_mass, np.zeros(3)),
    ] + [(masses.leg_com_fraction * masses.leg_mass, b) for b in params.platform_points]
    total = np.zeros(len(poses))
    for mass, point in points:
        total -= mass * (poses[:, :3] + rotation @ point) @ gravity
    return total


@pytest.mark.parametrize('model', MODELS)
def test_weight_gradient_is_the_potential_s(model):
    params, poses = _machine(model)
    gradient = weight_gradient(params, poses, MASSES)
    step = 1e-6
    for k in range(6):
        delta = np.zeros(6)
        delta[k] = step
        numeric = (
            _potential(params, poses + delta, MASSES) - _potential(params, poses - delta, MASSES)
        ) / (2 * step)
        np.testing.assert_allclose(gradient[:, k], numeric, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize('model', MODELS)
@pytest.mark.parametrize('mode', list(MeasuringMode))
def test_the_loads_balance_the_weights_force_and_moment(model, mode):
    params, poses = _machine(model)
    n = len(poses)
    released = np.arange(n) % 6
    loads = static_loads(params, poses, MASSES, mode, released)
    arch = params.architecture
    jacobian = arch.legs(arch.chains(params), poses).pose_jacobian()
    # Cartesian balance on the platform: each leg pushes tau_c dlambda_c/dP (along the leg), the
    # link pulls T towards O, the weights hang at their points.
    rotation = rotation_matrices(poses[:, 3:6])
    joints = np.einsum('nij,cj->nci', rotation, params.platform_points)
    leg_forces = loads.thrust[..., None] * jacobian[:, :, :3]
    radius = np.linalg.norm(poses[:, :3], axis=1)[:, None]
    link_force = -loads.link[:, None] * poses[:, :3] / radius
    mass, moment = MASSES.platform_side(params)
    gravity = np.asarray(MASSES.gravity)
    force = leg_forces.sum(axis=1) + link_force + mass * gravity
    torque = np.cross(joints, leg_forces).sum(axis=1) + np.cross(rotation @ moment, gravity)
    weight = mass * np.linalg.norm(gravity)
    np.testing.assert_allclose(force, 0.0, atol=1e-9 * weight)
    np.testing.assert_allclose(torque, 0.0, atol=1e-9 * weight)
    assert weight > 200.0
    if mode == MeasuringMode.PASSIVE_ACTUATOR:
        assert np.all(loads.thrust[np.arange(n), released] == 0.0), 'the released chain is free'
        assert np.max(np.abs(loads.link)) > 10.0, 'the link carries part of the weight'
    if mode == MeasuringMode.LVDT:
        assert np.all(loads.link == 0.0)
    if mode == MeasuringMode.COMPLIANT:
        # Least energy: no other tension moves less (the thrusts are orthogonal to the free one).
        assert np.max(np.abs(loads.link)) > 0.0


def test_reading_loads_are_the_leg_force_times_its_lever():
    params, poses = _machine('gough_stewart')
    loads = static_loads(params, poses, MASSES, 'lvdt')
    # A prismatic leg: the reading is the leg's length, so its force is the thrust.
    np.testing.assert_allclose(loads.chains, loads.thrust, rtol=1e-12)
    np.testing.assert_allclose(loads.reading_loads, loads.thrust, rtol=1e-12)


def test_no_weight_no_load_and_bad_input_is_named():
    params, poses = _machine('hexa_slide', n=3)
    loads = static_loads(params, poses, MassModel(), 'passive_actuator', np.zeros(3, int))
    assert np.all(loads.thrust == 0.0) and np.all(loads.link == 0.0)
    with pytest.raises(Exception, match='released chain'):
        static_loads(params, poses, MASSES, 'passive_actuator')
    with pytest.raises(ValueError, match='leg_com_fraction'):
        MassModel(leg_com_fraction=1.5)
    with pytest.raises(ValueError, match='platform_mass'):
        MassModel(platform_mass=-1.0)


def test_mass_model_reads_the_physical_description_keys(tmp_path):
    path = tmp_path / 'physical.yaml'
    path.write_text(
        'format: hexacal-physical/1\n'
        'gravity: [0, 0, -9.81]\n'
        'platform: {mass: 20, com: [0, 0, 0.01], inertia: [1, 1, 1, 0, 0, 0]}\n'
        'payload: {mass: 3, com: [0, 0, 0.1]}\n'
        'legs: {mass: 2, com_fraction: 0.4}\n'
        'link: {mass: 1.5, com_fraction: 0.5, axial_stiffness: 1.0e7}\n'
    )
    masses = MassModel.load(path)
    assert masses.platform_mass == 20.0 and masses.payload_com == (0.0, 0.0, 0.1)
    assert masses.leg_com_fraction == 0.4 and masses.link_mass == 1.5
    assert masses.gravity == (0.0, 0.0, -9.81)
    path.write_text('platform: 3\n')
    with pytest.raises(ValueError, match='platform'):
        MassModel.load(path)


def test_mass_model_reads_a_complete_physical_file_with_the_contracts_reader(tmp_path):
    from hexacal_msgs_py.physical_file import default_physical, write_physical_file

    shipped = default_physical('gough_stewart')
    path = write_physical_file(tmp_path / 'physical.yaml', shipped)
    assert MassModel.load(path) == MassModel.from_physical(shipped)
    # A missing section takes the model's shipped default, as the MuJoCo machine takes it.
    path.write_text('format: hexacal-physical/1\nmodel: hexa_slide\nlegs: {mass: 3.0}\n')
    masses = MassModel.load(path)
    assert masses.leg_mass == 3.0
    assert masses.platform_mass == default_physical('hexa_slide').platform_mass > 0.0
    assert masses.gravity == default_physical('hexa_slide').gravity
    path.write_text('format: hexacal-physical/1\nmodel: hexa_slide\nlink: {stiffness: 1}\n')
    with pytest.raises(ValueError, match='link.stiffness'):
        MassModel.load(path)
