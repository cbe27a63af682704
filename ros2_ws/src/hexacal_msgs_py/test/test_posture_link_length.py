"""The posture's measured link length (lvdt mode) on the contract: validation and round trips."""

from hexacal_msgs_py.conversions import (
    joint_state_to_posture_reading,
    posture_reading_to_joint_state,
)
from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.names import LINK_LENGTH_JOINT, POSTURE_NAMES
from hexacal_msgs_py.readings import PostureReading, PostureScatter
import pytest

VALUES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.01, -0.02, 0.03)
ERRORS = (1e-7,) * 6 + (1e-6,) * 3
COUNTS = (50,) * 9


def test_without_link_length_the_message_is_byte_identical_to_before():
    reading = PostureReading.from_values(5, VALUES, scatter=PostureScatter(ERRORS, COUNTS))
    message = posture_reading_to_joint_state(reading)
    assert LINK_LENGTH_JOINT not in message.name
    assert len(message.name) == len(message.velocity) == len(POSTURE_NAMES)
    assert joint_state_to_posture_reading(message).link_length is None


def test_link_length_round_trips_as_an_optional_joint():
    reading = PostureReading.from_values(9, VALUES, device_turn=0.5, link_length=0.3012)
    message = posture_reading_to_joint_state(reading)
    assert list(message.name)[-1] == LINK_LENGTH_JOINT
    assert message.position[-1] == 0.3012
    assert list(message.velocity) == []
    assert joint_state_to_posture_reading(message) == reading


def test_link_length_scatter_round_trips_in_velocity_and_effort():
    scatter = PostureScatter(
        ERRORS, COUNTS, link_length_standard_error=2e-7, link_length_sample_count=48
    )
    reading = PostureReading.from_values(9, VALUES, scatter=scatter, link_length=0.2995)
    message = posture_reading_to_joint_state(reading)
    assert message.velocity[-1] == 2e-7 and message.effort[-1] == 48.0
    back = joint_state_to_posture_reading(message)
    assert back == reading
    assert back.scatter.link_length_sample_count == 48


def test_link_length_without_its_own_scatter_travels_as_unknown():
    reading = PostureReading.from_values(
        9, VALUES, scatter=PostureScatter(ERRORS, COUNTS), link_length=0.3
    )
    message = posture_reading_to_joint_state(reading)
    assert message.velocity[-1] == 0.0 and message.effort[-1] == 1.0
    back = joint_state_to_posture_reading(message)
    assert back.link_length == 0.3 and back.scatter.standard_errors == ERRORS


@pytest.mark.parametrize('length', [0.0, -0.3, float('nan'), float('inf'), 'long'])
def test_bad_link_length_is_refused_by_name(length):
    with pytest.raises(InvalidReadingError, match=LINK_LENGTH_JOINT):
        PostureReading.from_values(1, VALUES, link_length=length)


def test_link_scatter_needs_both_error_and_count():
    with pytest.raises(InvalidReadingError, match='both'):
        PostureScatter(ERRORS, COUNTS, link_length_standard_error=1e-7)
    with pytest.raises(InvalidReadingError, match=LINK_LENGTH_JOINT):
        PostureScatter(ERRORS, COUNTS, link_length_standard_error=-1.0,
                       link_length_sample_count=3)
