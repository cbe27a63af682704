"""The standing the release checks rehearse from: where the device measured the platform."""

from __future__ import annotations

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.device import fixed_point, inclinometer_angles
from hexacal_identify.core.machine.kinematics import inverse_kinematics, measured_pose
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.release_plan import measured_machine, Rehearser
from hexacal_identify.core.planning.plan_check import default_stroke, plan_targets
from hexacal_identify.core.walk.execution import PlanExecution
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.standing import estimate_pose
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')


def _case(model: str, seed: int = 4):
    """Return the true machine, a nominal of Table 2 set 2, the link length and two poses."""
    truth = default_parameters(model)
    workspace = truth.architecture.default_workspace()
    poses = np.array(sample_poses(truth, 2, np.random.default_rng(seed), 'sphere', workspace))
    return truth, nominal_set(2, seed=seed, model=model), workspace.link_length, poses


@pytest.mark.parametrize('model', MODELS)
def test_the_measured_pose_is_where_the_device_says_and_the_estimate_is_not(model):
    truth, nominal, length, poses = _case(model)
    actuators = inverse_kinematics(truth, poses)
    centre = np.concatenate([fixed_point(length), np.zeros(3)])
    estimates = np.array([
        estimate_pose(nominal, a, [p, centre], length, 'hanging')[0]
        for a, p in zip(actuators, poses)
    ])
    measured = measured_pose(nominal, actuators, poses[:, :3], estimates)
    np.testing.assert_array_equal(measured[:, :3], poses[:, :3])
    # Millimetres of geometry put the model's forward kinematics millimetres away.
    assert np.max(np.abs(estimates[:, :3] - poses[:, :3])) > 1e-3
    # On the true machine's own model the angles fitted are the pose's.
    exact = measured_pose(truth, actuators, poses[:, :3], estimates)
    np.testing.assert_allclose(exact, poses, atol=1e-10)


@pytest.mark.parametrize('model', MODELS)
def test_each_rehearsed_machine_stands_at_the_measured_pose_reading_what_was_measured(model):
    truth, nominal, length, poses = _case(model)
    pose, actuators = poses[0], inverse_kinematics(truth, poses[:1])[0]
    arch = nominal.architecture
    rehearser = Rehearser(nominal, length, default_stroke(nominal), 0.005, 0.01)
    drawn = rehearser.machines
    assert rehearser.stand_measured(pose, actuators)
    assert len(rehearser.machines) == len(drawn) and rehearser.standing is not None
    standing = rehearser.standing.poses  # at the position, each its own angles
    np.testing.assert_array_equal(standing[:, :3], np.repeat(pose[None, :3], len(drawn), 0))
    assert np.ptp(standing[:, 3:], axis=0).max() > 1e-3
    np.testing.assert_array_equal(rehearser.standing.actuators[-1], actuators)
    for drawn_machine, added, at in zip(drawn, rehearser.machines, standing):
        zero_shifts = np.array([arch.actuator_zero_shift(drawn_machine, c)[1] for c in range(6)])
        np.testing.assert_allclose(inverse_kinematics(added, at[None])[0], actuators, atol=1e-12)
        change = added.vector - drawn_machine.vector  # only the actuator zeros moved
        along, *_ = np.linalg.lstsq(zero_shifts.T, change, rcond=None)
        np.testing.assert_allclose(zero_shifts.T @ along, change, atol=1e-12)
    if model == 'hexa_slide':  # a pose its legs cannot reach: no machine stands there
        assert measured_machine(nominal, pose + np.array([0, 0, 5.0, 0, 0, 0]), actuators) is None


def test_the_executor_measures_its_standing_with_the_inclinometer_while_it_reads():
    truth, nominal, length, poses = _case('hexa_slide')
    stroke = default_stroke(nominal)
    targets, _ = plan_targets(nominal, poses, ['sphere'] * 2, stroke, length)
    settings = ExecutionSettings(settle_s=0.2, wait_for_posture=False, path_step_m=0.0)
    execution = PlanExecution(nominal, poses, ['sphere'] * 2, targets, settings, stroke, length,
                              released=[2, 2])
    actuators = inverse_kinematics(truth, poses[:1])[0]
    execution.on_actuators(0.0, actuators)
    estimate = execution._estimate()
    assert estimate is not None and np.linalg.norm(estimate[:3] - poses[0, :3]) > 1e-3
    assert execution._measured_standing(estimate) is None  # no inclinometer yet
    alpha, beta = inclinometer_angles(poses[:1, :3])
    execution.on_inclinometer(0.0, float(alpha[0]), float(beta[0]))
    standing = execution._measured_standing(estimate)
    assert standing is not None
    np.testing.assert_allclose(standing[:3], poses[0, :3], atol=1e-12)
    execution.on_actuators(5.0, actuators)  # the inclinometer fell silent 5 s ago
    assert execution._measured_standing(estimate) is None
