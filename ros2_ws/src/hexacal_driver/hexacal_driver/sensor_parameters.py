"""
The driver's sensor-model parameters (sensor_models.py): their specs and checks.

Merged into parameters.PARAMETERS; all read-only (the streams' state is built once).
"""

from __future__ import annotations

import math

from hexacal_driver.sensor_models import parse_effects, SENSOR_DEFAULTS, SensorEffect
from hexacal_msgs_py.node_parameters import ParameterSpec as _Spec

_D = SENSOR_DEFAULTS

SENSOR_PARAMETERS: dict[str, _Spec] = {
    'sensor_effects': _Spec(
        '',
        "the sensors' departures from ideal: '' ideal sensors (uniform noise only, one stamp), "
        "'all', or a comma list of "
        + ', '.join(effect.value for effect in SensorEffect)
        + ' (docs/user-guide.md, Sensor models)',
        constraints="'', 'all' or a comma list of sensor effect names",
    ),
    'inclinometer_time_constant_s': _Spec(
        _D['inclinometer_time_constant_s'],
        "lag: time constant of the inclinometer's first-order output filter (s)",
        0.0,
        60.0,
    ),
    'actuator_resolution_m': _Spec(
        _D['actuator_resolution_m'],
        'quantisation: resolution of the actuator readings (m; 0 none)',
        0.0,
        0.001,
    ),
    'inclinometer_resolution_rad': _Spec(
        _D['inclinometer_resolution_rad'],
        'quantisation: resolution of the inclinometer angles (rad; 0 none)',
        0.0,
        0.01,
    ),
    'rotary_resolution_rad': _Spec(
        _D['rotary_resolution_rad'],
        'quantisation: resolution of the rotary angle (rad; 0 none; default a 20-bit encoder, '
        '2 pi / 2**20)',
        0.0,
        0.1,
    ),
    'inclinometer_clock_offset_s': _Spec(
        _D['inclinometer_clock_offset_s'],
        "clock: the inclinometer's stamps minus the true sample time (s; the sliders' clock is "
        'the reference)',
        -1.0,
        1.0,
    ),
    'encoder_clock_offset_s': _Spec(
        _D['encoder_clock_offset_s'],
        "clock: the rotary encoder's stamps minus the true sample time (s)",
        -1.0,
        1.0,
    ),
    'clock_jitter_s': _Spec(
        _D['clock_jitter_s'],
        'clock: standard deviation of the Gaussian jitter of every stamp, per stream (s)',
        0.0,
        0.1,
    ),
    'drop_probability': _Spec(
        _D['drop_probability'],
        'drops: probability that a message of a stream is lost (per message and stream)',
        0.0,
        0.9,
    ),
    'spike_rate_hz': _Spec(
        _D['spike_rate_hz'],
        'spikes: mean rate of vibration spikes on the inclinometer (1/s)',
        0.0,
        100.0,
    ),
    'spike_size_rad': _Spec(
        _D['spike_size_rad'],
        'spikes: size of a spike on each inclinometer angle (rad, random sign)',
        0.0,
        0.1,
    ),
    'inclinometer_drift_rad_per_s': _Spec(
        _D['inclinometer_drift_rad_per_s'],
        "drift: rate of the inclinometer zero's linear drift from the first sample, both "
        'axes (rad/s)',
        -0.001,
        0.001,
    ),
}


def sensor_parameter_problem(name: str, value: object) -> str | None:
    """Return what is wrong with a sensor-model parameter value, or None."""
    if name == 'sensor_effects':
        try:
            parse_effects(str(value))
        except ValueError as error:
            return f'sensor_effects {value!r}: {error}'
    elif not math.isfinite(float(value)):  # type: ignore[arg-type]
        return f'{name} must be finite, got {value}'
    return None
