"""
rosbag2's QoS text: the `offered_qos_profiles` of a topic, written and read in one place.

A bag stores, per topic, the QoS its publishers offered, as YAML text in the MCAP channel
metadata and as a list in metadata.yaml. Jazzy's rosbag2 (metadata version 9) spells the
policies as names ('reliable'); version 8 and older used the rmw integer enums, which
`read_qos_profiles` renames. The writer takes anything shaped like an rclpy QoSProfile
(policies with a `name`, durations with `nanoseconds`), so this module needs no rclpy.
"""

from __future__ import annotations

from typing import Any

from hexacal_msgs_py.readings import NS_PER_S
import yaml

from .errors import BagError

# RMW_DURATION_INFINITE: what rosbag2 writes for an unset deadline, lifespan or lease.
INFINITE_DURATION_NS = 2**63 - 1

# Integer enums of metadata version <= 8 (rmw_qos_*_policy_t) -> version 9 names.
_QOS_POLICY_NAMES: dict[str, dict[int, str]] = {
    'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'},
    'reliability': {
        0: 'system_default',
        1: 'reliable',
        2: 'best_effort',
        3: 'unknown',
        4: 'best_available',
    },
    'durability': {
        0: 'system_default',
        1: 'transient_local',
        2: 'volatile',
        3: 'unknown',
        4: 'best_available',
    },
    'liveliness': {
        0: 'system_default',
        1: 'automatic',
        2: 'manual_by_node',
        3: 'manual_by_topic',
        4: 'unknown',
        5: 'best_available',
    },
}


def _duration(nanoseconds: int) -> dict[str, int]:
    seconds, remainder = divmod(int(nanoseconds), NS_PER_S)
    return {'sec': seconds, 'nsec': remainder}


def qos_profile_entry(
    *,
    history: str,
    depth: int,
    reliability: str,
    durability: str,
    deadline_ns: int,
    lifespan_ns: int,
    liveliness: str,
    liveliness_lease_duration_ns: int,
    avoid_ros_namespace_conventions: bool,
) -> dict[str, Any]:
    """Return one offered profile as rosbag2 (version 9) spells it, keys in its order."""
    return {
        'history': history,
        'depth': int(depth),
        'reliability': reliability,
        'durability': durability,
        'deadline': _duration(deadline_ns),
        'lifespan': _duration(lifespan_ns),
        'liveliness': liveliness,
        'liveliness_lease_duration': _duration(liveliness_lease_duration_ns),
        'avoid_ros_namespace_conventions': bool(avoid_ros_namespace_conventions),
    }


def profile_entry(profile: Any) -> dict[str, Any]:
    """Return the rosbag2 entry of an rclpy QoSProfile (read through its attributes)."""
    return qos_profile_entry(
        history=profile.history.name.lower(),
        depth=profile.depth,
        reliability=profile.reliability.name.lower(),
        durability=profile.durability.name.lower(),
        deadline_ns=profile.deadline.nanoseconds,
        lifespan_ns=profile.lifespan.nanoseconds,
        liveliness=profile.liveliness.name.lower(),
        liveliness_lease_duration_ns=profile.liveliness_lease_duration.nanoseconds,
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )


def write_qos_profiles(entries: list[dict[str, Any]]) -> str:
    """Return the offered_qos_profiles YAML text of these entries (a YAML list)."""
    return yaml.safe_dump(entries, sort_keys=False)


def qos_profiles_yaml(profile: Any) -> str:
    """Return the offered_qos_profiles text of a topic offered with this rclpy QoSProfile."""
    return write_qos_profiles([profile_entry(profile)])


# What rosbag2 assumes of a topic whose QoS is not known: reliable, volatile, depth 10.
DEFAULT_QOS_PROFILES: list[dict[str, Any]] = [
    qos_profile_entry(
        history='keep_last',
        depth=10,
        reliability='reliable',
        durability='volatile',
        deadline_ns=INFINITE_DURATION_NS,
        lifespan_ns=INFINITE_DURATION_NS,
        liveliness='automatic',
        liveliness_lease_duration_ns=INFINITE_DURATION_NS,
        avoid_ros_namespace_conventions=False,
    )
]
DEFAULT_QOS_PROFILES_YAML = write_qos_profiles(DEFAULT_QOS_PROFILES)


def read_qos_profiles(qos_profiles_yaml: str, *, strict: bool = False) -> list[dict]:
    """
    Return the offered profiles of offered_qos_profiles YAML text (integer enums renamed).

    With `strict`, text that is not a YAML list of mappings raises BagError;
    otherwise it yields [] (reindexing foreign files must not fail on QoS).
    """
    try:
        profiles = yaml.safe_load(qos_profiles_yaml) if qos_profiles_yaml else []
    except yaml.YAMLError as error:
        if strict:
            raise BagError(f'QoS profiles are not valid YAML: {error}') from error
        return []
    if profiles is None:
        profiles = []
    if not isinstance(profiles, list) or not all(isinstance(p, dict) for p in profiles):
        if strict:
            raise BagError(f'QoS profiles must be a YAML list of mappings, got {profiles!r}')
        return []
    converted = []
    for profile in profiles:
        profile = dict(profile)
        for policy, names in _QOS_POLICY_NAMES.items():
            value = profile.get(policy)
            if isinstance(value, int) and not isinstance(value, bool):
                profile[policy] = names.get(value, 'unknown')
        converted.append(profile)
    return converted


def first_offered_profile(qos_profiles_yaml: str) -> dict[str, Any]:
    """Return the first offered profile of the text ({} if none or unreadable)."""
    profiles = read_qos_profiles(qos_profiles_yaml)
    return profiles[0] if profiles else {}
