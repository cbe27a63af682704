"""
Kinematic architectures: one module per machine model, each implementing base.Architecture.

Adding an architecture (the rotary hexapod 6-RUS was the third) is one module here - its
parameters class, chain constants, IK with its two Jacobians, frame motions,
default machine and workspace (the full list: ``base``'s docstring) - whose
declarative layout is registered in the contract
(``hexacal_msgs_py.models.register_model``) and whose instance is registered
here (``register_architecture``), plus its tests; nothing else in the core or
the command line names an architecture.
"""

from __future__ import annotations

from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
import numpy as np

from .base import Architecture, ChainIK, KinematicParameters, StackedLegs
from .gough_stewart import ARCHITECTURE as _GOUGH_STEWART
from .hexa_slide import ARCHITECTURE as _HEXA_SLIDE
from .rotary_hexapod import ARCHITECTURE as _ROTARY_HEXAPOD

# Every architecture hexacal knows, by model name (register_architecture adds one).
ARCHITECTURES: dict[str, Architecture] = {}


def register_architecture(arch: Architecture) -> Architecture:
    """
    Make `arch` known to the core under its model name; return it.

    Its layout must already be the contract's (``hexacal_msgs_py.models.register_model``)
    and its parameters class must belong to it.
    """
    if arch.name in ARCHITECTURES:
        raise ValueError(f'architecture {arch.name!r} is already registered')
    if MODELS.get(arch.name) is not arch.layout:
        raise ValueError(
            f'architecture {arch.name!r}: register its layout with '
            'hexacal_msgs_py.models.register_model and use MODELS[name] as its layout'
        )
    if getattr(arch.parameters_type, 'architecture', None) is not arch:
        raise ValueError(
            f'architecture {arch.name!r}: set {arch.parameters_type.__name__}.architecture to it'
        )
    ARCHITECTURES[arch.name] = arch
    return arch


register_architecture(_HEXA_SLIDE)
register_architecture(_GOUGH_STEWART)
register_architecture(_ROTARY_HEXAPOD)
assert set(ARCHITECTURES) == set(MODELS), 'every model of the contract has an architecture'


def architecture(model: str | None = None) -> Architecture:
    """Return the architecture of `model` (None: the default model's)."""
    name = DEFAULT_MODEL if model is None else model
    if name not in ARCHITECTURES:
        raise ValueError(
            f'unknown model {name!r}; hexacal knows {", ".join(sorted(ARCHITECTURES))}'
        )
    return ARCHITECTURES[name]


def parameters_for(model: str | None, vector: np.ndarray) -> KinematicParameters:
    """Return the parameters object of `model` holding `vector`."""
    return architecture(model).parameters(vector)


def default_parameters(model: str | None = None) -> KinematicParameters:
    return architecture(model).default_parameters()


__all__ = [
    'ARCHITECTURES',
    'Architecture',
    'KinematicParameters',
    'ChainIK',
    'StackedLegs',
    'architecture',
    'default_parameters',
    'parameters_for',
    'register_architecture',
]
