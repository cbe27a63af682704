"""core/walk/guard.py: the executor's predictions of a move before it is sent."""

from __future__ import annotations

import math

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.device import fixed_point
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.planning.plan_check import default_stroke
from hexacal_identify.core.walk.guard import GuardSettings, joint_samples, predict_move
from hexacal_identify.core.walk.platform_paths import sphere_path
from hexacal_msgs_py.measuring_modes import MeasuringMode
import numpy as np
import pytest

L = 0.75
GS = 'gough_stewart'
MODEL = default_parameters(GS)
STROKE = default_stroke(MODEL)
CENTRE = np.concatenate([fixed_point(L), np.zeros(3)])


def _on_sphere(x: float, y: float) -> np.ndarray:
    return np.array([x, y, -math.sqrt(L**2 - x**2 - y**2), 0.0, 0.0, 0.0])


EAST, WEST = _on_sphere(0.25, 0.0), _on_sphere(-0.25, 0.0)


def _predict(mode, points, released=None, start=CENTRE, **settings):
    current = inverse_kinematics(MODEL, start[None])[0]
    return predict_move(
        MODEL, mode, current, start, points, L, STROKE, GuardSettings(**settings), released
    )


def test_joint_samples_go_linearly_through_every_point_at_most_a_step_apart():
    points = np.array([[0.01, 0, 0, 0, 0, 0], [0.01, 0.003, 0, 0, 0, 0]])
    samples = joint_samples(np.zeros(6), points, 1e-3)
    np.testing.assert_array_equal(samples[0], np.zeros(6))
    assert np.max(np.abs(np.diff(samples, axis=0))) <= 1e-3 + 1e-15
    assert len(samples) == 1 + 10 + 3
    np.testing.assert_allclose(samples[10], points[0]) and np.testing.assert_allclose(
        samples[-1], points[1]
    )


def test_a_path_along_the_sphere_stays_inside_and_a_joint_space_move_does_not():
    along = inverse_kinematics(MODEL, sphere_path(EAST, WEST, L, 0.02))
    straight = inverse_kinematics(MODEL, WEST[None])  # one point: the controller interpolates
    inside = _predict(MeasuringMode.LVDT, along, start=EAST)
    assert inside.problem == '' and abs(inside.worst) < 1e-4
    # Joint-space interpolation pulls the platform 2.95 mm inside the sphere half-way.
    crossing = _predict(MeasuringMode.LVDT, straight, start=EAST, lvdt_stroke_m=2e-3,
                        lvdt_margin_m=5e-4)
    assert crossing.worst == pytest.approx(-2.953e-3, abs=2e-5)
    assert 'compressed by 2.953 mm on the way, beyond the LVDT stroke +-2 mm' in crossing.problem
    assert _predict(MeasuringMode.LVDT, straight, start=EAST).problem == ''  # +-5 mm less 1
    assert _predict(MeasuringMode.COMPLIANT, along, start=EAST).problem == ''
    forced = _predict(MeasuringMode.COMPLIANT, straight, start=EAST, max_force_n=1e3)
    assert forced.worst > 1e3 and 'beyond max_force_n 1000 N' in forced.problem
    # The same straight move within a generous force limit passes.
    assert _predict(MeasuringMode.COMPLIANT, straight, start=EAST).problem == ''


def test_the_released_actuator_is_kept_inside_its_stroke_along_the_move():
    along = inverse_kinematics(MODEL, sphere_path(CENTRE, EAST, L, 0.02))
    free = _predict(MeasuringMode.PASSIVE_ACTUATOR, along, released=2)
    assert free.problem == '' and free.worst < 0
    # A margin wider than the room the released actuator has left: refused, naming it.
    room = -free.worst + GuardSettings().released_margin_m
    tight = _predict(
        MeasuringMode.PASSIVE_ACTUATOR, along, released=2, released_margin_m=room + 1e-3
    )
    assert 'the released actuator would leave its stroke' in tight.problem


@pytest.mark.parametrize('mode', list(MeasuringMode))
def test_standing_still_is_always_fine(mode):
    current = inverse_kinematics(MODEL, CENTRE[None])
    released = 0 if mode == MeasuringMode.PASSIVE_ACTUATOR else None
    assert _predict(mode, current, released=released).problem == ''
