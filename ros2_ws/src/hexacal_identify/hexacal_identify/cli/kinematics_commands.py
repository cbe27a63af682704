"""
``hexacal ik`` and ``hexacal fk``: the kinematics of a parameters file, for scripts (SI units).

    hexacal ik PARAMS --pose x,y,z,theta,psi,phi [--json]
    hexacal fk PARAMS --actuators l1,l2,l3,l4,l5,l6 [--guess x,y,z,theta,psi,phi] [--json]

A pose is ``[x, y, z, theta, psi, phi]``: the platform origin in the base frame
(m) and the angles of R = R_Y(theta) R_X(psi) R_z(phi) (rad, eq. 2); the
actuators are the model's six readings lambda in chain order (Hexa Slide
slider_1..6 and Gough-Stewart leg_1..6 in m, rotary hexapod crank_1..6 in
rad).  ``--json`` prints one object
``{"model", "pose": {"x", "y", "z", "theta", "psi", "phi"}, "actuators": {name: value}}``
(floats at full precision); without it, one ``name value unit`` line each.

``--angles linuxcnc`` reads and prints the angles as LinuxCNC's genhexkins
A, B, C in degrees instead (R = Rz(C) Ry(B) Rx(A), core/machine/angle_conventions.py):
``--pose`` / ``--guess`` are ``x,y,z,a,b,c`` (m, deg) and the pose printed is
``x y z a b c`` (``--json``: ``"pose": {"x", "y", "z", "a", "b", "c"}``), so a
pose can be checked on both sides.  The default (``--angles hexacal``) prints
hexacal's own angles.

``ik`` does not limit the stroke (it prints what the pose needs; the
kinematics node refuses commands outside the stroke).  ``fk`` starts Newton
from ``--guess`` (default: the workspace centre, the device's fixed point
[0, 0, -L] with the platform level, [0, 0, +L] for a ``device.mount:
standing`` file) and follows the readings from there (core/machine/live.py), so the
pose printed is on the guess's branch.

A parameters file with a compliance section (``compliance.chains`` or ``compliance.chain_1..6``,
m/N: a calibration by ``hexacal calibrate --compliance``) is used loaded as the kinematics node
uses it (core/sessions/kinematics_session.py ``loaded_chains``, core/machine/live.py): the
encoders' readings at which the loaded chains reach the pose (``ik``), the pose of the joint
coordinates under the weights (``fk``); the weights are those of ``--physical FILE`` (a
physical description), else of the model's shipped one.  Such a run prints what it applied
(a ``compliance`` line; ``--json``: the ``"compliance"`` key); a rigid file's output is as before.

Exit codes: 0; 1 forward kinematics found no pose (``forward-kinematics-failed: ...``);
2 bad input or a pose no leg configuration reaches (``unreachable-pose: ...``), one line on stderr.

This module is imported by every ``hexacal`` start-up to register the commands: its top level uses
the standard library only.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import re
import sys

POSE_FIELDS = ('x', 'y', 'z', 'theta', 'psi', 'phi')
POSE_UNITS = ('m', 'm', 'm', 'rad', 'rad', 'rad')
LINUXCNC_POSE_FIELDS = ('x', 'y', 'z', 'a', 'b', 'c')
LINUXCNC_POSE_UNITS = ('m', 'm', 'm', 'deg', 'deg', 'deg')
ANGLES = ('hexacal', 'linuxcnc')
EXIT_OK, EXIT_NO_POSE, EXIT_BAD_INPUT = 0, 1, 2
# Let "--pose -0.1,0,-0.7,0,0,0" be a value, not an unknown option (argparse takes plain negative
# numbers only).
NEGATIVE_LIST = re.compile(r'^-[\d.]')


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        'ik',
        help='actuator readings of a platform pose (inverse kinematics of a parameters file)',
        description='Print the six actuator readings (m; rad for a rotary hexapod) that put the '
        'platform at a pose, by the inverse kinematics of the machine in a parameters YAML '
        '(any model).',
        fill=_ik_arguments,
    )
    subparsers.add_parser(
        'fk',
        help='platform pose of actuator readings (forward kinematics of a parameters file)',
        description='Print the platform pose [x, y, z (m), theta, psi, phi (rad)] of six actuator '
        'readings (m; rad for a rotary hexapod), by the forward kinematics of the machine in a '
        'parameters YAML (any model).',
        fill=_fk_arguments,
    )


def _common(parser: argparse.ArgumentParser) -> None:
    parser._negative_number_matcher = NEGATIVE_LIST  # values like -0.1,0,... are not options
    parser.add_argument(
        'parameters', type=Path, metavar='PARAMS', help='parameters YAML (its model: key)'
    )
    parser.add_argument(
        '--json',
        action='store_true',
        help='print {"model", "pose": {x, y, z, theta, psi, phi}, "actuators": {name: value}}',
    )
    parser.add_argument(
        '--angles',
        metavar='{' + ','.join(ANGLES) + '}',
        default='hexacal',
        help='hexacal: theta,psi,phi (rad) of R = R_Y(theta) R_X(psi) R_z(phi); linuxcnc: '
        "genhexkins' a,b,c (deg) of R = Rz(c) Ry(b) Rx(a), in --pose, --guess and the output",
    )
    parser.add_argument(
        '--physical',
        type=Path,
        default=None,
        metavar='FILE',
        help="physical description (hexacal-physical/1 YAML) whose weights load the file's "
        "compliance section, as the kinematics node's physical_file; default: the model's "
        'shipped one; unused for a file without compliances',
    )


def _ik_arguments(parser: argparse.ArgumentParser) -> None:
    _common(parser)
    parser.add_argument(
        '--pose',
        required=True,
        metavar='x,y,z,theta,psi,phi',
        help='platform pose: position (m) and eq. 2 angles (rad), comma-separated',
    )
    parser.set_defaults(handler=run_ik)


def _fk_arguments(parser: argparse.ArgumentParser) -> None:
    _common(parser)
    parser.add_argument(
        '--actuators',
        required=True,
        metavar='l1,l2,l3,l4,l5,l6',
        help='the six actuator readings (m; rad for a rotary hexapod) in chain order, '
        'comma-separated',
    )
    parser.add_argument(
        '--guess',
        metavar='x,y,z,theta,psi,phi',
        default=None,
        help='where the solve starts (default: the workspace centre, [0, 0, -L] hanging)',
    )
    parser.set_defaults(handler=run_fk)


def parse_values(text: str, option: str, what: str) -> list[float]:
    """Six comma-separated finite numbers (ValueError naming the option otherwise)."""
    parts = [part.strip() for part in text.split(',')]
    try:
        values = [float(part) for part in parts]
    except ValueError:
        raise ValueError(
            f'{option} {text!r}: expected six comma-separated numbers ({what})'
        ) from None
    if len(values) != 6:
        raise ValueError(
            f'{option} {text!r}: expected six comma-separated numbers ({what}), got {len(values)}'
        )
    if not all(math.isfinite(value) for value in values):
        raise ValueError(f'{option} {text!r}: every value must be finite')
    return values


def _pose_values(text: str, option: str, angles: str) -> list[float]:
    """Return a hexacal pose of an option's six values in the chosen angle convention."""
    _check_angles(angles)
    if angles == 'hexacal':
        return parse_values(text, option, 'x,y,z in m, theta,psi,phi in rad')
    import numpy as np

    from ..core.machine.angle_conventions import pose_from_linuxcnc

    values = parse_values(text, option, "x,y,z in m, LinuxCNC's a,b,c in deg")
    return [float(value) for value in pose_from_linuxcnc(np.array(values, dtype=float))]


