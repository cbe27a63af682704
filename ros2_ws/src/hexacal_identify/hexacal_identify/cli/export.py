"""
``hexacal export``: write a parameters file for a controller or as YAML / JSON.

A parameters file in a controller's format (LinuxCNC genhexkins) or as YAML / JSON.

``--format linuxcnc`` writes the HAL ``setp`` lines of LinuxCNC's generalised
hexapod kinematics (``genhexkins``) for a Gough-Stewart result::

    setp genhexkins.base.N.x|y|z       base joint of leg N+1, base (world) frame   = hexacal's A
    setp genhexkins.platform.N.x|y|z   platform joint of leg N+1, platform frame   = hexacal's B

in the chosen length unit (default mm, LinuxCNC's usual LINEAR_UNITS), and the
six leg offsets l0 as commented ``[JOINT_N] HOME_OFFSET`` lines: genhexkins'
joints are strut lengths, so a joint homed where its actuator reads zero has
position l0.  genhexkins computes the strut as ``|p + R a - b|`` with a the
platform and b the base joint, the same closure as hexacal's
``|p + R B - A| = lambda + l0``, so the points carry over unchanged.  Beside
the HAL file (``NAME.hal``) it writes the INI fragment ``NAME.ini``
(export_linuxcnc.py): ``[KINS]``, ``[TRAJ] HOME`` (a start of genhexkins'
forward kinematics on the working branch) and per joint the limits and homes
as strut lengths (``--home-pose``, ``--home-actuators``, ``--stroke``).  A Hexa
Slide has no genhexkins description and is refused.

``--format controller`` writes a self-describing JSON a custom controller
reads, ``--format kinematics-node`` the kinematics node's parameters file and
the parameters it names (export_controller.py); either model.

``--format mjcf`` writes the machine as a MuJoCo model (physics/mjcf.py, the simulated
machine's own writer) with the measuring device, the payload and the physical description
(``--physical FILE``, hexacal_msgs_py.physical_file; default: the model's shipped machine),
assembled at the workspace centre: open it in MuJoCo's viewer (``python -m mujoco.viewer
--mjcf NAME.xml``) or simulate it.

``--format yaml`` writes the parameters file format (SI units, its model, its
other parameters); ``--format json`` writes ``{"model": ..., "parameters":
{chain_1: {...}, ...}}`` (the chain dict of ``hexacal calibrate --json``).
Every write is atomic; bad input writes nothing.

This module is imported by every ``hexacal`` start-up to register the command:
its top level uses the standard library only.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
import sys

FORMATS = ('linuxcnc', 'yaml', 'json', 'controller', 'kinematics-node', 'mjcf')
LENGTH_UNITS = {'mm': 1e3, 'm': 1.0}
# Decimals written per unit: 1 nm either way, far below what a calibration resolves.
_DECIMALS = {'mm': 6, 'm': 9}
AXES = ('x', 'y', 'z')


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        'export',
        help='write a parameters file for a controller (LinuxCNC genhexkins HAL) or as YAML / '
        'JSON',
        description='Read a parameters YAML (e.g. the output of `hexacal calibrate`) and write it '
        'as LinuxCNC genhexkins settings (HAL setp lines of the base and platform joints, '
        'Gough-Stewart platforms only), as a parameters YAML, or as JSON {"model", "parameters"}. '
        'The file is written atomically.',
        fill=_export_arguments,
    )


def _export_arguments(parser: argparse.ArgumentParser) -> None:
    from .kinematics_commands import NEGATIVE_LIST

    # Formats and units are checked by the handler, so that a wrong one is a one-line error (exit
    # 2).
    parser._negative_number_matcher = NEGATIVE_LIST  # --home-pose -0.01,0,-0.8,... is a value
    parser.add_argument(
        'parameters', type=Path, metavar='CALIBRATED.yaml', help='parameters YAML to export'
    )
    parser.add_argument(
        '--format',
        required=True,
        metavar='{' + ','.join(FORMATS) + '}',
        help='linuxcnc: genhexkins HAL file and the INI fragment NAME.ini beside it '
        '(Gough-Stewart only); yaml: parameters file (SI); json: {"model", "parameters"} (SI); '
        'controller: JSON for a custom controller (geometry, conventions, check poses; SI); '
        "kinematics-node: the kinematics node's ROS parameters file and NAME.parameters.yaml; "
        "mjcf: a MuJoCo model of the machine with the device and its physics (MuJoCo's viewer)",
    )
    parser.add_argument(
        '--physical',
        type=Path,
        default=None,
        metavar='PHYSICAL.yaml',
        help="mjcf: the machine's physical description (masses, stiffnesses, servo gains, "
        "payload; docs/formats.md; default: the model's shipped realistic machine)",
    )
    parser.add_argument('--out', type=Path, required=True, help='file to write (atomically)')
    parser.add_argument(
        '--length-unit',
        metavar='{' + ','.join(LENGTH_UNITS) + '}',
        default=None,
        help='length unit of the linuxcnc file (default mm; yaml and json are always SI)',
    )
    parser.add_argument(
        '--home-pose',
        metavar='x,y,z,theta,psi,phi',
        default=None,
        help="linuxcnc: the pose a homed machine goes to, [TRAJ] HOME and the joints' HOME (m, "
        'eq. 2 angles in rad; default: the workspace centre, [0, 0, -L] hanging)',
    )
    parser.add_argument(
        '--home-actuators',
        metavar='l1,l2,l3,l4,l5,l6',
        default=None,
        help="linuxcnc: the actuator readings (m) where the home switches trip, the joints' "
        'HOME_OFFSET (default: 0 each, i.e. HOME_OFFSET = l0)',
    )
    parser.add_argument(
        '--stroke',
        metavar='LOW,HIGH',
        default=None,
        help="linuxcnc: the actuator readings (m) of the joints' MIN_LIMIT and MAX_LIMIT "
        "(default: the architecture's stroke, Gough-Stewart 0,0.5)",
    )
    parser.set_defaults(handler=run_export)


def run_export(args) -> int:
    from hexacal_msgs_py.parameters_file import read_parameters_file

    if args.format not in FORMATS:
        raise ValueError(f'unknown --format {args.format!r}; choose one of {", ".join(FORMATS)}')
    if args.length_unit is not None:
        if args.format != 'linuxcnc':
            raise ValueError(
                f'--length-unit applies to --format linuxcnc only ({args.format} is in SI units, '
                'm)'
            )
        if args.length_unit not in LENGTH_UNITS:
            raise ValueError(
                f'unknown --length-unit {args.length_unit!r}; choose one of '
                f'{", ".join(LENGTH_UNITS)}'
            )
    linuxcnc_options = [
        option
        for option, value in (
            ('--home-pose', args.home_pose),
            ('--home-actuators', args.home_actuators),
            ('--stroke', args.stroke),
        )
        if value is not None
    ]
    if linuxcnc_options and args.format != 'linuxcnc':
        raise ValueError(f'{linuxcnc_options[0]} applies to --format linuxcnc only')
    if getattr(args, 'physical', None) is not None and args.format != 'mjcf':
        raise ValueError('--physical applies to --format mjcf only')
    if args.out.is_dir():
        raise IsADirectoryError(f'--out {args.out} is a directory; name a file')
    contents = read_parameters_file(args.parameters)
    if args.format == 'linuxcnc':
        text = linuxcnc_hal(contents, source=args.parameters, unit=args.length_unit or 'mm')
        ini_path = ini_path_beside(args.out)
        ini_text = _linuxcnc_ini_text(args, contents)  # both made before either is written
        _write(args.out, text)
        _write(ini_path, ini_text)
        print(f'wrote {args.out}')
        print(f'wrote {ini_path}')
        from .export_linuxcnc import unrepresented

        for line in unrepresented(contents):
            print(f'not represented by genhexkins: {line}', file=sys.stderr)
        return 0
    if args.format == 'json':
        _write(args.out, json_text(contents))
    elif args.format == 'controller':
        from .export_controller import controller_json

        _write(args.out, controller_json(contents, args.parameters))
    elif args.format == 'mjcf':
        _write(args.out, mjcf_text(contents, getattr(args, 'physical', None)))
    elif args.format == 'kinematics-node':
        from .export_controller import kinematics_node_yaml, parameters_path_beside

        parameters_out = parameters_path_beside(args.out)
        node_text = kinematics_node_yaml(contents, args.parameters, parameters_out)
        _save_yaml(parameters_out, contents, source=args.parameters)
        _write(args.out, node_text)
        print(f'wrote {parameters_out}')
    else:
        _save_yaml(args.out, contents, source=args.parameters)
    print(f'wrote {args.out}')
    return 0


def mjcf_text(contents, physical_path: Path | None) -> str:
    """Return the MJCF of a parameters file's machine with its device and physics (module doc)."""
    from hexacal_msgs_py.models import DEVICE_MOUNT_KEY
    from hexacal_msgs_py.physical_file import default_physical, read_physical_file

    from ..core.architectures import parameters_for
    from ..core.machine.device import check_mount, DEFAULT_MOUNT
    from ..core.machine.live import home_pose
    from ..physics.mjcf import machine_mjcf

    params = parameters_for(contents.model, contents.vector)
    physical = (
        default_physical(contents.model)
        if physical_path is None
        else read_physical_file(physical_path)
    )
    if physical.model != contents.model:
        raise ValueError(
            f'--physical {physical_path} describes a {physical.model}, the parameters '
            f'a {contents.model}'
        )
    mount = check_mount(contents.extras.get(DEVICE_MOUNT_KEY, DEFAULT_MOUNT))
    link_length = params.architecture.default_workspace().link_length
    return machine_mjcf(params, physical, home_pose(link_length, mount), mount=mount).xml


