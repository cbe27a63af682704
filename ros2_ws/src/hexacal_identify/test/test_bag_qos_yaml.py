"""rosbag2 QoS text (hexacal_identify.bag.qos_yaml): byte-identical to what bags hold."""

from hexacal_identify.bag import BagError
from hexacal_identify.bag.qos_yaml import (
    DEFAULT_QOS_PROFILES_YAML,
    first_offered_profile,
    qos_profiles_yaml,
    read_qos_profiles,
)
import pytest

SENSOR_TEXT = (
    '- history: keep_last\n  depth: 5\n  reliability: best_effort\n  durability: volatile\n'
    '  deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n'
    '  liveliness: system_default\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n'
    '  avoid_ros_namespace_conventions: false\n'
)
DEFAULT_TEXT = (
    '- history: keep_last\n  depth: 10\n  reliability: reliable\n  durability: volatile\n'
    '  deadline:\n    sec: 9223372036\n    nsec: 854775807\n'
    '  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: automatic\n'
    '  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n'
    '  avoid_ros_namespace_conventions: false\n'
)


def test_the_text_of_a_profile_is_what_the_collector_always_wrote():
    from hexacal_msgs_py.qos import SENSOR_QOS

    assert qos_profiles_yaml(SENSOR_QOS) == SENSOR_TEXT
    assert DEFAULT_QOS_PROFILES_YAML == DEFAULT_TEXT


def test_written_text_reads_back():
    (profile,) = read_qos_profiles(SENSOR_TEXT)
    assert profile['reliability'] == 'best_effort' and profile['depth'] == 5
    assert profile['deadline'] == {'sec': 0, 'nsec': 0}
    assert first_offered_profile(DEFAULT_TEXT)['durability'] == 'volatile'


def test_version_8_integer_policies_are_renamed():
    (profile,) = read_qos_profiles('- {history: 1, reliability: 2, durability: 1, liveliness: 9}')
    assert profile == {
        'history': 'keep_last',
        'reliability': 'best_effort',
        'durability': 'transient_local',
        'liveliness': 'unknown',
    }


def test_unreadable_text_is_an_error_only_when_strict():
    for text in ('reliability: [', '{a: 1}', '[1, 2]'):
        assert read_qos_profiles(text) == []
        assert first_offered_profile(text) == {}
        with pytest.raises(BagError, match='QoS profiles'):
            read_qos_profiles(text, strict=True)
    assert read_qos_profiles('') == []
