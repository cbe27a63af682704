"""
``hexacal history``, ``hexacal deploy ID``, ``hexacal rollback``: the calibration store.

Also what ``hexacal calibrate`` and ``hexacal verify`` use to add a calibration and attach a
verification.  Exit codes: 0 ok, 1 refused (a deploy refused by a check), 2 bad input (an
unknown id, a bad store, nothing to roll back to).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

# The store is imported where it runs: this module is imported by every `hexacal` start-up.
EXIT_OK, EXIT_REFUSED = 0, 1


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        'history',
        help='list the calibration store: every calibration, its state and verdict',
        description='List the calibrations of a store, oldest first: short id, time (UTC), '
        'state (stored / verified / active / forced / rolled-back), verification verdict, '
        'cost, postures and where they came from.',
        fill=_history_arguments,
    )
    subparsers.add_parser(
        'deploy',
        help='make a verified calibration the active one',
        description='Make a stored calibration the active one (what the kinematics node '
        'uses). Refused (exit 1) without a verification verdict pass on postures not used in '
        'its fit, or when it is a surprising jump from the active calibration (largest '
        'parameter change, largest platform position change over the workspace); --force '
        'deploys anyway and is recorded as forced.',
        fill=_deploy_arguments,
    )
    subparsers.add_parser(
        'rollback',
        help='return to the previously active calibration',
        description='Make the calibration active before the current one active again; the one '
        'left is recorded as rolled-back.',
        fill=_rollback_arguments,
    )


def add_store_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """Add ``--store DIR`` (default: the machine model's store, default_store_dir)."""
    parser.add_argument(
        '--store',
        type=Path,
        default=None,
        metavar='DIR',
        help=f'calibration store directory {what} (default: $HEXACAL_STORE/<model> if set, '
        'else ~/.local/share/hexacal/calibrations/<model>)',
    )


def _model_argument(parser: argparse.ArgumentParser) -> None:
    from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS

    parser.add_argument(
        '--model',
        choices=tuple(MODELS),
        default=DEFAULT_MODEL,
        help=f'machine model whose default store to use without --store (default {DEFAULT_MODEL})',
    )


def _history_arguments(parser: argparse.ArgumentParser) -> None:
    add_store_argument(parser, 'to list')
    _model_argument(parser)
    parser.add_argument('--json', action='store_true', help='print a JSON list of the entries')
    parser.set_defaults(handler=run_history)


def _deploy_arguments(parser: argparse.ArgumentParser) -> None:
    from ..store import DEFAULT_MAX_PARAMETER_CHANGE_M, DEFAULT_MAX_POSE_CHANGE_M

    parser.add_argument('id', help='the id of the calibration (or a unique prefix, 4+ hex)')
    add_store_argument(parser, 'holding it')
    _model_argument(parser)
    parser.add_argument(
        '--force',
        action='store_true',
        help='deploy even if unverified or a surprising jump (recorded as forced)',
    )
    parser.add_argument(
        '--max-parameter-change-mm',
        type=float,
        default=DEFAULT_MAX_PARAMETER_CHANGE_M * 1e3,
        help='refuse when a length parameter changes more than this from the active calibration '
        f'(mm, default {DEFAULT_MAX_PARAMETER_CHANGE_M * 1e3:g})',
    )
    parser.add_argument(
        '--max-pose-change-mm',
        type=float,
        default=DEFAULT_MAX_POSE_CHANGE_M * 1e3,
        help='refuse when the platform moves more than this at the same actuator readings over '
        f'the workspace (mm, default {DEFAULT_MAX_POSE_CHANGE_M * 1e3:g})',
    )
    parser.set_defaults(handler=run_deploy)


def _rollback_arguments(parser: argparse.ArgumentParser) -> None:
    add_store_argument(parser, 'to roll back')
    _model_argument(parser)
    parser.add_argument('--json', action='store_true', help='print the restored entry as JSON')
    parser.set_defaults(handler=run_rollback)


def store_dir(store: Path | None, model: str) -> Path:
    """Return --store, else the default store of `model`."""
    from ..store import default_store_dir

    return store if store is not None else default_store_dir(model)


def entry_json(entry, active_since: str | None = None) -> dict:
    """Return an entry as ``hexacal history --json`` prints it."""
    from hexacal_msgs_py import store_format as fmt

    record = entry.record
    fit = record.get(fmt.RECORD_FIT) or {}
    return {
        'id': entry.id,
        'short_id': entry.short_id,
        'time': entry.time,
        'state': str(entry.state),
        'verdict': entry.verdict,
        'active': entry.active,
        'active_since': active_since,
        'digest': entry.digest,
        'parameters': str(entry.parameters_path),
        'model': record.get(fmt.RECORD_MODEL),
        'cost': record.get(fmt.RECORD_COST),
        'rank': fit.get(fmt.FIT_RANK),
        'postures': record.get(fmt.RECORD_POSTURES_COUNT),
        'source': record.get(fmt.RECORD_SOURCE),
        'record': record,
    }


def _origin(record: dict) -> str:
    from hexacal_msgs_py import store_format as fmt

    bag = record.get(fmt.RECORD_BAG)
    if isinstance(bag, dict) and bag.get('path'):
        return Path(bag['path']).name
    return str(record.get(fmt.RECORD_SOURCE) or '-')


def run_history(args) -> int:
    from ..store import CalibrationStore

    store = CalibrationStore(store_dir(args.store, args.model))
    entries = store.entries()
    activation = store.activation()
    since = {activation.entry.id: activation.since} if activation else {}
    if args.json:
        print(json.dumps([entry_json(e, since.get(e.id)) for e in entries], allow_nan=False))
        return EXIT_OK
    if not entries:
        print(f'no calibrations in {store.root}')
        return EXIT_OK
    print(f'calibration store {store.root}')
    print(
        f'  {"id":8s}  {"time (UTC)":19s}  {"state":11s}  {"verdict":7s}  {"cost":12s}  '
        f'{"postures":>8s}  from'
    )
    for entry in entries:
        record = entry.record
        postures = record.get('postures')
        time = entry.time[:19].replace('T', ' ')
        print(
            f'{"*" if entry.active else " "} {entry.short_id:8s}  {time:19s}'
            f'  {entry.state:11s}  {entry.verdict or "-":7s}  {record.get("cost") or "-":12s}  '
            f'{"-" if postures is None else postures:>8}  {_origin(record)}'
        )
    if activation is not None:
        print(
            f'active: {activation.entry.short_id} since {activation.since[:19].replace("T", " ")}'
            f' UTC ({activation.reason})'
        )
    else:
        print('active: none deployed')
    return EXIT_OK


def run_deploy(args) -> int:
    from ..store import CalibrationStore, DeployRefused

    for name in ('max_parameter_change_mm', 'max_pose_change_mm'):
        value = getattr(args, name)
        if not value > 0:
            raise ValueError(f'--{name.replace("_", "-")} must be positive, got {value}')
    store = CalibrationStore(store_dir(args.store, args.model))
    try:
        entry = store.deploy(
            args.id,
            force=args.force,
            max_parameter_change_m=args.max_parameter_change_mm / 1e3,
            max_pose_change_m=args.max_pose_change_mm / 1e3,
        )
    except DeployRefused as refused:
        print(f'hexacal deploy: {refused}', file=sys.stderr)
        return EXIT_REFUSED
    activation = store.activation()
    print(f'deployed {entry.short_id} ({entry.state}) in {store.root}: {entry.parameters_path}')
    if activation is not None and activation.entry.id == entry.id:
        print(f'active since {activation.since} ({activation.reason})')
    return EXIT_OK


def run_rollback(args) -> int:
    from ..store import CalibrationStore

    store = CalibrationStore(store_dir(args.store, args.model))
    left = store.active()
    entry = store.rollback()
    if args.json:
        print(json.dumps(entry_json(entry), allow_nan=False))
        return EXIT_OK
    print(
        f'rolled back to {entry.short_id} ({entry.state})'
        + (f'; {left.short_id} is rolled-back' if left is not None else '')
        + f': {entry.parameters_path}'
    )
    return EXIT_OK


# `hexacal calibrate --store` without a directory: the machine model's default store.
MODEL_STORE = Path('<the store of the machine model>')


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--store [DIR]`` and ``--no-store`` to ``hexacal calibrate``."""
    parser.add_argument(
        '--store',
        type=Path,
        nargs='?',
        const=MODEL_STORE,
        default=None,
        metavar='DIR',
        help='keep the calibration, with its provenance, in this calibration store; --store '
        "alone: the machine model's store ($HEXACAL_STORE/<model> if set, else "
        '~/.local/share/hexacal/calibrations/<model>), the one the nodes deploy from. Default: '
        'not kept (an offline calibration joins no store unasked)',
    )
    parser.add_argument(
        '--no-store',
        action='store_true',
        help='do not keep the calibration in a store (the default; kept for scripts that say it)',
    )


def store_calibration(args, result, bag, mount: str):
    """
    Keep a converged calibration (the --output file) in the store asked for; the entry or None.

    Only with --store (DIR, or alone: the model's default store); a StoreError is bad input.
    Without it nothing is kept: an offline calibration does not join the machine's history.
    """
    from ..calibration_steps.calibration_run import device_prior_json
    from ..store import CalibrationStore
    from ..store.provenance import calibration_record

    if args.no_store and args.store is not None:
        raise ValueError('--store and --no-store contradict each other; give one')
    if args.store is None:
        return None
    store = CalibrationStore(calibrate_store_dir(args.store, result.parameters.model))
    record = calibration_record(
        result,
        source='hexacal calibrate',
        postures=bag.postures,
        nominal_file=args.nominal,
        noise=None if not args.noise_um else _noise(args.noise_um),
        robust_loss=args.robust,
        link_length=args.link_length,
        mount=mount,
        device_prior=device_prior_json(args.device_prior),
        bag=args.bag,
    )
    return store.add(args.output, record)


def calibrate_store_dir(store: Path | None, model: str) -> Path:
    """Return the directory ``hexacal calibrate --store [DIR]`` keeps a `model` calibration in."""
    return store_dir(None if store == MODEL_STORE else store, model)


def _noise(microns: float):
    from ..core.machine.measurements import NoiseModel

    return NoiseModel.from_microns(microns)


def add_verify_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--store DIR`` and ``--id ID`` to ``hexacal verify``."""
    add_store_argument(parser, 'holding the calibration (with --id)')
    parser.add_argument(
        '--id',
        default=None,
        metavar='ID',
        help='attach the verification figures to this store entry (an id or unique prefix; '
        'the --calibrated file must be its parameters file); with --store alone, the entry '
        'whose parameters file --calibrated is',
    )


def attach_verification(args, payload: dict, bag, model: str):
    """
    Attach a verification (the ``hexacal verify --json`` payload) to its store entry.

    Only when --store or --id is given; return the store's dir, the entry's id and state then
    (the ``store`` key of the JSON output), else None.  The figures carry
    the digest of the verified postures and of the --calibrated file (the entry's, or a
    StoreError).
    """
    from hexacal_msgs_py import store_format as fmt

    from ..store import CalibrationStore, StoreError

    if args.store is None and args.id is None:
        return None
    store = CalibrationStore(store_dir(args.store, model))
    calibrated = fmt.file_digest(args.calibrated)
    if args.id is None:
        entry = store.find_digest(calibrated)
        if entry is None:
            raise StoreError(
                f'no entry of calibration store {store.root} holds {args.calibrated}; name it '
                'with --id'
            )
        entry_id = entry.id
    else:
        entry_id = args.id
    figures = {
        **payload,
        fmt.VERIFICATION_CALIBRATED_DIGEST: calibrated,
        fmt.VERIFICATION_POSTURES_DIGEST: fmt.postures_digest(bag.postures),
    }
    entry = store.attach_verification(entry_id, figures)
    return {'dir': str(store.root), 'id': entry.id, 'state': str(entry.state)}
