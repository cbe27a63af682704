"""Topic, service, joint and parameter names of the hexacal contract (ROS-free).

Topic and service names are relative so that a node's namespace applies.
"""

SLIDERS_TOPIC = 'hexacal/sliders'
INCLINOMETER_TOPIC = 'hexacal/inclinometer'
ENCODER_TOPIC = 'hexacal/encoder'
POSTURE_TOPIC = 'hexacal/posture'
PARAMETERS_TOPIC = 'hexacal/parameters'
CALIBRATION_STATUS_TOPIC = 'hexacal/calibration_status'
CALIBRATE_SERVICE = 'hexacal/calibrate'

JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
FLOAT64_MULTI_ARRAY_TYPE = 'std_msgs/msg/Float64MultiArray'
DIAGNOSTIC_ARRAY_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
TRIGGER_TYPE = 'std_srvs/srv/Trigger'

SLIDERS_TYPE = JOINT_STATE_TYPE
INCLINOMETER_TYPE = JOINT_STATE_TYPE
ENCODER_TYPE = JOINT_STATE_TYPE
POSTURE_TYPE = JOINT_STATE_TYPE
PARAMETERS_TYPE = FLOAT64_MULTI_ARRAY_TYPE
CALIBRATION_STATUS_TYPE = DIAGNOSTIC_ARRAY_TYPE
CALIBRATE_SERVICE_TYPE = TRIGGER_TYPE

# Message type string of every topic, e.g. for recording and replaying bags.
TOPIC_TYPES: dict[str, str] = {
    SLIDERS_TOPIC: SLIDERS_TYPE,
    INCLINOMETER_TOPIC: INCLINOMETER_TYPE,
    ENCODER_TOPIC: ENCODER_TYPE,
    POSTURE_TOPIC: POSTURE_TYPE,
    PARAMETERS_TOPIC: PARAMETERS_TYPE,
    CALIBRATION_STATUS_TOPIC: CALIBRATION_STATUS_TYPE,
}

# JointState joint names. Slider positions are the articular variables
# lambda_i in m; inclinometer_x is alpha (about X), inclinometer_y is beta
# (about Y) and rotary is phi, all in rad.
N_CHAINS = 6
SLIDER_NAMES: tuple[str, ...] = tuple(f'slider_{i}' for i in range(1, N_CHAINS + 1))
INCLINOMETER_NAMES: tuple[str, ...] = ('inclinometer_x', 'inclinometer_y')
ENCODER_NAMES: tuple[str, ...] = ('rotary',)
POSTURE_NAMES: tuple[str, ...] = SLIDER_NAMES + INCLINOMETER_NAMES + ENCODER_NAMES

# The 54-vector is chain-major: for each chain A0 (3, base frame, m),
# B (3, platform frame, m), link length l (m), rail direction a_x, a_y
# (x, y components of the unit rail vector a).
PARAMETER_FIELDS: tuple[str, ...] = ('A0x', 'A0y', 'A0z', 'Bx', 'By', 'Bz', 'l', 'ax', 'ay')
N_PARAMETERS_PER_CHAIN = len(PARAMETER_FIELDS)
N_PARAMETERS = N_CHAINS * N_PARAMETERS_PER_CHAIN

# Full name of every entry of the 54-vector, e.g. 'chain_3.ax'.
PARAMETER_NAMES: tuple[str, ...] = tuple(
    f'chain_{chain}.{field}'
    for chain in range(1, N_CHAINS + 1)
    for field in PARAMETER_FIELDS)


def parameter_index(chain: int, field: str) -> int:
    """Index into the 54-vector of `field` of `chain` (1-based, as in chain_1)."""
    if not 1 <= chain <= N_CHAINS:
        raise ValueError(f'chain must be in 1..{N_CHAINS}, got {chain}')
    if field not in PARAMETER_FIELDS:
        raise ValueError(f'field must be one of {PARAMETER_FIELDS}, got {field!r}')
    return (chain - 1) * N_PARAMETERS_PER_CHAIN + PARAMETER_FIELDS.index(field)
