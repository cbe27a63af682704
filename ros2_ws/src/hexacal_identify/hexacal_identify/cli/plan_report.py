"""Run ``hexacal plan`` (choose measuring postures) and ``hexacal report`` (HTML of a result)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from hexacal_msgs_py.models import ActuatorQuantities, LINEAR_ACTUATOR

from .command_line import Progress

if TYPE_CHECKING:
    from ..core.planning.posture_limits import PostureLimits

# = hexacal_msgs_py.models.DEVICE_MOUNT_KEY (not imported: `hexacal --help` stays light)
MOUNT_PARAMETER = 'device.mount'

# The planner and the report are imported where they run: this module is imported by every
# `hexacal` start-up to register the commands.


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        'plan',
        help='choose K measuring postures that maximise an observability index; write a plan file',
        description='Draw feasible candidate postures (sphere and fixed-position, within the '
        'inclinometer range, actuator stroke, U/S-joint limits, away from singularities), score '
        'them with the identification Jacobian at the nominal parameters and choose K that '
        'maximise the observability index. The machine model (Hexa Slide, Gough-Stewart platform) '
        "is the nominal parameters file's; workspace limits not given default to that model's "
        "workspace. Writes the driver's plan-file format (YAML, SI units, the model under "
        'plan.model) atomically.',
        fill=_plan_arguments,
    )
    subparsers.add_parser(
        'report',
        help='write a self-contained HTML report (PNG figures) of a calibration result',
        description='Read a result JSON (from report.save_result, or the output of `hexacal '
        'calibrate --json` / `hexacal study --json`, which gives fewer figures) and write '
        'DIR/index.html with its figures.',
        fill=_report_arguments,
    )


def _plan_arguments(plan) -> None:
    from hexacal_msgs_py.measuring_modes import (
        DEFAULT_LVDT_STROKE_M,
        DEFAULT_MEASURING_MODE,
        LINK_FORCE_LIMIT_N,
        MEASURING_MODES,
    )

    from ..core.planning.observability import CRITERIA
    from ..core.planning.planner import METHODS
    from ..core.planning.posture_limits import PostureLimits
    from ..core.fit.residuals import COSTS
    from .study_device import device_names_argument, device_prior_argument

    plan.add_argument('--postures', type=int, required=True, help='number of postures K to choose')
    plan.add_argument(
        '--index',
        choices=CRITERIA,
        default='O1',
        help='O1 D-optimal (default), O2 inverse condition number, O3 smallest singular value, '
        'O4 noise amplification index, I least predicted position error over the workspace',
    )
    plan.add_argument(
        '--method',
        choices=METHODS,
        default='greedy',
        help='greedy (default), or exchange: greedy followed by Fedorov-style swaps',
    )
    plan.add_argument(
        '--candidates',
        type=int,
        default=2000,
        help='candidate postures to choose from (default 2000)',
    )
    plan.add_argument(
        '--cost',
        choices=COSTS,
        default='absolute',
        help='cost function to plan for (default absolute)',
    )
    plan.add_argument(
        '--nominal',
        type=Path,
        help='parameters YAML of the nominal machine, of any model (its '
        "'model' key; default: the Table 1 Hexa Slide)",
    )
    plan.add_argument('--seed', type=int, default=0, help='seed of the candidate draw (default 0)')
    plan.add_argument('--name', help='plan name (default: method-index-K-fingerprint)')
    plan.add_argument(
        '--noise-um',
        type=float,
        default=10.0,
        help='weight rows by the reading noise: +-X um actuators, +-X urad angles (default 10; '
        'only the actuator/angle ratio matters)',
    )
    plan.add_argument(
        '--unweighted',
        action='store_true',
        help='plan on the plain (unweighted) identification Jacobian',
    )
    plan.add_argument(
        '--fixed-fraction',
        type=float,
        help='share of fixed-position candidates (default: 0.25 for sphere-fixed/relative, 1 for '
        'fixed, else 0)',
    )
    # Workspace limits default (None) to the nominal model's workspace: the Hexa Slide's values in
    # brackets.
    defaults = PostureLimits()
    plan.add_argument(
        '--link-length',
        type=float,
        help=f'device link length L, m (default {defaults.link_length:g})',
    )
    plan.add_argument(
        '--xy-range-mm',
        type=float,
        help="|x|, |y| limit (default: the model's workspace; Hexa Slide "
        f'{defaults.xy_range_m * 1e3:g}, Gough-Stewart 250)',
    )
    plan.add_argument(
        '--rotation-range-deg',
        type=float,
        help=f"|theta|, |psi|, |phi| limit (default: the model's workspace; Hexa Slide "
        f'{math.degrees(defaults.rotation_range_rad):g}, Gough-Stewart 20)',
    )
    plan.add_argument(
        '--inclinometer-range-deg',
        type=float,
        default=math.degrees(defaults.inclinometer_range_rad),
        help='inclinometer range (default 45)',
    )
    plan.add_argument(
        '--stroke-m',
        '--slider-stroke-m',
        '--stroke',
        dest='stroke_m',
        type=float,
        nargs=2,
        metavar=('MIN', 'MAX'),
        help="actuator stroke: the reading lambda's range in its SI unit, m for sliders and "
        "legs, rad for cranks (default: the model's; Hexa Slide slider 0 0.9 m, Gough-Stewart "
        'leg extension 0 0.5 m, rotary hexapod crank -1.2 1.2 rad)',
    )
    plan.add_argument(
        '--max-u-joint-deg',
        type=float,
        default=math.degrees(defaults.max_u_joint_angle_rad),
        help='max angle of the base-side U joint: leg to rail (Hexa Slide), leg to the base '
        'normal (Gough-Stewart) (default 60)',
    )
    plan.add_argument(
        '--max-s-joint-deg',
        type=float,
        default=math.degrees(defaults.max_s_joint_angle_rad),
        help='max angle between leg and platform normal at the S joint (default 90)',
    )
    plan.add_argument(
        '--max-condition',
        type=float,
        help=f"max pose-Jacobian condition number, angles scaled by L (default: the model's "
        f'workspace, {defaults.max_condition:g} for both)',
    )
    plan.add_argument(
        '--mount',
        choices=('hanging', 'standing'),
        help="device mount: hanging (platform below the device's base joint) or standing (above "
        "it; an upright machine); default: the nominal file's device.mount, else hanging",
    )
    plan.add_argument(
        '--procedure',
        choices=('none', 'reversal', 'quarter-turns'),
        default='none',
        help='turning procedure: offer every candidate with the device turned about its link axis '
        'by 0/180 deg (reversal) or 0/90/180/270 deg (quarter-turns); the plan says which posture '
        'is taken in which mounting (device_turn) and groups them, one remount per turn (absolute '
        'cost)',
    )
    plan.add_argument(
        '--identify-device',
        type=device_names_argument,
        default=(),
        metavar='NAMES',
        help='device parameters identified with the machine, e.g. dL,alpha0,beta0,gamma: the plan '
        'also informs them (absolute cost)',
    )
    plan.add_argument(
        '--device-prior',
        type=device_prior_argument,
        default=None,
        metavar='NAME=VALUE:STD',
        help="prior knowledge of the device, SI units, e.g. dL=0:10e-6 (a caliper's +-10 um): the "
        'plan starts from its information (needs the noise weighting)',
    )
    plan.add_argument(
        '--measuring-mode',
        choices=MEASURING_MODES,
        default=DEFAULT_MEASURING_MODE.value,
        help='how the machine is driven while the link is attached (issue #18): '
        "passive_actuator (default; the paper's: one actuator released per posture, the plan "
        'chooses which and writes it as released_actuator), lvdt (all six commanded, a '
        "telescopic link: the plan reports each posture's predicted extension) or compliant "
        '(all six commanded against the rigid link, torque-limited drives); written into the '
        'plan as measuring_mode',
    )
    plan.add_argument(
        '--lvdt-stroke-m',
        type=float,
        default=DEFAULT_LVDT_STROKE_M,
        help="lvdt mode: the LVDT link's stroke about its nominal length, +- m (default "
        f'{DEFAULT_LVDT_STROKE_M:g})',
    )
    plan.add_argument(
        '--physical',
        type=Path,
        default=None,
        metavar='FILE',
        help='passive_actuator: physical description YAML (docs/formats.md; its gravity and '
        'masses): the measuring link holds the platform with the five commanded chains; each '
        'move releases a chain that keeps its load within --max-link-force-n where one does, '
        'a posture no release keeps within it is left out and the postures chosen again; the '
        'plan reports the predicted load at each posture',
    )
    plan.add_argument(
        '--max-link-force-n',
        type=float,
        default=LINK_FORCE_LIMIT_N,
        help='with --physical: the largest force the measuring link bears, N (default '
        f'{LINK_FORCE_LIMIT_N:g}: a link of the documented kind)',
    )
    plan.add_argument('--out', type=Path, required=True, help='plan file to write (YAML)')
    plan.add_argument(
        '--json', action='store_true', help='print one JSON object (no progress display)'
    )
    plan.set_defaults(handler=run_plan)


def _report_arguments(report) -> None:
    report.add_argument('result', type=Path, help='result JSON file')
    report.add_argument('--out', type=Path, required=True, help='output directory')
    report.add_argument('--title', help='page title')
    report.set_defaults(handler=run_report)


def _limits(args, nominal, extras: dict) -> PostureLimits:
    """
    Return the nominal machine's default limits (its architecture's workspace) and the options.

    The options given replace the defaults. The device mount: --mount, else the nominal file's
    ``device.mount``, else hanging.
    """
    from ..core.planning.posture_limits import PostureLimits

    given = {
        'mount': args.mount or extras.get(MOUNT_PARAMETER),
        'link_length': args.link_length,
        'xy_range_m': None if args.xy_range_mm is None else args.xy_range_mm / 1e3,
        'rotation_range_rad': None
        if args.rotation_range_deg is None
        else math.radians(args.rotation_range_deg),
        'actuator_stroke_m': None if args.stroke_m is None else tuple(args.stroke_m),
        'max_condition': args.max_condition,
        'inclinometer_range_rad': math.radians(args.inclinometer_range_deg),
        'max_u_joint_angle_rad': math.radians(args.max_u_joint_deg),
        'max_s_joint_angle_rad': math.radians(args.max_s_joint_deg),
    }
    return PostureLimits.for_machine(
        nominal, **{name: value for name, value in given.items() if value is not None}
    )


def load_nominal(path: Path | None) -> tuple:
    """
    Return (parameters, other parameters of the file) of a parameters YAML of any model.

    Its ``model`` key names the model (calibration_steps.machine_files.load_machine_and_extras,
    the one loader); no file: the default machine (no other parameters).
    """
    if path is None:
        from ..core.architectures import default_parameters

        return default_parameters(), {}
    from ..calibration_steps.machine_files import load_machine_and_extras

    return load_machine_and_extras(path)


def run_plan(args) -> int:
    import numpy as np

    from ..core.machine.device import DevicePrior, procedure_turns
    from ..core.machine.measurements import NoiseModel
    from ..core.planning.observability import INDICES, PREDICTION
    from ..core.planning.planner import plan_postures, progress_steps

    nominal, extras = load_nominal(args.nominal)
    layout = nominal.layout
    limits = _limits(args, nominal, extras)
    if args.out.is_dir():
        raise IsADirectoryError(f'--out {args.out} is a directory; name a YAML file')
    weighted = not args.unweighted and args.cost != 'relative' and args.noise_um > 0
    noise = NoiseModel.from_microns(args.noise_um) if weighted else None
    rehearsed = args.measuring_mode == 'passive_actuator'  # its releases: a stage of its own
    progress = Progress(
        enabled=not args.json,
        total=progress_steps(args.postures, args.method, args.measuring_mode),
        prefix='hexacal plan',
    )
    try:
        planning = plan_postures(
            nominal,
            args.postures,
            index=args.index,
            method=args.method,
            n_candidates=args.candidates,
            cost=args.cost,
            limits=limits,
            fixed_fraction=args.fixed_fraction,
            seed=args.seed,
            noise=noise,
            name=args.name,
            progress=progress.step,
            stage=progress.stage,
            device_columns=args.identify_device,
            device_prior=args.device_prior or DevicePrior(),
            device_turns=procedure_turns(args.procedure),
            measuring_mode=args.measuring_mode,
            lvdt_stroke_m=args.lvdt_stroke_m,
            link_load=_link_load(args),
        )
    finally:
        progress.close()
    random = planning.random_indices()
    planning.plan.metadata['random_mean_indices'] = random
    planning.plan.save(args.out)
    plan = planning.plan
    counts = {kind: int((plan.kinds == kind).sum()) for kind in ('sphere', 'fixed')}
    if args.json:
        print(
            json.dumps(
                {
                    'out': str(args.out),
                    'name': plan.name,
                    'model': plan.model,
                    'mount': plan.mount,
                    'postures': len(plan),
                    'kinds': counts,
                    'index': args.index,
                    'method': args.method,
                    'cost': args.cost,
                    'weighted': weighted,
                    'candidates': len(planning.candidates),
                    'rank': planning.rank,
                    'indices': planning.indices,
                    # None: random draws of this size identify too little for the index.
                    'random_mean_indices': {
                        name: value if math.isfinite(value) else None
                        for name, value in random.items()
                    },
                    'candidate_seconds': planning.candidate_seconds,
                    'selection_seconds': planning.selection_seconds,
                    **({'rehearsal_seconds': planning.measuring_seconds} if rehearsed else {}),
                    'exchange_swaps': max(len(planning.exchange_history) - 1, 0),
                    'procedure': args.procedure,
                    'device_columns': list(planning.candidates.device_columns),
                    'device_turns': {
                        f'{turn:.6f}': int(np.sum(np.isclose(plan.turns, turn)))
                        for turn in procedure_turns(args.procedure)
                    },
                    **(
                        {}
                        if planning.measuring is None  # no measuring mode: nothing it adds
                        else planning.measuring.to_json(layout.actuator_names)
                    ),
                }
            )
        )
        return 0
    print(
        f"plan '{plan.name}' for the {layout.title} ({plan.mount} device): {len(plan)} postures "
        f"({counts['sphere']} sphere, "
        f'{counts["fixed"]} fixed) chosen from {len(planning.candidates)} candidates by '
        f'{args.method} on {args.index} '
        f'({"noise-weighted" if weighted else "unweighted"}, cost {args.cost})'
    )
    print(
        f'  candidates {planning.candidate_seconds:.2f} s, selection '
        f'{planning.selection_seconds:.2f} s'
        + (f', rehearsal {planning.measuring_seconds:.2f} s' if rehearsed else '')
        + (
            f', {len(planning.exchange_history) - 1} exchange swaps'
            if args.method == 'exchange'
            else ''
        )
    )
    print('  index       ' + '  '.join(f'{name:>10}' for name in INDICES))
    planned = planning.indices
    print('  planned     ' + '  '.join(f'{_index_cell(planned[name]):>10}' for name in INDICES))
    print('  random mean ' + '  '.join(f'{_index_cell(random[name]):>10}' for name in INDICES))
    if not all(math.isfinite(random[name]) for name in INDICES):
        print(
            f'  (n/a: random draws of {len(plan)} postures leave parameters unidentified; such an '
            'index has no finite value)'
        )
    error = planning.indices[PREDICTION]
    if weighted and math.isfinite(error):
        random_error = random[PREDICTION]
        print(
            f'  predicted RMS position error over the workspace (linearised, noise-weighted fit): '
            f'{error * 1e6:.1f} um planned, '
            + (
                f'{random_error * 1e6:.1f} um random'
                if math.isfinite(random_error)
                else f'none for random draws of {len(plan)} postures (they leave parameters '
                'unidentified)'
            )
        )
    if args.procedure != 'none' or planning.candidates.device_columns:
        mountings = ', '.join(
            f'{int(np.sum(np.isclose(plan.turns, turn)))} at {math.degrees(turn):g} deg'
            for turn in procedure_turns(args.procedure)
        )
        print(
            f'  device: {", ".join(planning.candidates.device_columns) or "no parameters"} '
            f'identified with the machine; procedure {args.procedure}: {mountings} (turn the '
            'device about its link axis between the groups)'
        )
    _print_measuring(
        planning.measuring, layout.actuator_names, layout.actuator_quantities,
        nominal.architecture.released_margin,
    )
    if planning.rank < layout.n_parameters:
        print(
            f'  note: these {len(plan)} postures identify {planning.rank} of '
            f'{layout.n_parameters} parameters with the {args.cost} cost, so every index is 0 '
            '(the plan maximises log det(M + delta I), the information on the identifiable '
            'part). Too few to calibrate from alone; as a verification plan that is fine: a '
            'verification identifies nothing, it needs postures the fit did not use, spread '
            'over the workspace'
        )
    print(f'wrote {args.out}')
    return 0


def _link_load(args):
    """Return the planner's LinkLoad of --physical and --max-link-force-n (None: no file)."""
    if args.physical is None:
        return None
    from ..core.fit.statics import MassModel
    from ..core.modes.link_load import LinkLoad

    return LinkLoad(MassModel.load(args.physical), args.max_link_force_n)


