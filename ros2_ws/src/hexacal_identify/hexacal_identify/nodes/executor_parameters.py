"""
The executor node's ROS parameters: names, defaults, ranges and descriptions.

Kept apart from nodes/executor.py so the node module holds only the glue; the
checks beyond type and range are core/sessions/executor_session.py's `parameter_problem`
(`declare_parameters` installs them as the node's parameter callback). How the
inclinometer input is read (inclinometer_type, signs, offsets) is declared as the
collector declares it (nodes/input_parameters.py).
"""

from __future__ import annotations

from typing import Any

from hexacal_msgs_py.models import MAX_DEVICE_TURN
from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC, INCLINOMETER_NAMES
from hexacal_msgs_py.node_parameters import parameter_descriptor
from hexacal_msgs_py.node_parameters import ParameterSpec as _Spec
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from .input_parameters import declare_mapping_parameters, INCLINOMETER_READING_PARAMETERS
# ACTUATOR_PARAMETERS: declared once the nominal file is read, with its model's defaults.
from ..core.sessions.executor_session import ACTUATOR_PARAMETERS, parameter_problem
from ..core.walk.guard import GuardSettings
from ..core.walk.settings import ExecutionSettings

SETTINGS = ExecutionSettings()
GUARD = GuardSettings()
PARAMETERS: dict[str, _Spec] = {
    'plan': _Spec('', 'plan YAML written by `hexacal plan` (required)'),
    'nominal': _Spec(
        '',
        "nominal parameters YAML of the machine (required); its 'model' (none: "
        "hexa_slide) is the machine model and its 'device.mount' the device mount",
    ),
    'command_topic': _Spec(
        DEFAULT_COMMAND_TOPIC,
        'trajectory_msgs/JointTrajectory commands go '
        "here: the topic of ros2_control's joint_trajectory_controller",
    ),
    'max_actuator_speed_m_s': _Spec(
        SETTINGS.max_actuator_speed_m_s,
        'the fastest an actuator moves (m/s; rad/s for actuators that turn): a move starts '
        'and stops at rest, its acceleration at most this speed / 0.25 s',
        1e-6,
        10.0,
    ),
    'position_tolerance_m': _Spec(
        SETTINGS.position_tolerance_m,
        'the machine is at the target '
        'when every measured actuator is within this of it (m; rad for actuators that turn); it '
        'allows for the strain of the measuring link with a nominal '
        'model millimetres off',
        1e-7,
        0.1,
    ),
    'still_tolerance_m': _Spec(
        SETTINGS.still_tolerance_m,
        'the machine is still when no measured actuator moves more than this (peak to peak, '
        'm; rad for actuators that turn) over settle_s: above the reading noise',
        1e-7,
        0.01,
    ),
    'settle_s': _Spec(
        SETTINGS.settle_s, 'how long the machine must stand still at a target (s)', 0.01, 60.0
    ),
    'timeout_s': _Spec(
        SETTINGS.timeout_s,
        'a posture not reached, still and measured within this '
        'of its first command is skipped and reported (s)',
        0.1,
        3600.0,
    ),
    'fixed_tolerance_rad': _Spec(
        SETTINGS.fixed_tolerance_rad,
        'a fixed-position posture is '
        'reached when both inclinometer angles are within this (rad); '
        'keep it below the 5e-5 rad at which identify counts a posture '
        'as fixed',
        1e-7,
        0.01,
    ),
    'max_corrections': _Spec(
        SETTINGS.max_corrections,
        'closed-loop corrections of a fixed-position posture before it is skipped',
        0,
        100,
    ),
    'path_step_m': _Spec(
        SETTINGS.path_step_m,
        'a move goes along the link sphere through '
        'points at most this far apart (m; also this / L rad in each angle), so '
        'the platform stays where the measuring link lets it; 0: straight moves in joint '
        'space (no points on the sphere)',
        0.0,
        1.0,
    ),
    'inclinometer_settle_s': _Spec(
        SETTINGS.inclinometer_settle_s,
        'a fixed-position posture is judged on the inclinometer only once it has settled '
        'after a move (a real one lags through its filter): the medians of two consecutive '
        'windows of this length (s) agree within the noise, and the later window is averaged; '
        "about the inclinometer's time constant or longer; 0: the mean over settle_s as soon "
        'as the actuators are still (an inclinometer that does not lag)',
        0.0,
        60.0,
    ),
    'correction_nudge_m': _Spec(
        SETTINGS.correction_nudge_m,
        'a fixed-position correction smaller than this goes this far beyond its target and '
        'back (m), so the collector, which takes one posture per stationary period, sees a '
        'move and measures the corrected position; above its slider_tolerance_m; 0: '
        'straight corrections',
        0.0,
        0.01,
    ),
    'inclinometer_joints': _Spec(
        list(INCLINOMETER_NAMES),
        'the inclinometer joints alpha (about X), beta (about Y) of the inclinometer input (rad)',
        constraints='two distinct names',
    ),
    'check_releases_at_rest': _Spec(
        SETTINGS.check_releases_at_rest,
        "passive_actuator: before each move after the first, at rest, rehearse the posture's "
        'release again from where the machine stands (on the model and machines like it) and '
        "release another chain if it may jam (false: the plan's releases as planned; the "
        'guard and the recovery after a drive fault still act)',
    ),
    'wait_for_posture': _Spec(
        True,
        "wait for the collector's posture at each stop (false: move on once the machine is still)",
    ),
    'calibrate_when_done': _Spec(
        False, 'call hexacal/calibrate when the plan is done and report the answer'
    ),
    'refine_targets': _Spec(
        True,
        'once the postures measured allow a calibration of full rank, stop at rest, call '
        'hexacal/calibrate and compute the remaining targets with the intermediate model '
        '(again at later checkpoints, core/walk_refine/refinement.py); '
        'without the service: nominal targets',
    ),
    'refine_timeout_s': _Spec(
        120.0,
        'refine_targets: how long to wait for the intermediate calibration and its published '
        'parameters before going on with the current targets (s)',
        1.0,
        3600.0,
    ),
    'start_paused': _Spec(False, 'wait for hexacal/executor/resume before the first move'),
    'device_turn_nodes': _Spec(
        [],
        "nodes whose 'device_turn' parameter (rad) the executor sets "
        'when the operator resumes after turning the device for a plan '
        "posture (e.g. ['collector', 'driver']; names resolved in the "
        "executor's namespace); empty: none",
        constraints='distinct node names',
    ),
    'mounted_turn': _Spec(
        0.0,
        "the device's mounting at the start, rad about its link axis (0: "
        'normal; e.g. the last mounting of the plan walked before): a first '
        'posture in another mounting waits for the turn; with device_turn_nodes '
        'their device_turn is set to it before the first move',
        -MAX_DEVICE_TURN,
        MAX_DEVICE_TURN,
    ),
    'measuring_mode': _Spec(
        '',
        "how the machine is driven while the link is attached: '' the plan's mode (a plan "
        'without one: compliant, all six commanded), passive_actuator (per posture the '
        "plan's released actuator is released through hexacal/release/<joint> at rest and the "
        'five others commanded), lvdt or compliant (all six commanded)',
        constraints="'', passive_actuator, lvdt or compliant",
    ),
    'lvdt_stroke_m': _Spec(
        GUARD.lvdt_stroke_m,
        "lvdt: the stroke of the link, +- this about its rest length (m; the driver's "
        'lvdt_stroke_m); a move whose predicted extension (on the model, every path point and '
        'the joint-space way between) or a measured length (hexacal/link) leaves it less '
        'lvdt_margin_m pauses the plan',
        1e-6,
        1.0,
    ),
    'lvdt_margin_m': _Spec(
        GUARD.lvdt_margin_m, 'lvdt: kept inside the LVDT stroke by every move (m)', 0.0, 1.0
    ),
    'servo_stiffness_n_per_m': _Spec(
        GUARD.servo_stiffness_n_per_m,
        "compliant (named): each servo's stiffness (N/m, N m/rad for actuators that turn; the "
        "driver's); a move's predicted force (torque) is this x the predicted strain of the "
        'machine against the link',
        1.0,
        1e12,
    ),
    'max_force_n': _Spec(
        GUARD.max_force_n,
        'compliant (named): a move whose predicted force on a servo exceeds this (N; N m for '
        "actuators that turn) is not sent: the plan pauses (default 0.8 x the driver's: room "
        'for what the model misses)',
        1e-6,
        1e9,
    ),
    'max_link_force_n': _Spec(
        GUARD.max_link_force_n,
        'compliant: a move whose predicted tension or compression of the measuring link (the '
        "servos' strain carried by the rigid link) exceeds this (N) is not sent: the plan pauses "
        "(default 0.8 x the 500 N a measuring link of the documented kind bears, the driver's "
        'max_link_force_n)',
        1e-6,
        1e9,
    ),
    'released_margin_m': _Spec(
        GUARD.released_margin_m,
        'passive_actuator: the released actuator is kept this far inside the actuator stroke '
        '(stroke_limits_m) along every move (predicted on the model, m; rad for actuators that '
        'turn); a move that would jam '
        'the passive system or leave it pauses the plan',
        0.0,
        1.0,
    ),
    'physical_file': _Spec(
        '',
        "passive_actuator, a plan made with the link's load (its link_force_limit_n): the "
        'physical description YAML (hexacal-physical/1: masses and centres of mass, gravity, '
        'payload) whose weights load the measuring link; the releases the executor chooses '
        "again at rest and after a drive fault keep the link within the plan's limit, as the "
        "planner's did; '' = the model's shipped physical description; unused for a plan made "
        "without the link's load",
    ),
    'release_wait_s': _Spec(
        10.0,
        'passive_actuator: how long to wait for a release service (std_srvs/SetBool '
        'hexacal/release/<joint>) and its answer before the plan pauses (s)',
        0.1,
        600.0,
    ),
    'shutdown_when_done': _Spec(
        False,
        'stop the node once the plan is done or aborted (and the '
        'calibration answered); a refused plan is then a start-up error '
        '(exit code 2)',
    ),
}
# Declared once the nominal file is read: their defaults are the model's.
MODEL_PARAMETERS: dict[str, _Spec] = {
    'stroke_limits_m': _Spec(
        [0.0, 1.0],
        '[low, high] actuator stroke (m; rad for actuators that turn) every target must lie '
        "in; default: the plan's (hexacal plan's --stroke-m, recorded "
        "in the plan file), else the model's (its default workspace)",
        constraints='two finite numbers, low < high',
    ),
    'actuator_joints': _Spec(
        ['slider_1'],
        'the six actuator joints in chain order, as the '
        'controller and the sliders input name them; default: the '
        "model's (slider_1..6 or leg_1..6)",
        constraints='six distinct names',
    ),
}


