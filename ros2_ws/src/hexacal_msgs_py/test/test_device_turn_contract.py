"""
The device turn in the contract.

The optional 'device_turn' joint of postures and inclinometer messages.
"""

import math

from builtin_interfaces.msg import Time
from hexacal_msgs_py import conversions as conv
from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.inputs import InputMapping
from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE
from hexacal_msgs_py.names import (
    DEVICE_TURN_JOINT,
    INCLINOMETER_NAMES,
    POSTURE_NAMES,
    posture_names,
)
from hexacal_msgs_py.readings import (
    ActuatorReading,
    EncoderReading,
    InclinometerReading,
    PostureReading,
)
import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

SLIDERS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)


def posture(turn: float = 0.0) -> PostureReading:
    return PostureReading(1_234_567_890, SLIDERS, 0.01, -0.02, 0.03, device_turn=turn)


def joint_state(names, positions, stamp_ns: int = 5) -> JointState:
    seconds, nanoseconds = divmod(stamp_ns, 1_000_000_000)
    return JointState(
        header=Header(stamp=Time(sec=seconds, nanosec=nanoseconds)),
        name=list(names),
        position=[float(p) for p in positions],
    )


def test_the_joint_name_and_defaults():
    assert DEVICE_TURN_JOINT == 'device_turn'
    assert DEVICE_TURN_JOINT not in POSTURE_NAMES  # optional: the nine values stay nine
    assert PostureReading(0, SLIDERS, 0.0, 0.0, 0.0).device_turn == 0.0
    assert InclinometerReading(0, 0.0, 0.0).device_turn == 0.0
    assert len(posture(math.pi).values()) == 9


@pytest.mark.parametrize('turn', [0.0, math.pi, -math.pi / 2, 2 * math.pi])
@pytest.mark.parametrize('model', [HEXA_SLIDE, GOUGH_STEWART])
def test_posture_round_trip(turn, model):
    message = conv.posture_reading_to_joint_state(posture(turn), model=model)
    expected = posture_names(model) + ((DEVICE_TURN_JOINT,) if turn else ())
    assert tuple(message.name) == expected
    back = conv.joint_state_to_posture_reading(message, model)
    assert back == posture(turn)
    assert back.device_turn == turn


def test_a_normally_mounted_posture_message_is_as_before():
    message = conv.posture_reading_to_joint_state(posture(0.0))
    assert tuple(message.name) == POSTURE_NAMES
    assert list(message.position) == list(posture().values())


def test_an_old_message_without_the_joint_reads_as_turn_zero():
    old = joint_state(POSTURE_NAMES, SLIDERS + (0.01, -0.02, 0.03), stamp_ns=1_234_567_890)
    assert conv.joint_state_to_posture_reading(old).device_turn == 0.0
    old_inclinometer = joint_state(INCLINOMETER_NAMES, (0.01, -0.02))
    assert conv.joint_state_to_inclinometer_reading(old_inclinometer).device_turn == 0.0


def test_the_joint_in_any_order():
    names = ('device_turn',) + POSTURE_NAMES[::-1]
    message = joint_state(names, (math.pi, 0.03, -0.02, 0.01) + SLIDERS[::-1], 1_234_567_890)
    assert conv.joint_state_to_posture_reading(message) == posture(math.pi)


@pytest.mark.parametrize('turn', [0.0, math.pi, math.pi / 2])
def test_inclinometer_round_trip(turn):
    reading = InclinometerReading(7, 0.01, -0.02, turn)
    message = conv.inclinometer_reading_to_joint_state(reading)
    assert tuple(message.name) == INCLINOMETER_NAMES + ((DEVICE_TURN_JOINT,) if turn else ())
    assert conv.joint_state_to_inclinometer_reading(message) == reading


def test_from_parts_takes_the_turn_of_the_inclinometer():
    parts = PostureReading.from_parts(
        ActuatorReading(3, SLIDERS),
        InclinometerReading(4, 0.1, 0.2, math.pi),
        EncoderReading(5, 0.3),
    )
    assert parts.device_turn == math.pi
    assert parts.stamp_ns == 3


