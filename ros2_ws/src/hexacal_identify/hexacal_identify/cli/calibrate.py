"""``hexacal calibrate BAG`` and ``hexacal bag-info BAG``: the nodes' work, offline from a bag."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys
from typing import Any

from .store import add_calibrate_arguments, calibrate_store_dir, store_calibration

# The solver, the bag reader and the report are imported where they run: this module is imported by
# every `hexacal` start-up to register the commands.
UM, MM = 1e6, 1e3


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        'calibrate',
        help='calibrate from a recorded bag (no ROS graph needed)',
        description='Identify the kinematic parameters (54 of a Hexa Slide, 42 of a '
        'Gough-Stewart platform: the model the --nominal file names) from a rosbag2 bag '
        '(directory with metadata.yaml + .mcap, or a single .mcap file) with the same core '
        "call the identify node uses. Postures come from the bag's /hexacal/posture topic, or "
        'are re-detected from its raw sensor streams; their actuator joints (slider_1..6 or '
        "leg_1..6) must be the nominal model's.",
        fill=_calibrate_arguments,
    )
    subparsers.add_parser(
        'bag-info',
        help='describe a bag (like `ros2 bag info`) and its postures',
        description="Print a bag's files, duration, topics with types and counts, "
        'and the postures it holds.',
        fill=_bag_info_arguments,
    )


def device_prior_argument(text: str):
    """
    Parse --device-prior NAME=VALUE:STD,... (SI units) into a DevicePrior of at least one.

    argparse names a bad one (exit code 2).
    """
    from .study_device import device_prior_argument as parsed_prior

    prior = parsed_prior(text)
    if not prior:
        raise argparse.ArgumentTypeError(
            'no device prior given: expected NAME=VALUE:STD[,...] in SI units, e.g. dL=0:10e-6'
        )
    return prior


def _calibrate_arguments(calibrate: argparse.ArgumentParser) -> None:
    from ..core.machine.device import DEFAULT_LINK_LENGTH_M
    from ..core.fit.identification import ROBUST_LOSSES
    from ..core.fit.residuals import COSTS
    from ..core.fit.weighting import WEIGHT_MODES
    from .study_device import device_names_argument

    calibrate.add_argument('bag', type=Path, help='bag directory or .mcap file')
    calibrate.add_argument(
        '--nominal',
        type=Path,
        required=True,
        help='parameters YAML to start from; its model (key model, none: hexa_slide) is the '
        "machine's",
    )
    calibrate.add_argument(
        '--output', type=Path, required=True, help='parameters YAML to write (atomically)'
    )
    calibrate.add_argument(
        '--cost', choices=COSTS, default='absolute', help='cost function (default absolute)'
    )
    calibrate.add_argument(
        '--link-length',
        type=float,
        default=DEFAULT_LINK_LENGTH_M,
        help=f'device link length L in m (default {DEFAULT_LINK_LENGTH_M})',
    )
    calibrate.add_argument(
        '--mount',
        choices=('hanging', 'standing'),
        default=None,
        help="device mount: hanging (platform below the device's base joint) or standing (an "
        "upright machine); default: the nominal file's device.mount, else hanging",
    )
    calibrate.add_argument(
        '--identify-device',
        type=device_names_argument,
        default=(),
        help='device defects to identify jointly, e.g. dL,alpha0,gamma (beta0 and phi0 are '
        'frame definitions: eq. 7 cannot see them)',
    )
    calibrate.add_argument(
        '--device-prior',
        type=device_prior_argument,
        default=None,
        metavar='NAME=VALUE:STD,...',
        help='prior knowledge of device parameters in SI units (m, rad), e.g. '
        'dL=0:10e-6,alpha0=0:50e-6 (link length offset 0 +- 10 um from a caliper, inclinometer '
        'zero 0 +- 50 urad from its certificate): each is identified, weighed against the data '
        'by the reading noise (needs --noise-um, or postures that carry their scatter)',
    )
    calibrate.add_argument(
        '--noise-um',
        type=float,
        default=None,
        help='known reading noise half-width (um on sliders, urad on angles): weight residuals '
        'by it',
    )
    calibrate.add_argument(
        '--weights',
        choices=WEIGHT_MODES,
        default='auto',
        help="what weighs the residuals: each posture's measured scatter (scatter), the "
        '--noise-um model (noise-model) or nothing (none); default auto: scatter when every '
        'posture carries it, else the noise model when given, else none',
    )
    calibrate.add_argument(
        '--scatter-floor-um',
        type=float,
        default=0.1,
        help='smallest standard error a posture is credited with when weighed by its scatter '
        '(um on actuators, urad on angles; default 0.1)',
    )
    calibrate.add_argument(
        '--robust', choices=ROBUST_LOSSES, default=None, help='robust loss (huber or soft_l1)'
    )
    _compliance_arguments(calibrate)
    calibrate.add_argument(
        '--save-result',
        type=Path,
        default=None,
        metavar='FILE',
        help='write the full result (what `hexacal report` reads) as JSON',
    )
    calibrate.add_argument(
        '--report',
        type=Path,
        default=None,
        metavar='DIR',
        help='write the HTML calibration report (index.html + PNG figures) into DIR',
    )
    calibrate.add_argument(
        '--json', action='store_true', help='print the result as one JSON object'
    )
    _redetection_arguments(calibrate)
    add_calibrate_arguments(calibrate)
    calibrate.set_defaults(handler=run_calibrate)


def _compliance_arguments(calibrate: argparse.ArgumentParser) -> None:
    from ..core.fit.compliance import COMPLIANCE_MODES

    calibrate.add_argument(
        '--compliance',
        choices=COMPLIANCE_MODES,
        default='none',
        help='axial compliances identified with the geometry from the static loads of each '
        'posture: none (rigid), shared (one for the six chains, one for the link) or '
        'per_chain (one per chain, one for the link); needs --physical',
    )
    calibrate.add_argument(
        '--physical',
        type=Path,
        default=None,
        metavar='FILE',
        help='physical description YAML (gravity, platform {mass, com}, payload {mass, com}, '
        'legs {mass, com_fraction}, link {mass, com_fraction}; SI units): the weights that load '
        'the chains and the link; with --compliance none (a hexacal-physical/1 file, with its '
        'stiffnesses), the deflection check: how far its compliances bias the rigid fit, which '
        'its residuals cannot show',
    )
    calibrate.add_argument(
        '--compliance-prior',
        type=compliance_prior_argument,
        default=None,
        metavar='NAME=VALUE:STD,...',
        help='datasheet compliances in m/N, e.g. link=1e-7:2e-8 (a 1e7 N/m link +- 20 %%): each '
        'weighed against the data by the reading noise; names: chains or chain_1..chain_6, link',
    )


def compliance_prior_argument(text: str) -> dict[str, tuple[float, float]]:
    """Parse --compliance-prior NAME=VALUE:STD,... (m/N); argparse names a bad one."""
    from ..calibration_steps.calibration_run import parse_compliance_prior

    try:
        prior = parse_compliance_prior(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    if not prior:
        raise argparse.ArgumentTypeError('no compliance prior given: expected NAME=VALUE:STD')
    return prior


def compliance_model(args, bag, nominal):
    """Return the ComplianceModel of --compliance for a bag's postures (None: rigid)."""
    from ..calibration_steps.calibration_run import (
        compliance_for_postures,
        drive_stiffness_of,
        released_friction_of,
    )
    from ..core.fit.statics import MassModel

    if args.compliance == 'none':
        if args.compliance_prior:
            raise ValueError('--compliance-prior needs --compliance shared|per_chain')
        return None  # with --physical: the rigid fit's deflection check (deflection_of)
    if args.physical is None:
        raise ValueError(
            f'--compliance {args.compliance} needs the masses that load the machine: --physical '
            'FILE'
        )
    mode = bag.measuring_mode
    if mode is None:
        raise ValueError(
            f'--compliance {args.compliance}: the bag does not record its measuring mode, and the '
            'loads depend on it (which chains and whether the link carry the weight)'
        )
    return compliance_for_postures(
        args.compliance,
        MassModel.load(args.physical),
        mode,
        bag.released_joints,
        nominal.layout.actuator_names,
        args.compliance_prior,
        label='--compliance',
        released_friction=released_friction_of(args.physical, nominal.model),
        drive_stiffness=drive_stiffness_of(args.physical, nominal.model),
    )


