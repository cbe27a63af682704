"""
The calibration result file (``hexacal calibrate --save-result``): the one owner of its format.

A result file is one strict JSON object (no NaN: a missing number is null), SI units::

    {<the keys of `hexacal calibrate --json`: model, rank, reason, parameters, ...>,
     "adequacy": {...},
     "device_prior": {name: {"value", "std"}},   <- only when the calibration had one
     "format": "hexacal-result/1",
     "report_data": {<REPORT_DATA_KEYS: the vectors and arrays a report needs>}}

A plain ``hexacal calibrate --json`` output reads as a result too (then without
``report_data``): what every result has is ``rank`` and ``reason``. The core builds the
payload (hexacal_identify.report.page.result_payload); this module names its keys and reads
and writes the file.

ROS-free and core-free: the standard library only.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hexacal_msgs_py.files import atomic_write

RESULT_FORMAT = 'hexacal-result/1'
FORMAT_KEY = 'format'  # RESULT_FORMAT in a saved result; absent in a plain --json output
REPORT_DATA_KEY = 'report_data'
ADEQUACY_KEY = 'adequacy'
DEVICE_PRIOR_KEY = 'device_prior'  # {name: {"value", "std"}} (SI), when the calibration had one
# What every result has, saved or printed by `hexacal calibrate --json`.
REQUIRED_KEYS = ('rank', 'reason')
# The keys under REPORT_DATA_KEY (arrays as nested lists, SI; NaN as null). 'mount' only when
# the device mount was known.
REPORT_DATA_KEYS = (
    'parameter_names',
    'parameters',
    'initial_parameters',
    'true_parameters',
    'std',
    'covariance',
    'initial_rms_residual',
    'residuals',  # {"values", "channels", "postures"}
    'used_postures',
    'poses',
    'kinds',
    'singular_values',
    'verdict',
    'link_length',
    'extras',
    'mount',
)


def write_result_file(path: Path | str, payload: dict[str, Any]) -> Path:
    """
    Write a result payload as strict JSON, atomically; return the path.

    The payload holds builtins only (no numpy, no NaN): ValueError names a NaN or infinity.
    """
    return atomic_write(Path(path), json.dumps(payload, allow_nan=False))


def read_result_file(path: Path | str) -> dict[str, Any]:
    """
    Read a result file: a saved result, or a plain ``hexacal calibrate --json`` output.

    ValueError names the file when it is not JSON or not a hexacal result.
    """
    try:
        payload = json.loads(Path(path).read_text(encoding='utf-8'))
    except json.JSONDecodeError as error:
        raise ValueError(f'{path}: not a JSON result file ({error})') from None
    if not isinstance(payload, dict) or any(key not in payload for key in REQUIRED_KEYS):
        raise ValueError(
            f'{path}: not a hexacal result (expected the output of save_result or '
            "`hexacal calibrate --json`, with 'rank' and 'reason')"
        )
    return payload


__all__ = [
    'ADEQUACY_KEY',
    'DEVICE_PRIOR_KEY',
    'FORMAT_KEY',
    'read_result_file',
    'REPORT_DATA_KEY',
    'REPORT_DATA_KEYS',
    'REQUIRED_KEYS',
    'RESULT_FORMAT',
    'write_result_file',
]
