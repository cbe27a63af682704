"""
Prior knowledge of the device from the node's device.* parameters (core.device.DevicePrior).

`device.link_length` (m, a caliper's measured length; 0 = not measured) with
`device.link_length_std` (m; > 0 makes a prior on dL = device.link_length - link_length,
`link_length` being the length the device model assumes), and `device.<defect>` /
`device.<defect>_std` (rad) for alpha0, beta0, gamma, phi0. A std > 0 makes a prior: that
parameter is identified, and the prior is weighed against the data by the reading noise, so
it needs noise_slider_m and noise_angle_rad (else the calibration fails as
`device-prior-without-noise`). The result status carries each prior
(`prior.device.<name>`, `prior_std.device.<name>`) beside the posterior (`device.<name>`,
`std.device.<name>`), and the report shows them side by side. A negative or non-finite std,
and a link std without the measured length, are refused when set (prior_parameter_problem).
"""

from __future__ import annotations

from collections.abc import Mapping
import math

from ..core.machine.device import DevicePrior

LINK_LENGTH_PRIOR = 'device.link_length'
ANGLE_PRIORS = ('alpha0', 'beta0', 'gamma', 'phi0')
PRIOR_VALUE_PARAMETERS = (LINK_LENGTH_PRIOR, *(f'device.{name}' for name in ANGLE_PRIORS))
PRIOR_STD_PARAMETERS = tuple(f'{name}_std' for name in PRIOR_VALUE_PARAMETERS)
PRIOR_PARAMETERS = (*PRIOR_VALUE_PARAMETERS, *PRIOR_STD_PARAMETERS)


def device_prior(values: Mapping[str, float], link_length: float) -> DevicePrior:
    """
    Return the prior the device.* parameter `values` give (empty: none; missing = 0).

    The link's is on dL = device.link_length - link_length (the length the device model
    assumes); ValueError when its std is set without the measured length.
    """
    entries = []
    std = values.get(f'{LINK_LENGTH_PRIOR}_std', 0.0)
    if std > 0:
        measured = values.get(LINK_LENGTH_PRIOR, 0.0)
        if measured <= 0:
            raise ValueError(
                f'{LINK_LENGTH_PRIOR}_std = {std:g} m but {LINK_LENGTH_PRIOR} is not set: give '
                'the measured link length in m'
            )
        entries.append(('dL', measured - link_length, std))
    for name in ANGLE_PRIORS:
        std = values.get(f'device.{name}_std', 0.0)
        if std > 0:
            entries.append((name, values.get(f'device.{name}', 0.0), std))
    return DevicePrior(tuple(entries))


def prior_parameter_problem(name: str, value: float, link: tuple[float, float]) -> str | None:
    """
    Return why a device.* parameter value is refused when set, or None.

    `link` is (device.link_length, device.link_length_std) with this change applied: a link std
    without the measured length is refused.
    """
    if name in PRIOR_VALUE_PARAMETERS and not math.isfinite(value):
        return (
            f'{name} must be finite (SI units: m for the link, rad for angles), got {value!r}'
        )
    if name in PRIOR_STD_PARAMETERS and not (math.isfinite(value) and value >= 0):
        return (
            f'{name} must be a finite standard deviation >= 0 (0 = no prior), got {value!r}'
        )
    if name == LINK_LENGTH_PRIOR and value < 0:
        return f'{LINK_LENGTH_PRIOR} is a length in m (0 = not measured), got {value!r}'
    if name in (LINK_LENGTH_PRIOR, f'{LINK_LENGTH_PRIOR}_std') and link[1] > 0 and link[0] <= 0:
        return (
            f'{LINK_LENGTH_PRIOR}_std > 0 makes a prior on the link length, but '
            f'{LINK_LENGTH_PRIOR} is not set: give the measured length in m '
            f'(-p device.link_length:=0.7503), or set {LINK_LENGTH_PRIOR}_std to 0'
        )
    return None
