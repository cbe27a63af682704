"""
Topic, service, joint and parameter names of the hexacal contract (ROS-free).

Topic and service names are relative so that a node's namespace applies. The ROS interface
names live in interface_names (no imports, for launch tooling) and are re-exported here.
"""

from hexacal_msgs_py.interface_names import (  # noqa: F401 - re-exported
    CALIBRATE_SERVICE,
    CALIBRATE_SERVICE_TYPE,
    CALIBRATION_STATUS_NAME,
    CALIBRATION_STATUS_TOPIC,
    CALIBRATION_STATUS_TYPE,
    COLLECTOR_STATUS_NAME,
    DEFAULT_COMMAND_TOPIC,
    DEPLOY_FORCE_SERVICE,
    DEPLOY_SERVICE,
    DEPLOYMENT_STATUS_NAME,
    DIAGNOSTIC_ARRAY_TYPE,
    DRIVER_RESET_SERVICE,
    DRIVER_STATUS_NAME,
    ENCODER_TOPIC,
    ENCODER_TYPE,
    EXECUTOR_ABORT_SERVICE,
    EXECUTOR_PAUSE_SERVICE,
    EXECUTOR_RESUME_SERVICE,
    EXECUTOR_STATUS_NAME,
    IMU_TYPE,
    INCLINOMETER_TOPIC,
    INCLINOMETER_TYPE,
    JOINT_STATE_TYPE,
    JOINT_TRAJECTORY_TYPE,
    KINEMATICS_STATUS_NAME,
    LINK_TOPIC,
    LINK_TYPE,
    MACHINE_MARKERS_TOPIC,
    MARKER_ARRAY_TYPE,
    PARAMETERS_TOPIC,
    PARAMETERS_TYPE,
    PLATFORM_POSE_TOPIC,
    POSE_STAMPED_TYPE,
    POSTURE_TOPIC,
    POSTURE_TYPE,
    release_service,
    RELEASE_SERVICE_PREFIX,
    RELEASE_SERVICE_TYPE,
    ROLLBACK_SERVICE,
    SET_BOOL_TYPE,
    SLIDERS_TOPIC,
    SLIDERS_TYPE,
    TARGET_POSE_TOPIC,
    TOPIC_TYPES,
    TRIGGER_TYPE,
    VERIFICATION_STATUS_NAME,
    VERIFY_SERVICE,
)
from hexacal_msgs_py.models import (  # noqa: F401 - DEVICE_TURN_JOINT, MAX_DEVICE_TURN re-exported
    DEFAULT_MODEL,
    DEVICE_JOINT_NAMES,
    DEVICE_TURN_JOINT,
    GOUGH_STEWART,
    HEXA_SLIDE,
    LINK_LENGTH_JOINT,
    MAX_DEVICE_TURN,
    model_layout,
    MODELS,
)

_HEXA = MODELS[HEXA_SLIDE]

# JointState joint names. Actuator positions are the articular variables
# lambda_i in m (Hexa Slide: slider_1..6 along the rails; Gough-Stewart:
# leg_1..6, leg extensions); inclinometer_x is alpha (about X), inclinometer_y
# is beta (about Y) and rotary is phi, all in rad. The per-model layouts live
# in models.py; the names below are the Hexa Slide's (the default model).
N_CHAINS = _HEXA.n_chains
SLIDER_NAMES: tuple[str, ...] = _HEXA.actuator_names
LEG_NAMES: tuple[str, ...] = MODELS[GOUGH_STEWART].actuator_names
INCLINOMETER_NAMES: tuple[str, ...] = DEVICE_JOINT_NAMES[:2]
ENCODER_NAMES: tuple[str, ...] = DEVICE_JOINT_NAMES[2:]
POSTURE_NAMES: tuple[str, ...] = _HEXA.posture_names
# DEVICE_TURN_JOINT ('device_turn', rad) is an optional extra joint of the
# posture and inclinometer JointStates (not in POSTURE_NAMES / INCLINOMETER_NAMES):
# the device's rotation about its link axis from its normal mounting (0 normal,
# pi reversed, pi/2 quarter turn); absent means 0.  |turn| <= MAX_DEVICE_TURN (2 pi).
# LINK_LENGTH_JOINT ('link_length', m) is reserved for the lvdt measuring mode
# (measuring_modes.py): the measured length of a telescopic link, the fourth
# device reading; like device_turn it is not in POSTURE_NAMES.

# The Hexa Slide's 54-vector is chain-major: for each chain A0 (3, base frame,
# m), B (3, platform frame, m), link length l (m), rail direction a_x, a_y
# (x, y components of the unit rail vector a).
PARAMETER_FIELDS: tuple[str, ...] = _HEXA.fields
N_PARAMETERS_PER_CHAIN = len(PARAMETER_FIELDS)
N_PARAMETERS = N_CHAINS * N_PARAMETERS_PER_CHAIN

# Full name of every entry of the 54-vector, e.g. 'chain_3.ax'.
PARAMETER_NAMES: tuple[str, ...] = _HEXA.parameter_names


def actuator_names(model: str | None = None) -> tuple[str, ...]:
    """Actuator joint names of `model` on hexacal/sliders (None: the Hexa Slide's slider_1..6)."""
    return model_layout(DEFAULT_MODEL if model is None else model).actuator_names


def posture_names(model: str | None = None) -> tuple[str, ...]:
    """
    Return the joint names of a posture of `model`.

    Its six actuators, inclinometer_x, inclinometer_y, rotary.
    """
    return model_layout(DEFAULT_MODEL if model is None else model).posture_names


def parameter_index(chain: int, field: str) -> int:
    """Index into the 54-vector of `field` of `chain` (1-based, as in chain_1)."""
    return _HEXA.parameter_index(chain, field)
