"""
The collector's parameters: declarations (names, types, defaults, ranges) and checks.

Every parameter is read only except `output_dir`, `bag_name`, `flush_every_s` and
`device_turn`. The input mapping parameters are dynamically typed ([1, -1] is as good as
[1.0, -1.0]); InputMapping checks them and names the problem (exit 2 at start).
"""

from __future__ import annotations

from typing import Any

from hexacal_msgs_py.errors import HexacalContractError
from hexacal_msgs_py.inputs import (
    DEFAULT_INCLINOMETER_JOINTS,
    DEFAULT_ROTARY_JOINT,
    InputMapping,
)
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.names import DEVICE_TURN_JOINT, MAX_DEVICE_TURN
from hexacal_msgs_py.node_parameters import parameter_descriptor, ParameterSpec
from hexacal_msgs_py.parameters_file import read_parameters_file
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from .collector_inputs import RAW_TOPICS
from .input_parameters import declare_mapping_parameters, INCLINOMETER_READING_PARAMETERS
from ..bag.naming import bag_name_problem
from ..core.architectures.actuator_defaults import actuator_defaults
from ..core.detection.turn_history import turn_problem
from ..core.detection.vocabulary import detector_problem, DETECTORS

MODEL_CHOICES = ('', *MODELS)
# Defaults are the detector's and StreamSynchronizer's (max_skew_s).
DETECTOR_PARAMETERS = {
    'window_s': ParameterSpec(
        0.3,
        'a sample is stationary when every channel stayed within its tolerance '
        'over this window (s)',
        0.02,
        10.0,
    ),
    'capture_s': ParameterSpec(0.5, 'stationary time averaged into one posture (s)', 0.02, 60.0),
    'slider_tolerance_m': ParameterSpec(
        2e-4, 'peak-to-peak slider motion still counted as stationary (m)', 1e-7, 0.1
    ),
    'angle_tolerance_rad': ParameterSpec(
        2e-4, 'peak-to-peak angle motion still counted as stationary (rad)', 1e-7, 0.1
    ),
    'max_gap_s': ParameterSpec(
        0.1, 'a longer gap in the data drops the posture being captured (s)', 0.001, 10.0
    ),
    'max_skew_s': ParameterSpec(
        0.02, 'largest stamp difference of paired sensor readings (s)', 0.0, 1.0
    ),
}
# The settled-streams detector's own settings (core.dwell_detector); recorded with the others.
DWELL_PARAMETERS = {
    'detector': ParameterSpec(
        'settled',
        "'settled': each stream judged on its own readings, a posture once every stream has "
        'settled (a lagging channel is waited for), spikes rejected, each posture with its '
        "scatter (the only detector: 'window' was removed in 0.2.0)",
        constraints=', '.join(repr(name) for name in DETECTORS),
    ),
    'inclinometer_clock_offset_s': ParameterSpec(
        0.0,
        "the inclinometer stamps' clock offset against the actuator stamps (its stamp minus "
        "theirs for one instant, s); with estimate_clock_offsets the estimate's start",
        -1.0,
        1.0,
    ),
    'encoder_clock_offset_s': ParameterSpec(
        0.0,
        "the encoder stamps' clock offset against the actuator stamps (s); with "
        "estimate_clock_offsets the estimate's start",
        -1.0,
        1.0,
    ),
    'estimate_clock_offsets': ParameterSpec(
        True,
        'estimate the inclinometer and encoder clock offsets from the starts of motion '
        '(detector settled; the status reports them); false: use the two offsets as given',
    ),
}
# name: (spec, read only), declared in this order before the model is known.
PARAMETERS = {
    'output_dir': (ParameterSpec('bags', 'directory that receives the bag directories'), False),
    'bag_name': (ParameterSpec('', 'bag directory name; empty: hexacal_<date>_<time>'), False),
    'record': (
        ParameterSpec(True, 'record from the start (else only after hexacal/start_recording)'),
        True,
    ),
    'flush_every_s': (
        ParameterSpec(
            0.5,
            'period of making the bag durable on disk (s); it is also flushed after every '
            'posture',
            0.05,
            60.0,
        ),
        False,
    ),
    'driver_node': (
        ParameterSpec(
            'driver', 'node (relative to this namespace) whose plan parameters are recorded'
        ),
        True,
    ),
    'model': (
        ParameterSpec(
            '',
            "machine model, which names the actuator joints: 'hexa_slide' "
            "(slider_1..6) or 'gough_stewart' (leg_1..6); '' = the model of parameters_file, "
            'else hexa_slide',
            constraints="'', " + ', '.join(repr(name) for name in MODELS),
        ),
        True,
    ),
    'parameters_file': (
        ParameterSpec(
            '',
            "a parameters YAML of the machine (e.g. identify's nominal file) whose "
            "'model' key gives the model; '' = none",
        ),
        True,
    ),
    **{name: (spec, True) for name, spec in DETECTOR_PARAMETERS.items()},
    **{name: (spec, True) for name, spec in DWELL_PARAMETERS.items()},
    'device_turn': (
        ParameterSpec(
            0.0,
            "the device's rotation about its link axis from its normal mounting (rad; 0 "
            'normal, pi reversed, pi/2 a quarter turn) for postures whose inclinometer '
            f"message has no '{DEVICE_TURN_JOINT}' joint (a message that has it wins); "
            'settable at run time',
            -MAX_DEVICE_TURN,
            MAX_DEVICE_TURN,
        ),
        False,
    ),
}


