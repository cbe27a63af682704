"""QoS profiles of the hexacal topics (imports rclpy)."""

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    qos_profile_sensor_data,
    QoSProfile,
    ReliabilityPolicy,
)

# Raw sensor streams: best effort, shallow; a lost sample is superseded by the next.
SENSOR_QOS: QoSProfile = qos_profile_sensor_data

# Synchronised postures feed the identification: none may be lost.
POSTURE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

# Latest identified parameters and calibration status are latched so that
# late joiners receive them.
PARAMETERS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# A subscriber that acts on the statuses of several nodes (a monitor: the demo, a test probe).
# hexacal/calibration_status has four publishers (identify, executor, collector, kinematics) and
# a reader of depth 1 keeps one sample for all of them: a status followed by another node's before
# the reader takes it is overwritten, e.g. identify's last 'collecting' count by the executor's
# 'done' 10 ms later. Deep enough for every status between two spins; compatible with STATUS_QOS
# (reliable, transient local: the latched ones still arrive).
STATUS_MONITOR_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# Commands: reliable, volatile (a stale command must not replay on a late joiner); what
# ros2_control's joint_trajectory_controller subscribes with (system default QoS: reliable,
# volatile).
COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

# The live platform pose is a stream like the sensors it comes from.
POSE_QOS: QoSProfile = SENSOR_QOS

# Machine markers: the latest set is what a visualiser needs, also when it joins late.
MARKERS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
