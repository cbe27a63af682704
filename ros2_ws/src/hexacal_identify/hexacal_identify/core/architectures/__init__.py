"""Kinematic architectures: one module per machine model, each implementing base.Architecture.

Adding an architecture (say a rotary-actuated 6-RUS) is one module here - its
parameters class, chain constants, IK with its two Jacobians, frame motions,
default machine and workspace - registered below, plus its layout in
``hexacal_msgs_py.models`` (names, units, file keys, actuator joints) and its
tests; nothing else in the core names an architecture.
"""

from __future__ import annotations

from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
import numpy as np

from .base import Architecture, KinematicParameters, Legs
from .gough_stewart import ARCHITECTURE as _GOUGH_STEWART
from .hexa_slide import ARCHITECTURE as _HEXA_SLIDE

ARCHITECTURES: dict[str, Architecture] = {
    arch.name: arch for arch in (_HEXA_SLIDE, _GOUGH_STEWART)
}
assert set(ARCHITECTURES) == set(MODELS), 'every model of the contract has an architecture'


def architecture(model: str | None = None) -> Architecture:
    """The architecture of `model` (None: the default, the Hexa Slide)."""
    name = DEFAULT_MODEL if model is None else model
    if name not in ARCHITECTURES:
        raise ValueError(
            f'unknown model {name!r}; hexacal knows {", ".join(sorted(ARCHITECTURES))}'
        )
    return ARCHITECTURES[name]


def parameters_for(model: str | None, vector: np.ndarray) -> KinematicParameters:
    """The parameters object of `model` holding `vector`."""
    return architecture(model).parameters(vector)


def default_parameters(model: str | None = None) -> KinematicParameters:
    return architecture(model).default_parameters()


__all__ = [
    'ARCHITECTURES',
    'Architecture',
    'KinematicParameters',
    'Legs',
    'architecture',
    'default_parameters',
    'parameters_for',
]
