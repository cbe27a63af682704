"""Errors raised by the hexacal interface contract (ROS-free)."""


class HexacalContractError(Exception):
    """Base class of every error raised by hexacal_msgs_py."""


class InvalidReadingError(HexacalContractError, ValueError):
    """A sensor reading or message does not satisfy the contract."""


class InvalidParametersError(HexacalContractError, ValueError):
    """A kinematic parameter vector or message does not satisfy the contract."""


class ParameterFileError(InvalidParametersError):
    """A parameters YAML file cannot be read, parsed, validated or written."""
