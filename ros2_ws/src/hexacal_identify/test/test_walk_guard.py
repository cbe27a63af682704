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


@pytest.mark.slow
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
    forced = _predict(MeasuringMode.COMPLIANT, straight, start=EAST, max_force_n=1e3,
                      servo_stiffness_n_per_m=2e6)
    assert forced.worst > 1e3 and 'beyond max_force_n 1000 N' in forced.problem
    # The same straight move at the default compliant servos stays within the default limits.
    assert _predict(MeasuringMode.COMPLIANT, straight, start=EAST).problem == ''


@pytest.mark.slow
def test_the_link_force_the_servos_cause_is_predicted_and_kept_within_its_limit():
    straight = inverse_kinematics(MODEL, WEST[None])
    free = _predict(MeasuringMode.COMPLIANT, straight, start=EAST)
    assert free.problem == '' and free.what == 'servo force'
    # The link's tension is the force part of J^T tau along P: what the servos push on it.
    loaded = _predict(MeasuringMode.COMPLIANT, straight, start=EAST, max_link_force_n=10.0)
    assert loaded.what == 'link force' and abs(loaded.worst) > 10.0, loaded
    assert 'beyond max_link_force_n 10 N' in loaded.problem
    assert 'the servos would load the measuring link with' in loaded.problem
    # The default limit is below what a link of the documented kind bears.
    assert GuardSettings().max_link_force_n < 500.0


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


def test_the_link_tension_balances_the_strained_servos_on_the_platform():
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_identify.core.modes.compliant import device_constrained_pose, link_tension

    # Targets of a nominal model strain the true machine against the link by millimetres.
    nominal = nominal_set(2, seed=0, model=GS, exact=MODEL)
    setpoints = inverse_kinematics(nominal, EAST[None])[0]
    pose, actuators = device_constrained_pose(MODEL, setpoints, EAST, L)
    stiffness = 2e4
    tension = link_tension(MODEL, pose, actuators, setpoints, stiffness)[0]
    thrust = stiffness * (setpoints - actuators)
    legs = MODEL.architecture.legs(MODEL.architecture.chains(MODEL), pose[None])
    generalised = np.asarray(legs.pose_jacobian())[0].T @ thrust
    # At the least-energy standing the servos' wrench is a pure force along the link.
    along = pose[:3] / np.linalg.norm(pose[:3])
    np.testing.assert_allclose(generalised[:3], tension * along, atol=1e-6 * abs(tension))
    np.testing.assert_allclose(generalised[3:], 0.0, atol=1e-6 * abs(tension))
    assert abs(tension) > 1.0 and np.max(np.abs(thrust)) > 1.0
