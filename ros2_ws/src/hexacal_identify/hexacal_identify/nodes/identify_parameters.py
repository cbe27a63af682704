"""
The identify node's ROS parameters: names, defaults, ranges and descriptions.

Kept apart from nodes/identify.py so the node module holds only the glue. Every one may be set
at run time (a calibration reads them when it starts); the checks beyond type and range are the
session's `parameter_problem` (hexacal_identify.session).
"""

from __future__ import annotations

import os

from hexacal_msgs_py.node_parameters import ParameterSpec as _Spec

from ..core.fit.compliance import COMPLIANCE_MODES
from ..core.fit.residuals import COSTS
from ..core.fit.weighting import WEIGHT_MODES
from ..core.machine.device import DEVICE_PARAMETER_NAMES
from ..core.machine.measurements import ScatterFloor
from ..session import DEFAULT_OUTPUT
from ..session.prior import ANGLE_PRIORS, LINK_LENGTH_PRIOR


def _angle_priors() -> dict[str, _Spec]:
    specs: dict[str, _Spec] = {}
    for name in ANGLE_PRIORS:
        specs[f'device.{name}'] = _Spec(
            0.0,
            f'prior value of the device defect {name} (rad), used when device.{name}_std > 0',
        )
        specs[f'device.{name}_std'] = _Spec(
            0.0,
            f'standard deviation of the prior on {name} (rad); > 0 makes it a prior (the defect '
            'is identified; needs noise_slider_m and noise_angle_rad, or postures with scatter); '
            '0.0 = no prior',
        )
    return specs


# Declared in this order: the prior values come before their stds (a std given at start-up is
# checked against its value).
PARAMETERS: dict[str, _Spec] = {
    'output_dir': _Spec(
        os.getcwd(),
        'directory the node writes under (default: its working directory)',
    ),
    'output': _Spec(
        DEFAULT_OUTPUT,
        'parameters YAML written after a calibration; relative to output_dir, and never '
        'outside it',
    ),
    'nominal': _Spec(
        '',
        'parameters YAML of the nominal model to start from (required to calibrate); its '
        "'model' key (none: hexa_slide) is the machine model, which names the posture joints",
    ),
    'cost': _Spec(
        'absolute',
        'cost function of the identification',
        constraints='one of ' + ', '.join(COSTS),
    ),
    'bag': _Spec('', "bag to calibrate from; '' = the postures received live"),
    'link_length': _Spec(
        0.75,
        'measuring link length L (m)',
        0.1,
        5.0,
    ),
    'identify_device': _Spec(
        '',
        "device defects to identify jointly, comma-separated (e.g. 'dL,alpha0,gamma'); '' = none",
        constraints='names from ' + ', '.join(DEVICE_PARAMETER_NAMES),
    ),
    'noise_slider_m': _Spec(
        0.0,
        'known actuator noise half-width (m; rad for actuators that turn); with '
        'noise_angle_rad > 0 the residuals are weighted by the reading noise; 0 = unweighted',
        0.0,
        0.01,
    ),
    'noise_angle_rad': _Spec(
        0.0,
        'known angle noise half-width (rad), see noise_slider_m',
        0.0,
        0.01,
    ),
    'weights': _Spec(
        'auto',
        "what weighs the residuals: 'scatter' (each posture's measured scatter, carried in the "
        "posture's velocity/effort), 'noise-model' (noise_slider_m, noise_angle_rad) or 'none'; "
        "'auto': scatter when every posture carries it, else the noise model when set, else none",
        constraints='one of ' + ', '.join(WEIGHT_MODES),
    ),
    'scatter_floor_actuator_m': _Spec(
        ScatterFloor().actuator_m,
        'smallest standard error (m; rad for actuators that turn) an actuator value is '
        'credited with when weighed by scatter',
        1e-9,
        0.01,
    ),
    'scatter_floor_angle_rad': _Spec(
        ScatterFloor().angle_rad,
        'smallest standard error (rad) an angle is credited with when weighed by scatter',
        1e-9,
        0.01,
    ),
    'robust_loss': _Spec('', "'' (least squares), 'huber' or 'soft_l1'"),
    'compliance': _Spec(
        'none',
        'axial compliances identified with the geometry from the static loads of each posture '
        '(as hexacal calibrate --compliance): none (rigid), shared (one for the six chains, one '
        'for the link) or per_chain (one per chain, one for the link); needs the measuring mode '
        "and, in passive_actuator, each posture's released actuator: a bag has them, live "
        'postures only in the lvdt mode (their link_length)',
        constraints='one of ' + ', '.join(COMPLIANCE_MODES),
    ),
    'physical_file': _Spec(
        '',
        'physical description YAML (gravity, platform, payload, legs, link masses and centres '
        'of mass; SI) whose weights load the chains and the link when compliance is not none; '
        "'' = the nominal model's shipped physical description",
    ),
    'deflection_check': _Spec(
        False,
        'with compliance none: after the calibration, how far the compliances of physical_file '
        "('' = the shipped description; it must give the stiffnesses) bias the rigid fit, as "
        'hexacal calibrate --physical: deflection_check.* on the calibration status and a '
        "warning when the bias exceeds the calibration's statistical error; needs the postures' "
        'measuring mode (a bag, or live lvdt postures)',
    ),
    'compliance_prior': _Spec(
        '',
        'datasheet compliances NAME=VALUE:STD,... in m/N (as hexacal calibrate '
        "--compliance-prior), e.g. 'link=1e-7:2e-8'; names: chains or chain_1..chain_6, link; "
        "'' = none",
    ),
    LINK_LENGTH_PRIOR: _Spec(
        0.0,
        'measured length of the device link (m), e.g. by a caliper; with '
        'device.link_length_std > 0 it is a prior on dL = device.link_length - link_length '
        '(link_length is the length the device model assumes); 0.0 = not measured',
    ),
    f'{LINK_LENGTH_PRIOR}_std': _Spec(
        0.0,
        'standard deviation of device.link_length (m); > 0 makes the prior (needs '
        'device.link_length > 0 and noise_slider_m, noise_angle_rad); 0.0 = no prior',
    ),
    **_angle_priors(),
    'verify_threshold_m': _Spec(
        0.0,
        'hexacal/verify passes when the calibrated position rms is at most this (m); 0 = 3x '
        'the rms the reading noise alone gives when noise_slider_m and noise_angle_rad are '
        'set, else 50 um',
        0.0,
        0.1,
    ),
    'report_dir': _Spec(
        'report',
        'HTML calibration report written after each calibration, relative to output_dir; '
        "'' = none",
    ),
    'calibration_store': _Spec(
        '',
        'calibration store directory: every calibration is kept there with its provenance and '
        "verifications, and deployed from there; '' = the machine model's default store "
        '(as `hexacal history`: $HEXACAL_STORE, else a directory per model under the user '
        'data directory)',
    ),
}
