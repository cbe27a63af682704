"""``hexacal study``: the paper's section 4, reproduced and printed beside the paper's numbers."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from .command_line import Progress

if TYPE_CHECKING:
    from ..core.architectures import KinematicParameters
    from ..studies.accuracy import StudyRun

# The studies (studies.accuracy, studies.planning, studies.defective_device, figures with
# matplotlib) are imported where they run: this module is imported by every `hexacal` start-up
# to register the command.
UM, DEG = 1e6, math.degrees(1.0)


def add_parser(subparsers) -> None:
    subparsers.add_parser(
        'study',
        help="reproduce the paper's simulation study (section 4)",
        description='Reproduce section 4 of the paper on the simulated Table 1 machine, print the '
        "paper's numbers "
        'side by side and write PNG figures (--model gough_stewart: the same study of the default '
        'Gough-Stewart '
        'platform). With --json, run only the configured calibration and print its result.',
        fill=add_arguments,
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from hexacal_msgs_py.models import MODELS

    from . import study_device as cli_study_device
    from . import study_plan
    from ..core.fit.residuals import COSTS

    parser.add_argument(
        '--model',
        choices=tuple(MODELS),
        default=None,
        help='machine model studied (default: the model of --true-params / --nominal-params, '
        'else hexa_slide); its default machine is simulated when --true-params is not given',
    )
    parser.add_argument(
        '--true-params',
        type=Path,
        help="parameters YAML of the simulated machine (default: the model's default machine, "
        'Table 1 for the Hexa Slide)',
    )
    parser.add_argument(
        '--nominal-params',
        type=Path,
        help='parameters YAML to start from (default: nominal set --nominal-set)',
    )
    parser.add_argument(
        '--nominal-set',
        type=int,
        choices=(1, 2, 3),
        default=2,
        help='Table 2 error set (default 2)',
    )
    parser.add_argument('--postures', type=int, default=50, help='measured postures (default 50)')
    parser.add_argument(
        '--noise-um',
        type=float,
        default=10.0,
        help='uniform noise half-width: um on sliders and legs, urad on cranks and angles '
        '(default 10)',
    )
    parser.add_argument('--seed', type=int, default=0, help='random seed (default 0)')
    parser.add_argument(
        '--seeds',
        type=int,
        default=5,
        help='seeds per noise level in the Table 3 study (default 5)',
    )
    parser.add_argument(
        '--cost', choices=COSTS, default='absolute', help='cost function (default absolute, eq. 7)'
    )
    parser.add_argument(
        '--validation-postures',
        type=int,
        default=50,
        help='fresh postures for pose errors (default 50)',
    )
    parser.add_argument(
        '--json',
        action='store_true',
        help='print one JSON object for the configured run, nothing else',
    )
    parser.add_argument(
        '--out',
        type=Path,
        default=Path('study_out'),
        help='directory for PNG figures (default study_out)',
    )
    study_plan.add_arguments(parser)
    cli_study_device.add_arguments(parser)
    add_mode_arguments(parser)
    parser.set_defaults(handler=run)


def add_mode_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the measuring-mode study (absent: the accuracy study)."""
    from hexacal_msgs_py.measuring_modes import DEFAULT_LVDT_STROKE_M, MEASURING_MODES

    group = parser.add_argument_group(
        'measuring modes (--measuring-mode: compare the accuracy of the procedures instead)'
    )
    group.add_argument(
        '--measuring-mode',
        choices=(*MEASURING_MODES, 'all'),
        default=None,
        help='simulate the measuring procedure of this mode (all: the three, and the compliant '
        'mode without refinement, the demo of today, as the baseline) on the true machine with '
        'targets from the nominal model, calibrate and print its accuracy; --postures, '
        '--noise-um, --seed, --nominal-set, --cost, --validation-postures and --json apply',
    )
    group.add_argument(
        '--refine',
        action=argparse.BooleanOptionalAction,
        default=True,
        help='with --measuring-mode: compute the remaining targets from an intermediate '
        'calibration once the postures so far give one of full rank, and again later (default '
        'on)',
    )
    group.add_argument(
        '--first-calibration',
        type=int,
        default=None,
        help='with --refine: postures measured before the first intermediate calibration '
        '(default: 2 x parameters / 5)',
    )
    group.add_argument(
        '--lvdt-stroke-m',
        type=float,
        default=DEFAULT_LVDT_STROKE_M,
        help='lvdt mode: the stroke of the link about its length, +- m (default '
        f'{DEFAULT_LVDT_STROKE_M:g})',
    )
    group.add_argument(
        '--lvdt-noise-m',
        type=float,
        default=1e-6,
        help='lvdt mode: uniform noise half-width of the LVDT reading, m (default 1e-6)',
    )
    group.add_argument(
        '--servo-stiffness-n-per-m',
        type=float,
        default=None,
        help='compliant mode: the stiffness of the servos, N/m (N m/rad for actuators that '
        "turn), for the force (torque) they carry (default 2e6 N/m at the actuator's joint: "
        '2e6 for sliders and legs, 2e6 x crank^2 N m/rad for cranks)',
    )


