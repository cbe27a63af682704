"""The driver's simulated device with defects and a turn about its link axis (ROS-free)."""

from __future__ import annotations

from dataclasses import replace
import math

from hexacal_driver.plan import generated_plan, load_plan, plan_document, PlanError, save_plan
from hexacal_driver.simulation import (
    device_true_poses,
    DWELLING,
    exact_readings,
    PlanWalker,
    SensorSimulator,
    WalkSample,
)
from hexacal_identify.core import table1_parameters
from hexacal_identify.core.machine.device import device_position, DeviceDefects, DeviceModel
from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
import numpy as np
import pytest

DEFECTS = DeviceDefects.parse('dL=5e-4,alpha0=2e-4,beta0=-1e-4,gamma=1e-4,phi0=3e-4')
L = 0.75


@pytest.fixture(scope='module')
def plan():
    return generated_plan('mixed', table1_parameters(), 8, seed=3)


@pytest.mark.parametrize('turn', [0.0, math.pi, math.pi / 2, -math.pi / 2])
@pytest.mark.parametrize('mount', ['hanging', 'standing'])
def test_readings_are_the_cores_simulated_measurements(plan, turn, mount):
    params = table1_parameters()
    if mount == 'standing':
        plan = replace(plan, poses=plan.poses * np.array([1, 1, -1, 1, 1, 1]), mount=mount)
    poses = device_true_poses(plan.poses, plan.kinds, L, DEFECTS, mount, turn)
    core = simulate_measurements(
        params,
        poses,
        np.array(plan.kinds),
        DeviceModel(L, mount),
        NoiseModel(0.0, 0.0),
        defects=DEFECTS,
        device_turn=turn,
    )
    walker = PlanWalker(params, poses, 1.0, 1.0) if mount == 'hanging' else None
    for i in range(len(poses)):
        sliders = walker.posture_actuators[i] if walker else core.actuator_positions[i]
        read = exact_readings(poses[i], sliders, mount, DEFECTS, turn)
        assert read.alpha_rad == pytest.approx(core.inclinometer[i, 0], abs=1e-14)
        assert read.beta_rad == pytest.approx(core.inclinometer[i, 1], abs=1e-14)
        assert read.phi_rad == pytest.approx(core.rotary[i], abs=1e-14)
        np.testing.assert_allclose(
            read.actuators_m, core.actuator_positions[i], rtol=0, atol=1e-12
        )
    # The link fits: the readings give the platform position back through the defect model.
    back = device_position(
        core.inclinometer[:, 0],
        core.inclinometer[:, 1],
        L,
        DEFECTS,
        mount,
        np.full(len(poses), turn),
    ).position
    np.testing.assert_allclose(back, poses[:, :3], rtol=0, atol=1e-12)


def test_true_poses_lie_on_the_true_sphere_and_fixed_ones_read_zero(plan):
    poses = device_true_poses(plan.poses, plan.kinds, L, DEFECTS, 'hanging', math.pi)
    np.testing.assert_allclose(np.linalg.norm(poses[:, :3], axis=1), L + DEFECTS.dL, atol=1e-12)
    np.testing.assert_array_equal(poses[:, 3:], plan.poses[:, 3:])
    for pose, kind in zip(poses, plan.kinds):
        if kind == 'fixed':
            read = exact_readings(pose, np.zeros(6), 'hanging', DEFECTS, math.pi)
            assert abs(read.alpha_rad) < 1e-12 and abs(read.beta_rad) < 1e-12
    # Reversed, the zero point is elsewhere than in the normal mounting (alpha0, beta0 flip).
    fixed = [i for i, kind in enumerate(plan.kinds) if kind == 'fixed']
    normal = device_true_poses(plan.poses, plan.kinds, L, DEFECTS, 'hanging', 0.0)
    assert np.linalg.norm(normal[fixed, :3] - poses[fixed, :3], axis=1).min() > 1e-4


def test_an_ideal_normally_mounted_device_reads_as_before(plan):
    assert device_true_poses(plan.poses, plan.kinds, L) is not plan.poses
    np.testing.assert_array_equal(device_true_poses(plan.poses, plan.kinds, L), plan.poses)
    sample = WalkSample(plan.poses[0], np.zeros(6), 0, DWELLING, 0)
    read = SensorSimulator(NoiseModel(0.0, 0.0), np.random.default_rng(0)).read(sample)
    assert read.phi_rad == plan.poses[0][5]  # unwrapped, bit for bit
    # Turned, an ideal device reads the turned frame; the rotary reads phi - turn.
    turned = SensorSimulator(NoiseModel(0.0, 0.0), np.random.default_rng(0)).read(sample, math.pi)
    assert turned.alpha_rad == pytest.approx(-read.alpha_rad, abs=1e-12)
    assert turned.beta_rad == pytest.approx(-read.beta_rad, abs=1e-12)
    expected_phi = (plan.poses[0][5] - math.pi + math.pi) % (2 * math.pi) - math.pi
    assert turned.phi_rad == pytest.approx(expected_phi, abs=1e-12)


def test_plan_files_keep_per_posture_turns(plan, tmp_path):
    turns = (None, math.pi, None, -math.pi / 2, None, None, 0.0, None)
    turned = replace(plan, device_turns=turns)
    save_plan(tmp_path / 'turned.yaml', turned)
    back = load_plan(tmp_path / 'turned.yaml')
    assert back.device_turns == turns
    np.testing.assert_array_equal(back.poses, plan.poses)
    assert back.device_turn(1) == math.pi and back.device_turn(0, 0.5) == 0.5
    assert back.device_turn(6, 0.5) == 0.0  # the plan's own 0 wins over the parameter
    assert plan_document(back)['postures'][1]['device_turn'] == math.pi
    assert 'device_turn' not in plan_document(back)['postures'][0]
    assert (
        '1 with a device turn' not in back.describe() and '3 with a device turn' in back.describe()
    )
    # A plan without turns is written as before and has none.
    save_plan(tmp_path / 'plain.yaml', plan)
    assert 'device_turn' not in (tmp_path / 'plain.yaml').read_text()
    assert load_plan(tmp_path / 'plain.yaml').device_turns == ()
    assert replace(plan, device_turns=(None,) * len(plan)).device_turns == ()


@pytest.mark.parametrize(
    'value, text',
    [
        ('7.0', 'device_turn must be a finite angle within +-2 pi rad'),
        ('.nan', 'device_turn must be a finite angle'),
        ('pi', 'device_turn must be a number of rad'),
        ('null', 'device_turn must be a number of rad, got null'),
        ('true', 'device_turn must be a number of rad'),
    ],
)
def test_bad_turns_in_plan_files_are_named(plan, tmp_path, value, text):
    path = tmp_path / 'bad.yaml'
    save_plan(path, plan)
    lines = path.read_text().splitlines()
    index = next(i for i, line in enumerate(lines) if line.startswith('  - '))
    lines[index] = lines[index][:-1] + f', device_turn: {value}}}'
    path.write_text('\n'.join(lines) + '\n')
    with pytest.raises(PlanError, match='posture 0: ' + text.replace('+', r'\+')):
        load_plan(path)
