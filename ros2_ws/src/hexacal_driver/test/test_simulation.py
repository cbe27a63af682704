"""Unit tests of the driver's ROS-free parts: plan walking, sensor readings, posture plans."""

from __future__ import annotations

import math
from pathlib import Path

from hexacal_driver.plan import (
    check_reachable,
    FIXED_PLAN,
    generated_plan,
    load_plan,
    MIXED_PLAN,
    PlanError,
    PosturePlan,
    RANDOM_PLAN,
    resolve_plan,
    save_plan,
)
from hexacal_driver.simulation import (
    DONE,
    DWELLING,
    exact_readings,
    interpolate_pose,
    PlanWalker,
    SensorSimulator,
    SETTLING,
    smooth_step,
)
from hexacal_identify.calibration_steps.calibration_run import calibrate
from hexacal_identify.core.detection.dwell_detector import detect_dwell_postures
from hexacal_identify.core.machine.measurements import (
    FIXED,
    NoiseModel,
    simulate_measurements,
    SPHERE,
)
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
import numpy as np
import pytest

TRUE = table1_parameters()
L = 0.75


@pytest.fixture(scope='module')
def mixed_plan() -> PosturePlan:
    return generated_plan(MIXED_PLAN, TRUE, 20, seed=3)


# --------------------------------------------------------------------------- time law, paths


def test_smooth_step_starts_and_stops_at_rest():
    assert smooth_step(0.0) == 0.0 and smooth_step(1.0) == 1.0
    assert smooth_step(-1.0) == 0.0 and smooth_step(2.0) == 1.0
    h = 1e-6
    assert abs(smooth_step(h) - smooth_step(0.0)) / h < 1e-6  # zero slope at both ends
    assert abs(smooth_step(1.0) - smooth_step(1.0 - h)) / h < 1e-6
    values = [smooth_step(s) for s in np.linspace(0, 1, 101)]
    assert all(b >= a for a, b in zip(values, values[1:]))


def test_interpolated_positions_stay_on_the_link_sphere(mixed_plan):
    start, end = mixed_plan.poses[0], mixed_plan.poses[1]
    assert mixed_plan.kinds[:2] == (SPHERE, SPHERE)
    for s in np.linspace(0, 1, 11):
        pose = interpolate_pose(start, end, s)
        assert np.linalg.norm(pose[:3]) == pytest.approx(L, abs=1e-12)
        assert pose[3:] == pytest.approx(start[3:] + s * (end[3:] - start[3:]))
    assert interpolate_pose(start, end, 0.0) == pytest.approx(start, abs=1e-15)
    assert interpolate_pose(start, end, 1.0) == pytest.approx(end, abs=1e-12)


# --------------------------------------------------------------------------- plan walker


def test_walker_timeline_holds_each_posture_for_dwell_s(mixed_plan):
    walker = PlanWalker(TRUE, mixed_plan.poses, settle_s=0.4, dwell_s=1.0)
    assert walker.lap_duration_s == pytest.approx(20 * 1.4)
    first = walker.sample(0.0)
    assert first.phase == SETTLING and first.posture_index == 0
    assert first.pose == pytest.approx(mixed_plan.poses[0])  # starts at the first posture
    for index in (0, 1, 7, 19):
        for into in (0.41, 0.9, 1.39):
            sample = walker.sample(index * 1.4 + into)
            assert sample.phase == DWELLING and sample.posture_index == index
            assert sample.pose == pytest.approx(mixed_plan.poses[index])
            assert sample.actuators == pytest.approx(walker.posture_actuators[index])
    moving = walker.sample(1.4 + 0.2)
    assert moving.phase == SETTLING and moving.posture_index == 1
    assert not np.allclose(moving.actuators, walker.posture_actuators[0])
    assert not np.allclose(moving.actuators, walker.posture_actuators[1])
    done = walker.sample(walker.lap_duration_s + 5.0)
    assert done.phase == DONE and done.posture_index == 19
    assert done.pose == pytest.approx(mixed_plan.poses[19])


