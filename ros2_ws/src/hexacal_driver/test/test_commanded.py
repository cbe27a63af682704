"""
The driver's commanded mode, ROS-free.

Trajectory checks, bounded-speed following, the link's constraint, and the executor's rules
(core/walk/execution.py) walking a plan on it to a calibration.
"""

from __future__ import annotations

import math

from hexacal_driver.plan import machine_workspace
from hexacal_driver.simulation import (
    check_trajectory,
    CommandFollower,
    device_constrained_pose,
    MOVING,
    SensorSimulator,
    STILL,
    TrajectoryPoint,
)
from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.device import fixed_point
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
from hexacal_identify.core.planning.planner import plan_postures
from hexacal_identify.core.walk.execution import ExecutionSettings, PlanExecution
from hexacal_identify.core.walk.execution import ExecutionState as State
import numpy as np
import pytest

L = 0.75
GS = 'gough_stewart'
SLIDERS = tuple(f'slider_{i}' for i in range(1, 7))
TRUE = default_parameters()
HOME = np.array([0.0, 0.0, -L, 0.0, 0.0, 0.0])


def _points(*points):
    return [(list(positions), time_s) for positions, time_s in points]


# --------------------------------------------------------------------------- commands


def test_a_trajectory_is_reordered_to_the_machine_joints():
    names = list(reversed(SLIDERS))
    checked, problem = check_trajectory(
        names, _points(([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], 1.0)), SLIDERS, (0.0, 0.9)
    )
    assert problem is None
    np.testing.assert_array_equal(checked[0].positions, [0.6, 0.5, 0.4, 0.3, 0.2, 0.1])
    assert checked[0].time_from_start_s == 1.0


@pytest.mark.parametrize(
    'names, points, problem',
    [
        (
            [f'leg_{i}' for i in range(1, 7)],
            [([0.1] * 6, 1.0)],
            "are not this machine's actuators",
        ),
        (list(SLIDERS[:5]), [([0.1] * 5, 1.0)], 'missing'),
        ([*SLIDERS[:5], 'slider_1'], [([0.1] * 6, 1.0)], 'joint names repeat'),
        ([], [], 'no joint names'),
        (list(SLIDERS), [], 'empty trajectory'),
        (list(SLIDERS), [([0.1] * 5, 1.0)], 'point 0 has 5 positions for 6 joints'),
        (list(SLIDERS), [([0.1] * 5 + [math.nan], 1.0)], 'non-finite'),
        (list(SLIDERS), [([0.1] * 6, 1.0), ([0.2] * 6, 1.0)], 'is not after that of point 0'),
        (list(SLIDERS), [([0.1] * 6, -1.0)], 'negative'),
        (
            list(SLIDERS),
            [([0.1] * 5 + [0.95], 1.0)],
            'outside the actuator stroke [0, 0.9] m: slider_6 0.95 m',
        ),
    ],
)
def test_bad_commands_are_rejected_with_the_reason(names, points, problem):
    checked, reason = check_trajectory(names, _points(*points), SLIDERS, (0.0, 0.9))
    assert checked == [] and problem in reason


def test_the_follower_moves_at_bounded_speed_and_respects_a_slower_time_from_start():
    follower = CommandFollower(TRUE, HOME, 0.1, L)
    start = follower.setpoints.copy()
    target = start + np.array([0.05, -0.02, 0.0, 0.01, 0.0, 0.0])
    end = follower.command(10.0, [TrajectoryPoint(target, 0.1)])  # asks for 0.5 m/s: too fast
    assert end == pytest.approx(10.5)  # 0.05 m at 0.1 m/s
    np.testing.assert_allclose(follower.setpoints_at(10.25), start + 0.5 * (target - start))
    assert follower.sample(10.25).phase == MOVING
    assert follower.sample(10.6).phase == STILL
    np.testing.assert_allclose(follower.setpoints_at(11.0), target)
    slow = follower.command(20.0, [TrajectoryPoint(start, 2.0)])  # slower than the limit: 2 s
    assert slow == pytest.approx(22.0)
    # A new trajectory replaces the one followed, from where the setpoints are.
    follower.command(21.0, [TrajectoryPoint(target, 0.1)])
    np.testing.assert_allclose(follower.setpoints_at(21.0), start + 0.5 * (target - start))


def test_multi_point_trajectories_go_through_every_point():
    follower = CommandFollower(TRUE, HOME, 1.0, L)
    start = follower.setpoints.copy()
    middle, end = start + 0.01, start + 0.03
    follower.command(0.0, [TrajectoryPoint(middle, 1.0), TrajectoryPoint(end, 3.0)])
    np.testing.assert_allclose(follower.setpoints_at(1.0), middle)
    np.testing.assert_allclose(follower.setpoints_at(2.0), start + 0.02)
    assert follower.end_time_s == pytest.approx(3.0)


# --------------------------------------------------------------------------- the measuring link


def _upright(params):
    """
    Return a Gough-Stewart machine reflected z -> -z (upright, for the standing device).

    Upright, for the standing device.
    """
    from hexacal_identify.core.architectures.gough_stewart import GoughStewartParameters

    mirror = np.diag([1.0, 1.0, -1.0])
    return GoughStewartParameters.from_parts(
        params.base_points @ mirror, params.platform_points @ mirror, params.leg_offsets
    )