def deflection_of(args, bag, result, mount: str):
    """Return the deflection check of a rigid fit with --physical (None: not asked)."""
    if args.physical is None or args.compliance != 'none':
        return None
    from ..calibration_steps.calibration_run import deflection_check

    return deflection_check(
        result, str(args.physical), bag.measuring_mode, bag.released_joints, cost=args.cost,
        link_length=args.link_length, mount=mount, identify_device=args.identify_device,
    )


def compliance_lines(result) -> list[str]:
    """Return the identified compliances (m/N, with the stiffness they mean) as summary lines."""
    import math

    if not result.compliance:
        return []
    lines = [f'axial compliances ({result.compliance_mode}; m/N, stiffness N/m):']
    for name, value in result.compliance.items():
        std = result.compliance_std.get(name, float('nan'))
        std_text = f'{std:.3g}' if math.isfinite(std) else 'n/a'
        stiffness = f', {1.0 / value:.3g} N/m' if value > 0 else ''
        lines.append(f'  {name}: {value:.4g} +- {std_text} m/N{stiffness}')
    return lines


def clock_offset_argument(text: str) -> tuple[str, float]:
    """Parse --clock-offset STREAM=SECONDS (STREAM inclinometer or encoder)."""
    stream, _, seconds = text.partition('=')
    try:
        value = float(seconds)
    except ValueError:
        value = float('nan')
    if stream not in ('inclinometer', 'encoder') or not abs(value) <= 1.0:
        raise argparse.ArgumentTypeError(
            f'expected inclinometer=S or encoder=S (s, within +-1), got {text!r}'
        )
    return stream, value