def test_walker_loops_back_to_the_first_posture(mixed_plan):
    walker = PlanWalker(TRUE, mixed_plan.poses, settle_s=0.5, dwell_s=1.0, loop=True)
    lap = walker.lap_duration_s
    moving = walker.sample(lap + 0.25)
    assert moving.phase == SETTLING and moving.lap == 1 and moving.posture_index == 0
    assert not np.allclose(moving.pose, mixed_plan.poses[0])  # on its way back from the last
    back = walker.sample(lap + 0.75)
    assert back.phase == DWELLING and back.lap == 1
    assert back.pose == pytest.approx(mixed_plan.poses[0])


def test_walker_sliders_move_smoothly(mixed_plan):
    rate_hz = 100.0
    walker = PlanWalker(TRUE, mixed_plan.poses[:6], settle_s=0.5, dwell_s=1.0)
    times = np.arange(0.0, walker.lap_duration_s, 1.0 / rate_hz)
    sliders = np.array([walker.sample(t).actuators for t in times])
    steps = np.abs(np.diff(sliders, axis=0)).max(axis=1)
    distances = np.abs(np.diff(walker.posture_actuators, axis=0)).max(axis=1)
    # Peak quintic speed is 1.875 x the mean: a step is at most ~2 x (distance / samples).
    assert steps.max() <= 2.2 * distances.max() / (0.5 * rate_hz)
    dwelling = np.array([walker.sample(t).phase == DWELLING for t in times])
    assert np.all(steps[dwelling[:-1] & dwelling[1:]] == 0.0)


def test_walker_rejects_unreachable_postures():
    far = np.array([[0.0, 0.0, -3.0, 0.0, 0.0, 0.0]])
    with pytest.raises(Exception, match='unreachable'):
        PlanWalker(TRUE, far, settle_s=0.5, dwell_s=1.0)
    with pytest.raises(ValueError, match='settle_s'):
        PlanWalker(TRUE, np.array([[0.0, 0.0, -L, 0, 0, 0]]), settle_s=0.0, dwell_s=1.0)


# --------------------------------------------------------------------------- sensor readings


def test_exact_readings_match_the_core_measurement_model(mixed_plan):
    sliders = check_reachable(mixed_plan, TRUE)
    expected = simulate_measurements(TRUE, mixed_plan.poses, np.array(mixed_plan.kinds))
    for i, pose in enumerate(mixed_plan.poses):
        reading = exact_readings(pose, sliders[i])
        assert reading.actuators_m == pytest.approx(expected.actuator_positions[i], abs=1e-15)
        assert [reading.alpha_rad, reading.beta_rad] == pytest.approx(
            expected.inclinometer[i], abs=1e-15
        )
        assert reading.phi_rad == pytest.approx(expected.rotary[i], abs=1e-15)
    fixed = [i for i, kind in enumerate(mixed_plan.kinds) if kind == FIXED]
    assert fixed
    for i in fixed:  # the fixed position reads zero on the inclinometer
        reading = exact_readings(mixed_plan.poses[i], sliders[i])
        assert abs(reading.alpha_rad) < 1e-15 and abs(reading.beta_rad) < 1e-15


def test_noise_is_fresh_uniform_and_within_its_half_widths(mixed_plan):
    walker = PlanWalker(TRUE, mixed_plan.poses[:1], settle_s=0.5, dwell_s=1.0)
    sample = walker.sample(1.0)
    exact = exact_readings(sample.pose, sample.actuators)
    sensors = SensorSimulator(
        NoiseModel(actuator_m=1e-5, angle_rad=2e-5), np.random.default_rng(1)
    )
    readings = [sensors.read(sample) for _ in range(4000)]
    actuator_errors = np.array([r.actuators_m - exact.actuators_m for r in readings])
    angle_errors = np.array(
        [
            [r.alpha_rad - exact.alpha_rad, r.beta_rad - exact.beta_rad, r.phi_rad - exact.phi_rad]
            for r in readings
        ]
    )
    assert np.abs(actuator_errors).max() <= 1e-5 and np.abs(angle_errors).max() <= 2e-5
    assert np.abs(actuator_errors).max() > 0.95e-5  # uniform: the edges are reached
    assert np.abs(actuator_errors.mean(axis=0)).max() < 1e-6
    # Uniform on [-h, h] has standard deviation h / sqrt(3).
    assert actuator_errors.std() == pytest.approx(1e-5 / math.sqrt(3), rel=0.05)
    assert len({tuple(e) for e in actuator_errors}) == len(readings)
    quiet = SensorSimulator(NoiseModel(), np.random.default_rng(1)).read(sample)
    assert quiet.actuators_m == pytest.approx(exact.actuators_m, abs=0.0)


