"""core/walk/correction_response.py: fixed-position corrections learn how the machine answers."""

from hexacal_identify.core.walk.correction_response import (
    CorrectionResponse,
    MAX_GAIN,
    MAX_LEARNED_CHANGE_RAD,
)
import numpy as np
import pytest

TOLERANCE_RAD = 2e-5  # the executor's default fixed_tolerance_rad


def corrections_needed(answer: np.ndarray, reading: np.ndarray, learn: bool, limit: int = 12):
    """Return how many corrections a machine answering `answer` x the asked change needs."""
    response = CorrectionResponse()
    for count in range(limit + 1):
        if np.max(np.abs(reading)) <= TOLERANCE_RAD:
            return count
        if learn:
            asked = response.ask(reading)
            response.sent(reading, asked)
        else:
            asked = -reading  # the model's first-order correction, as before
        reading = reading + answer @ asked
    return None


@pytest.mark.parametrize(
    'answer, reading',
    [
        # MuJoCo Hexa Slide, passive_actuator: each correction left about 25 % behind.
        (np.diag([0.75, 0.75]), np.array([0.00104, 0.0391])),
        # Kinematic machine, passive_actuator: 70 % left, beta's sign flipping (cross-coupled),
        # from a reading where the answer is linear.
        (np.array([[0.8, -0.25], [0.2, 1.7]]), np.array([0.01, -0.015])),
    ],
)
def test_corrections_converge_on_a_machine_that_answers_otherwise(answer, reading):
    learned = corrections_needed(answer, reading, learn=True)
    plain = corrections_needed(answer, reading, learn=False)
    assert learned is not None and learned <= 5  # the executor's default max_corrections
    assert plain is None or plain > 5, plain  # the first-order corrections alone skip it


def test_a_machine_that_answers_as_the_model_says_is_corrected_once():
    assert corrections_needed(np.eye(2), np.array([0.01, -0.02]), learn=True) == 1


def test_noise_and_implausible_answers_are_not_learned():
    response = CorrectionResponse()
    first = np.array([5e-5, 0.0])  # below MIN_LEARNED_CHANGE_RAD: the noise would be learned
    response.sent(first, response.ask(first))
    response.ask(np.array([4e-5, 3e-5]))
    np.testing.assert_array_equal(response.gain, np.eye(2))
    # A change too large for a linear answer: the platform landed centimetres off.
    large = np.array([-0.215, -0.0198])
    assert np.linalg.norm(large) > MAX_LEARNED_CHANGE_RAD
    response.sent(large, response.ask(large))
    response.ask(np.array([-0.149, 0.0741]))
    np.testing.assert_array_equal(response.gain, np.eye(2))
    # A change asked for that the machine answered with nothing (a disturbance, a fault):
    # B would be singular, its inverse an unbounded correction.
    big = np.array([0.01, 0.0])
    response = CorrectionResponse()
    response.sent(big, response.ask(big))
    response.ask(big)
    np.testing.assert_array_equal(response.gain, np.eye(2))
    # A plausible answer (half the change) is learned, within MAX_GAIN.
    response.ask(big)
    response.sent(big, np.array([-0.01, 0.0]))
    response.ask(np.array([0.005, 0.0]))
    assert response.gain[0, 0] == pytest.approx(0.5)
    assert 1 / MAX_GAIN <= np.linalg.svd(response.gain, compute_uv=False).min()
