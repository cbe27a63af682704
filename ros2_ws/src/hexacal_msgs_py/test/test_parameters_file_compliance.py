"""The parameters file's optional compliance section: written only when identified, read back."""

from hexacal_msgs_py.parameters_file import (
    compliance_extras,
    compliances_from_extras,
    read_parameters_file,
    save_parameters,
)
import numpy as np
import pytest

# One Hexa Slide chain (A0, B, l, a_xy), six times: a valid 54-vector.
CHAIN = np.array([0.4, 0.1, 0.0, 0.1, 0.02, 0.0, 0.5, 0.3, 0.1])


def test_rigid_files_carry_no_compliance_and_read_as_rigid(tmp_path):
    path = tmp_path / 'rigid.yaml'
    vector = np.tile(CHAIN, 6)
    save_parameters(path, vector, extras=compliance_extras({}) or None)
    contents = read_parameters_file(path)
    assert 'compliance' not in path.read_text()
    assert compliances_from_extras(contents.extras) == {}


def test_compliances_round_trip_with_their_std(tmp_path):
    path = tmp_path / 'loaded.yaml'
    values = {'chains': 2.0e-8, 'link': 1.0e-7}
    extras = compliance_extras(values, {'chains': 1.5e-9, 'link': float('nan')})
    save_parameters(path, np.tile(CHAIN, 6), extras=extras)
    contents = read_parameters_file(path)
    assert compliances_from_extras(contents.extras) == values
    assert contents.extras['compliance_std.chains'] == 1.5e-9
    assert 'compliance_std.link' not in contents.extras  # an unknown std is left out


def test_bad_compliance_sections_are_named():
    with pytest.raises(ValueError, match='compliance.legs: not a compliance'):
        compliances_from_extras({'compliance.legs': 1e-8})
    with pytest.raises(ValueError, match='compliance.link: a compliance is a finite number'):
        compliances_from_extras({'compliance.link': 'stiff'})
    with pytest.raises(ValueError, match='both given'):
        compliances_from_extras({'compliance.chains': 1e-8, 'compliance.chain_2': 1e-8})
    with pytest.raises(ValueError, match='unknown compliance'):
        compliance_extras({'legs': 1e-8})
