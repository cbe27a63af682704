"""core/walk/platform_paths.py: the one pose interpolation, for the executor and the driver."""

from __future__ import annotations

from hexacal_identify.core.walk.platform_paths import interpolate_pose, SAME_SPHERE, sphere_path
import numpy as np
import pytest

L = 0.75


def _pose(direction, radius, angles=(0.0, 0.0, 0.0)) -> np.ndarray:
    direction = np.asarray(direction, dtype=float)
    return np.concatenate([direction / np.linalg.norm(direction) * radius, angles])


def _in_plane(p, a, b) -> bool:
    return abs(float(np.dot(p, np.cross(a[:3], b[:3])))) < 1e-12


def test_with_the_link_length_near_sphere_positions_follow_it_with_a_linear_radius():
    start = _pose([0.3, 0.0, -1.0], L * (1 - 0.5 * SAME_SPHERE), (0.0, 0.1, 0.0))
    end = _pose([-0.2, 0.4, -1.0], L * (1 + 0.5 * SAME_SPHERE), (0.2, 0.0, -0.1))
    radii = np.linalg.norm([start[:3], end[:3]], axis=1)
    for s in np.linspace(0.0, 1.0, 7):
        pose = interpolate_pose(start, end, s, L)
        assert np.linalg.norm(pose[:3]) == pytest.approx((1 - s) * radii[0] + s * radii[1])
        assert _in_plane(pose[:3], start, end)  # the great circle through both
        assert pose[3:] == pytest.approx(start[3:] + s * (end[3:] - start[3:]))
    assert interpolate_pose(start, end, 1.0, L) == pytest.approx(end, abs=1e-12)


def test_with_the_link_length_positions_off_the_sphere_go_straight():
    start = _pose([0.3, 0.0, -1.0], L)
    end = _pose([-0.2, 0.4, -1.0], L * (1 + 2 * SAME_SPHERE))
    middle = interpolate_pose(start, end, 0.5, L)
    assert middle[:3] == pytest.approx(0.5 * (start[:3] + end[:3]), abs=1e-15)


def test_without_a_link_length_equal_radii_share_their_own_sphere():
    radius = L + 0.002  # the simulated machine's true link, which its walker does not know
    start, end = _pose([0.3, 0.0, -1.0], radius), _pose([-0.2, 0.4, -1.0], radius)
    for s in np.linspace(0.0, 1.0, 7):
        pose = interpolate_pose(start, end, s)
        assert np.linalg.norm(pose[:3]) == pytest.approx(radius, abs=1e-12)
    # Asked with the nominal L, 2 mm (more than SAME_SPHERE L) off its sphere: a straight line.
    straight = interpolate_pose(start, end, 0.5, L)
    assert straight[:3] == pytest.approx(0.5 * (start[:3] + end[:3]), abs=1e-15)
    apart = _pose([-0.2, 0.4, -1.0], radius + 1e-6)  # different spheres: a straight line
    middle = interpolate_pose(start, apart, 0.5)
    assert middle[:3] == pytest.approx(0.5 * (start[:3] + apart[:3]), abs=1e-15)


def test_a_sphere_path_is_steps_of_at_most_step_m_ending_at_the_target():
    start, end = _pose([0.3, 0.0, -1.0], L), _pose([-0.2, 0.4, -1.0], L, (0.1, 0.0, 0.0))
    path = sphere_path(start, end, L, 0.02)
    steps = np.linalg.norm(np.diff(np.vstack([start, path])[:, :3], axis=0), axis=1)
    assert np.all(steps <= 0.02) and path[-1] == pytest.approx(end)
    assert np.linalg.norm(path[:, :3], axis=1) == pytest.approx(np.full(len(path), L))
    assert sphere_path(start, end, L, 0.0).tolist() == [end.tolist()]
