"""The contract's names before issue #17 stay importable as deprecated aliases."""

# rename.py: old names on purpose (this test checks the deprecated aliases).

import hexacal_msgs_py
from hexacal_msgs_py import conversions
from hexacal_msgs_py.readings import ActuatorReading, PostureReading, SliderReading


def test_old_reading_name_is_the_new_class():
    assert SliderReading is ActuatorReading
    assert {'ActuatorReading', 'SliderReading'} <= set(hexacal_msgs_py.__all__)
    assert hexacal_msgs_py.SliderReading is ActuatorReading


def test_old_field_name_reads_the_actuator_positions():
    reading = ActuatorReading(5, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6))
    assert reading.slider_positions == reading.actuator_positions == (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    posture = PostureReading(5, (0.4,) * 6, 0.01, 0.02, 0.03)
    assert posture.slider_positions == posture.actuator_positions


def test_old_conversion_names_are_the_new_functions():
    assert conversions.joint_state_to_slider_reading is conversions.joint_state_to_actuator_reading
    assert conversions.slider_reading_to_joint_state is conversions.actuator_reading_to_joint_state
