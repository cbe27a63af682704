"""
The ROS-free numerical core of hexacal: model, kinematics, identification, identifiability.

Nothing in this subpackage imports rclpy or ROS message packages.

The names below are imported from their submodules on first use (PEP 562), so
``from hexacal_identify.core.model import ...`` loads the model alone, not the
solver and scipy with it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

_EXPORTS = {
    'device': ('DeviceModel', 'inclinometer_angles', 'measured_position'),
    'errors': (
        'CalibrationError',
        'ForwardKinematicsError',
        'InvalidMeasurementError',
        'RankDeficientError',
        'TooFewPosturesError',
        'UnreachablePoseError',
    ),
    'identification': ('IdentificationResult', 'SolverOptions', 'identify'),
    'kinematics': ('forward_kinematics', 'inverse_kinematics'),
    'measurements': ('FIXED', 'SPHERE', 'Measurements', 'NoiseModel', 'simulate_measurements'),
    'model': (
        'N_PARAMETERS',
        'HexaParameters',
        'nominal_set',
        'parameter_names',
        'table1_parameters',
    ),
    'postures': ('Workspace', 'sample_poses'),
    'residuals': ('COSTS', 'ChannelSigma'),
}
_MODULE_OF = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [
    'COSTS',
    'FIXED',
    'SPHERE',
    'N_PARAMETERS',
    'CalibrationError',
    'ChannelSigma',
    'DeviceModel',
    'ForwardKinematicsError',
    'HexaParameters',
    'IdentificationResult',
    'InvalidMeasurementError',
    'Measurements',
    'NoiseModel',
    'RankDeficientError',
    'SolverOptions',
    'TooFewPosturesError',
    'UnreachablePoseError',
    'Workspace',
    'forward_kinematics',
    'identify',
    'inclinometer_angles',
    'inverse_kinematics',
    'measured_position',
    'nominal_set',
    'parameter_names',
    'sample_poses',
    'simulate_measurements',
    'table1_parameters',
]


def __getattr__(name: str):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:
    from .device import DeviceModel, inclinometer_angles, measured_position
    from .errors import (
        CalibrationError,
        ForwardKinematicsError,
        InvalidMeasurementError,
        RankDeficientError,
        TooFewPosturesError,
        UnreachablePoseError,
    )
    from .identification import IdentificationResult, identify, SolverOptions
    from .kinematics import forward_kinematics, inverse_kinematics
    from .measurements import FIXED, Measurements, NoiseModel, simulate_measurements, SPHERE
    from .model import (
        HexaParameters,
        N_PARAMETERS,
        nominal_set,
        parameter_names,
        table1_parameters,
    )
    from .postures import sample_poses, Workspace
    from .residuals import ChannelSigma, COSTS
