"""
The kinematics node's ROS parameters: names, defaults, ranges and descriptions.

Kept apart from nodes/kinematics_node.py so the node module holds only the glue; the checks beyond
type and range are core/sessions/kinematics_session.py's `check_parameter`. Every parameter is
read only except `RUNTIME_PARAMETERS`; `stroke_limits` is declared without a default (`UNSET`:
a double array, unset = the architecture's stroke).
"""

from __future__ import annotations

from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC
from hexacal_msgs_py.node_parameters import ParameterSpec as _Spec

from ..core.machine.device import MOUNTS
from ..core.sessions.kinematics_session import MIN_MOVE_TIME_S

DEFAULT_BASE_FRAME = 'hexacal_base'
RUNTIME_PARAMETERS = ('base_frame', 'max_actuator_speed', 'stroke_limits')
# Actuator quantities (core.architectures.actuator_defaults): declared once the model in use is
# known, with its defaults (the specs' for sliders and legs; the default model's if none yet).
ACTUATOR_PARAMETERS = {'max_actuator_speed': 'speed'}
UNSET = ('stroke_limits',)  # spec default None: declared as a double array without a value

PARAMETERS: dict[str, _Spec] = {
    'parameters': _Spec(
        '',
        'parameters YAML (either model) to start from when the calibration '
        "store has no active calibration; '' = wait for a deploy",
    ),
    'follow_calibrations': _Spec(
        False,
        'true: take every calibration published on hexacal/parameters '
        '(latched), verified or not, from any process on the ROS domain (RISK: an '
        'unverified calibration moves the machine); false: only the deployed one',
    ),
    'calibration_store': _Spec(
        '',
        'calibration store whose active calibration is used and whose '
        "deploys and rollbacks are followed; '' = the machine model's default store",
    ),
    'model': _Spec(
        '',
        'machine model (hexa_slide, gough_stewart) whose default calibration '
        "store is followed when calibration_store is ''; '' = the parameters file's "
        "model, else every model's default store until one has a deployed calibration",
        constraints="'', " + ', '.join(repr(m) for m in MODELS),
    ),
    'physical_file': _Spec(
        '',
        'physical description (hexacal-physical/1 YAML: gravity, masses and centres of mass) '
        "whose weights load the calibration's chain compliances (its compliance section) in "
        "the pose and the compensated commands; '' = the model's shipped physical "
        'description; unused when the calibration has no compliances',
    ),
    'base_frame': _Spec(
        DEFAULT_BASE_FRAME,
        'frame_id of the platform pose and the markers (the base frame '
        'OXYZ); target poses must be in it (or have an empty frame_id)',
    ),
    'command_topic': _Spec(
        DEFAULT_COMMAND_TOPIC,
        'topic of the compensated actuator commands '
        "(trajectory_msgs/JointTrajectory; ros2_control's joint_trajectory_controller "
        'listens on <controller>/joint_trajectory)',
    ),
    'max_actuator_speed': _Spec(
        0.02,
        "actuator speed (m/s) that sets a command's time_from_start: the "
        'largest travel from the current readings / this speed (at least '
        f'{MIN_MOVE_TIME_S:g} s)',
        1e-6,
        10.0,
    ),
    'stroke_limits': _Spec(
        None,
        '[low, high] actuator readings (m) a command may ask for; unset = '
        "the architecture's workspace stroke (Hexa Slide 0-0.9 m, Gough-Stewart 0-0.5 m)",
    ),
    'link_length': _Spec(
        0.75,
        'measuring link length L (m): the first pose solve starts at the '
        'workspace centre, the fixed point [0, 0, -L] (standing: +L)',
        0.1,
        5.0,
    ),
    'mount': _Spec(
        '',
        'device mount, which side of the base the workspace centre is: '
        "'hanging' or 'standing'; '' = the parameters file's device.mount, else hanging",
        constraints="'', " + ', '.join(repr(m) for m in MOUNTS),
    ),
    'max_pose_rate_hz': _Spec(
        200.0,
        'actuator readings solved per second at most (by their stamps); the others are skipped',
        0.1,
        10000.0,
    ),
    'markers_rate_hz': _Spec(
        10.0,
        'machine markers published per second at most (when the pose changed); 0 = no markers',
        0.0,
        100.0,
    ),
}


def actuator_parameter_defaults(model: str | None) -> dict[str, float]:
    """Return the defaults of ACTUATOR_PARAMETERS for a machine of `model` (None: not known)."""
    from ..core.architectures.actuator_defaults import actuator_defaults

    return actuator_defaults(model, PARAMETERS, ACTUATOR_PARAMETERS)
