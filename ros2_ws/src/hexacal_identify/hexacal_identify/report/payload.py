"""
The result file's payload: ``IdentificationResult.to_json()`` plus the arrays a report needs.

``save_result`` writes it (its format: hexacal_msgs_py.result_file); ``report_data`` holds the
vectors and arrays in SI units, NaN as null.
"""

from __future__ import annotations

from pathlib import Path

from hexacal_msgs_py.result_file import (
    ADEQUACY_KEY,
    DEVICE_PRIOR_KEY,
    FORMAT_KEY,
    REPORT_DATA_KEY,
    RESULT_FORMAT,
    write_result_file,
)
import numpy as np

from ..core.jsonsafe import json_safe as _plain
from ..core.machine.device import check_mount, DEFAULT_LINK_LENGTH_M


def result_payload(
    result,
    extras: dict | None = None,
    *,
    measurements=None,
    true_parameters=None,
    link_length: float | None = None,
    mount: str | None = None,
    device_prior=None,
) -> dict:
    """
    ``result.to_json()`` plus the arrays of ``report_data`` (see module doc).

    ``mount``: the device mount (device.py), recorded when given; a report of a file without it
    takes the side of the device's base joint the poses are on.  ``device_prior``: the DevicePrior
    the calibration was given (or its ``{name: {value, std}}`` form), recorded as ``device_prior``
    beside ``device`` and ``device_std`` (what ``calibrate --json`` prints); the page shows prior
    and posterior side by side.
    """
    payload = result.to_json()
    payload[ADEQUACY_KEY] = result.adequacy.to_json()
    if device_prior is not None:
        payload[DEVICE_PRIOR_KEY] = _device_prior_dict(device_prior)
    layout = result.parameters.layout
    n = layout.n_parameters
    used = [int(i) for i in result.used_postures]
    kinds = None
    if measurements is not None:
        kinds = [str(k) for k in np.asarray(measurements.kinds)[used]]
    identifiability = result.identifiability
    truth = None
    if true_parameters is not None:
        truth = np.asarray(getattr(true_parameters, 'vector', true_parameters), dtype=float)[:n]
    if link_length is None:
        link_length = DEFAULT_LINK_LENGTH_M
    payload[FORMAT_KEY] = RESULT_FORMAT
    payload[REPORT_DATA_KEY] = _plain(
        {
            'parameter_names': list(layout.parameter_names),
            'parameters': result.parameters.vector,
            'initial_parameters': result.initial_parameters.vector,
            'true_parameters': truth,
            'std': np.asarray(result.std, dtype=float)[:n],
            'covariance': np.asarray(result.covariance, dtype=float)[:n, :n],
            'initial_rms_residual': result.initial_rms_residual,
            'residuals': {
                'values': result.residuals,
                'channels': [str(c) for c in result.residual_channels],
                'postures': [int(p) for p in result.residual_postures],
            },
            'used_postures': used,
            'poses': result.poses if result.poses is not None else [],
            'kinds': kinds,
            'singular_values': identifiability.singular_values,
            'verdict': identifiability.verdict(),
            'link_length': link_length,
            'extras': extras or {},
        }
    )
    if mount is not None:
        payload[REPORT_DATA_KEY]['mount'] = check_mount(mount)
    return payload


def _device_prior_dict(prior) -> dict:
    """{name: {"value", "std"}} (SI) of a DevicePrior, or such a dict as it is."""
    if isinstance(prior, dict):
        return {
            str(name): {'value': float(entry['value']), 'std': float(entry['std'])}
            for name, entry in prior.items()
        }
    return {name: {'value': float(value), 'std': float(std)} for name, value, std in prior.entries}


def save_result(path: Path | str, result, extras: dict | None = None, **details) -> Path:
    """
    Write ``result_payload`` as a result file (hexacal_msgs_py.result_file).

    ``details`` are ``result_payload``'s keywords (measurements, true_parameters, link_length,
    mount, device_prior).
    """
    return write_result_file(path, _plain(result_payload(result, extras, **details)))