def _check_angles(angles: str) -> None:
    # Checked here, not by argparse choices, so that a wrong one is a one-line error (exit 2).
    if angles not in ANGLES:
        raise ValueError(f'unknown --angles {angles!r}; choose one of {", ".join(ANGLES)}')


def loaded_machine(path: Path, physical: Path | None):
    """
    Return (parameters, mount, LoadedChains or None, what the output says of the compliance).

    The compliance section of the parameters file at ``path`` loaded by the weights of
    ``physical`` (None: the model's shipped description), as the kinematics node loads it;
    ('', None) of a rigid file.
    """
    from hexacal_msgs_py.parameters_file import compliances_from_extras, read_parameters_file

    from ..calibration_steps.machine_files import load_machine_and_mount
    from ..core.sessions.kinematics_session import loaded_chains

    params, mount = load_machine_and_mount(path)
    compliances = compliances_from_extras(read_parameters_file(path).extras)
    if not compliances:
        return params, mount, None, ''
    loaded, text = loaded_chains(params.model, compliances, str(physical) if physical else '')
    return params, mount, loaded, text if loaded is not None else ''


def _print(
    params, pose, actuators, as_json: bool, angles: str = 'hexacal', compliance: str = ''
) -> None:
    if angles == 'linuxcnc':
        _print_linuxcnc(params, pose, actuators, as_json, compliance)
        return
    fields = {field: float(value) for field, value in zip(POSE_FIELDS, pose)}
    if _answer_head(params, fields, actuators, as_json, compliance):
        return
    for field, value, unit in zip(POSE_FIELDS, pose, POSE_UNITS):
        extra = f'  ({math.degrees(value):.6f} deg)' if unit == 'rad' else ''
        print(f'{field:<8} {value: .12f} {unit}{extra}')
    _print_actuators(params, actuators)


