"""
``hexacal verify``: verification without ground truth, offline from a bag.

``hexacal verify BAG --nominal N --calibrated C``: verification without ground truth, offline from
a bag.

The bag holds fresh postures, never used in the fit (a second, verification plan
walked after the calibration). For each, what the device measured (position by
eq. 4, the fixed point for a fixed-position posture; phi from the rotary sensor)
is compared with forward kinematics at the measured actuator readings, once with
the nominal and once with the calibrated parameters (core/assessment/verification.py). The
device measures through the defects identified with the calibration (the
calibrated file's `device.defects.<name>` keys) unless --device-defects names others.
A calibration that carries axial compliances (its `compliance.*` keys) is verified with
the static loads of each posture (core/fit/compliance.py): the weights of --physical FILE,
else of the model's shipped physical description (said in the output).

Exit codes: 0 pass (calibrated position rms <= threshold, FK converged on every
posture), 1 fail, 2 bad input (one line on stderr naming the problem).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from .store import add_verify_arguments, attach_verification, store_dir

# numpy, the bag reader and the core are imported where they run: this module is imported by every
# `hexacal` start-up to register the command.
UM = 1e6
EXIT_PASS, EXIT_FAIL = 0, 1


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        'verify',
        help='verify a calibration on fresh postures of a bag, without ground truth',
        description=(
            'Compare what the measuring device measured at fresh postures '
            '(not used in the fit) with forward kinematics at the measured actuator readings, '
            'for the nominal and the calibrated parameters: position error rms/max (m) and '
            'rotary error rms (rad), the improvement (nominal rms / calibrated rms) and a '
            'verdict: pass when the calibrated position rms is within the threshold and forward '
            'kinematics converged on every posture. Exit code 0 pass, 1 fail, 2 bad input.'
        ),
        fill=_verify_arguments,
    )


def _verify_arguments(parser: argparse.ArgumentParser) -> None:
    from ..core.machine.device import DEFAULT_LINK_LENGTH_M
    from ..core.assessment.verification import DEFAULT_THRESHOLD_M, NOISE_THRESHOLD_FACTOR

    parser.add_argument(
        'bag', type=Path, help='bag directory or .mcap file with the verification postures'
    )
    parser.add_argument(
        '--nominal',
        type=Path,
        required=True,
        help='nominal parameters YAML (what the machine was believed to be before calibrating)',
    )
    parser.add_argument(
        '--calibrated',
        type=Path,
        required=True,
        help="calibrated parameters YAML (hexacal calibrate --output, identify's output)",
    )
    parser.add_argument(
        '--threshold-um',
        type=float,
        default=None,
        help='pass when the calibrated position rms is at most this (um); default '
        f'{NOISE_THRESHOLD_FACTOR:g} x the rms the reading noise alone gives with --noise-um, '
        f'else {DEFAULT_THRESHOLD_M * UM:g} um',
    )
    parser.add_argument(
        '--noise-um',
        type=float,
        default=None,
        help='reading noise half-width (um on actuators, urad on angles): report the residual it '
        'alone gives, and set the default threshold from it',
    )
    parser.add_argument(
        '--link-length',
        type=float,
        default=DEFAULT_LINK_LENGTH_M,
        help=f'device link length L in m (default {DEFAULT_LINK_LENGTH_M})',
    )
    parser.add_argument(
        '--mount',
        choices=('hanging', 'standing'),
        default=None,
        help="device mount; default: the nominal (else the calibrated) file's device.mount, "
        'else hanging',
    )
    parser.add_argument(
        '--device-defects',
        default=None,
        metavar='D',
        help="the measuring device's defects, SI ('dL=5e-4,alpha0=2e-4'; 'none': an ideal "
        "device); default: those identified with the calibration (the calibrated file's "
        'device.defects.* keys), the same device measuring again',
    )
    parser.add_argument(
        '--physical',
        type=Path,
        default=None,
        metavar='FILE',
        help='physical description YAML (gravity, platform {mass, com}, payload {mass, com}, '
        'legs {mass, com_fraction}, link {mass, com_fraction}; SI units): the weights that load '
        "the chains and the link of a calibration with compliances (the calibrated file's "
        "compliance.* keys); default: the model's shipped physical description",
    )
    parser.add_argument(
        '--report',
        type=Path,
        default=None,
        metavar='DIR',
        help='write an HTML page (index.html + verification.png) into DIR',
    )
    parser.add_argument('--json', action='store_true', help='print the result as one JSON object')
    add_verify_arguments(parser)
    parser.set_defaults(handler=run_verify)


def run_verify(args) -> int:
    from ..core.machine.device import DeviceModel
    from ..core.machine.measurements import NoiseModel
    from ..core.assessment.verification import PASS, verify
    from ..calibration_steps.bag_postures import postures_from_bag
    from ..calibration_steps.machine_files import load_machine_and_mount
    from ..calibration_steps.posture_checks import check_model, measurements_from_postures

    if args.threshold_um is not None and not (
        math.isfinite(args.threshold_um) and args.threshold_um > 0
    ):
        raise ValueError(
            f'--threshold-um must be a positive number of um, got {args.threshold_um}'
        )
    if args.noise_um is not None and not (math.isfinite(args.noise_um) and args.noise_um > 0):
        raise ValueError(f'--noise-um must be a positive number of um, got {args.noise_um}')
    nominal, nominal_mount = load_machine_and_mount(args.nominal)
    calibrated, calibrated_mount = load_machine_and_mount(args.calibrated)
    mount = args.mount or (nominal_mount if nominal_mount != 'hanging' else calibrated_mount)
    bag = postures_from_bag(args.bag)
    check_model(bag.model, nominal, f'bag {args.bag}', str(args.nominal))
    if not bag.postures:
        raise ValueError(
            f'bag {args.bag} holds no usable posture to verify on'
            + (f" ({len(bag.rejected)} set aside beyond a sensor's range)" if bag.rejected else '')
        )
    defects, defects_source = _device_defects(args)
    compliance, compliance_payload = calibrated_compliance(args, bag, calibrated)
    result = verify(
        nominal,
        calibrated,
        measurements_from_postures(bag.postures, nominal_link_length=args.link_length),
        device=DeviceModel(link_length=args.link_length, mount=mount),
        calibrated_defects=defects,
        threshold_m=None if args.threshold_um is None else args.threshold_um / UM,
        noise=NoiseModel.from_microns(args.noise_um) if args.noise_um else None,
        postures_model=bag.model,
        calibrated_compliance=compliance,
    )
    payload = result.to_json()
    payload['bag'] = {
        'path': str(args.bag),
        'source': bag.source,
        'invalid_messages': bag.invalid_messages,
        'rejected_postures': [{'index': i, 'reason': r, 'detail': d} for i, r, d in bag.rejected],
    }
    payload['nominal_file'], payload['calibrated_file'] = str(args.nominal), str(args.calibrated)
    payload['device_defects'] = {
        'values': {name: getattr(defects, name) for name in defects_source[1]},
        'source': defects_source[0],
    }
    payload['compliance'] = compliance_payload
    if args.report:
        from ..report.page import write_verification_report

        page = write_verification_report(
            {
                **result.to_json(per_posture=True),
                'source': f'bag {args.bag} ({bag.source})',
                'nominal_file': str(args.nominal),
                'calibrated_file': str(args.calibrated),
            },
            args.report,
            title=f'hexacal verification report: {args.bag}',
        )
        payload['report'] = str(page)
    fitted = fitted_on(args, bag, calibrated.model)
    # A calibration fits its own postures by construction: that verification tells nothing.
    payload['fitted_postures'] = fitted or None
    stored = None if fitted else attach_verification(args, payload, bag, calibrated.model)
    if stored is not None:
        payload['store'] = stored
    if args.json:
        print(json.dumps(payload, allow_nan=False))
    else:
        _print_table(args, bag, payload)
        if fitted:
            print(
                'does not count: these are the postures the calibration was fitted to '
                f'({fitted}); a calibration fits its own postures by construction, so this says '
                'nothing of other poses - verify on a recording it was not fitted to'
                + (' (not attached to the store)' if args.store or args.id else '')
            )
        if stored is not None:
            print(f'attached to {stored["id"][:8]} ({stored["state"]}) in {stored["dir"]}')
    return EXIT_PASS if result.verdict == PASS else EXIT_FAIL


def fitted_on(args, bag, model: str) -> str:
    """
    Return how the bag's postures are known to be those the calibration was fitted to, or ''.

    The --calibrated file's header names the postures it was fitted to (``hexacal calibrate``
    and the identify node write it); a file without it is looked up in the store (--store,
    else the model's default store, read only), whose entry records them.
    """
    from hexacal_msgs_py import store_format as fmt

    verified = fmt.postures_digest(bag.postures)
    if fmt.fitted_postures_digest(args.calibrated) == verified:
        return f'its file {args.calibrated} names them'
    from ..store import CalibrationStore, StoreError

    root = store_dir(args.store, model)
    if not root.is_dir():
        return ''
    try:
        entry = CalibrationStore(root).find_digest(fmt.file_digest(args.calibrated))
    except (StoreError, OSError):
        return ''  # attaching names a bad store; an unreadable one says nothing here
    if entry is not None and entry.record.get(fmt.RECORD_POSTURES_DIGEST) == verified:
        return f'store entry {entry.short_id} in {root} records them'
    return ''


def calibrated_compliance(args, bag, calibrated):
    """
    Return the calibration's compliances for verify() (None: rigid) and what the output says.

    ((ComplianceModel, values) or None, {'values': m/N, 'mode', 'physical': where the weights
    come from}) of the calibrated file's compliance section, loaded through the bag's measuring
    mode (passive_actuator: each posture's released chain) by the weights of --physical, else
    of the model's shipped physical description.
    """
    from hexacal_msgs_py.parameters_file import compliances_from_extras, read_parameters_file

    values = compliances_from_extras(read_parameters_file(args.calibrated).extras)
    if not values:
        physical = 'not used: the calibration carries no compliances (rigid)'
        if args.physical is None:
            physical = ''
        return None, {'values': {}, 'mode': 'none', 'physical': physical}
    from ..calibration_steps.calibration_run import drive_stiffness_of, identified_compliance
    from ..core.fit.statics import physical_weights

    masses, physical = physical_weights(str(args.physical or ''), calibrated.model)
    if args.physical is not None:
        physical = f'--physical {args.physical}'
    else:
        physical += ' (no --physical given: the weights of your machine may differ)'
    mode = bag.measuring_mode
    released = bag.released_joints
    model, vector = identified_compliance(
        values,
        masses,
        mode,
        released,
        calibrated.layout.actuator_names,
        f'the calibration {args.calibrated} carries compliances:',
        drive_stiffness_of(args.physical, calibrated.model),
    )
    return (model, vector), {'values': values, 'mode': model.mode, 'physical': physical}


def _device_defects(args):
    """
    Return the defects of the device that measured the bag, and where they come from.

    (defects, (where they come from, names given)) of the device that measured the bag: the
    --device-defects option, else those identified with the calibration (calibrated file).
    """
    from ..core.machine.device import DEVICE_PARAMETER_NAMES, DeviceDefects
    from ..calibration_steps.machine_files import load_device_defects

    if args.device_defects is None:
        defects, names = load_device_defects(args.calibrated)
        return defects, ('calibrated file' if names else 'none (ideal device)', names)
    if args.device_defects.strip().lower() == 'none':
        return DeviceDefects(), ('--device-defects none (ideal device)', ())
    try:
        defects = DeviceDefects.parse(args.device_defects)
    except ValueError as error:
        raise ValueError(f'--device-defects: {error}') from None
    return defects, (
        '--device-defects',
        tuple(n for n in DEVICE_PARAMETER_NAMES if getattr(defects, n)),
    )


def _print_table(args, bag, payload: dict) -> None:
    def cell(value, scale: float) -> str:
        return 'n/a' if value is None else f'{value * scale:.2f}'

    print(
        f'verification of {args.bag} ({payload["model"]}, {payload["postures"]} postures from the '
        f'{bag.source})'
    )
    if bag.rejected:
        print(f"  {len(bag.rejected)} posture(s) set aside (beyond a sensor's range)")
    nominal, calibrated = payload['nominal'], payload['calibrated']
    device = payload['device_defects']
    if device['values']:
        from ..core.machine.device import DEVICE_PARAMETER_NAMES, DEVICE_PARAMETER_UNITS

        units = dict(zip(DEVICE_PARAMETER_NAMES, DEVICE_PARAMETER_UNITS))
        print(
            '  measuring device ('
            + device['source']
            + '): '
            + ', '.join(
                f'{name} {value * UM:.2f} {"um" if units[name] == "m" else "urad"}'
                for name, value in device['values'].items()
            )
        )
    else:
        print(f'  measuring device: {device["source"]}')
    compliance = payload['compliance']
    if compliance['values']:
        print(
            '  compliances (calibrated file): '
            + ', '.join(f'{name} {value:.4g}' for name, value in compliance['values'].items())
            + f' m/N; weights of {compliance["physical"]}'
        )
    elif compliance['physical']:
        print(f'  --physical {compliance["physical"]}')
    print(f'  {"":22s}{"nominal":>14s}{"calibrated":>14s}')
    for label, key, scale in (
        ('position rms [um]', 'position_rms_m', UM),
        ('position max [um]', 'position_max_m', UM),
        ('rotary rms [urad]', 'rotary_rms_rad', UM),
    ):
        print(f'  {label:22s}{cell(nominal[key], scale):>14s}{cell(calibrated[key], scale):>14s}')
    print(f'  {"FK failures":22s}{nominal["fk_failures"]:>14d}{calibrated["fk_failures"]:>14d}')
    for name, figures in (('nominal', nominal), ('calibrated', calibrated)):
        for failure in figures['failed_postures'][:10]:
            print(f'    {name}: posture {failure["index"]}: {failure["reason"]}')
    improvement = payload['improvement']
    print(
        f'improvement: {"n/a" if improvement is None else f"{improvement:.1f}x"} (nominal rms / '
        'calibrated rms)'
    )
    noise = payload.get('expected_noise')
    if noise and noise.get('position_rms_m') is not None:
        print(
            f'expected from the reading noise alone: {noise["position_rms_m"] * UM:.2f} um, '
            f'{noise["rotary_rms_rad"] * UM:.2f} urad'
        )
    print(f'threshold: {payload["threshold_m"] * UM:.2f} um ({payload["threshold_source"]})')
    print(f'verdict: {payload["verdict_reason"]}')
    if payload.get('report'):
        print(f'wrote {payload["report"]}')
