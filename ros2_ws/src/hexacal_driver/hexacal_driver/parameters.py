"""
Parameters of the driver node (ROS-free): their specs and the checks beyond type and range.

The node declares `PARAMETERS` with descriptors (hexacal_msgs_py.node_parameters) and
refuses a value for which `parameter_problem` names a problem, at start-up and at run time.
"""

from __future__ import annotations

import math
from typing import Any

from hexacal_driver.plan import GENERATED_PLANS, load_plan, PlanError
from hexacal_driver.sensor_parameters import sensor_parameter_problem, SENSOR_PARAMETERS
from hexacal_identify.core.machine.device import DeviceDefects
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.measuring_modes import (
    COMPLIANT_SERVO_STIFFNESS_N_PER_M,
    DEFAULT_LVDT_STROKE_M,
    LINK_FORCE_LIMIT_N,
    measuring_mode,
    MEASURING_MODES,
    MeasuringMode,
)
from hexacal_msgs_py.models import MAX_DEVICE_TURN, MODELS
from hexacal_msgs_py.node_parameters import ParameterSpec as _Spec
from hexacal_msgs_py.parameters_file import load_parameters
from hexacal_msgs_py.physical_file import PhysicalFileError, read_physical_file

# Parameters that may change while the node runs; all others shape the plan and are read-only.
RUNTIME_PARAMETERS = ('slider_noise_m', 'angle_noise_rad', 'device_turn')


MODEL_CHOICES = ('', *MODELS)
PHYSICS_CHOICES = ('kinematic', 'mujoco')

