"""
Controller files of ``hexacal export``: a JSON a custom controller reads, the kinematics node's.

``--format controller`` (either model, made for the Hexa Slide, which no stock
controller knows) writes one self-describing JSON object: the model, its
units, the pose and rotation convention and the inverse kinematics in words,
every chain's geometry with the values a controller needs spelled out (the
Hexa Slide's full unit rail direction, az included), the stroke, the home
pose with its actuator readings, and check poses with the readings hexacal's
inverse kinematics gives them, so that a controller's implementation can be
tested against hexacal's before it moves a machine.  docs/formats.md is its
reference.

``--format kinematics-node`` writes the ROS 2 parameters file of hexacal's own
``kinematics`` node (``--ros-args --params-file NAME.yaml``; its key
``/**/kinematics`` matches the node in any namespace) and, beside it,
the parameters it names (``NAME.parameters.yaml``, a copy in the parameters
file format): the node starts on this calibration, with the stroke and mount
written out, and keeps it (``follow_calibrations: false``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from hexacal_msgs_py.models import DEVICE_MOUNT_KEY, GOUGH_STEWART, HEXA_SLIDE, ROTARY_HEXAPOD
from hexacal_msgs_py.parameters_file import parameters_to_chain_dict
import numpy as np

from ..core.architectures import parameters_for
from ..core.errors import UnreachablePoseError
from ..core.machine.device import check_mount, DEFAULT_MOUNT
from ..core.machine.kinematics import inverse_kinematics
from ..core.machine.live import home_pose

CONTROLLER_FORMAT = 'hexacal-controller'
CONTROLLER_VERSION = 1
KINEMATICS_NODE = 'kinematics'
# Check poses about the home pose: offsets (m, rad) a controller's IK must reproduce.
_CHECK_OFFSETS = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.05, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, -0.04, 0.03, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.12, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, -0.1, 0.0],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.15],
        [0.03, 0.02, -0.02, 0.08, -0.06, 0.1],
    ]
)
ROTATION_TEXT = (
    'R = R_Y(theta) R_X(psi) R_z(phi): theta about the base Y axis, psi about the base X axis, '
    "phi about the platform's own z axis; R maps platform coordinates to base coordinates"
)
IK_TEXT = {
    HEXA_SLIDE: (
        'per chain, d = p + R B - A0; the slider reading lambda solves |d - lambda a| = l, the '
        'smaller root: lambda = a.d - sqrt(l^2 - |d|^2 + (a.d)^2) (no real root: unreachable)'
    ),
    GOUGH_STEWART: 'per leg, lambda = |p + R B - A| - l0 (the leg extension)',
    ROTARY_HEXAPOD: (
        'per chain, D = p + R B - A, K = (|D|^2 + r^2 - l^2) / (2 r); with the unit motor axis n, '
        'the zero reference h and w = n x h, the crank angle phi = atan2(D.w, D.h) + '
        "acos(K / |(D.h, D.w)|) (the machine's branch; |K| > |(D.h, D.w)|: unreachable) and the "
        'reading lambda = phi - alpha0 in [-pi, pi) (rad): the crank tip A + r (cos phi h + '
        'sin phi w) lies at l from p + R B'
    ),
}


def _pose_dict(pose) -> dict[str, float]:
    return {
        name: float(value)
        for name, value in zip(('x', 'y', 'z', 'theta', 'psi', 'phi'), pose)
    }


def _chains(params, model: str) -> list[dict]:
    per_chain = params.per_chain
    names = params.layout.actuator_names
    chains = []
    for index in range(per_chain.shape[0]):
        chain = {'name': f'chain_{index + 1}', 'actuator': names[index]}
        if model == HEXA_SLIDE:
            chain.update(
                A0=per_chain[index, 0:3].tolist(),
                B=per_chain[index, 3:6].tolist(),
                l=float(per_chain[index, 6]),
                a=params.rail_directions[index].tolist(),
            )
        elif model == ROTARY_HEXAPOD:
            from ..core.architectures.rotary_hexapod import axis_frame

            axis, zero, _, _, _ = axis_frame(per_chain[index, 8], per_chain[index, 9])
            chain.update(
                A=per_chain[index, 0:3].tolist(),
                B=per_chain[index, 3:6].tolist(),
                l=float(per_chain[index, 6]),
                r=float(per_chain[index, 7]),
                n=axis.tolist(),
                h=zero.tolist(),
                alpha0=float(per_chain[index, 10]),
            )
        else:
            chain.update(
                A=per_chain[index, 0:3].tolist(),
                B=per_chain[index, 3:6].tolist(),
                l0=float(per_chain[index, 6]),
            )
        chains.append(chain)
    return chains


def controller_payload(contents, source: Path) -> dict:
    """Return the ``--format controller`` object of a parameters file (module doc)."""
    model = contents.model
    if model not in IK_TEXT:
        raise ValueError(f'{os.fspath(source)}: no controller description for model {model!r}')
    params = parameters_for(model, contents.vector)
    workspace = params.architecture.default_workspace()
    mount = check_mount(contents.extras.get(DEVICE_MOUNT_KEY, DEFAULT_MOUNT))
    home = home_pose(workspace.link_length, mount)
    try:
        home_readings = inverse_kinematics(params, home[None])[0]
    except UnreachablePoseError as error:
        raise ValueError(
            f'{os.fspath(source)}: the workspace centre is unreachable: {error}'
        ) from None
    checks = []
    for pose in home + _CHECK_OFFSETS:
        try:  # a check pose this machine cannot reach is left out, not an error
            checks.append((pose, inverse_kinematics(params, pose[None])[0]))
        except UnreachablePoseError:
            continue
    low, high = workspace.actuator_stroke_m
    return {
        'format': CONTROLLER_FORMAT,
        'version': CONTROLLER_VERSION,
        'model': model,
        'source': os.fspath(source),
        'units': {'length': 'm', 'angle': 'rad'},
        'pose': {
            'fields': ['x', 'y', 'z', 'theta', 'psi', 'phi'],
            'meaning': 'p = [x, y, z], the platform frame origin in the base frame, and R',
            'rotation': ROTATION_TEXT,
        },
        'inverse_kinematics': IK_TEXT[model],
        'actuators': list(params.layout.actuator_names),
        'chains': _chains(params, model),
        'parameters': parameters_to_chain_dict(contents.vector, model),
        'stroke': [float(low), float(high)],
        'actuator_unit': params.layout.actuator_unit,
        'mount': mount,
        'home': {'pose': _pose_dict(home), 'actuators': home_readings.tolist()},
        'checks': [
            {'pose': _pose_dict(pose), 'actuators': values.tolist()} for pose, values in checks
        ],
    }


def controller_json(contents, source: Path) -> str:
    """Return the ``--format controller`` JSON text (floats at full precision)."""
    return json.dumps(controller_payload(contents, source), indent=2) + '\n'


def parameters_path_beside(out: Path) -> Path:
    """Return where ``--format kinematics-node`` puts the parameters: NAME.parameters.yaml."""
    return out.with_name(out.stem + '.parameters.yaml')


def kinematics_node_yaml(contents, source: Path, parameters_file: Path) -> str:
    """Return the kinematics node's parameters file naming ``parameters_file`` (module doc)."""
    params = parameters_for(contents.model, contents.vector)
    workspace = params.architecture.default_workspace()
    mount = check_mount(contents.extras.get(DEVICE_MOUNT_KEY, DEFAULT_MOUNT))
    low, high = workspace.actuator_stroke_m
    return '\n'.join(
        [
            f'# hexacal kinematics node settings for a {contents.layout.title}, written by '
            f'hexacal export from {os.fspath(source)}',
            '# ros2 run hexacal_identify kinematics --ros-args --params-file THIS_FILE; the '
            'parameters file it names was written with it.',
            f'/**/{KINEMATICS_NODE}:  # the kinematics node, in any namespace',
            '  ros__parameters:',
            f'    parameters: {json.dumps(os.fspath(parameters_file.resolve()))}',
            '    # keep this calibration: calibrations published on hexacal/parameters do not '
            'replace it',
            '    follow_calibrations: false',
            f'    stroke_limits: [{float(low)!r}, {float(high)!r}]',
            f'    link_length: {float(workspace.link_length)!r}',
            f'    mount: {mount}',
            '',
        ]
    )
