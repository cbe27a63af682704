"""
The run of ``hexacal demo``: files, plans, the system's nodes, two walks, calibrate, verify.

``run_demo`` writes the simulated truth and the nominal model, plans both walks, claims a ROS
domain of its own, and starts the nodes as child processes through bringup: their launches
are those of ``bringup.system.launches`` (the ``bringup`` executable's and the launch file's),
started and stopped by its supervisor (NodeGroup). The demo's own rclpy node (demo_session)
watches them, walks each plan with an executor and calls the services; at the end the report
(demo_report) and summary.json (demo_summary) are written.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from datetime import datetime
import os
from pathlib import Path
import sys
import time
from typing import TYPE_CHECKING

from hexacal_msgs_py.measuring_modes import (
    COMPLIANT_SERVO_STIFFNESS_N_PER_M,
    GUARD_FORCE_FRACTION,
    LINK_FORCE_LIMIT_N,
)
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS

from .demo import (
    actuator_speed,
    DemoError,
    executor_physical,
    EXECUTOR_SPEED_M_S,
    EXIT_FAILED,
    EXIT_OK,
    measuring_mode,
    model_name,
    physics,
    physics_parameters,
    refines,
)
from .demo_refinement import refinement_summary
from .demo_report import pose_summaries, report, stored_verification
from .demo_session import DemoSession, GRAPH_TIMEOUT_S, log_tail, walk
from .demo_summary import build_summary, SUMMARY_FILE, write_summary

if TYPE_CHECKING:
    from ..bringup.launch_spec import NodeLaunch

# Executor and commanded driver: moves at up to --actuator-speed (0.5 m/s) on a machine that
# follows at twice it; the collector's detector window 0.2 s + capture 0.3 s (the executor waits
# for each posture).
DRIVER_SPEED_FACTOR = 2.0  # the simulated drive's speed limit over the executor's
DRIVER_SPEED_M_S = DRIVER_SPEED_FACTOR * EXECUTOR_SPEED_M_S  # at the default --actuator-speed
COLLECTOR_WINDOWS = {'window_s': 0.2, 'capture_s': 0.3}
PLAN_CANDIDATES = 1000
# The supervisor stops the machine first, so that the collector records to the end.
STOP_ORDER = ('executor', 'driver', 'collector', 'identify')

# The drives' and the executor's limits sized for sliders (the nodes' defaults: m, N/m, N).
SLIDER_DRIVE_LIMITS = {
    'max_following_error_m': (5e-4, 'length'),
    'servo_stiffness_n_per_m': (COMPLIANT_SERVO_STIFFNESS_N_PER_M, 'stiffness'),
    'max_force_n': (LINK_FORCE_LIMIT_N, 'force'),
}
SLIDER_EXECUTOR_LIMITS = {
    'position_tolerance_m': (5e-3, 'length'),
    'still_tolerance_m': (1e-4, 'length'),
    'released_margin_m': (1e-3, 'length'),
    'servo_stiffness_n_per_m': (COMPLIANT_SERVO_STIFFNESS_N_PER_M, 'stiffness'),
    'max_force_n': (GUARD_FORCE_FRACTION * LINK_FORCE_LIMIT_N, 'force'),
}


def actuator_limits(arch, limits: dict[str, tuple[float, str]]) -> dict[str, float]:
    """
    Return the node parameters of `limits` in the actuators' unit of `arch` (none for sliders).

    The nodes' defaults are sized for sliders (m, N/m, N); an architecture whose actuators
    turn gets them through its lever (Architecture.actuator_limit: rad, N m/rad, N m), so the
    compliant servos, the following-error guard and the executor's tolerances mean the same
    travel at the actuator's joint. The measuring link's force limits (``max_link_force_n``)
    are on the link, in N for every architecture, and are not among them.
    """
    if arch.actuator_lever_m == 1.0:
        return {}
    return {
        name: arch.actuator_limit(value, dimension)
        for name, (value, dimension) in limits.items()
    }


def claim_domain_id() -> int:
    """Return a ROS domain id no test session or other demo uses (held until exit)."""
    from ..ros_domain import claim_domain_id as claim, NoFreeDomainError

    try:  # from pid * 7: away from the test sessions, which start at their pid
        return claim('HEXACAL_DEMO_DOMAIN_ID', start=os.getpid() * 7)
    except NoFreeDomainError as error:
        raise DemoError(str(error)) from None


@dataclass
class DemoPaths:
    """Where the demo writes: its work directory and each file in it."""

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


def demo_paths(args: argparse.Namespace) -> DemoPaths:
    """Return the demo's paths: --out (default out/demo_<timestamp>), --bag-dir."""
    stamp = datetime.now().strftime('%Y%m%d_%H%M%S')
    work = (args.out or Path('out') / f'demo_{stamp}').resolve()
    from ..core.architectures import architecture

    truth = architecture(model_name(args)).truth_file_name
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


