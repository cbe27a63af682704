"""
``hexacal``: the command-line tool (study, parameter files, offline calibration from bags).

Exit codes: 0 success; 1 the calibration ran but did not converge (verify: fail; deploy:
refused by a check); 2 bad input or a refused calibration (one line on stderr naming the
problem, no traceback).
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys
from typing import cast

from . import study as cli_study
from .command_line import LazySubcommands

EXIT_OK, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2


def _add_params_parser(subparsers) -> None:
    subparsers.add_parser(
        'params',
        help="write a parameters YAML: a model's default machine (Table 1) or a nominal set 1-3",
        description='Write a ROS 2 parameters YAML (SI units) for the default machine of a '
        'model (the Hexa Slide of Table 1, or the default Gough-Stewart platform) or one of '
        "its nominal sets (the default machine + seeded errors with Table 2's statistics).",
        fill=_params_arguments,
    )


def _params_arguments(parser: argparse.ArgumentParser) -> None:
    from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS

    parser.add_argument(
        'which',
        choices=('table1', 'default', 'nominal'),
        help="table1: the exact Table 1 Hexa Slide; default: the model's default machine "
        '(Table 1 for hexa_slide); nominal: a nominal set',
    )
    parser.add_argument(
        '--model',
        choices=tuple(MODELS),
        default=DEFAULT_MODEL,
        help=f'machine model (default {DEFAULT_MODEL})',
    )
    parser.add_argument(
        '--set', type=int, choices=(1, 2, 3), default=2, help='nominal set (default 2)'
    )
    parser.add_argument(
        '--seed', type=int, default=0, help='seed of the nominal errors (default 0)'
    )
    parser.add_argument('--out', type=Path, required=True, help='output YAML file')
    parser.set_defaults(handler=_write_params)


def _write_params(args) -> int:
    from hexacal_msgs_py.parameters_file import save_parameters

    from ..core.architectures import architecture
    from ..core.machine.model import nominal_set

    arch = architecture(args.model)
    # `table1` names the Hexa Slide's default machine (its default_machine_alias) only.
    if args.which == 'table1' and arch.default_machine_alias != args.which:
        raise ValueError(
            f"table1 is the Hexa Slide of Rauf, Kim, Ryu's Table 1, not a {args.model}; "
            f'write `default` for the default {args.model} machine'
        )
    if args.which in ('table1', 'default'):
        params = arch.default_parameters()
        comment = default_machine_comment(args.model, params.vector)
    else:
        params = nominal_set(args.set, seed=args.seed, model=args.model)
        comment = (
            f'nominal set {args.set} ({arch.machine_label} + errors with Table 2 statistics, '
            f'seed {args.seed}), SI units'
        )
    save_parameters(args.out, params.vector, header_comment=comment, model=args.model)
    print(f'wrote {args.out}')
    return EXIT_OK


def default_machine_comment(model: str, vector) -> str:
    """Return the header comment of the default-machine file of `model` (as data/ ships it)."""
    from ..core.architectures import architecture

    arch = architecture(model)
    return arch.default_machine_comment(arch.parameters(vector))


def build_parser(fill: bool = True) -> argparse.ArgumentParser:
    """
    Build the whole ``hexacal`` parser.

    With fill=False a command's arguments are added when it is chosen.

    main() parses with fill=False, so a command imports only the modules its own options and
    handler need (see cli.command_line.LazySubcommands) and `hexacal --help` imports none of them.
    """
    parser = argparse.ArgumentParser(
        prog='hexacal',
        description='Kinematic calibration of six-leg parallel manipulators: Hexa Slide, '
        'Gough-Stewart (ROS 2).',
    )
    # typeshed types add_subparsers as the base action, whatever `action` makes it.
    subparsers = cast(
        LazySubcommands,
        parser.add_subparsers(
            dest='command', required=True, metavar='COMMAND', action=LazySubcommands
        ),
    )
    cli_study.add_parser(subparsers)
    _add_params_parser(subparsers)
    for module_name in (
        'calibrate',
        'demo',
        'plan_report',
        'export',
        'verify',
        'kinematics_commands',
        'store',
    ):
        module = _optional_module(module_name)
        if module is not None:
            module.add_parsers(subparsers)
    if fill:
        subparsers.fill_all()
    return parser


def _full(name: str) -> str:
    return name if name.startswith('hexacal_identify.') else f'{__package__}.{name}'


def _optional_module(name: str):
    import importlib

    try:
        return importlib.import_module(_full(name))
    except ModuleNotFoundError as error:
        if error.name == _full(name):
            return None
        raise


def _named_errors() -> tuple[type[BaseException], ...]:
    """Errors that mean bad input: reported in one line, exit code 2."""
    from hexacal_msgs_py.errors import HexacalContractError

    from ..core.errors import CalibrationError

    errors: list[type[BaseException]] = [
        HexacalContractError,
        CalibrationError,
        FileNotFoundError,
        NotADirectoryError,
        IsADirectoryError,
        PermissionError,
        ValueError,
    ]
    bag = _optional_module('hexacal_identify.bag')
    if bag is not None and hasattr(bag, 'BagError'):
        errors.append(bag.BagError)
    store = _optional_module('hexacal_identify.store')
    if store is not None:  # a bad store, an unknown id, nothing to roll back to
        errors.append(store.StoreError)
    return tuple(errors)


def main(argv: list[str] | None = None) -> int:
    args = build_parser(fill=False).parse_args(argv)
    try:
        return int(args.handler(args))
    except _named_errors() as error:
        print(f'hexacal {args.command}: error: {_one_line(error)}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f'hexacal {args.command}: interrupted', file=sys.stderr)
        return 130


def _one_line(error: BaseException) -> str:
    text = str(error) or type(error).__name__
    return ' | '.join(line.strip() for line in text.splitlines() if line.strip())


if __name__ == '__main__':
    sys.exit(main())