PARAMETERS: dict[str, _Spec] = {
    'true_params': _Spec(
        '',
        'parameters YAML (SI) of the simulated true machine, of any model '
        "(its 'model' key; 'device.mount: standing' for an upright device, "
        'default hanging); empty: the default machine of `model` (Hexa Slide: '
        'Table 1 of the paper)',
    ),
    'model': _Spec(
        '',
        "machine model: 'hexa_slide' or 'gough_stewart'; '' = the model of "
        'true_params, else hexa_slide. Without true_params the default machine of '
        'the model is simulated; with it, the two must agree',
        constraints="'', " + ', '.join(repr(name) for name in MODELS),
    ),
    'link_length': _Spec(
        0.75, 'measuring link length L between the U-joint centres (m)', 0.1, 5.0
    ),
    'slider_noise_m': _Spec(
        1e-5,
        'half-width of the uniform actuator noise (m; rad for actuators that turn, the LVDT '
        'link reading takes it in m)',
        0.0,
        0.01,
    ),
    'angle_noise_rad': _Spec(
        1e-5, 'half-width of the uniform inclinometer and rotary noise (rad)', 0.0, 0.1
    ),
    'seed': _Spec(0, 'seed of the random plan and of the noise', 0, 2**31 - 1),
    'rate_hz': _Spec(100.0, 'publishing rate of every sensor stream (Hz)', 1.0, 1000.0),
    'settle_s': _Spec(1.0, 'time to move from one posture to the next (s)', 0.05, 600.0),
    'dwell_s': _Spec(1.5, 'time standing still at each posture (s)', 0.1, 3600.0),
    'plan': _Spec(
        'random',
        'posture plan: random (sphere postures), fixed (fixed-position '
        'postures), mixed (3 sphere : 1 fixed) or the path of a plan YAML',
        constraints="'random', 'fixed', 'mixed' or an existing plan file",
    ),
    'postures': _Spec(50, 'number of postures of a random, fixed or mixed plan', 1, 100000),
    'loop': _Spec(False, 'walk the plan again when done (else stand at the last posture)'),
    'wait_for_subscriber': _Spec(
        True, 'hold the first posture until the three sensor streams have a matched subscriber'
    ),
    'imu_topic': _Spec(
        '',
        'also publish the inclinometer reading as a sensor_msgs/Imu on this topic '
        "(orientation by hexacal_msgs_py.inputs' convention, stamped as the inclinometer "
        "JointState message), as a real Imu inclinometer would; '' = none",
    ),
    'command_topic': _Spec(
        '',
        "'' (default): walk the plan; else follow trajectory_msgs/"
        'JointTrajectory commands on this topic (e.g. /joint_trajectory_'
        'controller/joint_trajectory) like a trajectory controller with mock '
        'hardware, instead of walking a plan',
    ),
    'device_defects': _Spec(
        '',
        "the simulated device's errors, 'NAME=VALUE,...' with NAME one "
        'of dL (link length offset, m: the true link is link_length + dL), '
        'alpha0, beta0 (inclinometer zero offsets, rad), gamma (skew of the '
        "inclinometer axes, rad), phi0 (rotary zero offset, rad); '' = an "
        'ideal device',
        constraints="'' or NAME=VALUE pairs (core.device.DeviceDefects.parse)",
    ),
    'device_turn': _Spec(
        0.0,
        "the device's rotation about its link axis from its normal "
        'mounting (rad; 0 normal, pi reversed, pi/2 a quarter turn), for the '
        'postures whose plan entry names none; settable at run time',
        -MAX_DEVICE_TURN,
        MAX_DEVICE_TURN,
    ),
    'max_actuator_speed_m_s': _Spec(
        0.1,
        'commanded mode: the fastest an actuator moves (m/s; rad/s for actuators that turn); '
        "slower when a point's time_from_start asks for it",
        1e-6,
        10.0,
    ),
    # The drives in commanded mode (drives.py): the measuring mode and a real drive's guards.
    # 'compliant' is the default: a drive that is not told otherwise commands all six.
    'measuring_mode': _Spec(
        MeasuringMode.COMPLIANT.value,
        'commanded mode: how the drives meet the measuring link: passive_actuator (stiff '
        'drives, one joint released through hexacal/release/<joint>), lvdt (stiff drives, a '
        'telescopic link measured on hexacal/link) or compliant (six compliant servos as '
        'before the modes had names, the default for now); the plan walker ignores it',
        constraints=', '.join(repr(mode) for mode in MEASURING_MODES),
    ),
    'max_following_error_m': _Spec(
        5e-4,
        'commanded mode, passive_actuator and lvdt: the stiff drives fault when a commanded '
        'actuator would stand farther than this from its setpoint (m; rad for actuators that '
        'turn)',
        1e-9,
        1.0,
    ),
    'servo_stiffness_n_per_m': _Spec(
        COMPLIANT_SERVO_STIFFNESS_N_PER_M,
        'commanded mode, compliant: the stiffness of each servo (N/m; N m/rad for actuators '
        'that turn); its force (effort of the sliders message, N; a torque in N m for those) = '
        "stiffness x (position - setpoint) (2e4 N/m: the millimetres a nominal model's targets "
        'miss load the link with a few hundred newtons at most)',
        1.0,
        1e12,
    ),
    'max_force_n': _Spec(
        LINK_FORCE_LIMIT_N,
        'commanded mode, compliant: the servos fault when the force of an actuator would exceed '
        'this (N, N m for a torque; the rigid measuring link carries it: by default the 500 N '
        'a link of the documented kind bears)',
        1e-6,
        1e9,
    ),
    'max_link_force_n': _Spec(
        LINK_FORCE_LIMIT_N,
        'commanded mode, compliant: the servos fault when the tension or compression they put '
        'on the measuring link would exceed this (N; 500 N: a tenth of the buckling load of a '
        '0.75 m link of 1e7 N/m, 50 um of stretch)',
        1e-6,
        1e9,
    ),
    'lvdt_stroke_m': _Spec(
        DEFAULT_LVDT_STROKE_M,
        'commanded mode, lvdt: the stroke of the link, +- this about its rest length (m); beyond '
        'it the link is at its end stop and the drives fault (max_following_error_m)',
        1e-6,
        1.0,
    ),
    # The machine behind the commanded mode: the kinematic model or the MuJoCo simulation.
    'physics': _Spec(
        'kinematic',
        'commanded mode: the machine the drives move: kinematic (the geometric model, exact '
        'at every instant) or mujoco (a MuJoCo simulation: masses, gravity, servo gains, '
        'springs and released-actuator friction of the physical description, '
        'hexacal_driver.physics_follower; needs the mujoco package)',
        constraints=', '.join(repr(name) for name in PHYSICS_CHOICES),
    ),
    'physical': _Spec(
        '',
        "physics mujoco: the machine's physical description YAML (docs/formats.md: masses, "
        "stiffnesses, servo gains, following-error limit, friction, payload); '' = the "
        "model's shipped realistic machine",
        constraints="'' or a physical description file",
    ),
    **SENSOR_PARAMETERS,  # sensor_effects and the sensor models' parameters (read-only)
}

