"""Statics of the weights: the chains' and the link's loads balance the wrench, every mode."""

from dataclasses import replace

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.architectures.base import ACTUATED, ACTUATOR_BODY, HINGE, LEG_BODY
from hexacal_identify.core.errors import InvalidMeasurementError
from hexacal_identify.core.fit.statics import (
    actuator_weight_loads,
    MassModel,
    released_force_loads,
    static_loads,
    weight_gradient,
)
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
    if model == 'gough_stewart':
        # A cylinder's housing turns with its leg but does not extend: only its weight's share
        # across the leg reaches the platform joint, its axial weight goes to the base.
        share = MASSES.leg_com_fraction * MASSES.leg_mass
        mass -= 6 * share
        moment = moment - share * params.platform_points.sum(axis=0)
        units = _leg_units(params, poses)
        across = share * (gravity - (units @ gravity)[..., None] * units)
        leg_forces = leg_forces + across
    if model == 'hexa_slide':
        # A leg's base-side share rides on its slider: along the rail the drive holds it with
        # the thrust, so the leg pushes the platform with both.
        share = (1.0 - MASSES.leg_com_fraction) * MASSES.leg_mass
        along = loads.thrust + share * params.rail_directions @ gravity
        leg_forces = along[..., None] * jacobian[:, :, :3]
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


def _leg_units(params, poses):
    """Return the Gough-Stewart legs' unit vectors (N, 6, 3) from A to B."""
    rotation = rotation_matrices(poses[:, 3:6])
    legs = (
        poses[:, None, :3] + np.einsum('nij,cj->nci', rotation, params.platform_points)
        - params.base_points
    )
    return legs / np.linalg.norm(legs, axis=2, keepdims=True)