def study_model(args) -> str:
    """
    Return the model studied.

    --model, else the model of the parameters files given, else the Hexa Slide.

    Every model named (option and files) must be the same one: a mismatch is a named error.
    """
    from hexacal_msgs_py.models import DEFAULT_MODEL
    from hexacal_msgs_py.parameters_file import load_model

    named = [(f'--model {args.model}', args.model)] if args.model else []
    for option, path in (
        ('--true-params', args.true_params),
        ('--nominal-params', args.nominal_params),
    ):
        if path is not None:
            model = load_model(path)
            named.append((f'{option} {path} (a {model} file)', model))
    models = {model for _, model in named}
    if len(models) > 1:
        raise ValueError(
            'the machine models disagree: '
            + ', '.join(text for text, _ in named)
            + '; the model studied, the simulated machine and the starting model must be one model'
        )
    return models.pop() if models else DEFAULT_MODEL


def configured_run(args) -> StudyRun:
    from ..core.architectures import default_parameters
    from ..core.machine.device import DeviceDefects
    from ..calibration_steps.machine_files import load_machine
    from ..studies.accuracy import StudyRun

    model = study_model(args)
    true_params = load_machine(args.true_params) if args.true_params else default_parameters(model)
    nominal = load_machine(args.nominal_params) if args.nominal_params else None
    if args.postures < 1:
        raise ValueError(f'--postures must be positive, got {args.postures}')
    return StudyRun(
        true_params=true_params,
        nominal_params=nominal,
        nominal_set_number=args.nominal_set,
        postures=args.postures,
        noise_um=args.noise_um,
        seed=args.seed,
        cost=args.cost,
        validation_postures=args.validation_postures,
        defects=args.device_defects or DeviceDefects(),
        identify_device=args.identify_device,
        weighted=args.weighted,
        robust_loss=args.robust,
        lvdt=args.lvdt,
        procedure=args.procedure,
        device_prior=args.device_prior,
    )


def run(args) -> int:
    from . import study_device as cli_study_device
    from . import study_plan
    from ..studies.accuracy import run_calibration

    args.model = study_model(args)  # resolved once: the files' model when --model is not given
    if args.plan:
        return study_plan.run(args)
    if args.measuring_mode is not None:
        from . import study_modes
        from ..calibration_steps.machine_files import load_machine

        return study_modes.run(args, load_machine)
    configured = configured_run(args)
    if args.json:
        print(json.dumps(run_calibration(configured).to_json()))
        return 0
    from ..core.architectures import default_parameters

    # The study's sections run on the model's default machine (the paper's: Table 1); the
    # configured run on --true-params when given.
    truth = default_parameters(configured.model)
    progress = Progress(enabled=True)
    args.out.mkdir(parents=True, exist_ok=True)
    _print_model(truth)
    _print_identifiability(args.out, truth)
    _print_noise_free(args.out, progress, truth)
    _print_noise_table(args.out, args.seeds, progress, truth)
    _print_procedures(progress, truth)
    cli_study_device.print_sections(args, progress, truth)
    _print_configured(configured)
    progress.close()
    print(f'\nfigures written to {args.out}/')
    return 0