def _validate(parameters: list[Parameter]) -> SetParametersResult:
    for parameter in parameters:
        problem = parameter_problem(parameter.name, parameter.value)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
    return SetParametersResult(successful=True)


def declare_parameters(node: Node) -> dict[str, Any]:
    """Declare PARAMETERS and how the inclinometer is read, checked; return their values."""
    node.add_on_set_parameters_callback(_validate)
    for name, spec in PARAMETERS.items():
        if name not in ACTUATOR_PARAMETERS:
            node.declare_parameter(name, spec.default, parameter_descriptor(name, spec))
    values = {
        name: node.get_parameter(name).value
        for name in PARAMETERS
        if name not in ACTUATOR_PARAMETERS
    }
    values.update(declare_mapping_parameters(node, INCLINOMETER_READING_PARAMETERS))
    return values


def declare_model_parameters(
    node: Node, plan_name: str, defaults: dict[str, object]
) -> dict[str, Any]:
    """
    Declare plan_name, MODEL_PARAMETERS and ACTUATOR_PARAMETERS; return their values.

    `defaults`: the model's (executor_session.model_defaults).
    """
    # As the driver's: a collector with driver_node:=executor records the plan in its bag.
    node.declare_parameter(
        'plan_name',
        plan_name,
        ParameterDescriptor(
            description='name of the plan being walked (set by the node)', read_only=True
        ),
        ignore_override=True,
    )
    specs = {**MODEL_PARAMETERS, **{name: PARAMETERS[name] for name in ACTUATOR_PARAMETERS}}
    return {
        name: node.declare_parameter(name, defaults[name], parameter_descriptor(name, spec)).value
        for name, spec in specs.items()
    }