def run_ik(args) -> int:
    import numpy as np

    from ..core.errors import UnreachablePoseError
    from ..core.machine.kinematics import inverse_kinematics

    pose = _pose_values(args.pose, '--pose', args.angles)
    params, _, loaded, compliance = loaded_machine(args.parameters, args.physical)
    try:
        actuators = inverse_kinematics(params, np.array([pose], dtype=float))[0]
        if loaded is not None:  # the encoders' readings of the loaded chains (no stroke limit)
            actuators = actuators + loaded.shifts(params, np.array([pose]))[0]
    except UnreachablePoseError as error:
        print(
            f'hexacal ik: error: {error.reason}: pose {pose} is unreachable: '
            f'{params.architecture.unreachable_reason}',
            file=sys.stderr,
        )
        return EXIT_BAD_INPUT
    _print(params, pose, actuators, args.json, args.angles, compliance)
    return EXIT_OK


def run_fk(args) -> int:
    import numpy as np

    from ..core.errors import ForwardKinematicsError
    from ..core.machine.live import home_pose, solve_pose
    from ..core.machine.postures import Workspace

    _check_angles(args.angles)
    actuators = parse_values(args.actuators, '--actuators', 'the six readings in SI units')
    guess: list[float] | np.ndarray | None = (
        None if args.guess is None else _pose_values(args.guess, '--guess', args.angles)
    )
    params, mount, loaded, compliance = loaded_machine(args.parameters, args.physical)
    if guess is None:
        guess = home_pose(Workspace().link_length, mount)
    try:
        pose = solve_pose(params, actuators, guess, loaded)
    except ForwardKinematicsError as error:
        print(
            f'hexacal fk: error: {error.reason}: readings {actuators}: {_one_line(error)}',
            file=sys.stderr,
        )
        return EXIT_NO_POSE
    _print(params, pose, actuators, args.json, args.angles, compliance)
    return EXIT_OK


def _print_linuxcnc(params, pose, actuators, as_json: bool, compliance: str = '') -> None:
    from ..core.machine.angle_conventions import linuxcnc_from_pose

    values = [float(value) for value in linuxcnc_from_pose(pose)]
    fields = dict(zip(LINUXCNC_POSE_FIELDS, values))
    if _answer_head(params, fields, actuators, as_json, compliance):
        return
    for field, value, unit in zip(LINUXCNC_POSE_FIELDS, values, LINUXCNC_POSE_UNITS):
        print(f'{field:<8} {value: .12f} {unit}')
    _print_actuators(params, actuators)


def _answer_head(params, pose: dict, actuators, as_json: bool, compliance) -> bool:
    """Print the whole JSON answer (return True), or the text answer's first lines (False)."""
    if as_json:
        names = params.layout.actuator_names
        payload = {
            'model': params.model,
            'pose': pose,
            'actuators': {name: float(value) for name, value in zip(names, actuators)},
        }
        if compliance:
            payload['compliance'] = compliance
        print(json.dumps(payload))
        return True
    print(f'model {params.model}')
    if compliance:
        print(f'compliance {compliance}')
    return False


def _print_actuators(params, actuators) -> None:
    """Print one ``name value unit`` line per actuator (the model's unit; rad also in deg)."""
    unit = params.layout.actuator_unit
    for name, value in zip(params.layout.actuator_names, actuators):
        extra = f'  ({math.degrees(value):.6f} deg)' if unit == 'rad' else ''
        print(f'{name:<8} {value: .12f} {unit}{extra}')


def _one_line(error: BaseException) -> str:
    return ' | '.join(line.strip() for line in str(error).splitlines() if line.strip())
