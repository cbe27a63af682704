"""
Model: Table 1 in SI units, nominal sets, validation of parameter vectors.

Table 1 in SI units, nominal sets with Table 2's statistics, validation of parameter vectors.
"""

from hexacal_identify.core.machine.model import (
    error_stats_mm,
    HexaParameters,
    nominal_set,
    parameter_names,
    table1_parameters,
    TABLE2_ERROR_STATS_MM,
)
import numpy as np
import pytest


def test_table1_in_si_units_chain_major():
    params = table1_parameters()
    assert params.per_chain[0, 0] == pytest.approx(-0.7359)  # chain 1 A0x, mm -> m
    assert params.per_chain[2, 7] == pytest.approx(
        0.0002
    )  # chain 3 ax (Table 1: 0.2 = 1000 x component)
    assert params.leg_lengths[1] == pytest.approx(0.9948)
    rails = params.rail_directions
    np.testing.assert_allclose(np.linalg.norm(rails, axis=1), 1.0, atol=1e-12)
    assert np.all(rails[:, 2] < 0), 'rails descend inward'
    assert parameter_names()[:3] == ['chain_1.A0x', 'chain_1.A0y', 'chain_1.A0z']
    assert parameter_names()[-1] == 'chain_6.ay'


@pytest.mark.parametrize('number', [1, 2, 3])
def test_nominal_sets_have_table2_statistics(number):
    errors = nominal_set(number, seed=11).vector - table1_parameters().vector
    np.testing.assert_allclose(error_stats_mm(errors), TABLE2_ERROR_STATS_MM[number], rtol=1e-9)


def test_nominal_sets_are_seeded():
    assert np.array_equal(nominal_set(2, seed=3).vector, nominal_set(2, seed=3).vector)
    assert not np.array_equal(nominal_set(2, seed=3).vector, nominal_set(2, seed=4).vector)


def test_invalid_parameter_vectors_are_rejected_with_the_name():
    vector = table1_parameters().vector.copy()
    vector[5] = np.nan
    with pytest.raises(ValueError, match='chain_1.Bz'):
        HexaParameters(vector)
    vector = table1_parameters().vector.copy()
    vector[9 * 2 + 7] = 1.2
    with pytest.raises(ValueError, match='chain_3.a'):
        HexaParameters(vector)
    with pytest.raises(ValueError, match='54'):
        HexaParameters(np.zeros(53))


def test_shipped_table1_file_is_the_table1_machine():
    from pathlib import Path

    import hexacal_identify
    from hexacal_msgs_py.parameters_file import load_parameters

    shipped = Path(hexacal_identify.__file__).parent / 'data' / 'table1_exact.yaml'
    np.testing.assert_array_equal(load_parameters(shipped), table1_parameters().vector)
