"""
hexacal interface contract: names, readings, errors, conversions, parameter files.

This module and names, readings, errors and parameters_file are ROS-free;
qos imports rclpy and conversions imports the message packages, so import
those explicitly where ROS is available.
"""

from hexacal_msgs_py.errors import (
    HexacalContractError,
    InvalidParametersError,
    InvalidReadingError,
    ParameterFileError,
)
from hexacal_msgs_py.readings import (
    EncoderReading,
    InclinometerReading,
    PostureReading,
    SliderReading,
)

__all__ = [
    'EncoderReading',
    'HexacalContractError',
    'InclinometerReading',
    'InvalidParametersError',
    'InvalidReadingError',
    'ParameterFileError',
    'PostureReading',
    'SliderReading',
]