def detector_argument(text: str) -> str:
    """Parse --detector: 'settled'; the removed 'window' is refused naming its successor."""
    from ..core.detection.vocabulary import detector_problem

    problem = detector_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return text


def _redetection_arguments(calibrate: argparse.ArgumentParser) -> None:
    calibrate.add_argument(
        '--detector',
        type=detector_argument,
        default='settled',
        metavar='settled',
        help='when postures are re-detected from raw streams: settled (each stream judged on '
        "its own readings, postures with their scatter), the only detector ('window' was "
        'removed in 0.2.0); default settled',
    )
    calibrate.add_argument(
        '--clock-offset',
        type=clock_offset_argument,
        action='append',
        default=[],
        metavar='STREAM=S',
        help="re-detection: a stream's clock offset against the actuators' (its stamps minus "
        'theirs, s), e.g. inclinometer=0.03 (repeatable); default: estimated from the data',
    )


def redetection_options(args) -> dict:
    """Return postures_from_bag's re-detection options from the calibrate arguments."""
    options: dict = {'detector': args.detector}
    options.update({f'{stream}_clock_offset_s': value for stream, value in args.clock_offset})
    return options


def _bag_info_arguments(info: argparse.ArgumentParser) -> None:
    info.add_argument('bag', type=Path, help='bag directory or .mcap file')
    info.set_defaults(handler=run_bag_info)


