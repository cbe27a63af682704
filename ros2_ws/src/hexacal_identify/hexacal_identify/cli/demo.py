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
targets throughout, the procedure before issue #18); the drives' figures are also split
before -> after refinement, from the driver's status at each rest (demo_refinement.py), and
the verification plan is walked on the calibration's targets, never refined.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from datetime import datetime
import math
import os
from pathlib import Path
import signal
import sys
import time
from typing import Callable, TYPE_CHECKING

from hexacal_msgs_py.measuring_modes import MEASURING_MODES, MeasuringMode
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS  # numpy-free: `hexacal --help` stays fast

from .demo_refinement import refined_at, refinement_lines, refinement_summary, RestLog
from .demo_summary import build_summary, SUMMARY_FILE, summary_lines, write_summary
from ..bringup.system import executor_takes_measuring_mode

if (
    TYPE_CHECKING
):  # numpy and the process launcher are imported where the demo runs, not at `hexacal` start-up
    import numpy as np

    from ..bringup.supervisor import NodeGroup, RunningNode

GRAPH_TIMEOUT_S = 30.0
CALIBRATE_TIMEOUT_S = 300.0
MODEL_CHOICES = tuple(MODELS)
EXIT_OK, EXIT_FAILED = 0, 1

# The paper's procedure (issue #18): the planner rehearses every move's release.
DEMO_MEASURING_MODE = MeasuringMode.PASSIVE_ACTUATOR.value
DRIVE_FAULT_NOTICE = 'the drive faulted: '  # how the executor's notice names a drive fault


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
        'float with a decimal point), e.g. max_force_n=2000.0 to see its guard fault, '
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


# --------------------------------------------------------------------------- ROS domain


def claim_domain_id() -> int:
    """Return a ROS domain id no test session or other demo uses (held until exit)."""
    from ..ros_domain import claim_domain_id as claim, NoFreeDomainError

    try:  # from pid * 7: away from the test sessions, which start at their pid
        return claim('HEXACAL_DEMO_DOMAIN_ID', start=os.getpid() * 7)
    except NoFreeDomainError as error:
        raise DemoError(str(error)) from None


# --------------------------------------------------------------------------- the run


@dataclass
class DemoPaths:
    work: Path
    bag: Path
    true_params: Path
    nominal: Path
    calibration: Path
    logs: Path
    plan: Path
    verification_plan: Path
    report: Path
    summary: Path


def _model(args) -> str:
    return getattr(args, 'model', None) or DEFAULT_MODEL


def _mode(args) -> str:
    return getattr(args, 'measuring_mode', None) or DEMO_MEASURING_MODE


def _refine(args) -> bool:
    return bool(getattr(args, 'refine', True))


def _paths(args) -> DemoPaths:
    stamp = datetime.now().strftime('%Y%m%d_%H%M%S')
    work = (args.out or Path('out') / f'demo_{stamp}').resolve()
    from ..core.architectures import architecture

    truth = architecture(_model(args)).truth_file_name
    bag = (args.bag_dir / f'demo_{stamp}').resolve() if args.bag_dir is not None else work / 'bag'
    return DemoPaths(
        work,
        bag,
        work / truth,
        work / 'nominal_set2.yaml',
        work / 'calibration.yaml',
        work / 'logs',
        work / 'plan.yaml',
        work / 'verification_plan.yaml',
        work / 'report',
        work / SUMMARY_FILE,
    )


def _check_args(args) -> None:
    from hexacal_msgs_py.models import model_layout

    count = model_layout(_model(args)).n_parameters
    minimum = math.ceil(count / 4)
    if args.postures < minimum:
        raise ValueError(
            f'--postures must be at least {minimum} ({count} parameters, 4 residuals '
            f'per posture), got {args.postures}'
        )
    for name in ('noise_um', 'settle_s', 'dwell_s', 'rate_hz'):
        value = getattr(args, name)
        if not math.isfinite(value) or value < 0 or (name != 'noise_um' and value == 0):
            raise ValueError(f'--{name.replace("_", "-")} must be positive, got {value}')
    if args.verify_postures < 0:
        raise ValueError(f'--verify-postures must be 0 or more, got {args.verify_postures}')


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM too ends the demo through its cleanup (children stopped)


def run(args) -> int:
    _check_args(args)
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        return _run(args)
    finally:
        signal.signal(signal.SIGTERM, previous)


