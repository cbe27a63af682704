"""
Node parameters declared with descriptors: one spec type and one descriptor builder for every node.

The nodes of hexacal_identify and the simulated driver declare their parameters from tables of
`ParameterSpec` (name -> default, description, range) and hand rcl the descriptor
`parameter_descriptor` builds. The spec is ROS-free, so a parameter table can be read (launch
files, docs, tests) without ROS; rcl_interfaces is imported only when a descriptor is built.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, TYPE_CHECKING

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor


@dataclass(frozen=True)
class ParameterSpec:
    """
    A node parameter: default (its type), description, range, further constraints.

    Default (its type), description, range (numbers), further constraints (text).
    """

    default: Any  # a bool, int, float, str or list: its type is the parameter's
    description: str
    low: float | int | None = None
    high: float | int | None = None
    constraints: str = ''


def parameter_descriptor(
    name: str, spec: ParameterSpec, read_only: bool = True
) -> ParameterDescriptor:
    """
    Return the descriptor rcl enforces.

    Type from the default, range for numbers (none when the spec gives no low and high), lists
    of either number type.
    """
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    descriptor = ParameterDescriptor(
        name=name,
        description=spec.description,
        read_only=read_only,
        additional_constraints=spec.constraints,
    )
    if isinstance(spec.default, list):
        descriptor.dynamic_typing = (
            True  # [0, 1] is as good as [0.0, 1.0]; the node checks the items
        )
    elif spec.low is None or spec.high is None:
        pass  # a number without a range: any value of its type (the node checks the rest)
    elif isinstance(spec.default, float):
        descriptor.floating_point_range = [
            FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)
        ]
    elif isinstance(spec.default, int) and not isinstance(spec.default, bool):
        descriptor.integer_range = [
            IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)
        ]
    return descriptor


__all__ = ['ParameterSpec', 'parameter_descriptor']