@pytest.mark.parametrize('model, mount', [(None, 'hanging'), (GS, 'hanging'), (GS, 'standing')])
def test_the_link_holds_the_platform_on_its_sphere_and_the_readings_are_the_true_machine(
    model, mount
):
    from hexacal_identify.core.machine.postures import sample_poses

    truth = default_parameters(model)
    nominal = nominal_set(2, seed=0, model=model)
    poses = sample_poses(truth, 5, np.random.default_rng(1), 'sphere', machine_workspace(truth, L))
    if (
        mount == 'standing'
    ):  # the same machine and postures reflected: (x, y, -z, -theta, -psi, phi)
        truth, nominal = _upright(truth), _upright(nominal)
        poses[:, [2, 3, 4]] *= -1.0
    exact = inverse_kinematics(truth, poses)
    for pose, sliders in zip(poses, exact):
        # Setpoints the true machine reaches on the sphere: that pose, exactly.
        found, readings = device_constrained_pose(truth, sliders, pose + 1e-3, L, mount)
        np.testing.assert_allclose(found, pose, atol=1e-9)
        np.testing.assert_allclose(readings, sliders, atol=1e-12)
    # Setpoints from the nominal model: strained, but on the sphere and consistent with the truth.
    commanded = inverse_kinematics(nominal, poses)
    for pose, setpoints in zip(poses, commanded):
        found, readings = device_constrained_pose(truth, setpoints, pose, L, mount)
        assert abs(np.linalg.norm(found[:3]) - L) < 1e-12
        assert (found[2] < 0) == (mount == 'hanging')
        np.testing.assert_allclose(readings, inverse_kinematics(truth, found[None])[0], atol=1e-12)
        assert 1e-6 < np.abs(readings - setpoints).max() < 0.01  # micrometres to millimetres


# --------------------------------------------------------------------------- the executor on it


def _walk(model, postures, noise=1e-5, seed=0, **settings):
    """Executor rules + commanded machine + a collector that measures after 0.5 s of stillness."""
    truth, nominal = default_parameters(model), nominal_set(2, seed=0, model=model)
    plan = plan_postures(nominal, postures, n_candidates=400, cost='sphere-fixed', seed=seed).plan
    stroke = default_stroke(nominal)
    targets = check_plan(nominal, plan.poses, plan.kinds, stroke, L, path_step_m=0.02)
    execution = PlanExecution(
        nominal,
        plan.poses,
        plan.kinds,
        targets,
        ExecutionSettings(max_actuator_speed_m_s=0.5, settle_s=0.3, **settings),
        stroke,
        L,
    )
    follower = CommandFollower(truth, np.concatenate([fixed_point(L), np.zeros(3)]), 1.0, L)
    sensors = SensorSimulator(NoiseModel(noise, noise), np.random.default_rng(seed))
    t, still_since, samples, postures_seen = 0.0, None, [], []
    while execution.state not in (State.DONE, State.ABORTED) and t < 300.0:
        sample = follower.sample(t)
        reading = sensors.read(sample)
        execution.on_actuators(t, reading.actuators_m)
        execution.on_inclinometer(t, reading.alpha_rad, reading.beta_rad)
        if sample.phase == STILL:
            if still_since is None:
                still_since, samples = t, []
            samples.append(
                [*reading.actuators_m, reading.alpha_rad, reading.beta_rad, reading.phi_rad]
            )
            if t - still_since >= 0.5 and len(samples) > 0:
                posture = np.mean(samples[-30:], axis=0)
                postures_seen.append(posture)
                execution.on_posture(t, posture[:6])
                still_since = math.inf  # one posture per stop
        else:
            still_since = None
        commands = execution.start(t) if execution.state == State.WAITING else execution.step(t)
        for command in commands:
            follower.command(
                t,
                [
                    TrajectoryPoint(point, time_s)
                    for point, time_s in zip(command.points, command.times)
                ],
            )
        t += 0.01
    return execution, postures_seen, truth, nominal, plan


@pytest.mark.slow
@pytest.mark.parametrize('model', [None, GS])
def test_the_executor_walks_a_plan_on_the_commanded_machine_to_a_good_calibration(model):
    from hexacal_identify.calibration_steps.calibration_run import calibrate
    from hexacal_msgs_py.readings import PostureReading

    execution, seen, truth, nominal, plan = _walk(model, 16)
    assert execution.state == State.DONE and execution.measured == 16 and not execution.skipped
    fixed = [i for i, kind in enumerate(plan.kinds) if kind == 'fixed']
    assert fixed and all(execution.outcomes[i].corrections >= 1 for i in fixed)
    angles = np.array(seen)[:, 6:8]
    at_fixed_point = np.all(np.abs(angles) <= 5e-5, axis=1)  # what identify counts as fixed
    assert at_fixed_point.sum() >= len(fixed)
    readings = [PostureReading.from_values(10**9 * (i + 1), list(p)) for i, p in enumerate(seen)]
    result = calibrate(nominal, readings, link_length=L)
    assert result.reason == 'converged'
    # 16 postures for 54 parameters and 10 um noise: each parameter as close to the truth as the
    # fit says (5 of its standard deviations), and all of them closer than the nominal's worst.
    error = np.abs(result.parameters.vector - truth.vector)
    assert np.all(error <= 5.0 * result.std), np.max(error / result.std)
    assert error.max() < 0.5 * np.abs(nominal.vector - truth.vector).max()


@pytest.mark.slow
def test_fixed_positions_that_never_converge_are_skipped_after_max_corrections():
    execution, *_ = _walk(None, 8, fixed_tolerance_rad=1e-7, max_corrections=1)
    skipped = execution.skipped
    assert skipped and all(o.kind == 'fixed' for o in skipped)
    assert all(
        o.reason.startswith('fixed position not reached after 1 corrections') for o in skipped
    )
    assert execution.measured == 8 - len(skipped)