def run_calibrate(args) -> int:
    from hexacal_msgs_py.parameters_file import save_parameters

    from ..core.errors import CalibrationError
    from ..core.fit.identification import CONVERGED
    from ..core.machine.measurements import NoiseModel, ScatterFloor
    from ..calibration_steps.bag_postures import postures_from_bag
    from ..calibration_steps.calibration_run import calibrate, device_prior_json
    from ..calibration_steps.machine_files import (
        compliance_file_extras,
        device_defects_extras,
        load_machine_and_mount,
    )
    from ..calibration_steps.posture_checks import (
        check_model,
        link_length_count,
        measurements_from_postures,
    )

    if not (math.isfinite(args.scatter_floor_um) and args.scatter_floor_um > 0):
        raise ValueError(
            f'--scatter-floor-um must be a positive number of um, got {args.scatter_floor_um}'
        )
    nominal, mount = load_machine_and_mount(args.nominal)
    mount = args.mount or mount
    mount_option: dict[str, Any] = {} if mount == 'hanging' else {'mount': mount}
    if args.output.exists() and args.output.is_dir():
        raise IsADirectoryError(f'--output {args.output} is a directory; name a YAML file')
    bag = postures_from_bag(args.bag, **redetection_options(args))
    check_model(bag.model, nominal, f'bag {args.bag}', str(args.nominal))
    noise = NoiseModel.from_microns(args.noise_um) if args.noise_um else None
    compliance = compliance_model(args, bag, nominal)
    try:
        result = calibrate(
            nominal,
            bag.postures,
            cost=args.cost,
            link_length=args.link_length,
            identify_device=args.identify_device,
            noise=noise,
            robust_loss=args.robust,
            mount=mount,
            device_prior=args.device_prior,
            weights=args.weights,
            scatter_floor=ScatterFloor.from_microns(args.scatter_floor_um),
            compliance=compliance,
        )
    except CalibrationError as error:
        if bag.rejected or bag.invalid_messages or bag.notes:  # say what of the bag was not used
            error.args = (f'{error} [bag {args.bag}: {_not_used(bag)}]',)
        raise
    adequacy = result.adequacy
    from hexacal_msgs_py.store_format import FITTED_POSTURES_COMMENT, postures_digest

    comment = (
        f'hexacal calibrate {args.bag} (cost {args.cost}, {len(result.used_postures)} postures, '
        f'{result.reason}), SI units\n{FITTED_POSTURES_COMMENT}{postures_digest(bag.postures)}'
    )
    if result.reason == CONVERGED:
        # The device defects identified with it go along: `hexacal verify` measures with the same
        # device.
        save_parameters(
            args.output,
            result.parameters.vector,
            model=result.parameters.model,
            header_comment=comment,
            extras={**device_defects_extras(result), **compliance_file_extras(result)} or None,
        )
        stored = store_calibration(args, result, bag, mount)
    else:
        stored = None
    # After the calibration is saved: a file the check cannot use loses nothing.
    check = deflection_of(args, bag, result, mount) if result.reason == CONVERGED else None
    measurements = (
        measurements_from_postures(bag.postures, nominal_link_length=args.link_length)
        if args.save_result or args.report
        else None
    )
    extras = {'bag': str(args.bag), 'nominal': str(args.nominal)}
    if args.save_result:
        from ..report.page import save_result

        save_result(
            args.save_result,
            result,
            extras,
            measurements=measurements,
            link_length=args.link_length,
            device_prior=args.device_prior,
            **mount_option,
        )
    if args.report:
        from ..report.page import write_report

        write_report(
            result,
            args.report,
            title=f'hexacal calibration report: {args.bag}',
            extras=extras,
            measurements=measurements,
            link_length=args.link_length,
            device_prior=args.device_prior,
            **mount_option,
        )
    if args.json:
        payload = result.to_json()
        payload['device_prior'] = device_prior_json(
            args.device_prior
        )  # beside device / device_std, SI units
        payload['bag'] = {
            'path': str(args.bag),
            'model': bag.model,
            'postures': len(bag.postures),
            'source': bag.source,
            'ignored_topics': bag.ignored_topics,
            'invalid_messages': bag.invalid_messages,
            'rejected_postures': [
                {'index': i, 'reason': r, 'detail': d} for i, r, d in bag.rejected
            ],
            'notes': list(bag.notes),  # what re-detection noticed, in words
            # Postures with a measured link length L_m (lvdt), which replaced L in eq. 4.
            'postures_with_link_length': link_length_count(bag.postures),
        }
        payload['measuring_mode'] = bag.measuring_mode  # the bag's; None: it does not say
        payload['adequacy'] = adequacy.to_json()
        # With --physical and the rigid model: what its compliances would bias (None: not run).
        payload['deflection_check'] = None if check is None else check.to_json()
        payload['output'] = str(args.output) if result.reason == CONVERGED else None
        # Where it was kept; None: in no store (not asked, or not converged).
        payload['store'] = (
            {'dir': str(_store_root(args, result)), 'id': stored.id}
            if stored is not None
            else None
        )
        print(json.dumps(payload))
    else:
        _print_summary(args, bag, result, adequacy)
        if check is not None:
            print(check.text())
        print(_store_line(args, result, stored))
    return 0 if result.reason == CONVERGED else 1