def test_from_values_takes_an_optional_turn():
    values = SLIDERS + (0.01, -0.02, 0.03)
    assert PostureReading.from_values(1, values).device_turn == 0.0
    assert PostureReading.from_values(1, values, device_turn=math.pi).device_turn == math.pi


@pytest.mark.parametrize('bad', [float('nan'), float('inf'), 7.0, -6.3, 'pi', None, True])
def test_an_invalid_turn_is_named(bad):
    with pytest.raises(InvalidReadingError, match='device_turn'):
        PostureReading(0, SLIDERS, 0.0, 0.0, 0.0, device_turn=bad)
    with pytest.raises(InvalidReadingError, match='device_turn'):
        InclinometerReading(0, 0.0, 0.0, bad)


@pytest.mark.parametrize('bad', [float('nan'), 7.0])
def test_an_invalid_turn_joint_is_an_invalid_reading(bad):
    message = joint_state(POSTURE_NAMES + (DEVICE_TURN_JOINT,), SLIDERS + (0.01, -0.02, 0.03, bad))
    with pytest.raises(InvalidReadingError, match='device_turn'):
        conv.joint_state_to_posture_reading(message)
    inclinometer = joint_state(INCLINOMETER_NAMES + (DEVICE_TURN_JOINT,), (0.01, -0.02, bad))
    with pytest.raises(InvalidReadingError, match='device_turn'):
        conv.joint_state_to_inclinometer_reading(inclinometer)


def test_a_repeated_turn_joint_is_an_invalid_reading():
    message = joint_state(
        INCLINOMETER_NAMES + (DEVICE_TURN_JOINT, DEVICE_TURN_JOINT), (0.01, -0.02, 1.0, 2.0)
    )
    with pytest.raises(InvalidReadingError, match='device_turn'):
        conv.joint_state_to_inclinometer_reading(message)


def test_a_mapped_inclinometer_without_the_joint_reads_turn_zero():
    """
    Check a mapped inclinometer without the device_turn joint reads turn zero.

    A user's /joint_states (mapped joint names, signs) without the joint: the normal mounting; with
    it, its value.
    """
    mapping = InputMapping(
        actuator_joints=tuple(f'axis_{i}' for i in range(1, 7)),
        inclinometer_joints=('tilt_x', 'tilt_y'),
        rotary_joint='yaw',
        inclinometer_signs=(-1, 1),
    )
    names = tuple(f'axis_{i}' for i in range(1, 7)) + ('tilt_x', 'tilt_y', 'yaw')
    message = joint_state(names, SLIDERS + (0.01, -0.02, 0.03))
    reading = conv.joint_state_to_inclinometer_reading(message, mapping)
    assert (reading.alpha, reading.beta, reading.device_turn) == (-0.01, -0.02, 0.0)
    turned = joint_state(names + (DEVICE_TURN_JOINT,), SLIDERS + (0.01, -0.02, 0.03, math.pi))
    assert conv.joint_state_to_inclinometer_reading(turned, mapping).device_turn == math.pi
    # The Imu path has no joint: always the normal mounting (the collector's parameter decides).
    imu = conv.inclinometer_angles_to_imu(InclinometerReading(9, 0.01, -0.02))
    assert conv.imu_to_inclinometer_reading(imu).device_turn == 0.0


def test_device_defect_keys_of_a_parameters_file():
    from hexacal_msgs_py.models import device_defect_key, DEVICE_DEFECT_NAMES, DEVICE_DEFECT_UNITS

    assert DEVICE_DEFECT_NAMES == ('dL', 'alpha0', 'beta0', 'gamma', 'phi0')
    assert DEVICE_DEFECT_UNITS == ('m', 'rad', 'rad', 'rad', 'rad')
    assert [device_defect_key(n) for n in DEVICE_DEFECT_NAMES] == [
        'device.defects.dL',
        'device.defects.alpha0',
        'device.defects.beta0',
        'device.defects.gamma',
        'device.defects.phi0',
    ]
    with pytest.raises(ValueError, match='tilt'):
        device_defect_key('tilt')