def _index_cell(value: float) -> str:
    """Return an index for the table: 4 significant digits, or n/a when not finite."""
    return f'{value:.4g}' if math.isfinite(value) else 'n/a'


def _print_measuring(
    measuring,
    actuator_names: tuple[str, ...],
    units: ActuatorQuantities = LINEAR_ACTUATOR,
    margin: float | None = None,
) -> None:
    """
    Print what the plan's measuring mode adds: released actuators, or LVDT extensions.

    The released actuator's travel and margin in the actuators' display unit (mm, or deg for
    cranks); the LVDT's in mm.
    """
    import numpy as np

    from ..core.modes.released_actuator import DEFAULT_MARGIN_M

    margin = DEFAULT_MARGIN_M if margin is None else margin
    print(f'  measuring mode {measuring.mode.value}')
    release = measuring.release
    if release is not None:
        names = release.names(actuator_names)
        chosen, worst = release.chosen_conditions, release.worst_conditions
        print('  released actuator per posture (condition number of the five commanded + link):')
        for start in range(0, len(names), 5):
            print(
                '   '
                + ''.join(
                    f' {i:>3} {names[i]} ({chosen[i]:.3g})'
                    for i in range(start, min(start + 5, len(names)))
                )
            )
        print(
            f'  conditioning, angles scaled by L: chosen max {np.max(chosen):.3g} (median '
            f'{np.median(chosen):.3g}); the worst actuator to release would give max '
            f'{np.max(worst):.3g} (median {np.median(worst):.3g}); the released actuator travels '
            f'up to {units.shown(np.max(release.released_travel), 1)} on a move, inside its '
            f'stroke less {units.shown(margin, 2)}'
            + (
                f'; {int(np.sum(release.via_centre))} move(s) by way of the centre'
                if np.any(release.via_centre)
                else ''
            )
        )
        if release.move_conditions is not None and release.jams is not None:
            risky = np.flatnonzero(release.jams > 0)
            print(
                f'  rehearsed on {release.machines} machines (the nominal and '
                f'{release.machines - 1} with drawing-tolerance errors): worst condition along '
                f'a move {np.max(release.move_conditions):.3g}; '
                + (
                    f'{len(risky)} move(s) jam on some of them whatever is released (to '
                    f'posture(s) {", ".join(str(i) for i in risky[:10])}): the drive may fault '
                    'there before the first calibration refines the targets'
                    if risky.size
                    else 'no move jams on any of them'
                )
            )
    if measuring.link_forces is not None:
        forces, over = measuring.link_forces, measuring.overloaded
        moves = measuring.link_move_forces
        along = (
            ''
            if moves is None
            else f', along the moves {np.max(moves):.4g} N (from the swap of the releases at '
            'the posture before)'
        )
        print(
            f'  measuring link at the postures, predicted from the weights: largest force '
            f'{np.max(forces):.4g} N (median {np.median(forces):.4g} N){along}, limit '
            f'{measuring.link_force_limit_n:g} N'
            + (
                f'; beyond it on the way to {len(over)} posture(s) '
                f'({", ".join(str(i) for i in over[:10])}'
                f'{", ..." if len(over) > 10 else ""}): the released actuator leaves the link '
                "the platform's load there; measure in lvdt (the link then carries its own "
                'weight only), or leave those postures out'
                if over.size
                else ''
            )
        )
    lvdt = measuring.lvdt
    if lvdt is not None:
        print(
            f'  LVDT link: predicted extension on the nominal machine max '
            f'{np.max(np.abs(lvdt.extensions)) * 1e6:.3g} um over {len(lvdt.extensions)} postures '
            f"({'inside' if lvdt.inside else 'OUTSIDE'} the +-{lvdt.stroke_m * 1e3:g} mm stroke); "
            f'an actuator error of d makes up to {np.max(lvdt.gains):.3g} d of extension, so the '
            f'stroke absorbs model errors up to {lvdt.tolerated_error_m * 1e3:.3g} mm'
        )


def run_report(args) -> int:
    from ..report.page import write_report

    page = write_report(args.result, args.out, title=args.title)
    print(f'wrote {page}')
    return 0