def test_reading_loads_are_the_leg_force_times_its_lever():
    params, poses = _machine('gough_stewart')
    loads = static_loads(params, poses, MASSES, 'lvdt')
    # A prismatic leg: the reading is the leg's length, so its force is the thrust, less the
    # housing's axial weight: the housing lies between the actuator and the leg's spring.
    housing = MASSES.leg_mass * _leg_units(params, poses) @ np.asarray(MASSES.gravity)
    assert np.abs(housing).max() > 10.0
    np.testing.assert_allclose(loads.chains, loads.thrust - housing, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(loads.reading_loads, loads.chains, rtol=1e-12)
    weightless = static_loads(params, poses, replace(MASSES, leg_mass=0.0), 'lvdt')
    np.testing.assert_allclose(weightless.chains, weightless.thrust, rtol=1e-12)


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


ALL_MODELS = ('hexa_slide', 'gough_stewart', 'rotary_hexapod')
MOVING = replace(MASSES, actuator_moving_mass=3.0)


def _actuator_parts(params, pose, rods=None):
    """
    Return the actuators' moving parts' centres (6, 3) at ``pose`` from the mechanism.

    ``rods`` (6,): place each part as a rigid rod hanging that far before the platform joint
    along the chain's first body (the part rides on the leg); None: the middle of the part's
    segment, as the mechanism places it at the pose.
    """
    centres = []
    for c, chain in enumerate(params.architecture.mechanism(params, pose)):
        part = next(body for body in chain.bodies if body.carries == ACTUATOR_BODY)
        if rods is None:
            centres.append(part.segment.mean(axis=0))
        else:
            leg = chain.platform_joint - chain.bodies[0].segment[0]
            centres.append(chain.platform_joint - rods[c] * leg / np.linalg.norm(leg))
    return np.array(centres)


def _rides_on_the_leg(params, pose):
    """Return the half lengths (6,) of parts that do not move with the reading at a held pose."""
    with_reading, _ = params.architecture.actuator_mass_motion(params, pose[None])
    if np.any(with_reading):
        return None
    return np.array([
        0.5 * np.linalg.norm(np.diff(next(
            body for body in chain.bodies if body.carries == ACTUATOR_BODY
        ).segment, axis=0))
        for chain in params.architecture.mechanism(params, pose)
    ])


@pytest.mark.parametrize('model', ALL_MODELS)
def test_actuator_parts_move_as_the_mechanism_places_them(model):
    params, poses = _machine(model, n=4)
    with_reading, with_pose = params.architecture.actuator_mass_motion(params, poses)
    jacobian = params.architecture.legs(params.architecture.chains(params), poses).pose_jacobian()
    step = 1e-6
    for n, pose in enumerate(poses):
        rods = _rides_on_the_leg(params, pose)
        for k in range(6):
            delta = np.zeros(6)
            delta[k] = step
            numeric = (
                _actuator_parts(params, pose + delta, rods)
                - _actuator_parts(params, pose - delta, rods)
            ) / (2 * step)
            np.testing.assert_allclose(with_pose[n, :, :, k], numeric, atol=1e-8)
        if rods is None:
            # A part moving with the reading moves with the pose only through it.
            np.testing.assert_allclose(
                with_pose[n], with_reading[n][..., None] * jacobian[n][:, None, :], atol=1e-12
            )
    assert np.max(np.abs(with_pose)) > 0.1


def _moving_potential_gradient(params, poses, masses, step=1e-6):
    """Return d U_a / d X (N, 6), U_a = -sum m g . p_c of the rigid parts (central differences)."""
    gradient = np.empty((len(poses), 6))
    for n, pose in enumerate(poses):
        rods = _rides_on_the_leg(params, pose)  # a rod's place on the leg is the pose's
        for k in range(6):
            delta = np.zeros(6)
            delta[k] = step
            rise = (
                _actuator_parts(params, pose + delta, rods)
                - _actuator_parts(params, pose - delta, rods)
            ) / (2 * step)
            gradient[n, k] = -masses.actuator_moving_mass * np.sum(rise @ masses.gravity)
    return gradient


def _base_side_motion(params, pose):
    """
    Return the legs' base-side joints' motion per unit reading (6, 3) and the legs' units.

    From the mechanism: the actuated joint's axis for a slider, its axis x the arm to the leg's
    joint for a crank.
    """
    tips, units = [], []
    for chain in params.architecture.mechanism(params, pose):
        actuated = next(
            joint for body in chain.bodies for joint in body.joints if joint.role == ACTUATED
        )
        start, joint = next(body for body in chain.bodies if body.carries == LEG_BODY).segment
        if actuated.kind == HINGE:
            tips.append(np.cross(actuated.axis, start - actuated.anchor))
        else:
            tips.append(actuated.axis)
        units.append((joint - start) / np.linalg.norm(joint - start))
    return np.array(tips), np.array(units)


def _housing_gradient(params, poses, masses, step=1e-6):
    """
    Return d U_l / d X (N, 6) of the legs' weight less the lumped share's (central differences).

    A leg whose housing does not extend (the Gough-Stewart's cylinder): the housing is a rigid
    body hanging on the base-side joint A, its centre a = f |B - A| from A along the leg at the
    pose (as the mechanism's leg body places it), a held fixed.  A rigid leg on a slider or a
    crank's tip: its centre at the fraction f of its segment.  The lumped share (what
    ``weight_gradient`` holds) is f m at B.
    """
    gradient = np.zeros((len(poses), 6))
    fraction = masses.leg_com_fraction

    def potential(pose, arms):
        total = 0.0
        for c, chain in enumerate(params.architecture.mechanism(params, pose)):
            leg = next(body for body in chain.bodies if body.carries == LEG_BODY)
            start, joint = leg.segment
            unit = (joint - start) / np.linalg.norm(joint - start)
            if params.model == 'gough_stewart':
                centre = start + arms[c] * unit
            else:  # a rigid leg on the slider (crank): its fraction
                centre = start + fraction * (joint - start)
            total -= masses.leg_mass * (centre - fraction * joint) @ np.asarray(masses.gravity)
        return total

    for n, pose in enumerate(poses):
        arms = [
            fraction * np.linalg.norm(np.diff(chain.bodies[0].segment, axis=0))
            for chain in params.architecture.mechanism(params, pose)
        ]
        for k in range(6):
            delta = np.zeros(6)
            delta[k] = step
            gradient[n, k] = (
                potential(pose + delta, arms) - potential(pose - delta, arms)
            ) / (2 * step)
    return gradient


@pytest.mark.parametrize('model', ALL_MODELS)
@pytest.mark.parametrize('mode', list(MeasuringMode))
def test_moving_parts_weight_is_held_by_virtual_work(model, mode):
    params, poses = _machine(model, n=6)
    n = len(poses)
    released = np.arange(n) % 6
    loads = static_loads(params, poses, MOVING, mode, released)
    arch = params.architecture
    jacobian = arch.legs(arch.chains(params), poses).pose_jacobian()
    link_row = np.zeros((n, 6))
    link_row[:, :3] = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    held = np.einsum('ncx,nc->nx', jacobian, loads.thrust) - loads.link[:, None] * link_row
    numeric = _moving_potential_gradient(params, poses, MOVING)
    numeric += _housing_gradient(params, poses, MOVING)
    # The drives and the link hold the platform's weights and the parts' potential gradient.
    np.testing.assert_allclose(
        held, weight_gradient(params, poses, MOVING) + numeric, atol=1e-5 * 9.81 * 3.0
    )
    if mode == MeasuringMode.PASSIVE_ACTUATOR:
        assert np.all(loads.thrust[np.arange(n), released] == 0.0), 'the released drive is free'
    # The leg carries the drive's thrust less the parts' weight along their motion at a held
    # pose: a slider's, a crank's, not a rod's.
    with_reading, _ = arch.actuator_mass_motion(params, poses)
    along = -MOVING.actuator_moving_mass * with_reading @ np.asarray(MOVING.gravity)
    if model == 'gough_stewart':
        # The housing between the drive and the leg's spring: its axial weight is the spring's.
        along += MOVING.leg_mass * _leg_units(params, poses) @ np.asarray(MOVING.gravity)
    if model != 'gough_stewart':
        # The leg's base-side share across the leg pushes the slider (crank): the drive holds
        # it.
        share = (1.0 - MOVING.leg_com_fraction) * MOVING.leg_mass
        for k, pose in enumerate(poses):
            tips, units = _base_side_motion(params, pose)
            across = tips - np.sum(tips * units, axis=1)[:, None] * units
            along[k] -= share * across @ np.asarray(MOVING.gravity)
    lever = np.linalg.norm(jacobian[:, :, :3], axis=2)
    np.testing.assert_allclose(
        loads.chains, (loads.thrust - along) * lever, rtol=1e-12, atol=1e-9
    )
    np.testing.assert_allclose(loads.reading_loads, loads.chains * lever, rtol=1e-12)
    if mode == MeasuringMode.PASSIVE_ACTUATOR and model != 'gough_stewart':
        # The released slider's or crank's weight along its motion is its leg's load.
        free = loads.chains[np.arange(n), released]
        assert np.all(np.abs(free) > 0.1)


@pytest.mark.parametrize('model', ALL_MODELS)
def test_without_moving_mass_the_loads_are_unchanged(model):
    params, poses = _machine(model, n=6)
    released = np.arange(6)
    for mode in MeasuringMode:
        plain = static_loads(params, poses, MASSES, mode, released)
        zero = static_loads(
            params, poses, replace(MASSES, actuator_moving_mass=0.0), mode, released
        )
        moving = static_loads(params, poses, MOVING, mode, released)
        for name in ('thrust', 'chains', 'link', 'reading_loads'):
            assert np.array_equal(getattr(plain, name), getattr(zero, name))
        if mode == MeasuringMode.PASSIVE_ACTUATOR:
            assert not np.allclose(moving.reading_loads, plain.reading_loads, atol=1e-3)
        if mode == MeasuringMode.LVDT and model != 'gough_stewart':
            # Six holding drives hold the sliders' (cranks') weight: the legs do not see it.
            np.testing.assert_allclose(moving.reading_loads, plain.reading_loads, atol=1e-9)
            assert not np.allclose(moving.thrust, plain.thrust, atol=1e-3)
    pose_load, reading_load = actuator_weight_loads(params, poses, MASSES)
    assert np.all(pose_load == 0.0) and np.all(reading_load == 0.0)


def test_mass_model_reads_the_actuators_moving_mass(tmp_path):
    from hexacal_msgs_py.physical_file import default_physical

    path = tmp_path / 'physical.yaml'
    path.write_text('platform: {mass: 20}\nlegs: {mass: 2}\n')
    assert MassModel.load(path).actuator_moving_mass == 0.0, 'mass keys only: as before'
    path.write_text('platform: {mass: 20}\nactuators: {moving_mass: 2.5}\n')
    assert MassModel.load(path).actuator_moving_mass == 2.5
    shipped = default_physical('hexa_slide')
    assert MassModel.from_physical(shipped).actuator_moving_mass == shipped.actuator_moving_mass
    assert shipped.actuator_moving_mass > 0.0
    with pytest.raises(ValueError, match='actuator_moving_mass'):
        MassModel(actuator_moving_mass=-1.0)


@pytest.mark.parametrize('model', MODELS)
def test_a_force_on_the_released_actuator_is_held_by_the_others_and_the_link(model):
    params, poses = _machine(model)
    released = np.arange(len(poses)) % 6
    unit = released_force_loads(params, poses, released)
    rows = np.arange(len(poses))
    np.testing.assert_array_equal(unit.thrust[rows, released], 1.0)
    # No weight: J^T tau - T j_L = 0 with the released actuator pushing 1 N along +lambda.
    arch = params.architecture
    jacobian = np.array(arch.legs(arch.chains(params), poses).pose_jacobian())
    link_row = np.zeros((len(poses), 6))
    link_row[:, :3] = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    balance = np.einsum('ncx,nc->nx', jacobian, unit.thrust) - unit.link[:, None] * link_row
    np.testing.assert_allclose(balance, 0.0, atol=1e-9 * np.abs(unit.link).max())
    assert np.abs(unit.link).min() > 0.0  # the link takes part of it at every posture
    leg_factor = np.linalg.norm(jacobian[:, :, :3], axis=2)
    np.testing.assert_allclose(unit.reading_loads, unit.thrust * leg_factor**2)
    with pytest.raises(InvalidMeasurementError, match='released chains'):
        released_force_loads(params, poses, released[:-1])