# Executor and commanded driver: moves at up to 0.5 m/s (executor) on a machine that follows at 1
# m/s; the collector's detector window 0.2 s + capture 0.3 s (the executor waits for each posture).
EXECUTOR_SPEED_M_S = 0.5
DRIVER_SPEED_M_S = 1.0
COLLECTOR_WINDOWS = {'window_s': 0.2, 'capture_s': 0.3}
PLAN_CANDIDATES = 1000


# The drives' and the executor's limits sized for sliders (the nodes' defaults: m, N/m, N).
SLIDER_DRIVE_LIMITS = {
    'max_following_error_m': (5e-4, 'length'),
    'servo_stiffness_n_per_m': (2e6, 'stiffness'),
    'max_force_n': (1e5, 'force'),
}
SLIDER_EXECUTOR_LIMITS = {
    'position_tolerance_m': (5e-3, 'length'),
    'still_tolerance_m': (1e-4, 'length'),
    'released_margin_m': (1e-3, 'length'),
    'servo_stiffness_n_per_m': (2e6, 'stiffness'),
    'max_force_n': (1e5, 'force'),
}


def actuator_limits(arch, limits: dict[str, tuple[float, str]]) -> dict[str, float]:
    """
    Return the node parameters of `limits` in the actuators' unit of `arch` (none for sliders).

    The nodes' defaults are sized for sliders (m, N/m, N); an architecture whose actuators
    turn gets them through its lever (Architecture.actuator_limit: rad, N m/rad, N m), so the
    compliant servos, the following-error guard and the executor's tolerances mean the same
    travel at the actuator's joint.
    """
    if arch.actuator_lever_m == 1.0:
        return {}
    return {
        name: arch.actuator_limit(value, dimension)
        for name, (value, dimension) in limits.items()
    }


def _physics_params(args: argparse.Namespace) -> dict[str, str]:
    """Return the driver's physics parameters of ``--physics`` / ``--physical`` (if given)."""
    params = {}
    if getattr(args, 'physics', None):
        params['physics'] = args.physics
    if getattr(args, 'physical', None):
        params['physical'] = str(Path(args.physical).resolve())
    return params


def _physics(args: argparse.Namespace) -> str:
    """Return the simulated machine: --physics, a physics driver param, else kinematic."""
    given = dict(getattr(args, 'driver_param', []) or []).get('physics')
    return str(given or getattr(args, 'physics', None) or 'kinematic')


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


def _plans(args, nominal, paths: DemoPaths) -> None:
    """Write the calibration plan (O1) and the verification plan (fresh postures, another draw)."""
    from ..core.machine.measurements import NoiseModel
    from ..core.planning.planner import plan_postures

    noise = NoiseModel.from_microns(args.noise_um) if args.noise_um > 0 else None
    mixed = args.plan == 'mixed'
    plan_postures(
        nominal,
        args.postures,
        index='O1',
        cost='sphere-fixed' if mixed else 'absolute',
        fixed_fraction=0.25 if mixed else None,
        n_candidates=PLAN_CANDIDATES,
        seed=args.seed,
        noise=noise,
        name='demo-calibration',
        measuring_mode=_mode(args),
    ).plan.save(paths.plan)
    if args.verify_postures:
        plan_postures(
            nominal,
            args.verify_postures,
            index='O1',
            cost='absolute',
            n_candidates=PLAN_CANDIDATES,
            seed=args.seed + 1000,
            noise=noise,
            name='demo-verification',
            measuring_mode=_mode(args),
        ).plan.save(paths.verification_plan)