# Actuator quantities (core.architectures.actuator_defaults): declared once the true machine's
# model is known, with that model's defaults (the specs' for sliders and legs).
ACTUATOR_PARAMETERS = {
    'slider_noise_m': 'reading',
    'max_actuator_speed_m_s': 'speed',
    'max_following_error_m': 'length',
    'servo_stiffness_n_per_m': 'stiffness',
    'max_force_n': 'force',
}


def actuator_parameter_defaults(model: str) -> dict[str, float]:
    """Return the defaults of ACTUATOR_PARAMETERS for a true machine of `model`."""
    from hexacal_identify.core.architectures.actuator_defaults import actuator_defaults

    return actuator_defaults(model, PARAMETERS, ACTUATOR_PARAMETERS)


# Numbers whose descriptors give a range but let inf and nan through.
FINITE_PARAMETERS = (
    'link_length',
    'rate_hz',
    'settle_s',
    'dwell_s',
    'slider_noise_m',
    'angle_noise_rad',
    'max_actuator_speed_m_s',
    'max_following_error_m',
    'servo_stiffness_n_per_m',
    'max_force_n',
    'max_link_force_n',
    'lvdt_stroke_m',
)


def parameter_problem(name: str, value: Any) -> str | None:
    """Return what is wrong with a parameter value beyond type and range (descriptors), or None."""
    if name == 'plan':
        if value in GENERATED_PLANS:
            return None
        if not value:
            return f"plan must be one of {list(GENERATED_PLANS)} or a plan file path, got ''"
        try:
            load_plan(value)
        except PlanError as error:
            return (
                f'plan {value!r} is neither one of {list(GENERATED_PLANS)} nor a valid '
                f'plan file: {error}'
            )
    elif name == 'true_params' and value:
        try:
            load_parameters(value)
        except ParameterFileError as error:
            return f'true_params: {error}'
    elif name == 'device_defects':
        try:
            DeviceDefects.parse(value)
        except ValueError as error:
            return f'device_defects {value!r}: {error}'
    elif name == 'device_turn' and not (math.isfinite(value) and abs(value) <= MAX_DEVICE_TURN):
        return f'device_turn must be a finite angle within +-2 pi rad, got {value!r}'
    elif name == 'measuring_mode':
        try:
            measuring_mode(value)
        except ValueError:
            return f'measuring_mode must be one of {", ".join(MEASURING_MODES)}, got {value!r}'
    elif name == 'physics' and value not in PHYSICS_CHOICES:
        return f'physics must be one of {", ".join(PHYSICS_CHOICES)}, got {value!r}'
    elif name == 'physical' and value:
        try:
            read_physical_file(value)
        except PhysicalFileError as error:
            return f'physical: {error}'
    elif name == 'model' and value not in MODEL_CHOICES:
        return f"model must be '' or one of {', '.join(MODELS)}, got {value!r}"
    elif name in SENSOR_PARAMETERS:
        return sensor_parameter_problem(name, value)
    elif name in FINITE_PARAMETERS and not math.isfinite(value):
        return f'{name} must be finite, got {value}'
    return None
