"""The units of an actuator by its kind: linear (m, N, mm shown) or rotary (rad, N m, deg)."""

import math

from hexacal_msgs_py.models import (
    actuator_quantities,
    ACTUATOR_UNITS,
    LINEAR_ACTUATOR,
    MODELS,
    ROTARY_ACTUATOR,
)
import pytest


def test_every_actuator_unit_has_its_quantities_and_each_model_reads_its_own():
    assert {actuator_quantities(unit).unit for unit in ACTUATOR_UNITS} == set(ACTUATOR_UNITS)
    for layout in MODELS.values():
        assert layout.actuator_quantities.unit == layout.actuator_unit
    assert MODELS['hexa_slide'].actuator_quantities is LINEAR_ACTUATOR
    assert MODELS['gough_stewart'].actuator_quantities is LINEAR_ACTUATOR
    assert MODELS['rotary_hexapod'].actuator_quantities is ROTARY_ACTUATOR


def test_linear_and_rotary_actuators_carry_their_own_units():
    assert (LINEAR_ACTUATOR.effort_unit, LINEAR_ACTUATOR.stiffness_unit) == ('N', 'N/m')
    assert (ROTARY_ACTUATOR.effort_unit, ROTARY_ACTUATOR.stiffness_unit) == ('N m', 'N m/rad')
    assert (LINEAR_ACTUATOR.speed_unit, ROTARY_ACTUATOR.speed_unit) == ('m/s', 'rad/s')
    assert (LINEAR_ACTUATOR.kind, ROTARY_ACTUATOR.kind) == ('linear', 'rotary')


def test_readings_are_shown_in_mm_or_deg_and_small_differences_in_um_or_urad():
    assert LINEAR_ACTUATOR.shown(0.0123) == '12.300 mm'
    assert ROTARY_ACTUATOR.shown(math.pi / 4, 2) == '45.00 deg'
    assert LINEAR_ACTUATOR.shown_small(3.5e-6) == '3.5 um'
    assert ROTARY_ACTUATOR.shown_small(3.5e-6) == '3.5 urad'


def test_an_unknown_actuator_unit_is_named():
    with pytest.raises(ValueError, match="'deg'"):
        actuator_quantities('deg')
