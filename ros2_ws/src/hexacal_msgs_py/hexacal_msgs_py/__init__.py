"""
hexacal interface contract: names, readings, errors, conversions, parameter files.

This module and names, readings, errors and parameters_file are ROS-free;
qos imports rclpy and conversions imports the message packages, so import
those explicitly where ROS is available. The names below are imported on first
use, so that importing interface_names (launch tooling) does not import numpy.
"""

from importlib import import_module

# Public name -> the module that defines it.
_EXPORTS = {
    'ActuatorReading': 'hexacal_msgs_py.readings',
    'EncoderReading': 'hexacal_msgs_py.readings',
    'HexacalContractError': 'hexacal_msgs_py.errors',
    'InclinometerReading': 'hexacal_msgs_py.readings',
    'InvalidParametersError': 'hexacal_msgs_py.errors',
    'InvalidReadingError': 'hexacal_msgs_py.errors',
    'MeasuringMode': 'hexacal_msgs_py.measuring_modes',
    'ParameterFileError': 'hexacal_msgs_py.errors',
    'PostureReading': 'hexacal_msgs_py.readings',
    'PostureScatter': 'hexacal_msgs_py.readings',
    'SliderReading': 'hexacal_msgs_py.readings',
}

# Renamed names: answered (their module warns, DeprecationWarning) and never cached here, so
# every use warns.
_DEPRECATED = frozenset({'SliderReading'})

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> object:
    """Return an exported name, importing its module on first use (PEP 562)."""
    if name not in _EXPORTS:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(import_module(_EXPORTS[name]), name)
    if name not in _DEPRECATED:
        globals()[name] = value
    return value


def __dir__() -> list[str]:
    """Return the module's names with the lazily imported exports."""
    return sorted({*globals(), *__all__})
