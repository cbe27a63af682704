"""
Node parameter defaults in the actuators' unit: written for sliders, converted per model.

The nodes' parameter specs give the defaults a slider machine needs (m, m/s, N, N/m). A
parameter whose meaning is an actuator quantity is declared once the node knows its
machine's model, with that model's default: the same travel, speed, force and stiffness at
the actuator's joint through ``Architecture.actuator_limit`` (rad, rad/s, N m, N m/rad for a
crank; unchanged for sliders and legs, whose lever is 1 m). A reading noise or a scatter
floor is a sensor's figure instead: +-X um on a slider's scale is +-X urad on a motor's
encoder (``NoiseModel.from_microns``, the study's noise levels), so its number stays.
"""

from __future__ import annotations

from typing import Any, Mapping

from hexacal_msgs_py.models import DEFAULT_MODEL

from . import architecture
from .base import Architecture

# What an actuator quantity is: a travel ('length'), a speed ('speed': travel per second), a
# drive's force or its stiffness (both through the lever), or a sensor's reading figure.
ACTUATOR_DIMENSIONS = ('length', 'speed', 'force', 'stiffness', 'reading')


def actuator_default(arch: Architecture, value: float, dimension: str) -> float:
    """Return a slider-sized default `value` of an actuator quantity in `arch`'s unit."""
    if dimension not in ACTUATOR_DIMENSIONS:
        raise ValueError(
            f'dimension must be one of {", ".join(ACTUATOR_DIMENSIONS)}, got {dimension!r}'
        )
    if dimension == 'reading':
        return float(value)
    return arch.actuator_limit(value, 'length' if dimension == 'speed' else dimension)


def actuator_defaults(
    model: str | None, defaults: Mapping[str, Any], dimensions: Mapping[str, str]
) -> dict[str, float]:
    """
    Return the defaults of the parameters named in `dimensions` for a machine of `model`.

    `defaults`: each parameter's slider-sized default (a number, or a spec with ``default``);
    `dimensions`: parameter name -> one of ACTUATOR_DIMENSIONS. A `model` of None or ''
    (not known yet) is the default model's.
    """
    arch = architecture(model or DEFAULT_MODEL)
    result = {}
    for name, dimension in dimensions.items():
        value = defaults[name]
        value = getattr(value, 'default', value)
        result[name] = actuator_default(arch, float(value), dimension)
    return result
