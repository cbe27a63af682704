"""
Input mappings (issue #11).

Joints and topics of the user's drivers, the Imu inclinometer convention.
"""

import math

from hexacal_msgs_py import conversions as conv
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError
from hexacal_msgs_py.inputs import (
    inclinometer_angles_to_quaternion,
    InputMapping,
    InputMappingError,
    MAPPING_KEYS,
    quaternion_to_inclinometer_angles,
)
from hexacal_msgs_py.readings import InclinometerReading
import numpy as np
import pytest
from sensor_msgs.msg import Imu, JointState

ACTUATORS = ('act_a', 'act_b', 'act_c', 'act_d', 'act_e', 'act_f')


def broadcaster_message(stamp_ns: int = 1_500_000_000_000_000_123) -> JointState:
    """One /joint_states carrying every reading (custom names, another order) and other joints."""
    names = [
        'base_yaw',
        'act_c',
        'act_a',
        'incl_b',
        'act_b',
        'gripper',
        'act_d',
        'act_e',
        'act_f',
        'rot',
        'incl_a',
    ]
    values = {
        'act_a': 0.1,
        'act_b': 0.2,
        'act_c': 0.3,
        'act_d': 0.4,
        'act_e': 0.5,
        'act_f': 0.6,
        'incl_a': 0.01,
        'incl_b': -0.02,
        'rot': 0.03,
        'base_yaw': 7.0,
        'gripper': math.nan,
    }
    message = JointState(
        name=names,
        position=[values[n] for n in names],
        velocity=[1.0] * len(names),
        effort=[2.0] * len(names),
    )
    message.header.stamp = conv.to_stamp(stamp_ns)
    return message


def mapping(**overrides) -> InputMapping:
    arguments = {
        'actuator_joints': ACTUATORS,
        'inclinometer_joints': ('incl_a', 'incl_b'),
        'rotary_joint': 'rot',
        'topics': ('/joint_states',) * 3,
    }
    arguments.update(overrides)
    return InputMapping(**arguments)


def test_one_joint_states_message_gives_every_reading_by_the_mapping():
    message, m = broadcaster_message(), mapping()
    assert conv.joint_state_to_actuator_reading(message, mapping=m).actuator_positions == (
        0.1,
        0.2,
        0.3,
        0.4,
        0.5,
        0.6,
    )
    angles = conv.joint_state_to_inclinometer_reading(message, m)
    assert (angles.alpha, angles.beta, angles.stamp_ns) == (0.01, -0.02, 1_500_000_000_000_000_123)
    assert conv.joint_state_to_encoder_reading(message, m).phi == 0.03
    with pytest.raises(
        InvalidReadingError, match='lacks joint'
    ):  # the contract's names are not there
        conv.joint_state_to_actuator_reading(message)


def test_signs_and_offsets_apply_to_a_joint_state_inclinometer():
    m = mapping(inclinometer_signs=[-1, 1], inclinometer_offsets_rad=[0.005, -0.01])
    angles = conv.joint_state_to_inclinometer_reading(broadcaster_message(), m)
    assert angles.alpha == -(0.01 - 0.005) and angles.beta == -0.02 + 0.01
    assert m.inclinometer_angles(*m.raw_inclinometer(0.3, -0.2)) == pytest.approx(
        (0.3, -0.2), abs=1e-16
    )


def test_the_default_mapping_reads_exactly_as_without_one():
    m = InputMapping.default('gough_stewart')
    assert m.actuator_joints == tuple(f'leg_{i}' for i in range(1, 7)) and m.is_contract(
        'gough_stewart'
    )
    assert not mapping().is_contract()
    reading = InclinometerReading(5, 0.123456789, -0.987654321e-3)
    message = conv.inclinometer_reading_to_joint_state(reading)
    assert conv.joint_state_to_inclinometer_reading(message, InputMapping.default()) == reading


@pytest.mark.parametrize(
    'overrides, parameter, text',
    [
        ({'actuator_joints': ACTUATORS[:5]}, 'actuator_joints', 'must name 6 joints, got 5'),
        ({'actuator_joints': 'act_a'}, 'actuator_joints', 'must be a list of 6 joint names'),
        (
            {'actuator_joints': (*ACTUATORS[:5], 'act_a')},
            'actuator_joints',
            'act_a more than once',
        ),
        ({'actuator_joints': (*ACTUATORS[:5], '')}, 'actuator_joints', 'non-empty strings'),
        (
            {'inclinometer_joints': ('incl_a',)},
            'inclinometer_joints',
            'must name 2 joints, got 1',
        ),
        ({'rotary_joint': ''}, 'rotary_joint', 'must be a joint name'),
        ({'rotary_joint': 'act_b'}, 'rotary_joint', "'act_b' is also in actuator_joints"),
        (
            {'inclinometer_type': 'gyro'},
            'inclinometer_type',
            "'joint_state' or 'imu', got 'gyro'",
        ),
        ({'inclinometer_type': 'imu'}, 'inclinometer_type', "'imu' needs a topic of its own"),
        ({'inclinometer_signs': [1, 0.5]}, 'inclinometer_signs', 'each sign must be 1 or -1'),
        ({'inclinometer_signs': [1]}, 'inclinometer_signs', 'must be 2 numbers'),
        ({'inclinometer_offsets_rad': [0.0, math.nan]}, 'inclinometer_offsets_rad', 'finite'),
        ({'inclinometer_offsets_rad': [4.0, 0.0]}, 'inclinometer_offsets_rad', r'within \+-pi'),
    ],
)
def test_bad_mappings_are_named(overrides, parameter, text):
    with pytest.raises(InputMappingError, match=text) as caught:
        mapping(**overrides)
    assert caught.value.parameter == parameter and str(caught.value).startswith(parameter + ': ')
    assert isinstance(caught.value, HexacalContractError) and isinstance(caught.value, ValueError)


