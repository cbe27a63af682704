"""
The LinuxCNC INI fragment ``hexacal export --format linuxcnc`` writes beside its HAL file.

genhexkins' joints are strut lengths and its forward kinematics is a Newton
iteration that starts from the previous pose, or after homing from
``[TRAJ] HOME``: from LinuxCNC's default (all zeros) it fails on a hanging
machine or finds the mirror assembly above the base.  So the fragment gives

* ``[KINS]``: ``KINEMATICS = genhexkins``, ``JOINTS = 6``;
* ``[TRAJ]``: ``COORDINATES``, the units and ``HOME``, the home pose in X Y Z A B
  C (default: hexacal's workspace centre, where the kinematics node and
  ``hexacal fk`` start too, on the working branch by construction);
* per joint (strut N = hexacal's leg N+1): ``TYPE = LINEAR``, ``MIN_LIMIT`` /
  ``MAX_LIMIT`` = l0 + the stroke's ends, ``HOME`` = the strut length at the
  home pose (so a homed machine is at ``[TRAJ] HOME`` exactly and the first
  forward kinematics needs no step), ``HOME_OFFSET`` = the strut length where
  the joint's home switch trips (default: actuator reading zero, i.e. l0).

Everything is computed from the calibrated parameters and refused (ValueError)
when the home pose or a switch reading lies outside the stroke.

What genhexkins cannot represent (``unrepresented``): its struts are rigid, so a
calibration with axial compliances (the parameters file's ``compliance.*``) is
exported as its geometry alone, and the INI and the command say so: the loaded
machine stands off the commanded pose by each strut's deflection c F under the
weights unless something upstream compensates (hexacal's kinematics node with
the compliances and the masses does).
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path

from hexacal_msgs_py.models import DEVICE_MOUNT_KEY, GOUGH_STEWART
import numpy as np

from .export import _DECIMALS, LENGTH_UNITS
from ..core.architectures import parameters_for
from ..core.architectures.gough_stewart import GoughStewartParameters
from ..core.errors import UnreachablePoseError
from ..core.machine.angle_conventions import linuxcnc_from_pose
from ..core.machine.device import check_mount, DEFAULT_MOUNT
from ..core.machine.kinematics import inverse_kinematics
from ..core.machine.live import home_pose

ANGLE_DECIMALS = 9  # degrees: 1e-9 deg moves a joint 0.2 m off the axis by 3 pm
# LinuxCNC's [TRAJ] LINEAR_UNITS knows mm and inch (and their synonyms), not metres.
_LINUXCNC_LINEAR_UNITS = {'mm': 'mm'}


def unrepresented(contents) -> list[str]:
    """Return what of a parameters file genhexkins cannot represent, one line each ([]: none)."""
    from hexacal_msgs_py.parameters_file import compliances_from_extras

    values = compliances_from_extras(contents.extras)
    chains = {name: value for name, value in values.items() if name != 'link'}
    if not chains:
        return []
    given = ', '.join(f'{name} {value:.4g} m/N' for name, value in chains.items())
    return [
        f'axial compliances of the struts ({given}): genhexkins has rigid struts, the export '
        'carries the geometry only; the loaded machine deflects by c F per strut unless '
        'compensated upstream'
    ]


@dataclass(frozen=True)
class LinuxcncHoming:
    """What the INI says about homing and limits, in SI units (m, rad)."""

    pose: np.ndarray  # [TRAJ] HOME as a hexacal pose [x, y, z, theta, psi, phi]
    home_struts: np.ndarray  # [JOINT_N] HOME: strut lengths at that pose (6,)
    switch_struts: np.ndarray  # [JOINT_N] HOME_OFFSET: strut lengths at the home switches (6,)
    min_struts: np.ndarray  # [JOINT_N] MIN_LIMIT (6,)
    max_struts: np.ndarray  # [JOINT_N] MAX_LIMIT (6,)
    stroke: tuple[float, float]  # actuator readings (m) of the limits


def linuxcnc_homing(
    contents,
    home_pose_value=None,
    home_actuators=None,
    stroke: tuple[float, float] | None = None,
) -> LinuxcncHoming:
    """
    Return the home pose, strut lengths and limits of a Gough-Stewart parameters file.

    ``home_pose_value``: hexacal pose (None: the workspace centre of the file's mount);
    ``home_actuators``: actuator readings (m) where the home switches trip (None: zero);
    ``stroke``: (low, high) actuator readings (None: the architecture's). ValueError when the
    home pose is unreachable or outside the stroke, or a switch reading is outside it.
    """
    params = parameters_for(contents.model, contents.vector)
    if not isinstance(params, GoughStewartParameters):  # the leg offsets are genhexkins'
        raise ValueError(f'genhexkins describes a {GOUGH_STEWART} only, not a {params.model}')
    workspace = params.architecture.default_workspace()
    low, high = workspace.actuator_stroke_m if stroke is None else stroke
    if not low < high:
        raise ValueError(f'--stroke {low:g},{high:g}: the low end must be below the high end')
    mount = check_mount(contents.extras.get(DEVICE_MOUNT_KEY, DEFAULT_MOUNT))
    pose = (
        home_pose(workspace.link_length, mount)
        if home_pose_value is None
        else np.asarray(home_pose_value, dtype=float)
    )
    offsets = params.leg_offsets
    try:
        home_readings = inverse_kinematics(params, pose[None])[0]
    except UnreachablePoseError as error:
        raise ValueError(f'home pose {pose.tolist()} is unreachable: {error}') from None
    outside = np.flatnonzero((home_readings < low) | (home_readings > high))
    if outside.size:
        detail = ', '.join(f'leg {i + 1} {home_readings[i]:.6f} m' for i in outside)
        raise ValueError(
            f'home pose {pose.tolist()} needs actuator readings outside the stroke '
            f'[{low:g}, {high:g}] m ({detail}); choose another with --home-pose'
        )
    switches = np.zeros(6) if home_actuators is None else np.asarray(home_actuators, float)
    outside = np.flatnonzero((switches < low) | (switches > high))
    if outside.size:
        detail = ', '.join(f'leg {i + 1} {switches[i]:g} m' for i in outside)
        raise ValueError(
            f'--home-actuators: home switch readings outside the stroke [{low:g}, {high:g}] m '
            f'({detail})'
        )
    return LinuxcncHoming(
        pose=pose,
        home_struts=offsets + home_readings,
        switch_struts=offsets + switches,
        min_struts=offsets + low,
        max_struts=offsets + high,
        stroke=(float(low), float(high)),
    )


def linuxcnc_ini(
    contents, source: Path, hal_name: str, homing: LinuxcncHoming, unit: str = 'mm'
) -> str:
    """Return the INI fragment (module doc) of a Gough-Stewart parameters file."""
    if contents.model != GOUGH_STEWART:
        raise ValueError(f'{os.fspath(source)}: genhexkins describes a {GOUGH_STEWART} only')
    scale, decimals = LENGTH_UNITS[unit], _DECIMALS[unit]

    def number(value: float, places: int = decimals) -> str:
        text = f'{value:.{places}f}'
        return '0.' + '0' * places if float(text) == 0.0 else text  # no "-0.000000"

    def length(value: float) -> str:
        return number(value * scale)

    home = linuxcnc_from_pose(homing.pose, scale)
    home_words = ' '.join(
        [number(v) for v in home[:3]] + [number(v, ANGLE_DECIMALS) for v in home[3:]]
    )
    x, y, z, theta, psi, phi = homing.pose
    low, high = homing.stroke
    units_line = (
        [f'LINEAR_UNITS = {_LINUXCNC_LINEAR_UNITS[unit]}']
        if unit in _LINUXCNC_LINEAR_UNITS
        else [
            f'# LINEAR_UNITS: LinuxCNC knows mm and inch only; these numbers are in {unit}, '
            'export with --length-unit mm',
        ]
    )
    lines = [
        f'# LinuxCNC INI settings of a {contents.layout.title} for genhexkins, from hexacal',
        f'# Written by hexacal export from {os.fspath(source)} with {hal_name} (its HAL '
        'setp lines:',
        '# load that file as a [HAL] HALFILE). Merge these sections into the machine INI file.',
        f'# Lengths in {unit}, angles in degrees. Joint N is strut N = hexacal leg N+1; a '
        "joint's position is",
        '# its strut length |p + R platform.N - base.N| (hexacal: lambda + l0), so the limits '
        'and homes below',
        '# are the calibrated l0 plus actuator readings. Keep genhexkins.spindle-offset and '
        'tool-offset at 0',
        '# (they shift the z of every joint), or move [TRAJ] HOME by the same amount.',
        '#',
        '# Angles. X Y Z is the platform frame origin in the base frame (hexacal x, y, z). '
        'genhexkins',
        '# builds the platform rotation from A, B, C as R = Rz(C) Ry(B) Rx(A): roll A about '
        'the base X axis,',
        '# then pitch B about the base Y axis, then yaw C about the base Z axis (fixed axes). '
        'hexacal writes',
        '# the same matrix R as R_Y(theta) R_X(psi) R_z(phi): theta about the base Y axis, psi '
        'about the base',
        "# X axis, phi about the platform's own z axis. With phi = C = 0 the numbers are the "
        'same (B = theta,',
        '# A = psi), and a turn about z alone is too (C = phi); a turn about z together with '
        'a tilt is not:',
        "# hexacal turns about the platform's tilted z axis, genhexkins about the base Z axis. "
        '`hexacal ik` and',
        '# `hexacal fk` take and print A B C with --angles linuxcnc, so a pose can be '
        'checked on both sides.',
        '',
        '[KINS]',
        'KINEMATICS = genhexkins',
        'JOINTS = 6',
        '',
        '[TRAJ]',
        'COORDINATES = X Y Z A B C',
        *units_line,
        'ANGULAR_UNITS = degree',
        "# genhexkins' forward kinematics is Newton's method from the previous pose, after "
        'homing from HOME:',
        '# from all zeros it fails on this machine or finds the mirror pose. HOME is the pose '
        'of the [JOINT_N]',
        '# HOME strut lengths below (hexacal pose '
        f'x {x:.6g} m, y {y:.6g} m, z {z:.6g} m, theta {theta:.6g}, psi {psi:.6g}, '
        f'phi {phi:.6g} rad).',
        f'HOME = {home_words}',
    ]
    missing = unrepresented(contents)
    if missing:
        lines[1:1] = ['# NOT REPRESENTED by genhexkins:'] + [f'#   {line}' for line in missing]
    for leg in range(6):
        lines += [
            '',
            f'[JOINT_{leg}]',
            f'# strut {leg} = hexacal leg {leg + 1}, actuator stroke {low:g}-{high:g} m. '
            'HOME_OFFSET: home switch; HOME: at [TRAJ] HOME',
            'TYPE = LINEAR',
            f'MIN_LIMIT = {length(homing.min_struts[leg])}',
            f'MAX_LIMIT = {length(homing.max_struts[leg])}',
            f'HOME_OFFSET = {length(homing.switch_struts[leg])}',
            f'HOME = {length(homing.home_struts[leg])}',
        ]
    return '\n'.join(lines) + '\n'
