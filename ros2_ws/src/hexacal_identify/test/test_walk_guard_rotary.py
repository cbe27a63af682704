"""The executor's guard on a rotary hexapod: it stops a move before a crank's limit, in rad."""

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.walk.guard import GuardSettings, predict_move
from hexacal_msgs_py.measuring_modes import MeasuringMode
import numpy as np
import pytest

ARCH = architecture('rotary_hexapod')
MODEL = ARCH.default_parameters()
LINK_M = 0.75
START = np.array([0.0, 0.0, -LINK_M, 0.0, 0.0, 0.0])
# The guard's samples along a move: coarser than the executor's 1e-3 rad (the same check at
# fewer points; each compliant sample solves the machine against the link).
STEP_RAD = 0.05


def _on_sphere(x: float, y: float, radius: float = LINK_M) -> np.ndarray:
    return np.array([x, y, -np.sqrt(radius**2 - x**2 - y**2), 0.02, -0.01, 0.0])


def _move(target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    current, points = inverse_kinematics(MODEL, np.stack([START, target]))
    return current, points[None]


def test_a_released_crank_is_stopped_before_its_stroke_end():
    current, points = _move(_on_sphere(0.12, -0.05))
    released = 2
    end = float(points[0, released])
    settings = GuardSettings(released_margin_m=ARCH.released_margin, sample_step_m=STEP_RAD)
    # A stroke that ends 0.01 rad beyond the target: inside it, not inside its margin.
    stroke = (-1.2, end + 0.01) if end > current[released] else (end - 0.01, 1.2)
    prediction = predict_move(
        MODEL, MeasuringMode.PASSIVE_ACTUATOR, current, START, points, LINK_M, stroke,
        settings, released,
    )
    assert prediction.problem, prediction
    assert prediction.worst == pytest.approx(ARCH.released_margin - 0.01, abs=2e-3)
    assert ' rad less the 1.910 deg margin' in prediction.problem, prediction.problem
    wide = predict_move(
        MODEL, MeasuringMode.PASSIVE_ACTUATOR, current, START, points, LINK_M, (-1.2, 1.2),
        settings, released,
    )
    assert wide.problem == '' and wide.worst < 0, wide


def test_compliant_cranks_are_stopped_before_their_torque_limit_in_n_m():
    # A target 1 mm off the link sphere: the rigid link strains the six compliant servos.
    current, points = _move(_on_sphere(0.04, 0.02, LINK_M + 1e-3))
    stiffness = ARCH.actuator_limit(2e4, 'stiffness')
    limit = ARCH.actuator_limit(400.0, 'force')
    settings = GuardSettings(
        servo_stiffness_n_per_m=stiffness, max_force_n=limit, sample_step_m=STEP_RAD
    )
    prediction = predict_move(
        MODEL, MeasuringMode.COMPLIANT, current, START, points, LINK_M, (-1.2, 1.2), settings
    )
    assert prediction.worst > 0
    tight = GuardSettings(
        servo_stiffness_n_per_m=stiffness, max_force_n=prediction.worst / 2, sample_step_m=STEP_RAD
    )
    paused = predict_move(
        MODEL, MeasuringMode.COMPLIANT, current, START, points, LINK_M, (-1.2, 1.2), tight
    )
    assert paused.problem.startswith('a servo would carry'), paused
    assert ' N m on the way (strain ' in paused.problem and ' deg at ' in paused.problem
    assert 'N m/rad), beyond max_force_n' in paused.problem, paused.problem
    assert ' mm ' not in paused.problem and 'N/m)' not in paused.problem
