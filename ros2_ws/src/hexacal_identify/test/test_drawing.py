"""
Architecture.drawing: the machine at a pose as points and segments.

The machine at a pose as points and segments in the base frame (machine markers).
"""

from hexacal_identify.core.architectures import architecture, ARCHITECTURES
from hexacal_identify.core.machine.kinematics import inverse_kinematics, rotation_matrices
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE
import numpy as np
import pytest

COMMON = {'base_joints', 'platform_joints', 'platform', 'device_link'}


def poses_of(model: str, n: int = 20) -> np.ndarray:
    arch = architecture(model)
    return sample_poses(
        arch.default_parameters(), n, np.random.default_rng(7), 'sphere', arch.default_workspace()
    )


@pytest.mark.parametrize('model', sorted(ARCHITECTURES))
def test_every_architecture_draws_the_common_parts(model):
    arch = architecture(model)
    params = arch.default_parameters()
    for pose in poses_of(model, 5):
        drawn = arch.drawing(params, pose)
        assert COMMON <= set(drawn)
        for name, array in drawn.items():
            assert array.ndim in (2, 3) and array.shape[-1] == 3, name
            if array.ndim == 3:
                assert array.shape[1] == 2, name
            assert np.all(np.isfinite(array)), name
        rotation = rotation_matrices(pose[None, 3:])[0]
        assert np.allclose(
            drawn['platform_joints'], pose[:3] + params.platform_points @ rotation.T, atol=1e-15
        )
        assert np.allclose(drawn['base_joints'], params.base_points)
        assert np.array_equal(drawn['device_link'], [[[0.0, 0.0, 0.0], pose[:3]]])
        # The platform outline is one closed loop through the six joints.
        outline = drawn['platform']
        assert outline.shape == (6, 2, 3)
        assert np.array_equal(outline[1:, 0], outline[:-1, 1]) and np.array_equal(
            outline[0, 0], outline[-1, 1]
        )
        assert sorted(map(tuple, outline[:, 0])) == sorted(map(tuple, drawn['platform_joints']))


def test_hexa_slide_chains_close():
    arch = architecture(HEXA_SLIDE)
    params = arch.default_parameters()
    low, high = arch.default_workspace().actuator_stroke_m
    for pose in poses_of(HEXA_SLIDE):
        drawn = arch.drawing(params, pose)
        sliders = inverse_kinematics(params, pose[None])[0]
        assert set(drawn) == COMMON | {'rails', 'sliders', 'legs'}
        assert np.allclose(
            drawn['sliders'], params.base_points + sliders[:, None] * params.rail_directions
        )
        # Each leg runs from its slider to its platform joint and has the chain's length l.
        assert np.array_equal(drawn['legs'][:, 0], drawn['sliders'])
        assert np.array_equal(drawn['legs'][:, 1], drawn['platform_joints'])
        assert np.allclose(
            np.linalg.norm(drawn['legs'][:, 1] - drawn['legs'][:, 0], axis=1),
            params.leg_lengths,
            atol=1e-12,
        )
        # Rails run along a over the stroke, from the rail start A0.
        rails = drawn['rails']
        assert np.allclose(rails[:, 0], params.base_points + low * params.rail_directions)
        assert np.allclose(rails[:, 1], params.base_points + high * params.rail_directions)
        # Given the readings, the sliders are drawn where they read.
        moved = arch.drawing(params, pose, sliders + 0.01)
        assert np.allclose(moved['sliders'] - drawn['sliders'], 0.01 * params.rail_directions)


def test_hexa_slide_rail_reaches_a_slider_beyond_the_stroke():
    arch = architecture(HEXA_SLIDE)
    params = arch.default_parameters()
    pose = poses_of(HEXA_SLIDE, 1)[0]
    readings = inverse_kinematics(params, pose[None])[0]
    readings[2] = 1.2  # beyond the 0.9 m stroke
    drawn = arch.drawing(params, pose, readings)
    assert np.allclose(
        drawn['rails'][2, 1], params.base_points[2] + 1.2 * params.rail_directions[2]
    )


def test_gough_stewart_legs_have_the_read_lengths():
    arch = architecture(GOUGH_STEWART)
    params = arch.default_parameters()
    for pose in poses_of(GOUGH_STEWART):
        drawn = arch.drawing(params, pose)
        assert set(drawn) == COMMON | {'legs', 'cylinders'}
        readings = inverse_kinematics(params, pose[None])[0]
        legs, cylinders = drawn['legs'], drawn['cylinders']
        assert np.array_equal(legs[:, 0], params.base_points)
        assert np.array_equal(legs[:, 1], drawn['platform_joints'])
        assert np.allclose(
            np.linalg.norm(legs[:, 1] - legs[:, 0], axis=1),
            readings + params.leg_offsets,
            atol=1e-12,
        )
        # The cylinder is the leg at reading zero (l0 long), along the leg.
        housing = cylinders[:, 1] - cylinders[:, 0]
        assert np.allclose(np.linalg.norm(housing, axis=1), params.leg_offsets, atol=1e-12)
        assert np.allclose(np.cross(housing, legs[:, 1] - legs[:, 0]), 0.0, atol=1e-12)
        assert np.array_equal(arch.drawing(params, pose, readings)['legs'], legs)
