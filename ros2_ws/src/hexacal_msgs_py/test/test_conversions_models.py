"""Message conversions for every machine model: actuator joint names and parameter layouts."""

from hexacal_msgs_py import conversions as conv
from hexacal_msgs_py.errors import InvalidParametersError, InvalidReadingError
from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE, MODELS
from hexacal_msgs_py.names import actuator_names, POSTURE_NAMES, posture_names, SLIDER_NAMES
from hexacal_msgs_py.readings import ActuatorReading, PostureReading
import numpy as np
import pytest

POSTURE = PostureReading(1_234_567_890, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6), 0.01, -0.02, 0.03)
LEGS = ('leg_1', 'leg_2', 'leg_3', 'leg_4', 'leg_5', 'leg_6')
DEVICE = ('inclinometer_x', 'inclinometer_y', 'rotary')


def gough_stewart_vector() -> np.ndarray:
    per_chain = np.array([[0.5, 0.1, 0.0, 0.2, 0.05, 0.015, 0.6]] * 6)
    per_chain[:, 6] += np.arange(6) * 1e-3
    return per_chain.reshape(-1)


def test_names_per_model():
    assert actuator_names() == SLIDER_NAMES == MODELS[HEXA_SLIDE].actuator_names
    assert actuator_names(GOUGH_STEWART) == LEGS
    assert posture_names() == POSTURE_NAMES
    assert posture_names(GOUGH_STEWART) == LEGS + DEVICE


@pytest.mark.parametrize('model', [HEXA_SLIDE, GOUGH_STEWART])
def test_posture_round_trip_carries_the_models_names(model):
    message = conv.posture_reading_to_joint_state(POSTURE, model=model)
    assert tuple(message.name) == posture_names(model)
    assert conv.actuator_model(message.name).name == model
    assert conv.joint_state_to_posture_reading(message, model) == POSTURE
    assert conv.joint_state_to_posture_reading(message, MODELS[model]) == POSTURE


def test_default_model_is_the_hexa_slide():
    message = conv.posture_reading_to_joint_state(POSTURE)
    assert tuple(message.name) == POSTURE_NAMES
    assert conv.joint_state_to_posture_reading(message) == POSTURE
    sliders = conv.actuator_reading_to_joint_state(ActuatorReading(5, POSTURE.actuator_positions))
    assert tuple(sliders.name) == SLIDER_NAMES


def test_other_models_names_are_a_missing_joint():
    legs = conv.posture_reading_to_joint_state(POSTURE, model=GOUGH_STEWART)
    with pytest.raises(InvalidReadingError, match='lacks joint.*slider_1'):
        conv.joint_state_to_posture_reading(legs)
    sliders = conv.actuator_reading_to_joint_state(ActuatorReading(5, POSTURE.actuator_positions))
    with pytest.raises(InvalidReadingError, match='lacks joint.*leg_1'):
        conv.joint_state_to_actuator_reading(sliders, GOUGH_STEWART)
    assert conv.actuator_model(['inclinometer_x', 'slider_1']) is None


def test_slider_readings_with_leg_names():
    message = conv.actuator_reading_to_joint_state(
        ActuatorReading(7, POSTURE.actuator_positions), model=GOUGH_STEWART
    )
    assert tuple(message.name) == LEGS
    assert (
        conv.joint_state_to_actuator_reading(message, GOUGH_STEWART).actuator_positions
        == POSTURE.actuator_positions
    )


def test_gough_stewart_parameters_message():
    vector = gough_stewart_vector()
    message = conv.parameters_to_multiarray(vector)  # 42 values: the Gough-Stewart layout
    assert [(d.label, d.size, d.stride) for d in message.layout.dim] == [
        ('chain', 6, 42),
        ('Ax,Ay,Az,Bx,By,Bz,l0', 7, 7),
    ]
    assert conv.multiarray_model(message).name == GOUGH_STEWART
    assert conv.multiarray_to_parameters(message).tobytes() == vector.tobytes()
    assert conv.multiarray_to_parameters(message, GOUGH_STEWART).tobytes() == vector.tobytes()
    with pytest.raises(InvalidParametersError, match='for a hexa_slide'):
        conv.multiarray_to_parameters(message, HEXA_SLIDE)
    with pytest.raises(InvalidParametersError, match='l0 must be > 0'):
        bad = vector.copy()
        bad[6] = -0.1
        conv.parameters_to_multiarray(bad, GOUGH_STEWART)