def _paper(truth: KinematicParameters, text: str) -> str:
    """``text`` where the paper studied this model (its numbers are printed), else nothing."""
    from ..studies.accuracy import paper_reference

    return text if paper_reference(truth.model) is not None else ''


def _print_model(truth: KinematicParameters) -> None:
    """
    Print a line naming the machine where it is not the paper's.

    A line naming the machine where it is not the paper's (the paper's study prints as it always
    has).
    """
    from ..studies.accuracy import paper_reference

    if paper_reference(truth.model) is None:
        layout = truth.layout
        print(
            f'Model {layout.name}: {layout.title}, {layout.n_parameters} parameters per machine '
            f'({" ".join(layout.fields)} per chain), its default machine and workspace; the '
            "paper's "
            'numbers are for another machine and are not printed.\n'
        )


def _print_identifiability(out: Path, truth: KinematicParameters) -> None:
    from ..core.assessment.identifiability import DEFAULT_RANK_TOLERANCE
    from ..core.fit.residuals import COST_EQUATIONS
    from ..report import figures
    from ..studies.accuracy import identifiability_by_cost

    claim = _paper(truth, " (paper: 'all parameters are identifiable')")
    print(
        f'Identifiability of each cost function{claim}, '
        'exact data, 40 postures (30 sphere + 10 fixed-position where needed):'
    )
    print(
        f'  {"cost":<13} {"equations":<12} {"postures":<16} {"rank":>5} {"condition":>10}  verdict'
    )
    spectra = {}
    n_parameters = truth.layout.n_parameters
    for row in identifiability_by_cost(truth):
        report = row.report
        postures = f'{row.sphere_postures} sph + {row.fixed_postures} fix'
        verdict = (
            f'all {n_parameters} identifiable'
            if report.identifiable
            else 'NOT all identifiable: '
            + '; '.join(d.description for d in report.null_directions)
        )
        print(
            f'  {row.cost:<13} {COST_EQUATIONS[row.cost]:<12} {postures:<16} {report.rank:>5} '
            f'{report.condition_number:>10.3g}  {verdict}'
        )
        spectra[f'{row.cost} ({COST_EQUATIONS[row.cost]})'] = report.singular_values
    figures.singular_values(
        spectra, DEFAULT_RANK_TOLERANCE, out / 'identifiability_singular_values.png'
    )


def _print_noise_free(out: Path, progress: Progress, truth: KinematicParameters) -> None:
    import numpy as np

    from ..core.machine.model import error_stats_mm
    from ..report import figures
    from ..studies.accuracy import noise_free_recovery

    # The nominal sets' target statistics: Table 2's rows (every shipped architecture draws its
    # sets with them).
    target_stats = truth.architecture.nominal_error_stats_mm
    print(
        f'\nNo noise, 25 postures, eq. 7 ({_paper(truth, "paper Figs. 4-6: ")}every parameter '
        'identified):'
    )
    print(
        f'  {"set":>3} {"Table 2 max/mean/sigma mm":>27} {"ours max/mean/sigma mm":>25} '
        f'{"final max |error| m":>20} {"iters":>6} {"solve ms":>9}'
    )
    for outcome in noise_free_recovery(progress=progress.step, true_params=truth):
        number = outcome.run.nominal_set_number
        paper = '/'.join(f'{v:g}' for v in target_stats[number])
        ours = '/'.join(f'{v:.2f}' for v in error_stats_mm(outcome.initial_parameter_errors))
        final = float(np.max(np.abs(outcome.final_parameter_errors)))
        print(
            f'  {number:>3} {paper:>27} {ours:>25} {final:>20.2e} {outcome.result.iterations:>6} '
            f'{outcome.result.solve_seconds * 1e3:>9.1f}'
        )
        figures.parameter_errors(
            outcome.initial_parameter_errors,
            outcome.final_parameter_errors,
            f'Nominal set {number}, no noise{_paper(truth, f" (cf. paper Fig. {number + 3})")}',
            out / f'fig{number + 3}_parameter_errors_set{number}.png',
        )