# Actuator quantities (core.architectures.actuator_defaults): declared once the model is known,
# with its defaults (the specs' for sliders and legs).
ACTUATOR_PARAMETERS = {'slider_tolerance_m': 'length'}


class CollectorConfigurationError(Exception):
    """The collector's parameters contradict each other (e.g. model and parameters_file)."""


def resolve_model(model: str, parameters_file: str) -> str:
    """
    Return the collector's model: `model`, else the one `parameters_file` names, else default.

    Both given and different: CollectorConfigurationError; an unreadable file:
    its ParameterFileError (a contract error naming the file and key).
    """
    if not parameters_file:
        return model or DEFAULT_MODEL
    named = read_parameters_file(parameters_file).model
    if model and model != named:
        raise CollectorConfigurationError(
            f'model {model!r} contradicts parameters_file {parameters_file}, a {named} '
            "parameters file: leave model '' or name the file's model"
        )
    return named


def _validate(parameters: list[Parameter]) -> SetParametersResult:
    for parameter in parameters:
        problem = parameter_problem(parameter.name, parameter.value)
        if problem is not None:
            return SetParametersResult(successful=False, reason=problem)
    return SetParametersResult(successful=True)


def declare_parameters(node: Node) -> dict[str, Any]:
    """
    Declare the parameters that do not depend on the model, checked; return their values.

    ACTUATOR_PARAMETERS are declared once the model is known (declare_actuator_parameters).
    """
    # Registered before declaring, so command-line overrides are checked too.
    node.add_on_set_parameters_callback(_validate)
    for name, (spec, read_only) in PARAMETERS.items():
        if name not in ACTUATOR_PARAMETERS:
            node.declare_parameter(name, spec.default, parameter_descriptor(name, spec, read_only))
    return {
        name: node.get_parameter(name).value
        for name in PARAMETERS
        if name not in ACTUATOR_PARAMETERS
    }


def actuator_parameter_defaults(model: str) -> dict[str, float]:
    """Return the defaults of ACTUATOR_PARAMETERS for a machine of `model`."""
    specs = {name: PARAMETERS[name][0] for name in ACTUATOR_PARAMETERS}
    return actuator_defaults(model, specs, ACTUATOR_PARAMETERS)


def declare_actuator_parameters(node: Node, model: str) -> dict[str, Any]:
    """Declare ACTUATOR_PARAMETERS with the defaults of `model`; return their values."""
    values = {}
    for name, default in actuator_parameter_defaults(model).items():
        spec, read_only = PARAMETERS[name]
        descriptor = parameter_descriptor(name, spec, read_only)
        values[name] = node.declare_parameter(name, default, descriptor).value
    return values


def declare_inputs(node: Node, actuator_names: tuple[str, ...]) -> InputMapping:
    """Declare the input mapping parameters; InputMappingError names a problem."""
    specs = {
        'actuator_joints': ParameterSpec(
            list(actuator_names),
            'the six actuator joints in chain order, as the sliders input (hexacal/sliders, '
            'or the topic it is remapped to, e.g. /joint_states) names them; default: the '
            "model's (slider_1..6 or leg_1..6)",
            constraints='six distinct names',
        ),
        'inclinometer_joints': ParameterSpec(
            list(DEFAULT_INCLINOMETER_JOINTS),
            'the inclinometer joints alpha (about X), beta (about Y) of a JointState '
            'inclinometer input (rad)',
            constraints='two distinct names',
        ),
        'rotary_joint': ParameterSpec(
            DEFAULT_ROTARY_JOINT, 'the rotary sensor joint (phi, rad) of the encoder input'
        ),
        **INCLINOMETER_READING_PARAMETERS,  # the executor's too
    }
    value = declare_mapping_parameters(node, specs)
    sliders, inclinometer, encoder = (node.resolve_topic_name(topic) for topic in RAW_TOPICS)
    return InputMapping(
        actuator_joints=value['actuator_joints'],
        inclinometer_joints=value['inclinometer_joints'],
        rotary_joint=value['rotary_joint'],
        inclinometer_type=value['inclinometer_type'],
        inclinometer_signs=value['inclinometer_signs'],
        inclinometer_offsets_rad=value['inclinometer_offsets_rad'],
        topics=(sliders, inclinometer, encoder),
    )


def checked_turn(value: Any) -> float:
    """Return the device_turn parameter as a float (InvalidParameterValueException if bad)."""
    problem = turn_problem(value)
    if problem is not None:
        raise InvalidParameterValueException('device_turn', value, problem)
    return float(value)


def parameter_problem(name: str, value: Any) -> str | None:
    """Return why `value` cannot be the collector's parameter `name`, or None."""
    if name == 'device_turn':
        return turn_problem(value)
    if name == 'bag_name':
        return bag_name_problem(value)
    if name == 'detector':
        return detector_problem(value)
    if name == 'output_dir' and not value:
        return 'output_dir must not be empty'
    if name == 'model' and value not in MODEL_CHOICES:
        return f"model must be '' or one of {', '.join(MODELS)}, got {value!r}"
    if name == 'parameters_file' and value:
        try:
            read_parameters_file(value)
        except HexacalContractError as error:
            return f'parameters_file: {error}'
    return None