def test_separate_topics_may_reuse_a_joint_name():
    m = mapping(rotary_joint='act_b', topics=('/joint_states', '/joint_states', '/encoder'))
    assert m.rotary_joint == 'act_b'


def test_metadata_round_trip_and_a_bag_without_a_mapping():
    m = mapping(
        inclinometer_type='imu',
        inclinometer_signs=(-1.0, 1.0),
        inclinometer_offsets_rad=(0.1 / 3, -2e-5),
        topics=('/joint_states', '/imu', '/joint_states'),
    )
    record = m.to_metadata()
    assert set(record) == set(MAPPING_KEYS) and all(isinstance(v, str) for v in record.values())
    assert InputMapping.from_metadata({'model': 'hexa_slide', **record}) == m
    assert InputMapping.from_metadata({'model': 'hexa_slide', 'window_s': '0.3'}) is None
    partial = InputMapping.from_metadata({'rotary_joint': 'rot'}, 'gough_stewart')
    assert partial.actuator_joints[0] == 'leg_1' and partial.topics == ('', '', '')
    with pytest.raises(InputMappingError, match='actuator_joints: recorded value'):
        InputMapping.from_metadata({'actuator_joints': 'act_a,act_b'})


# --------------------------------------------------------------------------- the Imu convention


def rotation_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_the_sensors_up_vector_is_as_documented_whatever_the_heading():
    rng = np.random.default_rng(1)
    for alpha, beta, yaw in rng.uniform([-1.2, -1.2, -3.1], [1.2, 1.2, 3.1], (200, 3)):
        q = inclinometer_angles_to_quaternion(alpha, beta, yaw)
        up = rotation_matrix(q).T @ [0.0, 0.0, 1.0]
        assert up == pytest.approx(
            [math.sin(beta), -math.sin(alpha) * math.cos(beta), math.cos(alpha) * math.cos(beta)],
            abs=1e-15,
        )
        assert quaternion_to_inclinometer_angles(*q) == pytest.approx((alpha, beta), abs=1e-14)
        # -q is the same orientation
        assert quaternion_to_inclinometer_angles(*(-c for c in q)) == pytest.approx(
            (alpha, beta), abs=1e-14
        )


def test_small_tilts_read_minus_the_right_handed_rotation():
    # The sensor turned by +0.01 rad about its X axis (right hand) reads alpha = -0.01; about Y,
    # beta = -0.01.
    about_x = (math.sin(0.005), 0.0, 0.0, math.cos(0.005))
    about_y = (0.0, math.sin(0.005), 0.0, math.cos(0.005))
    assert quaternion_to_inclinometer_angles(*about_x) == pytest.approx((-0.01, 0.0), abs=1e-15)
    assert quaternion_to_inclinometer_angles(*about_y) == pytest.approx((0.0, -0.01), abs=1e-15)
    assert quaternion_to_inclinometer_angles(0.0, 0.0, math.sin(0.4), math.cos(0.4)) == (0.0, 0.0)


@pytest.mark.parametrize(
    'quaternion, text',
    [
        ((0.0, 0.0, 0.0, 0.0), 'not a unit quaternion'),
        ((0.0, 0.0, 0.0, 1.1), 'not a unit quaternion'),
        ((math.nan, 0.0, 0.0, 1.0), 'orientation.x is nan'),
    ],
)
def test_an_orientation_that_is_no_rotation_is_an_invalid_reading(quaternion, text):
    with pytest.raises(InvalidReadingError, match=text):
        quaternion_to_inclinometer_angles(*quaternion)


def test_imu_message_round_trip_with_signs_offsets_and_a_heading():
    m = mapping(
        inclinometer_type='imu',
        inclinometer_signs=(-1, 1),
        inclinometer_offsets_rad=(0.01, -0.02),
        topics=('/joint_states', '/imu', '/joint_states'),
    )
    reading = InclinometerReading(42, 0.123, -0.0456)
    message = conv.inclinometer_angles_to_imu(reading, 'imu_link', mapping=m, yaw=2.0)
    assert isinstance(message, Imu) and message.header.frame_id == 'imu_link'
    back = conv.imu_to_inclinometer_reading(message, m)
    assert back.stamp_ns == 42
    assert (back.alpha, back.beta) == pytest.approx((0.123, -0.0456), abs=1e-15)
    raw = conv.imu_to_inclinometer_reading(message)  # without the mapping: the sensor's own angles
    assert (raw.alpha, raw.beta) == pytest.approx((-0.123 + 0.01, -0.0456 - 0.02), abs=1e-15)
    message.orientation_covariance[0] = -1.0
    with pytest.raises(InvalidReadingError, match='no orientation estimate'):
        conv.imu_to_inclinometer_reading(message, m)