def write_plans(args: argparse.Namespace, nominal, paths: DemoPaths) -> None:
    """Write the calibration plan (O1) and the verification plan (fresh postures, another draw)."""
    from ..core.machine.measurements import NoiseModel

    noise = NoiseModel.from_microns(args.noise_um) if args.noise_um > 0 else None
    mixed = args.plan == 'mixed'
    link_load = _link_load(args)
    planning = _plan(
        'calibration plan', args, nominal, args.postures,
        cost='sphere-fixed' if mixed else 'absolute',
        fixed_fraction=0.25 if mixed else None,
        seed=args.seed,
        noise=noise,
        name='demo-calibration',
        link_load=link_load,
    )
    planning.plan.save(paths.plan)
    measuring = planning.measuring
    if measuring is not None and measuring.link_forces is not None:
        over = measuring.overloaded
        moves = measuring.link_move_forces
        print(
            'hexacal demo: the measuring link at the calibration postures, predicted from the '
            f'physical description: up to {max(measuring.link_forces):.0f} N'
            + ('' if moves is None else f', {max(moves):.0f} N along the moves')
            + (
                f', beyond the {measuring.link_force_limit_n:g} N a link of the documented kind '
                f'bears on the way to {len(over)} of {len(measuring.link_forces)}: the lvdt mode '
                'keeps it unloaded'
                if over.size
                else ''
            ),
            flush=True,
        )
    if args.verify_postures:
        _plan(
            'verification plan', args, nominal, args.verify_postures,
            cost='absolute',
            seed=args.seed + 1000,
            noise=noise,
            name='demo-verification',
            link_load=link_load,
        ).plan.save(paths.verification_plan)


def _plan(what: str, args: argparse.Namespace, nominal, postures: int, **options):
    """Return plan_postures of the demo's measuring mode, its stages and steps shown as it goes."""
    from ..core.planning.planner import plan_postures, progress_steps
    from .command_line import Progress

    mode = measuring_mode(args)
    progress = Progress(total=progress_steps(postures, measuring_mode=mode), prefix='hexacal demo')
    try:
        return plan_postures(
            nominal, postures, index='O1', n_candidates=PLAN_CANDIDATES, measuring_mode=mode,
            progress=progress.step, stage=lambda stage: progress.stage(f'{what}: {stage}'),
            **options,
        )
    finally:
        progress.close()


def _link_load(args: argparse.Namespace):
    """Return the MuJoCo machine's weights and the link's limit (passive_actuator), else None."""
    if physics(args) != 'mujoco' or measuring_mode(args) != 'passive_actuator':
        return None
    from hexacal_msgs_py.physical_file import default_physical, read_physical_file

    from ..core.fit.statics import MassModel
    from ..core.modes.link_load import LinkLoad

    physical = getattr(args, 'physical', None)
    description = (
        read_physical_file(physical) if physical else default_physical(model_name(args))
    )
    return LinkLoad(MassModel.from_physical(description))