def _store_root(args, result) -> Path:
    return calibrate_store_dir(args.store, result.parameters.model)


def _store_line(args, result, stored) -> str:
    """Return the line that says where the calibration was kept, or that it was not."""
    from ..core.fit.identification import CONVERGED

    if stored is not None:
        return f'stored as {stored.short_id} ({stored.state}) in {_store_root(args, result)}'
    if result.reason != CONVERGED:
        return 'not stored: the calibration did not converge'
    return (
        'not stored in a calibration store (an offline calibration joins none unasked): '
        "--store keeps it in the machine's store, --store DIR in another"
    )


def _print_summary(args, bag, result, adequacy) -> None:
    from hexacal_msgs_py.models import DEFAULT_MODEL
    import numpy as np

    from ..core.fit.identification import CONVERGED

    model = result.parameters.model
    model_text = '' if model == DEFAULT_MODEL else f' ({model})'  # the default goes unnamed
    print(f'bag {args.bag}{model_text}: {len(bag.postures)} postures from the {bag.source}')
    measuring = _measuring_line(bag)
    if measuring:
        print(measuring)
    if bag.ignored_topics:
        print(f'  ignored topics: {", ".join(bag.ignored_topics)}')
    if bag.invalid_messages:
        print(
            f'  {bag.invalid_messages} invalid message(s) skipped (NaN/inf, missing joints, '
            'mismatched lengths)'
        )
    if bag.rejected:
        print(f"  {len(bag.rejected)} posture(s) set aside (beyond a sensor's range):")
        for index, reason, detail in bag.rejected[:20]:
            print(f'    posture {index}: {reason}: {detail}')
    for note in bag.notes:
        print(f'  {note}')
    # A fit the noise cannot explain is never reported as simply "converged".
    solver = f'{result.reason} in'
    if adequacy.failed:
        solver = (
            f'{result.reason}, but the fit is inadequate: the residuals are '
            f'{adequacy.variance_factor**0.5:.3g} times what the reading noise predicts (see '
            'adequacy below);'
        )
    print(
        f'{solver} {result.iterations} iterations '
        f'({result.solve_seconds * 1e3:.1f} ms), cost {result.cost}, rank {result.rank}, '
        f'condition number {result.condition_number:.3g}'
    )
    print(f'postures used {len(result.used_postures)}, rejected {len(result.rejected_postures)}')
    for index, why in sorted(result.rejected_postures.items()):
        print(f'  posture {index}: {why}')
    print(
        'RMS residual: '
        + ', '.join(
            f'{k} {v * UM:.2f} {"urad" if k.startswith("phi") else "um"}'
            for k, v in result.rms_residual.items()
        )
    )
    correction = (result.parameters.vector - result.initial_parameters.vector) * MM
    print(
        f'largest correction {np.max(np.abs(correction)):.3f} mm, largest std '
        f'{np.nanmax(result.std) * UM:.2f} um'
        + result.parameters.architecture.std_note
    )
    for line in device_prior_lines(result, args.device_prior):
        print(line)
    for line in compliance_lines(result):
        print(line)
    print(f'weights: {result.weights_note or result.weights}')
    for line in adequacy.lines():
        print(line)
    if result.reason == CONVERGED:
        print(f'wrote {args.output}')
    else:
        print(f"not written: the solver stopped with '{result.reason}'", file=sys.stderr)


