"""Bag directory names (hexacal_identify.bag.naming)."""

from datetime import datetime

from hexacal_identify.bag.naming import bag_name_problem, next_bag_directory


def test_an_explicit_name_is_used_as_given_for_the_first_bag(tmp_path):
    (tmp_path / 'run').mkdir()
    assert next_bag_directory(tmp_path, 'run', first=True) == tmp_path / 'run'


def test_later_bags_get_the_first_free_suffix(tmp_path):
    assert next_bag_directory(tmp_path, 'run', first=False) == tmp_path / 'run'
    (tmp_path / 'run').mkdir()
    (tmp_path / 'run_2').mkdir()
    assert next_bag_directory(tmp_path, 'run', first=False) == tmp_path / 'run_3'


def test_without_a_name_the_bag_is_named_by_date_and_time(tmp_path):
    now = datetime(2026, 11, 24, 1, 2, 3)
    assert next_bag_directory(tmp_path, '', first=True, now=now) == (
        tmp_path / 'hexacal_20261124_010203'
    )
    (tmp_path / 'hexacal_20261124_010203').mkdir()
    assert next_bag_directory(tmp_path, '', first=True, now=now) == (
        tmp_path / 'hexacal_20261124_010203_2'
    )


def test_a_bag_name_must_be_a_plain_directory_name():
    assert bag_name_problem('run_1') is None
    assert bag_name_problem('') is None
    for name in ('a/b', '.', '..'):
        assert 'plain directory name' in bag_name_problem(name)
