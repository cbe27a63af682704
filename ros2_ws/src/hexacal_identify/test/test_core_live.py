"""
Core/live.py: the pose of live readings and actuator targets with the stroke check.

The pose of live readings (FK on the guess's branch) and actuator targets with the stroke check.
"""

from hexacal_identify.core.architectures import architecture, ARCHITECTURES
from hexacal_identify.core.errors import ForwardKinematicsError, UnreachablePoseError
from hexacal_identify.core.machine.kinematics import forward_kinematics, inverse_kinematics
from hexacal_identify.core.machine.live import (
    actuator_targets,
    default_stroke,
    home_pose,
    OutOfStrokeError,
    solve_pose,
)
from hexacal_identify.core.machine.postures import sample_poses
import numpy as np
import pytest


def test_home_pose_is_the_fixed_point_level():
    assert np.array_equal(home_pose(), [0, 0, -0.75, 0, 0, 0])
    assert np.array_equal(home_pose(0.5, 'standing'), [0, 0, 0.5, 0, 0, 0])


@pytest.mark.slow
@pytest.mark.parametrize('model', sorted(ARCHITECTURES))
def test_solve_pose_from_the_workspace_centre_over_the_workspace(model):
    arch = architecture(model)
    params = arch.default_parameters()
    poses = sample_poses(params, 60, np.random.default_rng(5), 'sphere', arch.default_workspace())
    readings = inverse_kinematics(params, poses)
    for pose, reading in zip(poses, readings):
        assert np.allclose(solve_pose(params, reading, home_pose()), pose, atol=1e-10, rtol=0)
    # Far poses are beyond plain Newton's branch check from the centre: the continuation reaches
    # them.
    far = np.argmax(np.linalg.norm(poses[:, :2], axis=1))
    direct = forward_kinematics(params, readings[far][None], home_pose()[None])
    assert not direct.converged[0] or np.linalg.norm(poses[far, :2]) < 0.05


def test_solve_pose_tracks_from_the_previous_pose():
    params = architecture().default_parameters()
    pose = np.array([0.1, -0.05, -0.74, 0.1, 0.05, -0.2])
    reading = inverse_kinematics(params, pose[None])[0]
    assert np.allclose(solve_pose(params, reading + 1e-6, pose), pose, atol=1e-4)


def test_solve_pose_failure_is_named():
    params = architecture().default_parameters()
    with pytest.raises(ForwardKinematicsError, match="no pose on the guess's branch"):
        solve_pose(params, [5.0] * 6, home_pose())
    with pytest.raises(ForwardKinematicsError, match='non-finite'):
        solve_pose(params, [0.2, 0.2, 0.2, 0.2, 0.2, np.nan], home_pose())
    with pytest.raises(ForwardKinematicsError, match='the guess itself is unreachable'):
        solve_pose(params, [5.0] * 6, [3.0, 0, -0.7, 0, 0, 0])


@pytest.mark.parametrize('model', sorted(ARCHITECTURES))
def test_actuator_targets_and_the_stroke(model):
    arch = architecture(model)
    params = arch.default_parameters()
    assert default_stroke(params) == tuple(arch.default_workspace().actuator_stroke_m)
    pose = sample_poses(params, 1, np.random.default_rng(2), 'sphere', arch.default_workspace())[0]
    expected = inverse_kinematics(params, pose[None])[0]
    assert np.array_equal(actuator_targets(params, pose), expected)
    # A tighter stroke refuses the same pose, naming the actuators outside it.
    high = float(np.sort(expected)[-2])  # the largest reading is above, the others not
    with pytest.raises(OutOfStrokeError) as refused:
        # The low end below every reading (a crank's angles are negative as well).
        actuator_targets(params, pose, (min(0.0, float(expected.min())), high))
    name = params.layout.actuator_names[int(np.argmax(expected))]
    assert refused.value.reason == 'outside-stroke' and name in str(refused.value)
    assert refused.value.indices == [int(np.argmax(expected))]
    assert isinstance(refused.value, UnreachablePoseError)  # a refused target either way


def test_actuator_targets_of_an_unreachable_pose():
    params = architecture('hexa_slide').default_parameters()
    with pytest.raises(UnreachablePoseError) as refused:
        actuator_targets(params, [3.0, 0.0, -0.7, 0.0, 0.0, 0.0])
    assert refused.value.reason == 'unreachable-pose'
