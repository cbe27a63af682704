"""The ROS-free numerical core of hexacal: model, kinematics, identification, identifiability.

Nothing in this subpackage imports rclpy or ROS message packages.
"""
from .device import DeviceModel, inclinometer_angles, measured_position
from .errors import (
    CalibrationError,
    ForwardKinematicsError,
    InvalidMeasurementError,
    RankDeficientError,
    TooFewPosturesError,
    UnreachablePoseError,
)
from .identification import IdentificationResult, SolverOptions, identify
from .kinematics import forward_kinematics, inverse_kinematics
from .measurements import FIXED, SPHERE, Measurements, NoiseModel, simulate_measurements
from .model import N_PARAMETERS, HexaParameters, nominal_set, parameter_names, table1_parameters
from .postures import Workspace, sample_poses
from .residuals import COSTS, ChannelSigma

__all__ = [
    "COSTS", "FIXED", "SPHERE", "N_PARAMETERS",
    "CalibrationError", "ChannelSigma", "DeviceModel", "ForwardKinematicsError", "HexaParameters",
    "IdentificationResult", "InvalidMeasurementError", "Measurements", "NoiseModel", "RankDeficientError",
    "SolverOptions", "TooFewPosturesError", "UnreachablePoseError", "Workspace",
    "forward_kinematics", "identify", "inclinometer_angles", "inverse_kinematics", "measured_position",
    "nominal_set", "parameter_names", "sample_poses", "simulate_measurements", "table1_parameters",
]
