"""
How the inclinometer input is read: parameters shared by the collector and the executor.

Both nodes read the inclinometer through a hexacal_msgs_py.inputs.InputMapping and declare
these parameters with the same names, types, defaults and meaning, so one parameters file
(``/**: ros__parameters: inclinometer_type: imu ...``) and one remap of
``hexacal/inclinometer`` serve both. They are dynamically typed ([1, -1] is as good as
[1.0, -1.0]); InputMapping checks them and names the problem (exit 2 at start).
"""

from __future__ import annotations

from typing import Any

from hexacal_msgs_py.inputs import DEFAULT_OFFSETS_RAD, DEFAULT_SIGNS, INCLINOMETER_TYPES
from hexacal_msgs_py.node_parameters import parameter_descriptor, ParameterSpec
from rclpy.node import Node

INCLINOMETER_READING_PARAMETERS: dict[str, ParameterSpec] = {
    'inclinometer_type': ParameterSpec(
        'joint_state',
        "'joint_state': the inclinometer input is a sensor_msgs/JointState with "
        "inclinometer_joints; 'imu': a sensor_msgs/Imu whose orientation gives alpha and "
        'beta (hexacal_msgs_py.inputs)',
        constraints=', '.join(repr(t) for t in INCLINOMETER_TYPES),
    ),
    'inclinometer_signs': ParameterSpec(
        list(DEFAULT_SIGNS),
        'per channel (alpha, beta): 1 or -1; angle = sign * (raw - offset)',
        constraints='two values, each 1 or -1',
    ),
    'inclinometer_offsets_rad': ParameterSpec(
        list(DEFAULT_OFFSETS_RAD),
        'per channel (alpha, beta): the raw reading with the link level (rad); '
        'angle = sign * (raw - offset)',
        constraints='two finite values within +-pi',
    ),
}


def declare_mapping_parameters(node: Node, specs: dict[str, ParameterSpec]) -> dict[str, Any]:
    """Declare input mapping parameters (read only, dynamically typed); return their values."""
    values = {}
    for name, spec in specs.items():
        descriptor = parameter_descriptor(name, spec)
        descriptor.dynamic_typing = True  # InputMapping checks the types
        values[name] = node.declare_parameter(name, spec.default, descriptor).value
    return values
