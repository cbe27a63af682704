"""
``hexacal demo``: the whole system on a simulated machine, end to end (what `make demo` runs).

The way a real machine is calibrated, with the simulated machine standing in
for it through the interfaces a real one offers: writes the true machine
(Table 1; with ``--model gough_stewart`` the default Gough-Stewart platform)
and the nominal model (set 2) as parameters YAML, plans the postures (O1) and
a second, verification plan, starts collector, identify and the driver in
commanded mode (it follows JointTrajectory commands like a ros2_control
trajectory controller) in a ROS domain of its own (localhost discovery),
walks the plan with the executor, calls `hexacal/calibrate`, walks the
verification plan, calls `hexacal/verify`, and prints the parameter and pose
errors before and after calibration (against the simulated truth), the
verification table (no truth needed), what the drives went through (the driver's
status: the largest deviation of a commanded actuator from its setpoint at rest, force
or link extension) and the path of the HTML report.
``--measuring-mode`` (passive_actuator, the default; lvdt; compliant) plans for the mode
and runs the driver (and an executor that declares the parameter) in it; a drive fault
stops the demo at once, naming it. Everything it writes lands under
``out/demo_<timestamp>/`` (the bag in ``bag/``), with ``summary.json`` (demo_summary.py).
The executor refines its targets from intermediate calibrations (``--no-refine``: nominal
targets throughout, the paper's procedure as a baseline); the drives' figures are also split
before -> after refinement, from the driver's status at each rest (demo_refinement.py), and
the verification plan is walked on the calibration's targets, never refined.

The modules of the demo, in the order it runs:

* ``demo`` (this one): the command line, its checks and the options read from it; numpy-free,
  so that ``hexacal --help`` stays fast.
* ``demo_run``: the run - files, plans, the nodes started as child processes by bringup's
  supervisor (the launches of bringup.system), the calibration and verification walks.
* ``demo_session``: the demo's rclpy node beside the nodes, which watches them and calls their
  services, and the walk of one plan by an executor.
* ``demo_report``: the printed report; ``demo_summary`` and ``demo_refinement``: summary.json.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import signal

from hexacal_msgs_py.measuring_modes import MEASURING_MODES, MeasuringMode
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS  # numpy-free: `hexacal --help` stays fast

MODEL_CHOICES = tuple(MODELS)
EXIT_OK, EXIT_FAILED = 0, 1

# The paper's procedure: the planner rehearses every move's release.
DEMO_MEASURING_MODE = MeasuringMode.PASSIVE_ACTUATOR.value
# The executor's speed limit (m/s, rad/s for cranks); the simulated drive follows at twice it,
# and the driver's parameter caps that at 10.
EXECUTOR_SPEED_M_S = 0.5
# passive_actuator on the MuJoCo machine: the link bears the motion's inertia with one chain
# released (the Hexa Slide demo's peak link force 952 N at 0.5 m/s, 662 N at 0.25 m/s, 546 N at
# 0.15 m/s, there at a release swap, not on a move).
PASSIVE_PHYSICS_SPEED = 0.15
MAX_ACTUATOR_SPEED = 5.0

# Names of the demo's parts kept importable from here; their modules load on first use.
_MOVED = {
    'GRAPH_TIMEOUT_S': 'demo_session',
    'CALIBRATE_TIMEOUT_S': 'demo_session',
    'DRIVE_FAULT_NOTICE': 'demo_session',
    'claim_domain_id': 'demo_run',
    'DemoPaths': 'demo_run',
    'DRIVER_SPEED_M_S': 'demo_run',
    'COLLECTOR_WINDOWS': 'demo_run',
    'PLAN_CANDIDATES': 'demo_run',
    'SLIDER_DRIVE_LIMITS': 'demo_run',
    'SLIDER_EXECUTOR_LIMITS': 'demo_run',
    'actuator_limits': 'demo_run',
    'parameter_error_rows': 'demo_report',
    'verification_table': 'demo_report',
    'report': 'demo_report',
    'pose_summaries': 'demo_report',
}


def __getattr__(name: str) -> object:
    """Return a name of the demo that lives in one of its modules (imported on first use)."""
    if name not in _MOVED:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    import importlib

    return getattr(importlib.import_module(f'{__package__}.{_MOVED[name]}'), name)


class DemoError(RuntimeError):
    """The demo could not complete; the message says which step and why."""


def add_parsers(subparsers) -> None:
    parser = subparsers.add_parser(
        'demo',
        help='simulate a machine, collect postures over ROS 2, calibrate, print the errors',
        description='Plan postures (O1), walk them with the executor on a simulated Table 1 '
        'machine (or, with --model gough_stewart, the default Gough-Stewart platform) driven '
        'through its trajectory-controller interface, collect, calibrate nominal set 2, walk a '
        'verification plan and verify; print parameter and pose errors before and after, the '
        "verification table, the drives' largest deviation and force or extension, and the "
        'HTML report path. Takes about 4 minutes with the defaults on 2 idle cores, most of it '
        'planning (far longer on a busy machine); everything lands under '
        'out/demo_<timestamp>, with summary.json.',
    )
    parser.add_argument(
        '--model',
        choices=MODEL_CHOICES,
        default=DEFAULT_MODEL,
        help='machine model: hexa_slide (Table 1, default) or gough_stewart '
        '(the default 6-UPS hexapod)',
    )
    parser.add_argument(
        '--postures', type=int, default=50, help='postures to collect (default 50)'
    )
    parser.add_argument(
        '--measuring-mode',
        choices=MEASURING_MODES,
        default=DEMO_MEASURING_MODE,
        help="how the drives meet the measuring link: passive_actuator (default; the paper's "
        'procedure: one actuator released per posture, chosen by the planner so that the move '
        'to it closes on machines unlike the nominal), lvdt (a telescopic link whose length is '
        'measured; all six commanded) or compliant (all six commanded, servos compliant); the '
        'plans are made for it and the driver and executor run it',
    )
    parser.add_argument(
        '--no-refine',
        dest='refine',
        action='store_false',
        help="walk every posture on the nominal model's targets (the executor's refine_targets "
        'false; both plans): the procedure before issue #18, as a baseline. Default: the '
        'executor refines the remaining targets from intermediate calibrations once the '
        'postures allow one of full rank, and the verification plan is walked on the '
        "calibration's targets",
    )
    parser.add_argument(
        '--driver-param',
        action='append',
        default=[],
        metavar='NAME=VALUE',
        type=_driver_param,
        help='set a parameter of the simulated driver (repeatable; docs/nodes.md, driver; a '
        'float with a decimal point), e.g. max_force_n=50.0 to see its guard fault, '
        'servo_stiffness_n_per_m=5e5 or lvdt_stroke_m=0.003',
    )
    parser.add_argument(
        '--noise-um',
        type=float,
        default=10.0,
        help='uniform noise half-width: um on sliders and legs, urad on cranks and angles '
        '(default 10)',
    )
    parser.add_argument(
        '--out',
        type=Path,
        default=None,
        help='work directory for the parameter YAMLs and logs (default out/demo_<timestamp>)',
    )
    parser.add_argument(
        '--bag-dir',
        type=Path,
        default=None,
        help='record the bag to <bag-dir>/demo_<timestamp> (default: <out>/bag)',
    )
    parser.add_argument(
        '--plan',
        choices=('mixed', 'random'),
        default='mixed',
        help='mixed: 3 sphere : 1 fixed-position postures, O1-planned for eqs. 8 + 10 '
        '(default); random: sphere postures, O1-planned for eq. 7',
    )
    parser.add_argument(
        '--verify-postures',
        type=int,
        default=20,
        help='fresh postures of the verification plan (default 20; 0: no verification)',
    )
    parser.add_argument(
        '--settle-s',
        type=float,
        default=0.3,
        help='how long the machine stands still at a target before its posture is taken',
    )
    parser.add_argument(
        '--dwell-s',
        type=float,
        default=1.2,
        help='longest wait for the collector at a standing posture beyond --settle-s '
        '(the executor moves on as soon as the posture is measured)',
    )
    parser.add_argument('--rate-hz', type=float, default=100.0, help='sensor rate (default 100)')
    parser.add_argument(
        '--actuator-speed',
        type=float,
        default=None,
        metavar='SPEED',
        help="the executor's fastest actuator move (m/s; rad/s for actuators that turn; at "
        f'most {MAX_ACTUATOR_SPEED:g}; default {EXECUTOR_SPEED_M_S}, or {PASSIVE_PHYSICS_SPEED} '
        "in passive_actuator with --physics mujoco, where the released machine's inertia "
        'loads the measuring link); the simulated drives follow at up to twice that',
    )
    parser.add_argument(
        '--sensor-effects',
        default='all',
        metavar='TEXT',
        help="the simulated sensors' departures from ideal, the driver's sensor_effects: 'all' "
        "(default: every effect at its realistic default), '' (ideal sensors), or a comma list "
        'of lag, quantisation, clock, drops, spikes, drift (docs/user-guide.md, Sensor models)',
    )
    parser.add_argument(
        '--physics',
        choices=('kinematic', 'mujoco'),
        default=None,
        help="the simulated machine, the driver's physics parameter: kinematic (the driver's "
        "default: hexacal's own kinematics) or mujoco (MuJoCo: gravity, servo stiffness, "
        'springs, friction of the physical description)',
    )
    parser.add_argument(
        '--physical',
        default=None,
        metavar='FILE',
        help="with --physics mujoco: the machine's physical description YAML (docs/formats.md; "
        "default: the model's shipped description)",
    )
    parser.add_argument('--seed', type=int, default=0, help='seed of plan, noise and nominal set')
    parser.add_argument(
        '--validation-postures',
        type=int,
        default=50,
        help='fresh postures for the pose errors (default 50)',
    )
    parser.set_defaults(handler=run)


def model_name(args: argparse.Namespace) -> str:
    """Return --model (the default model when absent)."""
    return getattr(args, 'model', None) or DEFAULT_MODEL


def measuring_mode(args: argparse.Namespace) -> str:
    """Return --measuring-mode (the demo's default when absent)."""
    return getattr(args, 'measuring_mode', None) or DEMO_MEASURING_MODE


def refines(args: argparse.Namespace) -> bool:
    """Return whether the executor refines its targets (not --no-refine)."""
    return bool(getattr(args, 'refine', True))


def physics_parameters(args: argparse.Namespace) -> dict[str, str]:
    """Return the driver's physics parameters of ``--physics`` / ``--physical`` (if given)."""
    params = {}
    if getattr(args, 'physics', None):
        params['physics'] = args.physics
    if getattr(args, 'physical', None):
        params['physical'] = str(Path(args.physical).resolve())
    return params


def executor_physical(args: argparse.Namespace) -> dict[str, str]:
    """Return the executor's physical_file: --physical's weights load the link (if given)."""
    physical = getattr(args, 'physical', None)
    return {'physical_file': str(Path(physical).resolve())} if physical else {}


def physics(args: argparse.Namespace) -> str:
    """Return the simulated machine: --physics, a physics driver param, else kinematic."""
    given = dict(getattr(args, 'driver_param', []) or []).get('physics')
    return str(given or getattr(args, 'physics', None) or 'kinematic')


def actuator_speed(args: argparse.Namespace) -> float:
    """Return the executor's speed limit: --actuator-speed, else the mode's and machine's."""
    speed = getattr(args, 'actuator_speed', None)
    if speed is not None:
        return float(speed)
    if physics(args) == 'mujoco' and measuring_mode(args) == 'passive_actuator':
        return PASSIVE_PHYSICS_SPEED
    return EXECUTOR_SPEED_M_S


def _driver_param(text: str) -> tuple[str, object]:
    """
    Parse NAME=VALUE: true/false a bool, digits an int, other numbers a float, else text.

    The driver checks names and types itself (its parameter descriptors): a float parameter
    takes a number with a decimal point or an exponent (max_force_n=500.0).
    """
    name, sep, value = (part.strip() for part in text.partition('='))
    if not sep or not name:
        raise argparse.ArgumentTypeError(f'expected NAME=VALUE, got {text!r}')
    if value.lower() in ('true', 'false'):
        return name, value.lower() == 'true'
    for kind in (int, float):
        try:
            return name, kind(value)
        except ValueError:
            pass
    return name, value


def _check_args(args) -> None:
    from hexacal_msgs_py.models import model_layout

    count = model_layout(model_name(args)).n_parameters
    minimum = math.ceil(count / 4)
    if args.postures < minimum:
        raise ValueError(
            f'--postures must be at least {minimum} ({count} parameters, 4 residuals '
            f'per posture), got {args.postures}'
        )
    for name in ('noise_um', 'settle_s', 'dwell_s', 'rate_hz', 'actuator_speed'):
        value = getattr(args, name)
        if value is None:  # --actuator-speed by default: actuator_speed(args)
            continue
        if not math.isfinite(value) or value < 0 or (name != 'noise_um' and value == 0):
            raise ValueError(f'--{name.replace("_", "-")} must be positive, got {value}')
    if args.actuator_speed is not None and args.actuator_speed > MAX_ACTUATOR_SPEED:
        raise ValueError(
            f'--actuator-speed must be at most {MAX_ACTUATOR_SPEED}, got {args.actuator_speed}'
        )
    if args.verify_postures < 0:
        raise ValueError(f'--verify-postures must be 0 or more, got {args.verify_postures}')


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM too ends the demo through its cleanup (children stopped)


def run(args) -> int:
    """Run the demo (demo_run.run_demo) with SIGTERM ending it through its cleanup."""
    _check_args(args)
    from .demo_run import run_demo

    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        return run_demo(args)
    finally:
        signal.signal(signal.SIGTERM, previous)