def _print_noise_table(
    out: Path, seeds: int, progress: Progress, truth: KinematicParameters
) -> None:
    from ..report import figures
    from ..studies.accuracy import noise_study, paper_reference

    paper_table = paper_reference(truth.model)
    noise_unit = truth.architecture.actuator_quantities.small  # um for sliders, urad for cranks
    print(
        '\nMeasurement noise, 50 postures, nominal set 2, eq. 7; mean over 50 validation '
        f'postures, {seeds} seeds (mean +- spread){_paper(truth, " [paper Table 3]")}:'
    )
    summaries = noise_study(seeds=range(seeds), progress=progress.step, true_params=truth)
    before_pos = summaries[0].mean_and_spread('before', 'position_mean_m')
    before_ori = summaries[0].mean_and_spread('before', 'orientation_mean_rad')
    print(
        f'  {"":<12} {"initial":>22} '
        + ' '.join(f'{"+-" + format(s.noise_um, "g") + " " + noise_unit:>24}' for s in summaries)
    )
    after_pos = [s.mean_and_spread('after', 'position_mean_m') for s in summaries]
    after_ori = [s.mean_and_spread('after', 'orientation_mean_rad') for s in summaries]
    print(
        f'  {"position um":<12} {_pm(before_pos, UM):>22} '
        + ' '.join(f'{_pm(v, UM):>24}' for v in after_pos)
    )
    if paper_table is not None:
        paper_pos = [paper_table[int(s.noise_um)]['position_m'] for s in summaries]
        print(
            f'  {"  paper":<12} {paper_table["initial"]["position_m"] * UM:>22.0f} '
            + ' '.join(f'{v * UM:>24.1f}' for v in paper_pos)
        )
    print(
        f'  {"orient. deg":<12} {_pm(before_ori, DEG, 3):>22} '
        + ' '.join(f'{_pm(v, DEG, 4):>24}' for v in after_ori)
    )
    if paper_table is not None:
        paper_ori = [paper_table[int(s.noise_um)]['orientation_rad'] for s in summaries]
        print(
            f'  {"  paper":<12} {paper_table["initial"]["orientation_rad"] * DEG:>22.2f} '
            + ' '.join(f'{v * DEG:>24.4f}' for v in paper_ori)
        )
    else:  # the figure's comparison bars: none
        paper_pos = paper_ori = [float('nan')] * len(summaries)
    figures.noise_table(
        [s.noise_um for s in summaries],
        [v[0] * UM for v in after_pos],
        [v[1] * UM for v in after_pos],
        [v * UM for v in paper_pos],
        [v[0] * DEG for v in after_ori],
        [v * DEG for v in paper_ori],
        out / 'table3_pose_error_vs_noise.png',
        noise_unit,
    )
    for figure_number, summary in zip((7, 8, 9), summaries):
        if summary.outcomes:
            first = summary.outcomes[0]
            figures.chain_errors(
                first.initial_parameter_errors,
                first.final_parameter_errors,
                f'Errors in kinematic chains, +-{summary.noise_um:g} {noise_unit} noise'
                f'{_paper(truth, f" (cf. paper Fig. {figure_number})")}',
                out / f'fig{figure_number}_chain_errors_{summary.noise_um:g}um.png',
            )