def deflection_summary(args: argparse.Namespace, paths: DemoPaths, nominal):
    """
    Return the deflection check of the demo's rigid fit on the MuJoCo machine (None: kinematic).

    The bag's postures calibrated offline as ``hexacal calibrate`` does, then checked against
    the machine's physical description (``--physical``, else the shipped one): what its
    compliances bias, beside the pose error against the true geometry the demo measures.
    """
    if physics(args) != 'mujoco':
        return None
    from ..calibration_steps.bag_postures import postures_from_bag
    from ..calibration_steps.calibration_run import calibrate, deflection_check

    from ..core.errors import CalibrationError
    from ..core.fit.identification import CONVERGED

    try:
        bag = postures_from_bag(paths.bag)
        result = calibrate(nominal, bag.postures)
        if result.reason != CONVERGED:
            raise CalibrationError(f'the offline fit did not converge ({result.reason})')
        return deflection_check(result, str(getattr(args, 'physical', None) or ''),
                                bag.measuring_mode, bag.released_joints)
    except (CalibrationError, ValueError) as error:
        print(f'hexacal demo: no deflection check: {error}', file=sys.stderr, flush=True)
        return None


def system_launches(
    args: argparse.Namespace, paths: DemoPaths, plan: Path, nominal: Path, *, refine: bool
) -> dict[str, NodeLaunch]:
    """
    Return executable -> NodeLaunch of the demo's system, as bringup starts it.

    collector, identify, the executor walking ``plan`` on the targets of ``nominal`` and the
    simulated driver in commanded mode, through bringup.system.launches: the demo gives only
    its own settings (the work directory's files, speeds, noise, --driver-param).
    """
    from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC

    from ..bringup.system import launches
    from ..core.architectures import architecture

    noise = args.noise_um * 1e-6
    arch = architecture(model_name(args))
    nodes = launches(
        nominal=str(paths.nominal),
        output_dir=str(paths.work),
        bag_dir=str(paths.bag.parent),
        bag_name=paths.bag.name,
        executor_plan=str(plan),
        command_topic=DEFAULT_COMMAND_TOPIC,
        measuring_mode=measuring_mode(args),
        collector={'parameters_file': str(paths.nominal), **COLLECTOR_WINDOWS},
        identify={
            'output': paths.calibration.name,
            'report_dir': str(paths.report),
            'noise_slider_m': noise,
            'noise_angle_rad': noise,
        },
        executor={
            'nominal': str(nominal),
            'max_actuator_speed_m_s': actuator_speed(args),
            'settle_s': float(args.settle_s),
            'timeout_s': 30.0 + float(args.dwell_s),
            'refine_targets': bool(refine),
            **actuator_limits(arch, SLIDER_EXECUTOR_LIMITS),
            **executor_physical(args),
        },
        driver={
            'true_params': str(paths.true_params),
            'max_actuator_speed_m_s': DRIVER_SPEED_FACTOR * actuator_speed(args),
            'rate_hz': float(args.rate_hz),
            'seed': args.seed,
            'slider_noise_m': noise,
            'angle_noise_rad': noise,
            'sensor_effects': getattr(args, 'sensor_effects', ''),
            **actuator_limits(arch, SLIDER_DRIVE_LIMITS),
            **physics_parameters(args),
            **dict(getattr(args, 'driver_param', []) or []),
        },
    )
    return {node.executable: node for node in nodes}


def write_machines(args: argparse.Namespace, paths: DemoPaths) -> tuple:
    """Write the simulated truth and nominal set 2 as parameters YAML; return both machines."""
    from hexacal_msgs_py.parameters_file import save_parameters

    from ..core.architectures import architecture
    from ..core.machine.model import nominal_set

    model = model_name(args)
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
    return true_params, nominal


