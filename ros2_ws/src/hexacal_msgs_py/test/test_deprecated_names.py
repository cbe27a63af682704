"""Renamed names of the contract stay importable and warn, naming the release that removes them."""

# rename.py: old names on purpose (this test checks the deprecated aliases).

import importlib
import warnings

import hexacal_msgs_py
from hexacal_msgs_py import conversions, readings
from hexacal_msgs_py.deprecation import REMOVED_IN
from hexacal_msgs_py.readings import ActuatorReading, PostureReading
import pytest


def test_removal_release_is_0_3_0():
    assert REMOVED_IN == '0.3.0'


def test_old_reading_name_is_the_new_class_and_warns():
    with pytest.warns(DeprecationWarning, match=r'SliderReading .*0\.3\.0.*ActuatorReading'):
        from hexacal_msgs_py.readings import SliderReading
    assert SliderReading is ActuatorReading
    assert {'ActuatorReading', 'SliderReading'} <= set(hexacal_msgs_py.__all__)
    for _ in range(2):  # every use warns: the package does not cache the old name
        with pytest.warns(DeprecationWarning, match=r'0\.3\.0'):
            assert hexacal_msgs_py.SliderReading is ActuatorReading


def test_old_field_name_reads_the_actuator_positions_and_warns():
    reading = ActuatorReading(5, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6))
    with pytest.warns(DeprecationWarning, match=r'slider_positions .*0\.3\.0.*actuator_positions'):
        old = reading.slider_positions
    assert old == reading.actuator_positions == (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    posture = PostureReading(5, (0.4,) * 6, 0.01, 0.02, 0.03)
    with pytest.warns(DeprecationWarning, match=r'0\.3\.0'):
        assert posture.slider_positions == posture.actuator_positions


@pytest.mark.parametrize('old, new', sorted(conversions.DEPRECATED_NAMES.items()))
def test_old_conversion_names_are_the_new_functions_and_warn(old, new):
    with pytest.warns(DeprecationWarning, match=rf'{old} .*0\.3\.0.*{new}'):
        function = getattr(conversions, old)
    assert function is getattr(conversions, new)


@pytest.mark.parametrize('module', [readings, conversions])
def test_every_deprecated_name_warns_and_others_are_missing(module):
    for old, new in module.DEPRECATED_NAMES.items():
        with pytest.warns(DeprecationWarning, match=r'0\.3\.0'):
            assert getattr(module, old) is getattr(module, new)
    with pytest.raises(AttributeError, match='no_such_name'):
        getattr(module, 'no_such_name')


def test_the_new_names_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        module = importlib.import_module('hexacal_msgs_py.readings')
        module.ActuatorReading(5, (0.1,) * 6).actuator_positions
        assert hexacal_msgs_py.ActuatorReading is module.ActuatorReading
        assert conversions.joint_state_to_actuator_reading is not None
