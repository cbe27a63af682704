"""The declarative model layouts: physical checks by field name, key slices, register_model."""

from dataclasses import replace

import math

from hexacal_msgs_py.models import (
    ChainKey,
    FieldBelow,
    GOUGH_STEWART,
    HEXA_SLIDE,
    MODELS,
    PositiveField,
    register_model,
    ROTARY_HEXAPOD,
    UnitVectorXY,
)
import pytest

HEXA = MODELS[HEXA_SLIDE]
GS = MODELS[GOUGH_STEWART]


def _hexa_vector() -> list[float]:
    chain = [0.1, 0.2, 0.3, 0.01, 0.02, -0.01, 0.99, 0.5, 0.4]
    return chain * 6


def test_hexa_slide_checks_read_the_fields_by_name_with_the_messages_files_print():
    vector = _hexa_vector()
    assert HEXA.physical_problem(vector) is None
    bad_rail = list(vector)
    bad_rail[HEXA.parameter_index(4, 'ax')] = 0.8
    bad_rail[HEXA.parameter_index(4, 'ay')] = 0.7
    assert HEXA.physical_problem(bad_rail) == (
        'chain_4.a = [0.8, 0.7] is not the x, y components of a unit vector '
        f'(ax^2 + ay^2 = {0.8 * 0.8 + 0.7 * 0.7!r} >= 1)'
    )
    bad_length = list(vector)
    bad_length[HEXA.parameter_index(2, 'l')] = -0.5
    assert HEXA.physical_problem(bad_length) == 'chain_2.l must be > 0 m, got -0.5'
    # Chain by chain, each chain's checks in the layout's order: chain 2 before chain 4.
    both = list(bad_rail)
    both[HEXA.parameter_index(2, 'l')] = -0.5
    assert HEXA.physical_problem(both).startswith('chain_2.l')
    assert HEXA.physical_checks == (UnitVectorXY('a', 'ax', 'ay'), PositiveField('l'))


def test_gough_stewart_check_and_key_slices():
    vector = [0.5, 0.1, 0.0, 0.2, 0.05, 0.015, 0.6] * 6
    assert GS.physical_problem(vector) is None
    vector[GS.parameter_index(5, 'l0')] = 0.0
    assert GS.physical_problem(vector) == (
        'chain_5.l0 must be > 0 m (the leg length at actuator reading zero), got 0.0'
    )
    assert GS.key_slices == {'A': slice(0, 3), 'B': slice(3, 6), 'l0': slice(6, 7)}
    # Field order, not file order (the Hexa Slide writes a before l).
    assert list(HEXA.key_slices) == ['A0', 'B', 'l', 'a']
    assert HEXA.key_slices['a'] == slice(7, 9)


@pytest.mark.parametrize(
    'change, message',
    [
        ({}, 'already registered'),
        ({'name': 'x', 'field_units': ('m',) * 6}, 'one unit per field'),
        ({'name': 'x', 'chain_keys': GS.chain_keys[:2]}, 'cover every field once'),
        (
            {'name': 'x', 'chain_keys': GS.chain_keys + (ChainKey('C', 6, None, 'again'),)},
            'cover every field once',
        ),
        ({'name': 'x', 'physical_checks': (PositiveField('r'),)}, r"unknown field\(s\) \['r'\]"),
        ({'name': 'x'}, "actuator joints leg_N are gough_stewart's"),
        ({'name': 'x', 'actuator_prefix': 'x', 'actuator_unit': 'deg'}, 'actuator_unit must be'),
        (
            {'name': 'x', 'actuator_prefix': 'x', 'physical_checks': (FieldBelow('el', 1.0),)},
            r"unknown field\(s\) \['el'\]",
        ),
    ],
)
def test_register_model_refuses_an_inconsistent_layout(change, message):
    with pytest.raises(ValueError, match=message):
        register_model(replace(GS, **change))
    assert set(MODELS) == {HEXA_SLIDE, GOUGH_STEWART, ROTARY_HEXAPOD}


def test_rotary_hexapod_reads_angles_and_refuses_a_vertical_motor_axis():
    rotary = MODELS[ROTARY_HEXAPOD]
    assert rotary.actuator_unit == 'rad' and GS.actuator_unit == HEXA.actuator_unit == 'm'
    assert rotary.actuator_names[0] == 'crank_1' and rotary.n_parameters == 66
    assert rotary.field_units[rotary.fields.index('axis_el')] == 'rad'
    vector = [0.4, 0.0, 0.0, 0.25, 0.0, 0.015, 0.78, 0.15, 3.14, 0.0, 0.0] * 6
    assert rotary.physical_problem(vector) is None
    vector[rotary.parameter_index(3, 'axis_el')] = -math.pi / 2
    assert rotary.physical_problem(vector) == (
        f'chain_3.axis_el must be within +-{math.pi / 2!r} rad (a vertical motor axis has no '
        f'azimuth), got {-math.pi / 2!r}'
    )
    assert rotary.key_slices == {
        'A': slice(0, 3),
        'B': slice(3, 6),
        'l': slice(6, 7),
        'r': slice(7, 8),
        'axis': slice(8, 10),
        'alpha0': slice(10, 11),
    }
