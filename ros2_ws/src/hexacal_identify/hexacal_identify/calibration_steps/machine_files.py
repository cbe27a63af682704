"""
The parameters files of a calibration: the machine they load, the device defects they carry.

``load_machine_and_extras`` is the one loader of a parameters file into a machine (on the
contract's read_parameters_file): ``load_machine_and_mount``, ``load_machine`` and the CLI's
``load_nominal`` go through it. The device defects and compliances a calibration identified
go to and come from the same file's extra keys.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from hexacal_msgs_py.models import device_defect_key, DEVICE_DEFECTS_KEY
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY as MOUNT_PARAMETER

from ..core.architectures import KinematicParameters, parameters_for
from ..core.machine.device import check_mount, DEFAULT_MOUNT, DEVICE_PARAMETER_NAMES, DeviceDefects

if TYPE_CHECKING:
    from ..core.fit.identification import IdentificationResult


# The default "exact" machine.
TABLE1_FILE = Path(__file__).parent.parent / 'data' / 'table1_exact.yaml'


def load_machine(path: Path | str) -> KinematicParameters:
    """
    Load the parameters of a parameters YAML, of the model it names.

    The parameters of a parameters YAML, of the model it names (ParameterFileError names the file
    and key).
    """
    return load_machine_and_mount(path)[0]


def load_machine_and_extras(path: Path | str) -> tuple[KinematicParameters, dict[str, object]]:
    """
    Load (parameters, the file's other keys) of a parameters YAML, of the model it names.

    The contract's reader checks the file (ParameterFileError names the file and key); the
    architecture's own checks of the values are a ValueError naming the file.
    """
    from hexacal_msgs_py.parameters_file import read_parameters_file

    loaded = read_parameters_file(path)
    try:
        return parameters_for(loaded.model, loaded.vector), dict(loaded.extras)
    except ValueError as error:
        raise ValueError(f'{path}: {error}') from None


def load_machine_and_mount(path: Path | str) -> tuple[KinematicParameters, str]:
    """
    Load (parameters, device mount) of a parameters YAML.

    Its model's parameters and its ``device.mount`` (default hanging; another value is a
    DeviceMountError naming the file).
    """
    from ..core.machine.device import DeviceMountError

    parameters, extras = load_machine_and_extras(path)
    try:
        mount = check_mount(str(extras.get(MOUNT_PARAMETER, DEFAULT_MOUNT)))
    except DeviceMountError as error:
        raise DeviceMountError(f'{path}: {MOUNT_PARAMETER}: {error}') from None
    return parameters, mount


def device_defects_extras(result: IdentificationResult) -> dict[str, float]:
    """
    Return the parameters-file keys of the device defects identified with `result`.

    The parameters-file keys (`device.defects.<name>`, SI) of the device defects identified with
    `result`; none identified: {} (the file is exactly as without the device).
    """
    return {
        device_defect_key(name): float(getattr(result.device, name)) for name in result.free_device
    }


def compliance_file_extras(result: IdentificationResult) -> dict[str, float]:
    """Return the parameters-file keys of the compliances identified with `result` ({}: rigid)."""
    from hexacal_msgs_py.parameters_file import compliance_extras

    return compliance_extras(result.compliance, result.compliance_std)


def load_device_defects(path: Path | str) -> tuple[DeviceDefects, tuple[str, ...]]:
    """
    Load the device defects a calibrated parameters file was calibrated with.

    (defects, names given) of a calibrated parameters file's `device.defects.<name>` keys: the
    device it was calibrated with (device_defects_from_extras).
    """
    from hexacal_msgs_py.parameters_file import read_parameters_file

    return device_defects_from_extras(read_parameters_file(path).extras, path)


def device_defects_from_extras(
    extras: dict, path: Path | str
) -> tuple[DeviceDefects, tuple[str, ...]]:
    """
    Return (defects, names given) of a parameters file's extras.

    (defects, names given) of a parameters file's extras (read_parameters_file). Absent keys are 0
    (the ideal device); a key naming no defect or a value that is not a small finite number is a
    ParameterFileError naming the file (`path`) and the key.
    """
    from hexacal_msgs_py.errors import ParameterFileError

    prefix = DEVICE_DEFECTS_KEY + '.'
    values: dict[str, float] = {}
    for key, value in extras.items():
        if not key.startswith(prefix):
            continue
        name = key[len(prefix):]
        if name not in DEVICE_PARAMETER_NAMES:
            raise ParameterFileError(
                f'{path}: {key}: not a device defect (one of {", ".join(DEVICE_PARAMETER_NAMES)})'
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterFileError(f'{path}: {key}: must be a number in SI units, got {value!r}')
        values[name] = float(value)
    try:
        return DeviceDefects(**values), tuple(values)
    except ValueError as error:
        raise ParameterFileError(f'{path}: {DEVICE_DEFECTS_KEY}: {error}') from None
