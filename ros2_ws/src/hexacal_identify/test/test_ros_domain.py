"""The ROS domain claim shared by the test sessions, the demo and the benchmarks (no DDS)."""

import fcntl

from hexacal_identify import ros_domain
from hexacal_identify.ros_domain import claim_domain_id, DOMAIN_ID_RANGE, lock_path
import pytest


def test_a_claim_locks_its_file_and_the_next_claim_takes_another_id(tmp_path):
    first = claim_domain_id(start=41, directory=tmp_path)
    second = claim_domain_id(start=41, directory=tmp_path)
    assert first == DOMAIN_ID_RANGE[41] and second == DOMAIN_ID_RANGE[42]
    assert lock_path(first, tmp_path).name == f'hexacal-test-ros-domain-{first}.lock'
    with open(lock_path(first, tmp_path), 'a') as other:
        with pytest.raises(OSError):
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)


def test_the_override_variable_names_the_id_without_a_lock(tmp_path, monkeypatch):
    monkeypatch.setenv('HEXACAL_X_DOMAIN_ID', '7')
    assert claim_domain_id('HEXACAL_X_DOMAIN_ID', directory=tmp_path) == 7
    assert not list(tmp_path.iterdir())
    monkeypatch.setenv('HEXACAL_X_DOMAIN_ID', '')
    assert claim_domain_id('HEXACAL_X_DOMAIN_ID', start=0, directory=tmp_path) == 1


def test_no_free_id_names_the_override_variable(tmp_path, monkeypatch):
    monkeypatch.setattr(ros_domain, 'DOMAIN_ID_RANGE', range(1, 3))
    claim_domain_id(directory=tmp_path)
    claim_domain_id(directory=tmp_path)
    with pytest.raises(ros_domain.NoFreeDomainError, match='set HEXACAL_X_DOMAIN_ID'):
        claim_domain_id('HEXACAL_X_DOMAIN_ID', directory=tmp_path)
