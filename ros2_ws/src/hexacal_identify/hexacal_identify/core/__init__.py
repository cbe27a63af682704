"""
The ROS-free numerical core of hexacal: model, kinematics, identification, identifiability.

Nothing in this subpackage imports rclpy or ROS message packages; scipy is
imported by the functions that solve, not here.
"""

from .errors import (
    CalibrationError,
    ForwardKinematicsError,
    InvalidMeasurementError,
    RankDeficientError,
    TooFewPosturesError,
    UnreachablePoseError,
)
from .fit.identification import IdentificationResult, identify, SolverOptions
from .fit.residuals import ChannelSigma, COSTS
from .machine.device import DeviceModel, inclinometer_angles, measured_position
from .machine.kinematics import forward_kinematics, inverse_kinematics
from .machine.measurements import FIXED, Measurements, NoiseModel, simulate_measurements, SPHERE
from .machine.model import (
    HexaParameters,
    N_PARAMETERS,
    nominal_set,
    parameter_names,
    table1_parameters,
)
from .machine.postures import sample_poses, Workspace

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