def device_prior_lines(result, prior) -> list[str]:
    """Return prior vs identified value of each identified device defect (um / urad lines)."""
    import numpy as np

    from ..core.machine.device import DEVICE_PARAMETER_NAMES

    if not result.free_device:
        return []
    lines = ['device parameters (prior -> identified; dL in um, angles in urad):']
    for index, name in enumerate(DEVICE_PARAMETER_NAMES):
        if name not in result.free_device:
            continue
        unit = 'um' if name == 'dL' else 'urad'
        given = prior.get(name) if prior is not None else None
        prior_text = (
            'none' if given is None else f'{given[0] * UM:.3f} +- {given[1] * UM:.3f} {unit}'
        )
        std = result.device_std[index]
        std_text = f'{std * UM:.3f}' if np.isfinite(std) else 'n/a'
        lines.append(
            f'  {name}: prior {prior_text}, identified {result.device.vector[index] * UM:.3f} +- '
            f'{std_text} {unit}'
        )
    return lines


def _measuring_line(bag) -> str:
    """Return the measuring mode line ('' when the bag does not record its mode)."""
    from ..calibration_steps.posture_checks import link_length_count

    measured = link_length_count(bag.postures)
    if bag.measuring_mode is None and not measured:
        return ''
    mode = bag.measuring_mode or 'not recorded'
    lengths = (
        f', {measured} of {len(bag.postures)} postures with a measured link length L_m '
        '(used in eq. 4)'
        if measured
        else ''
    )
    return f'  measuring mode: {mode}{lengths}'


def _not_used(bag) -> str:
    parts = []
    if bag.invalid_messages:
        parts.append(f'{bag.invalid_messages} invalid message(s) skipped')
    if bag.rejected:
        reasons: dict[str, int] = {}
        for _, reason, _ in bag.rejected:
            reasons[reason] = reasons.get(reason, 0) + 1
        parts.append(
            f'{len(bag.rejected)} posture(s) set aside ('
            + ', '.join(f'{n} {r}' for r, n in sorted(reasons.items()))
            + ')'
        )
    parts.extend(bag.notes)
    return '; '.join(parts)


def run_bag_info(args) -> int:
    from ..bag import open_bag
    from ..calibration_steps.bag_postures import postures_from_bag

    info = open_bag(args.bag).info()
    print(info.format())
    try:
        bag = postures_from_bag(args.bag)
    except Exception as error:  # the bag is readable but holds no usable postures: say why
        print(f'Postures:          none usable ({error})')
        return 0
    print(f'Postures:          {len(bag.postures)} (from the {bag.source})')
    for key, value in sorted(bag.plan.items()):
        print(f'Recorded:          {key} = {value}')
    for line in _posture_lines(bag):
        print(line)
    return 0


def _posture_lines(bag) -> list[str]:
    """Return per posture its released actuator and measured link length, where recorded."""
    measuring = bag.measuring
    if measuring.mode is None and not measuring.released and not any(
        p.link_length is not None for p in bag.postures
    ):
        return []  # a bag of before the measuring modes: nothing to say
    lines = [f'Measuring mode:    {measuring.mode or "not recorded"}']
    for index, posture in enumerate(bag.postures, start=1):
        released = measuring.released_at(posture.stamp_ns) or 'none'
        length = (
            f', link_length {posture.link_length:.6f} m' if posture.link_length is not None else ''
        )
        lines.append(f'Posture {index:<10} released actuator {released}{length}')
    return lines