def run_demo(args: argparse.Namespace) -> int:
    """Run the demo end to end; return its exit code (the report printed, summary.json written)."""
    started = time.monotonic()
    paths = demo_paths(args)
    # Planning takes the first minutes (every release rehearsed on several machines): say so at
    # once, before the imports, so that the demo is never silent.
    verify_text = (
        f' and a verification plan of {args.verify_postures}' if args.verify_postures else ''
    )
    print(
        f'hexacal demo: planning {args.postures} calibration postures{verify_text} '
        f'({model_name(args)}, {measuring_mode(args)}; O1 over {PLAN_CANDIDATES} candidates, '
        'every move rehearsed on machines unlike the nominal); then the nodes start',
        flush=True,
    )
    model = model_name(args)
    true_params, nominal = write_machines(args, paths)
    timings = {}  # summary.json's timings: seconds of each stage (docs/formats.md)
    stage_started = time.monotonic()
    write_plans(args, nominal, paths)
    timings['plan'] = time.monotonic() - stage_started
    print(f'hexacal demo: planned in {timings["plan"]:.0f} s', flush=True)
    domain_id = claim_domain_id()
    env = {'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    # The simulated machine's calibrations are kept in the work directory, not the user's store.
    env['HEXACAL_STORE'] = str(paths.work / 'store')
    os.environ.update(env)  # the demo's own node (demo_session) joins the same domain
    os.environ.pop('ROS_STATIC_PEERS', None)
    print(f'hexacal demo: work directory {paths.work}, ROS domain {domain_id}', flush=True)

    from ..bringup.supervisor import NodeGroup

    nodes = system_launches(args, paths, paths.plan, paths.nominal, refine=refines(args))
    group = NodeGroup()
    session = None
    verification = None
    kept_verification = None
    driver_values: dict[str, str] = {}
    verification_postures = 0
    try:
        group.start(nodes['collector'], env, paths.logs / 'collector.log')
        group.start(nodes['identify'], env, paths.logs / 'identify.log')
        session = DemoSession()
        session.nominal_file = paths.nominal
        session.wait(
            'the collector and identify nodes to come up',
            GRAPH_TIMEOUT_S,
            group,
            session.graph_ready,
        )
        group.start(nodes['driver'], env, paths.logs / 'driver.log')
        machine = '' if model == DEFAULT_MODEL else f' of a {model}'  # the default goes unnamed
        print(
            f'hexacal demo: the executor walks an O1 plan of {args.postures} postures '
            f'({args.plan}, {measuring_mode(args)}) on the simulated machine{machine} through its '
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
        walked = walk(
            session,
            group,
            nodes['executor'],
            'calibration',
            env,
            paths.logs / 'executor.log',
            measuring_mode(args),
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
            # fit. With refinement the calibration's targets, else the nominal ones.
            verification_executor = system_launches(
                args,
                paths,
                paths.verification_plan,
                paths.calibration if refines(args) else paths.nominal,
                refine=False,
            )['executor']
            walked = walk(
                session,
                group,
                verification_executor,
                'verification',
                env,
                paths.logs / 'executor_verification.log',
                measuring_mode(args),
            )
            verification_postures = walked
            session.wait(
                'identify to hold the verification postures',
                30.0,
                group,
                lambda: session.verification_postures >= walked,
            )
            verification = session.verify(group)
            kept_verification = stored_verification(verification, model)
        timings['verification'] = time.monotonic() - stage_started
        driver_values = session.fresh_driver_values(group)  # its peaks over both plans
    except DemoError as error:
        print(f'hexacal demo: error: {error}', file=sys.stderr, flush=True)
        for node in group.nodes:
            print(log_tail(node), file=sys.stderr)
        return EXIT_FAILED
    finally:
        if session is not None:
            session.close()
        codes = group.stop(order=STOP_ORDER)
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
        measuring_mode=measuring_mode(args),
        postures=calibration_postures,
        driver_values=driver_values,
        pose_errors=poses['after (calibrated)'],
        verification=kept_verification,
        physics=physics(args),
        fit=session.fit_values,
        refinement=refinement_summary(
            session.rest_log,
            measuring_mode(args),
            refine=refines(args),
            targets_models=session.targets_models,
            calibration_postures=calibration_postures,
            verification_postures=verification_postures,
        ),
    )
    check = deflection_summary(args, paths, nominal)
    summary['deflection_check'] = None if check is None else check.to_json()
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
    if check is not None:
        text += '\n' + check.text()
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