def ini_path_beside(out: Path) -> Path:
    """Return where the INI fragment of a HAL file ``out`` goes: NAME.ini beside NAME.hal."""
    ini = out.with_suffix('.ini')
    if ini == out:
        raise ValueError(
            f'--out {os.fspath(out)}: name the HAL file (NAME.hal); NAME.ini is the INI beside it'
        )
    return ini


def _linuxcnc_ini_text(args, contents) -> str:
    from .export_linuxcnc import linuxcnc_homing, linuxcnc_ini
    from .kinematics_commands import parse_values

    home = (
        None
        if args.home_pose is None
        else parse_values(args.home_pose, '--home-pose', 'x,y,z in m, theta,psi,phi in rad')
    )
    switches = (
        None
        if args.home_actuators is None
        else parse_values(args.home_actuators, '--home-actuators', 'the six readings in m')
    )
    stroke = None if args.stroke is None else _stroke(args.stroke)
    homing = linuxcnc_homing(contents, home, switches, stroke)
    return linuxcnc_ini(
        contents, args.parameters, args.out.name, homing, unit=args.length_unit or 'mm'
    )


def _stroke(text: str) -> tuple[float, float]:
    parts = text.split(',')
    try:
        low, high = (float(part) for part in parts)
    except ValueError:
        raise ValueError(f'--stroke {text!r}: expected LOW,HIGH in m') from None
    if not (math.isfinite(low) and math.isfinite(high)):
        raise ValueError(f'--stroke {text!r}: both ends must be finite')
    return low, high