def _print_procedures(progress: Progress, truth: KinematicParameters) -> None:
    from ..core.fit.residuals import COST_EQUATIONS, COSTS
    from ..studies.accuracy import run_calibration, StudyRun

    claim = _paper(truth, " (paper: 'of the same order as the noise')")
    noise_unit = truth.architecture.actuator_quantities.small
    print(
        '\nSphere + fixed-position procedure, 60 sphere + 20 fixed postures, '
        f'+-10 {noise_unit} noise, '
        f'nominal set 2{claim}:'
    )
    print(
        f'  {"cost":<13} {"equations":<12} {"outcome":<16} '
        f'{"position um":>12} {"orient. deg":>12} {"solve ms":>9}'
    )
    for cost in COSTS:
        progress.step(f'procedure {cost}')
        try:
            outcome = run_calibration(
                StudyRun(true_params=truth, postures=80, noise_um=10.0, cost=cost)
            )
        except Exception as error:  # a refusal is the finding: print why
            reason = getattr(error, 'reason', type(error).__name__)
            print(f'  {cost:<13} {COST_EQUATIONS[cost]:<12} {"refused: " + reason:<16}')
            continue
        after = outcome.after.summary()
        print(
            f'  {cost:<13} {COST_EQUATIONS[cost]:<12} {outcome.result.reason:<16} '
            f'{after["position_mean_m"] * UM:>12.1f} {after["orientation_mean_rad"] * DEG:>12.4f} '
            f'{outcome.result.solve_seconds * 1e3:>9.1f}'
        )


def _print_configured(run: StudyRun) -> None:
    from ..studies.accuracy import run_calibration

    outcome = run_calibration(run)
    result = outcome.result
    before, after = outcome.before.summary(), outcome.after.summary()
    print(
        f'\nConfigured run: {run.postures} postures, +-{run.noise_um:g} '
        f'{run.true_params.architecture.actuator_quantities.small}, seed {run.seed}, cost '
        f'{run.cost}: '
        f'{result.reason} in {result.iterations} iterations, {result.solve_seconds * 1e3:.1f} ms, '
        f'rank {result.rank}, condition {result.condition_number:.3g}'
    )
    no_defects = type(run.defects)  # the defect-free device of the same kind
    defective = run.defects != no_defects()
    print(
        f'  pose error before: {before["position_mean_m"] * UM:.1f} um, '
        f'{before["orientation_mean_rad"] * DEG:.4f} deg; after: '
        f'{after["position_mean_m"] * UM:.2f} um, {after["orientation_mean_rad"] * DEG:.5f} deg'
        + (' (frames the calibration works in)' if defective else '')
    )
    if defective and outcome.after_true_frames is not None:
        true_frames = outcome.after_true_frames.summary()
        print(
            '  after, in the true frames (gravity base frame, origin at O): '
            f'{true_frames["position_mean_m"] * UM:.2f} um, '
            f'{true_frames["orientation_mean_rad"] * DEG:.5f} deg; procedure {run.procedure}'
            + (f', device prior {run.device_prior.describe()}' if run.device_prior else '')
        )
        for name, value, std in zip(result.free_device, *_device_values(result)):
            print(
                f'  device {name}: identified {value:.4g} +- {std:.2g} (SI), true '
                f'{getattr(run.defects, name):.4g}'
            )
    if result.rejected_postures:
        print(
            f'  {len(result.rejected_postures)} posture(s) rejected: '
            + '; '.join(f'#{i}: {why}' for i, why in sorted(result.rejected_postures.items()))
        )


def _device_values(result) -> tuple[list[float], list[float]]:
    from ..core.machine.device import DEVICE_PARAMETER_NAMES

    index = [DEVICE_PARAMETER_NAMES.index(name) for name in result.free_device]
    return [float(result.device.vector[i]) for i in index], [
        float(result.device_std[i]) for i in index
    ]


def _pm(value: tuple[float, float], scale: float, digits: int = 1) -> str:
    return f'{value[0] * scale:.{digits}f} +- {value[1] * scale:.{digits}f}'