def test_walked_plan_gives_postures_that_calibrate_the_machine():
    """ROS-free end to end: walk at 100 Hz, detect postures, identify from nominal set 2."""
    plan = generated_plan(MIXED_PLAN, TRUE, 20, seed=5)
    rate_hz = 100.0
    walker = PlanWalker(TRUE, plan.poses, settle_s=0.4, dwell_s=1.0)
    sensors = SensorSimulator(NoiseModel(1e-5, 1e-5), np.random.default_rng(0))
    times = np.arange(0.0, walker.lap_duration_s, 1.0 / rate_hz)
    values = []
    for t in times:
        reading = sensors.read(walker.sample(t))
        values.append([*reading.actuators_m, reading.alpha_rad, reading.beta_rad, reading.phi_rad])
    stamps, values = (times * 1e9).astype(np.int64), np.array(values)
    postures, detector = detect_dwell_postures(
        {
            'sliders': (stamps, values[:, :6]),
            'inclinometer': (stamps, values[:, 6:8]),
            'encoder': (stamps, values[:, 8:]),
        }
    )
    assert len(postures) == len(plan), detector.dropped
    exact = simulate_measurements(TRUE, plan.poses, np.array(plan.kinds))
    measured = np.array([p.values for p in postures])
    assert np.abs(measured[:, :6] - exact.actuator_positions).max() < 1e-5
    assert np.abs(measured[:, 6:8] - exact.inclinometer).max() < 1e-5
    result = calibrate(nominal_set(2, seed=0), [p.reading for p in postures])
    assert result.reason == 'converged'
    assert np.abs(result.parameters.vector - TRUE.vector).max() < 1e-3


# --------------------------------------------------------------------------- plans


def test_generated_plans_have_the_requested_kinds():
    mixed = generated_plan(MIXED_PLAN, TRUE, 50, seed=0)
    assert len(mixed) == 50 and mixed.counts() == {SPHERE: 38, FIXED: 12}
    assert mixed.kinds[:8] == (SPHERE, SPHERE, SPHERE, FIXED) * 2
    assert mixed.name == 'mixed-50-seed0'
    fixed = generated_plan(FIXED_PLAN, TRUE, 5, seed=0)
    assert np.allclose(fixed.poses[:, :3], [0.0, 0.0, -L]) and set(fixed.kinds) == {FIXED}
    spheres = generated_plan(RANDOM_PLAN, TRUE, 5, seed=0)
    assert np.allclose(np.linalg.norm(spheres.poses[:, :3], axis=1), L)
    again = generated_plan(RANDOM_PLAN, TRUE, 5, seed=0)
    assert np.array_equal(spheres.poses, again.poses)  # seeded
    assert not np.array_equal(generated_plan(RANDOM_PLAN, TRUE, 5, seed=1).poses, spheres.poses)
    with pytest.raises(PlanError, match='positive integer'):
        generated_plan(RANDOM_PLAN, TRUE, 0, seed=0)
    with pytest.raises(PlanError, match="'spiral'"):
        generated_plan('spiral', TRUE, 5, seed=0)


def test_plan_file_round_trips_exactly(tmp_path, mixed_plan):
    path = tmp_path / 'plans' / 'plan.yaml'
    save_plan(path, mixed_plan)
    loaded = load_plan(path)
    assert loaded.name == mixed_plan.name and loaded.link_length == L
    assert np.array_equal(loaded.poses, mixed_plan.poses)
    assert loaded.kinds == mixed_plan.kinds
    assert resolve_plan(str(path), TRUE, 99, 0, L).name == mixed_plan.name


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'bad_plan.yaml'
    path.write_text(text)
    return path


ON_SPHERE_Z = -math.sqrt(L**2 - 0.1**2 - 0.2**2)