def json_text(contents) -> str:
    """``{"model": ..., "parameters": chain dict}`` (SI units; floats round-trip bit for bit)."""
    from hexacal_msgs_py.parameters_file import parameters_to_chain_dict

    payload = {
        'model': contents.model,
        'parameters': parameters_to_chain_dict(contents.vector, contents.model),
    }
    return json.dumps(payload, indent=2) + '\n'


def _save_yaml(out: Path, contents, source: Path) -> None:
    from hexacal_msgs_py.parameters_file import save_parameters

    comment = (
        f'{contents.layout.title} parameters exported by hexacal export from '
        f'{os.fspath(source)}, SI units'
    )
    save_parameters(
        out,
        contents.vector,
        extras=contents.extras or None,
        header_comment=comment,
        model=contents.model,
    )


def linuxcnc_hal(contents, source: Path, unit: str = 'mm') -> str:
    """
    Return the genhexkins HAL settings of a Gough-Stewart parameters file.

    The genhexkins HAL settings of a Gough-Stewart parameters file (ValueError for another model).
    """
    from hexacal_msgs_py.models import GOUGH_STEWART

    if contents.model != GOUGH_STEWART:
        raise ValueError(
            f"{os.fspath(source)} is a {contents.model} parameters file: LinuxCNC's genhexkins "
            f'describes a {GOUGH_STEWART} platform (6-UPS) only; use --format yaml or json'
        )
    layout = contents.layout
    scale, decimals = LENGTH_UNITS[unit], _DECIMALS[unit]
    chains = contents.vector.reshape(layout.n_chains, layout.fields_per_chain)
    a_first, b_first, l0_index = (layout.fields.index(name) for name in ('Ax', 'Bx', 'l0'))

    def number(value: float) -> str:
        text = f'{value * scale:.{decimals}f}'
        return '0.' + '0' * decimals if float(text) == 0.0 else text  # no "-0.000000"

    def setp_block(name: str, first: int) -> list[str]:
        lines = []
        for leg in range(layout.n_chains):
            for k, axis in enumerate(AXES):
                lines.append(
                    f'setp genhexkins.{name}.{leg}.{axis} {number(chains[leg, first + k]):>16}'
                )
            lines.append('')
        return lines

    lines = [
        f'# LinuxCNC genhexkins geometry of a {layout.title}, from hexacal',
        f'# Written by hexacal export from {os.fspath(source)}',
        f'# Lengths in {unit} ([TRAJ] LINEAR_UNITS = {unit} in the INI file). '
        "hexacal's leg N is strut (joint) N-1.",
        '# Load it after the kinematics module '
        '(loadrt genhexkins, or [KINS] KINEMATICS = genhexkins),',
        '# e.g. as a [HAL] HALFILE. '
        "Strut length = |p + R platform.N - base.N| (genhexkins, hexacal's",
        '# |p + R B - A|); the pose X Y Z A B C LinuxCNC reports '
        'is the platform frame in the base frame,',
        "# its A B C the roll-pitch-yaw angles of genhexkins (not hexacal's theta, psi, phi).",
        '',
        f'# Base joint centres in base (world) coordinates (hexacal chain_N.A), {unit}',
        *setp_block('base', a_first),
        f'# Platform joint centres in platform coordinates (hexacal chain_N.B), {unit}',
        *setp_block('platform', b_first),
        '# Leg offsets l0 = strut length at actuator reading zero (hexacal chain_N.l0), '
        f'{unit}. genhexkins joints',
        '# are strut lengths: for a joint homed where its actuator reads zero, '
        'put in the INI file',
    ]
    for leg in range(layout.n_chains):
        lines.append(f'# [JOINT_{leg}] HOME_OFFSET = {number(chains[leg, l0_index])}')
    return '\n'.join(lines) + '\n'


def _write(out: Path, text: str) -> None:
    from hexacal_msgs_py.files import atomic_write

    try:
        atomic_write(out, text)
    except OSError as error:
        raise ValueError(f'{os.fspath(out)}: cannot write: {error.strerror or error}') from None