def _run(args) -> int:
    started = time.monotonic()
    paths = _paths(args)
    # Planning takes the first minutes (every release rehearsed on several machines): say so at
    # once, before the imports, so that the demo is never silent.
    verify_text = (
        f' and a verification plan of {args.verify_postures}' if args.verify_postures else ''
    )
    print(
        f'hexacal demo: planning {args.postures} calibration postures{verify_text} '
        f'({_model(args)}, {_mode(args)}; O1 over {PLAN_CANDIDATES} candidates, every move '
        'rehearsed on machines unlike the nominal); then the nodes start',
        flush=True,
    )
    from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC
    from hexacal_msgs_py.parameters_file import save_parameters

    from ..core.architectures import architecture
    from ..core.machine.model import nominal_set
    from ..bringup.launch_spec import NodeLaunch
    from ..bringup.supervisor import NodeGroup

    model = _model(args)
    arch = architecture(model)
    true_params, nominal = (
        arch.default_parameters(),
        nominal_set(2, seed=args.seed, model=model),
    )
    truth_text, nominal_text = arch.machine_label, arch.nominal_label
    save_parameters(
        paths.true_params,
        true_params.vector,
        model=model,
        header_comment=f'hexacal demo: the simulated true machine ({truth_text}), SI units',
    )
    save_parameters(
        paths.nominal,
        nominal.vector,
        model=model,
        header_comment=(
            f'hexacal demo: nominal set 2 ({nominal_text}, seed {args.seed}), SI units'
        ),
    )
    timings = {}  # summary.json's timings: seconds of each stage (docs/formats.md)
    stage_started = time.monotonic()
    _plans(args, nominal, paths)
    timings['plan'] = time.monotonic() - stage_started
    print(f'hexacal demo: planned in {timings["plan"]:.0f} s', flush=True)
    domain_id = claim_domain_id()
    env = {'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    # The simulated machine's calibrations are kept in the work directory, not the user's store.
    env['HEXACAL_STORE'] = str(paths.work / 'store')
    os.environ.update(env)  # the in-process node below joins the same domain
    os.environ.pop('ROS_STATIC_PEERS', None)
    print(f'hexacal demo: work directory {paths.work}, ROS domain {domain_id}', flush=True)

    group = NodeGroup()
    session = None
    verification = None
    stored_verification = None
    driver_values: dict[str, str] = {}
    verification_postures = 0
    try:
        group.start(
            NodeLaunch(
                'collector',
                {
                    'output_dir': str(paths.bag.parent),
                    'bag_name': paths.bag.name,
                    'parameters_file': str(paths.nominal),
                    **COLLECTOR_WINDOWS,
                },
            ),
            env,
            paths.logs / 'collector.log',
        )
        group.start(
            NodeLaunch(
                'identify',
                {
                    'nominal': str(paths.nominal),
                    'output_dir': str(paths.work),
                    'output': paths.calibration.name,
                    'report_dir': str(paths.report),
                    'noise_slider_m': args.noise_um * 1e-6,
                    'noise_angle_rad': args.noise_um * 1e-6,
                },
            ),
            env,
            paths.logs / 'identify.log',
        )
        session = _RosSession()
        session.nominal_file = paths.nominal
        session.wait(
            'the collector and identify nodes to come up',
            GRAPH_TIMEOUT_S,
            group,
            session.graph_ready,
        )
        group.start(
            NodeLaunch(
                'driver',
                {
                    'true_params': str(paths.true_params),
                    'command_topic': DEFAULT_COMMAND_TOPIC,
                    'max_actuator_speed_m_s': DRIVER_SPEED_M_S,
                    'rate_hz': float(args.rate_hz),
                    'seed': args.seed,
                    'slider_noise_m': args.noise_um * 1e-6,
                    'angle_noise_rad': args.noise_um * 1e-6,
                    'sensor_effects': getattr(args, 'sensor_effects', ''),
                    'measuring_mode': _mode(args),
                    **actuator_limits(arch, SLIDER_DRIVE_LIMITS),
                    **_physics_params(args),
                    **dict(getattr(args, 'driver_param', []) or []),
                },
            ),
            env,
            paths.logs / 'driver.log',
        )
        machine = '' if model == DEFAULT_MODEL else f' of a {model}'  # the default goes unnamed
        print(
            f'hexacal demo: the executor walks an O1 plan of {args.postures} postures '
            f'({args.plan}, {_mode(args)}) on the simulated machine{machine} through its '
            f'trajectory-controller interface, +-{args.noise_um:g} '
            f'{MODELS[model].actuator_quantities.small} / +-{args.noise_um:g} urad noise, '
            f'{args.rate_hz:g} Hz'
            + (
                f', sensor effects {args.sensor_effects}'
                if getattr(args, 'sensor_effects', '')
                else ''
            ),
            flush=True,
        )
        stage_started = time.monotonic()
        walked = _walk(
            session,
            group,
            args,
            paths.plan,
            paths.nominal,
            'calibration',
            env,
            paths.logs / 'executor.log',
            refine=_refine(args),
        )
        session.wait(
            f'identify to hold the {walked} postures',
            30.0,
            group,
            lambda: session.identify_postures >= walked,
        )
        calibration_postures = walked
        calibrate_started = time.monotonic()
        timings['walk'] = calibrate_started - stage_started
        session.parameters = None  # an intermediate calibration's (refinement) are not these
        success, message = session.calibrate(group)
        if not success:
            raise DemoError(f'hexacal/calibrate refused: {message}')
        calibrated = session.wait(
            'the published parameters', 30.0, group, lambda: session.parameters
        )
        calibrate_s = time.monotonic() - calibrate_started
        timings['calibration'] = calibrate_s
        stage_started = time.monotonic()
        print(f'hexacal demo: calibrated in {calibrate_s:.1f} s: {message}', flush=True)
        held = session.identify_postures
        if held > walked:
            # The collector records every rest it detects: the one before the first move too.
            print(
                f'hexacal demo: {held} postures = the {walked} planned + {held - walked} '
                'where the machine rested before the executor moved it (the collector records '
                'every rest, measured like the others)',
                flush=True,
            )
        if args.verify_postures:
            print(
                'hexacal demo: the executor walks a verification plan of '
                f'{args.verify_postures} fresh postures',
                flush=True,
            )
            # Never refined: an intermediate calibration would fold these postures into the
            # fit. With refinement the calibration's targets, else the nominal ones (as before).
            walked = _walk(
                session,
                group,
                args,
                paths.verification_plan,
                paths.calibration if _refine(args) else paths.nominal,
                'verification',
                env,
                paths.logs / 'executor_verification.log',
                refine=False,
            )
            verification_postures = walked
            session.wait(
                'identify to hold the verification postures',
                30.0,
                group,
                lambda: session.verification_postures >= walked,
            )
            verification = session.verify(group)
            stored_verification = _stored_verification(verification, model)
        timings['verification'] = time.monotonic() - stage_started
        driver_values = session.fresh_driver_values(group)  # its peaks over both plans
    except DemoError as error:
        print(f'hexacal demo: error: {error}', file=sys.stderr, flush=True)
        for node in group.nodes:
            print(_log_tail(node), file=sys.stderr)
        return EXIT_FAILED
    finally:
        if session is not None:
            session.close()
        codes = group.stop(order=('executor', 'driver', 'collector', 'identify'))
    unclean = {name: code for name, code in codes.items() if code != 0}
    if unclean:
        print(
            f'hexacal demo: warning: nodes exited with {unclean} (logs in {paths.logs})',
            file=sys.stderr,
        )
    stage_started = time.monotonic()
    calibrated_params = true_params.with_vector(calibrated)
    poses = pose_summaries(true_params, nominal, calibrated_params, args)
    summary = build_summary(
        model=model,
        measuring_mode=_mode(args),
        postures=calibration_postures,
        driver_values=driver_values,
        pose_errors=poses['after (calibrated)'],
        verification=stored_verification,
        physics=_physics(args),
        fit=session.fit_values,
        refinement=refinement_summary(
            session.rest_log,
            _mode(args),
            refine=_refine(args),
            targets_models=session.targets_models,
            calibration_postures=calibration_postures,
            verification_postures=verification_postures,
        ),
    )
    text = report(
        true_params,
        nominal,
        calibrated_params,
        args,
        paths,
        time.monotonic() - started,
        verification,
        poses=poses,
        summary=summary,
    )
    timings['report'] = time.monotonic() - stage_started
    timings['total'] = time.monotonic() - started
    summary['timings'] = {
        stage: timings.get(stage, 0.0)
        for stage in ('plan', 'walk', 'calibration', 'verification', 'report', 'total')
    }
    write_summary(paths.summary, summary)
    print(text)
    if not (paths.bag / 'metadata.yaml').exists():
        print(
            f'hexacal demo: error: the bag {paths.bag} was not closed (no metadata.yaml)',
            file=sys.stderr,
        )
        return EXIT_FAILED
    return EXIT_OK


def _stored_verification(values: dict[str, str], model: str) -> dict | None:
    """
    Return the verification identify attached to its calibration in the store.

    The object of ``hexacal verify --json`` (VerificationResult.to_json, the one owner of its
    keys) with identify's provenance keys; None (with a warning) when it is not there.
    """
    from ..store import CalibrationStore, default_store_dir, StoreError

    entry_id = values.get('calibration_id')
    if not entry_id:
        print('hexacal demo: warning: the verification is not in the calibration store: '
              f'{values.get("store_error", "no calibration_id")}', file=sys.stderr)
        return None
    root = values.get('calibration_store') or default_store_dir(model)
    try:
        figures = CalibrationStore(root).get(entry_id).record.get('verification')
    except (StoreError, OSError) as error:
        print(f'hexacal demo: warning: calibration store {root}: {error}', file=sys.stderr)
        return None
    return dict(figures) if figures else None


def _walk(
    session: '_RosSession',
    group: NodeGroup,
    args,
    plan: Path,
    nominal: Path,
    label: str,
    env: dict,
    log: Path,
    *,
    refine: bool = True,
) -> int:
    """
    Start an executor on ``plan``, show its progress, wait until done; return the postures.

    ``refine``: the executor's refine_targets (intermediate calibrations at rest).
    """
    from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC
    from tqdm import tqdm

    from ..core.architectures import architecture
    from ..core.planning.planner import Plan
    from ..bringup.launch_spec import NodeLaunch

    total = len(Plan.load(plan))
    session.executor_values = {}
    session.walk_label = label
    session.walk_nominal = nominal
    executor = group.start(
        NodeLaunch(
            'executor',
            {
                'plan': str(plan),
                'nominal': str(nominal),
                'command_topic': DEFAULT_COMMAND_TOPIC,
                'max_actuator_speed_m_s': EXECUTOR_SPEED_M_S,
                'settle_s': float(args.settle_s),
                'timeout_s': 30.0 + float(args.dwell_s),
                'refine_targets': bool(refine),
                **actuator_limits(architecture(_model(args)), SLIDER_EXECUTOR_LIMITS),
                # Until the executor takes the mode the plan carries it (the executor reads it).
                **({'measuring_mode': _mode(args)} if executor_takes_measuring_mode() else {}),
            },
        ),
        env,
        log,
    )
    interactive = sys.stderr.isatty()
    bar = tqdm(
        total=total,
        desc=f'{label} postures',
        unit='posture',
        file=sys.stderr,
        disable=not interactive,
    )
    shown = 0

    def progress():
        nonlocal shown
        values = session.executor_values
        count = min(
            int(values.get('measured', 0) or 0) + int(values.get('skipped', 0) or 0), total
        )
        if count > shown:
            bar.update(count - shown)
            if not interactive and (count % 10 == 0 or count == total):
                print(f'{label} postures: {count}/{total}', flush=True)
            shown = count
        state = values.get('state')
        if state in ('refused', 'aborted'):
            raise DemoError(f'the executor {state} the {label} plan: {values}')
        if state == 'paused':
            # Paused by itself (its guard, a refused release, the drive's fault it heard first):
            # nobody here would resume it.
            what = f'the executor to walk the {label} plan'
            session.check_drives(what)
            notice = values.get('notice') or str(values)
            if notice.startswith(DRIVE_FAULT_NOTICE):
                mode = session.driver_values.get('measuring_mode') or _mode(args)
                raise DemoError(
                    f'the simulated drives faulted ({mode}) while waiting for {what}: '
                    f'{notice[len(DRIVE_FAULT_NOTICE):]}'
                )
            raise DemoError(f'the executor paused the {label} plan: {notice}')
        return values if state == 'done' else None

    try:
        # The executor may take its own timeout_s per posture before it skips one: wait as long.
        per_posture_s = 30.0 + float(args.dwell_s)
        done = session.wait(
            f'the executor to walk the {label} plan', 60.0 + per_posture_s * total, group, progress
        )
    finally:
        bar.close()
    _stop(group, executor)  # the next plan gets an executor of its own
    skipped = int(done.get('skipped', 0) or 0)
    if skipped:
        print(f'hexacal demo: {skipped} {label} posture(s) skipped: see {log}', flush=True)
    return int(done.get('measured', 0) or 0)


def _stop(group: NodeGroup, node: RunningNode) -> None:
    code = group.stop_node(node, 10.0)
    if code != 0:
        print(f'hexacal demo: warning: {node.name} exited with {code}', file=sys.stderr)


def _log_tail(node: RunningNode, lines: int = 15) -> str:
    if node.log_file is None:
        return ''
    path = Path(node.log_file.name)
    node.log_file.flush()
    text = path.read_text(errors='replace').splitlines()[-lines:]
    return f'--- {node.name} ({path}) ---\n' + '\n'.join(text)


def _follow_postures(
    session: '_RosSession', group: NodeGroup, total: int, timeout_s: float
) -> None:
    from tqdm import tqdm

    interactive = sys.stderr.isatty()
    bar = tqdm(
        total=total,
        desc='postures collected',
        unit='posture',
        file=sys.stderr,
        disable=not interactive,
    )
    shown = 0
    try:

        def progress() -> bool:
            nonlocal shown
            count = min(session.postures, total)
            if count > shown:
                bar.update(count - shown)
                if not interactive and (count % 10 == 0 or count == total):
                    print(f'postures collected: {count}/{total}', flush=True)
                shown = count
            return session.postures >= total

        session.wait(f'{total} postures', timeout_s, group, progress)
    finally:
        bar.close()


class _RosSession:
    """An in-process node that watches postures, calls the service and receives the result."""

    def __init__(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from hexacal_msgs_py.names import (
            CALIBRATE_SERVICE,
            CALIBRATION_STATUS_TOPIC,
            PARAMETERS_TOPIC,
            POSTURE_TOPIC,
            VERIFY_SERVICE,
        )
        from hexacal_msgs_py.qos import PARAMETERS_QOS, POSTURE_QOS, STATUS_MONITOR_QOS
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        from std_srvs.srv import Trigger

        self.context = Context()
        # Python keeps SIGINT: Ctrl-C raises KeyboardInterrupt and the children are stopped.
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('hexacal_demo', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.postures = 0  # seen here
        self.identify_postures = 0  # received by identify, from its status
        self.verification_postures = (
            0  # received by identify since the calibration, from its status
        )
        self.executor_values: dict[str, str] = {}  # the executor's latest status
        self.verification_values: dict[str, str] = {}  # identify's latest verification status
        self.fit_values: dict[str, str] = {}  # identify's latest status with a fit's adequacy
        self.driver_values: dict[str, str] = {}  # the simulated drives' latest status
        self.driver_statuses = 0  # driver statuses received (a fresh one: the count grows)
        self.parameters: np.ndarray | None = None
        # The drives' rests, tagged with the model the targets came from (demo_refinement.py).
        self.rest_log = RestLog()
        self.walk_label = ''  # the plan walked: calibration, verification
        self.walk_nominal: Path | None = None  # the executor's nominal file for that plan
        self.nominal_file: Path | None = None  # the demo's nominal model (set by _run)
        self.targets_models: list[str] = []  # the calibration walk's targets_model values
        self._trigger = Trigger
        self.node.create_subscription(JointState, POSTURE_TOPIC, self._on_posture, POSTURE_QOS)
        self.node.create_subscription(
            Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters, PARAMETERS_QOS
        )
        self.node.create_subscription(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, self._on_status, STATUS_MONITOR_QOS
        )
        self.client = self.node.create_client(Trigger, CALIBRATE_SERVICE)
        self.verify_client = self.node.create_client(Trigger, VERIFY_SERVICE)
        self.posture_topic = self.node.resolve_topic_name(POSTURE_TOPIC)

    def _on_posture(self, message) -> None:
        self.postures += 1

    def _on_status(self, message) -> None:
        from hexacal_msgs_py.conversions import status_values
        from hexacal_msgs_py.names import (
            DRIVER_STATUS_NAME,
            EXECUTOR_STATUS_NAME,
            VERIFICATION_STATUS_NAME,
        )

        for status in message.status:
            values = status_values(status)
            if status.name == EXECUTOR_STATUS_NAME:
                self.executor_values = values
                model = values.get('targets_model', '')
                if self.walk_label == 'calibration' and model and (
                    not self.targets_models or self.targets_models[-1] != model
                ):
                    self.targets_models.append(model)
            elif status.name == DRIVER_STATUS_NAME:
                self.driver_values = values
                self.driver_statuses += 1
                self.rest_log.hear(values, self.targets_refined())
            elif status.name == VERIFICATION_STATUS_NAME:
                self.verification_values = values
            elif values.get('outcome') == 'collecting':
                self.identify_postures = int(values.get('postures_received', 0))
                self.verification_postures = int(values.get('verification_postures', 0) or 0)
            if status.name != VERIFICATION_STATUS_NAME and 'adequacy.verdict' in values:
                self.fit_values = values

    def _on_parameters(self, message) -> None:
        from hexacal_msgs_py.conversions import multiarray_to_parameters

        self.parameters = multiarray_to_parameters(message)

    def targets_refined(self) -> bool:
        """Return whether the executor's targets now come from a calibration, not nominal."""
        if self.walk_nominal is not None and self.walk_nominal != self.nominal_file:
            return True  # the verification plan on the calibration's targets
        return refined_at(self.executor_values.get('targets_model', '')) is not None

    def graph_ready(self) -> bool:
        # The collector publishes postures and identify receives them (as this node does).
        return (
            self.node.count_publishers(self.posture_topic) >= 1
            and self.node.count_subscribers(self.posture_topic) >= 2
            and self.client.service_is_ready()
        )

    def wait(self, what: str, timeout_s: float, group: NodeGroup, condition: Callable[[], object]):
        deadline = time.monotonic() + timeout_s
        while True:
            result = condition()
            if result is not None and result is not False:
                return result
            self.check_drives(what)
            exited = group.exited()
            if exited:
                node = exited[0]
                raise DemoError(
                    f'{node.name} exited with {node.popen.returncode} while waiting '
                    f'for {what}\n{_log_tail(node)}'
                )
            if time.monotonic() > deadline:
                raise DemoError(f'timed out after {timeout_s:.0f} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.1)

    def check_drives(self, what: str) -> None:
        """Raise DemoError when the simulated drives are in fault: they hold, nothing moves."""
        values = self.driver_values
        if values.get('state') != 'fault':
            return
        mode = values.get('measuring_mode', '?')
        hint = ''
        if mode != 'compliant' and not executor_takes_measuring_mode():
            hint = (
                f'; the executor of this install commands all six actuators and does not drive '
                f'{mode} yet: try --measuring-mode compliant'
            )
        raise DemoError(
            f'the simulated drives faulted ({mode}) while waiting for {what}: '
            f'{values.get("fault") or "no reason given"}{hint}'
        )

    def fresh_driver_values(self, group: NodeGroup) -> dict[str, str]:
        """Return the driver's status values from a status received from now on (at rest)."""
        seen = self.driver_statuses
        return self.wait(
            'a fresh status of the simulated drives',
            GRAPH_TIMEOUT_S,
            group,
            lambda: self.driver_values if self.driver_statuses > seen else None,
        )

    def calibrate(self, group: NodeGroup) -> tuple[bool, str]:
        future = self.client.call_async(self._trigger.Request())
        response = self.wait(
            'the hexacal/calibrate response',
            CALIBRATE_TIMEOUT_S,
            group,
            lambda: future.result() if future.done() else None,
        )
        return bool(response.success), str(response.message)

    def verify(self, group: NodeGroup) -> dict[str, str]:
        """Call hexacal/verify; the verification status once its report section is written."""
        self.verification_values = {}
        future = self.verify_client.call_async(self._trigger.Request())
        response = self.wait(
            'the hexacal/verify response',
            CALIBRATE_TIMEOUT_S,
            group,
            lambda: future.result() if future.done() else None,
        )

        def figures():
            values = self.verification_values
            if values.get('outcome') == 'verified':
                return values if values.get('report_state') != 'writing' else None
            if values.get('outcome'):  # a refusal (no calibration, no postures since)
                raise DemoError(f'hexacal/verify refused: {response.message}')
            return None

        return self.wait('the verification figures', 60.0, group, figures)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# --------------------------------------------------------------------------- the report


def parameter_error_rows(
    true_vector: np.ndarray, vector: np.ndarray, model: str = DEFAULT_MODEL
) -> dict[str, tuple[float, float]]:
    """
    Return per file key of the model (Hexa Slide: A0, B, l, a) the (max, mean) |error| in mm.

    The Hexa Slide's a: unit-vector components x 1000.
    """
    import numpy as np

    layout = MODELS[model]
    groups = layout.key_slices
    errors = np.abs(np.asarray(vector) - np.asarray(true_vector)).reshape(
        layout.n_chains, layout.fields_per_chain
    ) * 1e3
    return {
        name: (float(errors[:, columns].max()), float(errors[:, columns].mean()))
        for name, columns in groups.items()
    }


def verification_table(values: dict[str, str]) -> list[str]:
    """Return the verification figures (identify's status values) as a table, um / urad."""

    def number(key: str) -> float:
        try:
            return float(values.get(key, 'nan'))
        except ValueError:
            return float('nan')

    lines = [
        '',
        f'Verification on {values.get("postures", "?")} fresh postures: what the device measured '
        '(eq. 4, rotary) vs forward kinematics at the measured actuators - no ground truth',
        f'{"":<20}{"position rms":>14}{"position max":>14}{"rotary rms":>12}',
        f'{"":<20}{"(um)":>14}{"(um)":>14}{"(urad)":>12}',
    ]
    for label, name in (('nominal', 'nominal'), ('calibrated', 'calibrated')):
        lines.append(
            f'{label:<20}{number(name + ".position_rms_m") * 1e6:>14.1f}'
            f'{number(name + ".position_max_m") * 1e6:>14.1f}'
            f'{number(name + ".rotary_rms_rad") * 1e6:>12.1f}'
        )
    lines.append(
        f'improvement {number("improvement"):.0f}x, threshold {number("threshold_m") * 1e6:.1f} '
        f'um: {values.get("verdict", "?")}'
    )
    return lines


def report(
    true_params,
    nominal,
    calibrated,
    args,
    paths: DemoPaths,
    wall_s: float,
    verification: dict[str, str] | None = None,
    *,
    poses: dict[str, dict] | None = None,
    summary: dict | None = None,
) -> str:
    from ..bag import open_bag

    model = true_params.model
    arch, layout = true_params.architecture, true_params.layout
    groups = layout.key_slices
    before = parameter_error_rows(true_params.vector, nominal.vector, model)
    after = parameter_error_rows(true_params.vector, calibrated.vector, model)
    title = (
        f'Parameter errors vs the simulated truth ({arch.machine_label}), |error| in mm'
        f'{arch.error_table_note}'
    )
    lines = [
        '',
        title,
        f'{"group":<6}{"count":>6}{"before max":>13}{"before mean":>13}'
        f'{"after max":>12}{"after mean":>12}',
    ]
    for name, columns in groups.items():
        count = layout.n_chains * (columns.stop - columns.start)
        lines.append(
            f'{name:<6}{count:>6}{before[name][0]:>13.3f}{before[name][1]:>13.3f}'
            f'{after[name][0]:>12.4f}{after[name][1]:>12.4f}'
        )
    if poses is None:
        poses = pose_summaries(true_params, nominal, calibrated, args)
    lines += [
        '',
        f'Pose errors over {args.validation_postures} validation postures',
        f'{"":<20}{"position mean":>15}{"position max":>14}{"orientation mean":>18}'
        f'{"orientation max":>17}',
        f'{"":<20}{"(um)":>15}{"(um)":>14}{"(deg)":>18}{"(deg)":>17}',
    ]
    for label, errors in poses.items():
        lines.append(
            f'{label:<20}{errors["position_mean_m"] * 1e6:>15.1f}'
            f'{errors["position_max_m"] * 1e6:>14.1f}'
            f'{math.degrees(errors["orientation_mean_rad"]):>18.5f}'
            f'{math.degrees(errors["orientation_max_rad"]):>17.5f}'
            + (
                f'  ({errors["failed_postures"]} FK failures)'
                if errors['failed_postures']
                else ''
            )
        )
    bag_text = str(paths.bag)
    try:
        info = open_bag(paths.bag).info()
        postures = sum(t.count for name, t in info.topics.items() if name.endswith('/posture'))
        bag_text += f'  ({info.message_count} messages, {postures} postures)'
    except Exception as error:  # noqa: BLE001 - the report still prints, with the path
        bag_text += f'  (unreadable: {error})'
    if verification:
        lines += verification_table(verification)
    if summary is not None:
        units = MODELS[summary['model']].actuator_quantities
        lines += summary_lines(summary) + refinement_lines(summary.get('refinement'), units)
    page = _report_page(paths, verification)
    lines += [
        '',
        f'bag:        {bag_text}',
        f'report:     {page}',
        f'calibrated: {paths.calibration}',
        f'summary:    {paths.summary}',
        f'nominal:    {paths.nominal}',
        f'truth:      {paths.true_params}',
        f'logs:       {paths.logs}',
        f'wall time:  {wall_s:.0f} s',
    ]
    return '\n'.join(lines)


def pose_summaries(true_params, nominal, calibrated, args) -> dict[str, dict]:
    """Return the pose errors (PoseErrors.summary) of nominal and calibrated vs the truth."""
    from ..core.fit.validation import pose_errors, validation_poses

    poses = validation_poses(
        true_params,
        args.validation_postures,
        args.seed,
        true_params.architecture.default_workspace(),
    )
    return {
        label: pose_errors(true_params, model, poses).summary()
        for label, model in (('before (nominal)', nominal), ('after (calibrated)', calibrated))
    }


def _report_page(paths: DemoPaths, verification: dict[str, str] | None) -> str:
    """Return the HTML report identify wrote (the verification's page when it has one)."""
    if verification and verification.get('report'):
        return verification['report']
    pages = sorted(paths.report.rglob('index.html')) if paths.report.exists() else []
    return str(pages[0]) if pages else f'{paths.report} (not written)'
