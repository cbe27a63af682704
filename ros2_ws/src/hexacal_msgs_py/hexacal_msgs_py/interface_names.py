"""
ROS interface names of the contract: topics, services, statuses, message types (no imports).

Imports nothing, not even numpy, so that launch tooling (``bringup --help``, the launch
file) names the contract cheaply; hexacal_msgs_py.names re-exports all of them.
Topic and service names are relative so that a node's namespace applies.
"""

SLIDERS_TOPIC = 'hexacal/sliders'
INCLINOMETER_TOPIC = 'hexacal/inclinometer'
ENCODER_TOPIC = 'hexacal/encoder'
POSTURE_TOPIC = 'hexacal/posture'
PARAMETERS_TOPIC = 'hexacal/parameters'
CALIBRATION_STATUS_TOPIC = 'hexacal/calibration_status'
CALIBRATE_SERVICE = 'hexacal/calibrate'
VERIFY_SERVICE = (
    'hexacal/verify'  # identify: verify the latest calibration on the postures received since
)
# identify: the calibration store's deploys (the kinematics node follows the active one).
DEPLOY_SERVICE = 'hexacal/deploy'  # deploy the latest calibration (verified, plausible)
DEPLOY_FORCE_SERVICE = 'hexacal/deploy_force'  # deploy it without those checks (recorded)
ROLLBACK_SERVICE = 'hexacal/rollback'  # back to the previously active calibration

# The executor walks a plan on the machine through its trajectory controller.
EXECUTOR_PAUSE_SERVICE = 'hexacal/executor/pause'
EXECUTOR_RESUME_SERVICE = 'hexacal/executor/resume'
EXECUTOR_ABORT_SERVICE = 'hexacal/executor/abort'
# ros2_control's joint_trajectory_controller listens here (absolute: the controller's
# own namespace).
DEFAULT_COMMAND_TOPIC = '/joint_trajectory_controller/joint_trajectory'

# Measuring modes (hexacal_msgs_py.measuring_modes). The LVDT link's length
# (joint 'link_length', m) is a fourth device reading on its own sensor stream; a machine whose
# actuators can be released offers one std_srvs/SetBool service per actuator joint
# (release_service(joint)): data true releases the joint (it follows the link, its encoder still
# reads), false locks it where it stands; the machine refuses either while moving.
LINK_TOPIC = 'hexacal/link'
RELEASE_SERVICE_PREFIX = 'hexacal/release/'
# The driver's drives fault at their limits (following error, force, link stroke) and hold until
# reset through this std_srvs/Trigger service (re-enabled where they stand).
DRIVER_RESET_SERVICE = 'hexacal/driver/reset'

# The kinematics node: the calibrated model at work.
PLATFORM_POSE_TOPIC = 'hexacal/platform_pose'  # FK of the live actuator readings
TARGET_POSE_TOPIC = (
    'hexacal/target_pose'  # commanded platform pose -> compensated actuator command
)
MACHINE_MARKERS_TOPIC = 'hexacal/machine_markers'  # base joints, rails/legs, platform, device link

# Status names on CALIBRATION_STATUS_TOPIC (one DiagnosticArray topic for every node's status).
CALIBRATION_STATUS_NAME = 'hexacal calibration'
COLLECTOR_STATUS_NAME = 'hexacal collector'
DEPLOYMENT_STATUS_NAME = 'hexacal deployment'
EXECUTOR_STATUS_NAME = 'hexacal executor'
KINEMATICS_STATUS_NAME = 'hexacal kinematics'
VERIFICATION_STATUS_NAME = 'hexacal verification'
DRIVER_STATUS_NAME = 'hexacal driver'  # the machine's drives: mode, released joint, faults

JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
FLOAT64_MULTI_ARRAY_TYPE = 'std_msgs/msg/Float64MultiArray'
DIAGNOSTIC_ARRAY_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
TRIGGER_TYPE = 'std_srvs/srv/Trigger'
SET_BOOL_TYPE = 'std_srvs/srv/SetBool'
IMU_TYPE = 'sensor_msgs/msg/Imu'
POSE_STAMPED_TYPE = 'geometry_msgs/msg/PoseStamped'
MARKER_ARRAY_TYPE = 'visualization_msgs/msg/MarkerArray'
JOINT_TRAJECTORY_TYPE = 'trajectory_msgs/msg/JointTrajectory'

SLIDERS_TYPE = JOINT_STATE_TYPE
INCLINOMETER_TYPE = JOINT_STATE_TYPE
ENCODER_TYPE = JOINT_STATE_TYPE
POSTURE_TYPE = JOINT_STATE_TYPE
PARAMETERS_TYPE = FLOAT64_MULTI_ARRAY_TYPE
CALIBRATION_STATUS_TYPE = DIAGNOSTIC_ARRAY_TYPE
CALIBRATE_SERVICE_TYPE = TRIGGER_TYPE
LINK_TYPE = JOINT_STATE_TYPE
RELEASE_SERVICE_TYPE = SET_BOOL_TYPE

# Message type string of every topic, e.g. for recording and replaying bags.
TOPIC_TYPES: dict[str, str] = {
    SLIDERS_TOPIC: SLIDERS_TYPE,
    INCLINOMETER_TOPIC: INCLINOMETER_TYPE,
    ENCODER_TOPIC: ENCODER_TYPE,
    POSTURE_TOPIC: POSTURE_TYPE,
    LINK_TOPIC: LINK_TYPE,
    PARAMETERS_TOPIC: PARAMETERS_TYPE,
    CALIBRATION_STATUS_TOPIC: CALIBRATION_STATUS_TYPE,
    PLATFORM_POSE_TOPIC: POSE_STAMPED_TYPE,
    TARGET_POSE_TOPIC: POSE_STAMPED_TYPE,
    MACHINE_MARKERS_TOPIC: MARKER_ARRAY_TYPE,
}


def release_service(joint: str) -> str:
    """Return the release/lock service of an actuator joint, e.g. hexacal/release/slider_3."""
    return RELEASE_SERVICE_PREFIX + joint


# The inclinometer input types (hexacal_msgs_py.inputs): a JointState or a sensor_msgs/Imu.
JOINT_STATE_INCLINOMETER = 'joint_state'
IMU_INCLINOMETER = 'imu'
INCLINOMETER_TYPES = (JOINT_STATE_INCLINOMETER, IMU_INCLINOMETER)