@pytest.mark.parametrize(
    'text, message',
    [
        ('plan: [1, 2\n', 'invalid YAML'),
        ('- 1\n', "keys 'plan' and 'postures'"),
        ('plan: {name: p, link_length: 0.75}\n', "'postures' must be a non-empty list"),
        (
            'plan: {name: p}\npostures: [{kind: fixed, pose: [0, 0, -0.75, 0, 0, 0]}]\n',
            'plan.link_length is missing',
        ),
        (
            'plan: {name: p, link_length: 0.75, speed: 2}\npostures: []\n',
            "unknown key(s) ['speed']",
        ),
        (
            'plan: {name: p, link_length: -1}\npostures: [{kind: fixed, pose: [0, 0, 1, 0, 0, '
            '0]}]\n',
            'link_length must be a positive number',
        ),
        (
            'plan: {name: p, link_length: 0.75}\npostures: [{kind: fixed, pose: [0, 0, -0.75]}]\n',
            'posture 0: pose must be 6 numbers',
        ),
        (
            'plan: {name: p, link_length: 0.75}\n'
            'postures: [{kind: flat, pose: [0, 0, -0.75, 0, 0, 0]}]\n',
            "posture 0: kind must be one of ['sphere', 'fixed']",
        ),
        (
            'plan: {name: p, link_length: 0.75}\npostures:\n  - {kind: fixed, pose: [0, 0, -0.75, '
            '0, 0, 0]}\n  - {kind: sphere, pose: [0.1, 0.2, -0.7, 0, 0, 0]}\n',
            f'posture 1: a sphere posture must lie on the link sphere |p| = 0.75 m below O '
            f'(z = {ON_SPHERE_Z!r}',
        ),
        (
            'plan: {name: p, link_length: 0.75}\n'
            'postures: [{kind: fixed, pose: [0.1, 0, -0.75, 0, 0, 0]}]\n',
            'posture 0: a fixed posture must be at [0, 0, -0.75] m',
        ),
        (
            'plan: {name: p, link_length: 0.75}\npostures: [{kind: fixed, pose: [0, 0, -0.75, 0, '
            '0, 4]}]\n',
            'posture 0: phi must be within +-pi rad',
        ),
        (
            'plan: {name: p, link_length: 0.75}\npostures: [{kind: fixed, pose: [0, 0, -0.75, 0, '
            '0, 0], speed: 1}]\n',
            "posture 0: keys must be ['kind', 'pose'], unknown ['speed']",
        ),
    ],
)
def test_bad_plan_files_name_the_problem(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(PlanError) as error:
        load_plan(path)
    assert str(path) in str(error.value)
    assert message in str(error.value)


def test_missing_plan_file_is_a_plan_error(tmp_path):
    with pytest.raises(PlanError, match='cannot read'):
        load_plan(tmp_path / 'absent.yaml')


def test_plans_are_checked_against_the_machine(tmp_path):
    good = (
        f'plan: {{name: p, link_length: 0.75}}\npostures:\n'
        f'  - {{kind: sphere, pose: [0.1, 0.2, {ON_SPHERE_Z!r}, 0.1, -0.1, 0.2]}}\n'
    )
    path = _write(tmp_path, good)
    assert check_reachable(load_plan(path), TRUE).shape == (1, 6)
    with pytest.raises(PlanError, match='differs from the device'):
        resolve_plan(str(path), TRUE, 1, 0, link_length=0.8)
    # A 2 m link puts the platform below where the legs reach (or beyond the slider stroke).
    path.write_text(
        'plan: {name: p, link_length: 2.0}\npostures:\n'
        '  - {kind: fixed, pose: [0.0, 0.0, -0.75, 0.0, 0.0, 0.0]}\n'
    )
    with pytest.raises(PlanError, match='a fixed posture must be at'):
        load_plan(path)
    path.write_text(
        'plan: {name: p, link_length: 2.0}\npostures:\n'
        '  - {kind: fixed, pose: [0.0, 0.0, -0.75, 0.0, 0.0, 0.0]}\n'.replace('-0.75', '-2.0')
    )
    with pytest.raises(PlanError, match=r"plan 'p': posture\(s\) \[0\]"):
        resolve_plan(str(path), TRUE, 1, 0, link_length=2.0)
