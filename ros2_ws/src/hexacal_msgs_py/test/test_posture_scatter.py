"""The posture scatter of the contract: validation and its JointState round trip."""

from hexacal_msgs_py.conversions import (
    joint_state_to_posture_reading,
    posture_reading_to_joint_state,
)
from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.names import POSTURE_NAMES
from hexacal_msgs_py.readings import PostureReading, PostureScatter
import pytest

VALUES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.01, -0.02, 0.03)
ERRORS = (1e-7, 2e-7, 3e-7, 4e-7, 5e-7, 6e-7, 1e-6, 2e-6, 3e-6)
COUNTS = (50, 50, 50, 50, 50, 50, 40, 40, 49)


def test_scatter_round_trips_through_velocity_and_effort():
    reading = PostureReading.from_values(
        123, VALUES, device_turn=0.5, scatter=PostureScatter(ERRORS, COUNTS)
    )
    message = posture_reading_to_joint_state(reading)
    assert list(message.velocity[: len(POSTURE_NAMES)]) == list(ERRORS)
    assert list(message.effort[: len(POSTURE_NAMES)]) == [float(n) for n in COUNTS]
    assert len(message.velocity) == len(message.name) == 10  # with device_turn
    back = joint_state_to_posture_reading(message)
    assert back == reading


def test_without_scatter_the_message_is_as_before():
    reading = PostureReading.from_values(5, VALUES)
    message = posture_reading_to_joint_state(reading)
    assert list(message.velocity) == [] and list(message.effort) == []
    assert joint_state_to_posture_reading(message).scatter is None


def test_scatter_read_by_joint_name_in_any_order():
    message = posture_reading_to_joint_state(
        PostureReading.from_values(7, VALUES, scatter=PostureScatter(ERRORS, COUNTS))
    )
    order = list(reversed(range(len(message.name))))
    message.name = [message.name[i] for i in order]
    message.position = [message.position[i] for i in order]
    message.velocity = [message.velocity[i] for i in order]
    message.effort = [message.effort[i] for i in order]
    assert joint_state_to_posture_reading(message).scatter == PostureScatter(ERRORS, COUNTS)


@pytest.mark.parametrize(
    'errors, counts, words',
    [
        (ERRORS[:8], COUNTS, 'expected 9'),
        ((-1e-7,) + ERRORS[1:], COUNTS, '>= 0'),
        ((float('nan'),) + ERRORS[1:], COUNTS, 'finite'),
        (ERRORS, (0,) + COUNTS[1:], 'whole number >= 1'),
        (ERRORS, (2.5,) + COUNTS[1:], 'whole number >= 1'),
    ],
)
def test_bad_scatter_is_refused_by_name(errors, counts, words):
    with pytest.raises(InvalidReadingError, match=words):
        PostureScatter(errors, counts)
