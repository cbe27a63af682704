"""
The exported HAL + INI pair driven through genhexkins' forward kinematics, as LinuxCNC runs it.

``genhexkins_forward`` is written from genhexkins' description (LinuxCNC
src/emc/kinematics/genhexkins.c, its comments and HAL pins; no code copied):
Newton's method on the six strut lengths from a start pose.  Per step, with
R = Rz(C) Ry(B) Rx(A) (A, B, C the roll, pitch, yaw in degrees) and for each
strut i the platform joint a_i (platform frame) and base joint b_i (base frame):
v_i = p + R a_i - b_i, u_i = v_i / |v_i|, the strut error |v_i| - joint_i, the
row [u_i, (R a_i) x u_i]; the step solves rows * delta = errors and is
subtracted from X Y Z and from the roll, pitch, yaw in radians.  It stops with
a solution when every |error| <= convergence-criterion (default 1e-9, machine
units), and fails when the summed |error| of a step exceeds max-error
(default 500) or after limit-iterations (default 120) steps, or on a joint
<= 0.  After homing LinuxCNC starts it from ``[TRAJ] HOME``; before anything
is set that pose is all zeros.
"""

from __future__ import annotations

import configparser
from dataclasses import dataclass
from pathlib import Path
import re

import hexacal_identify
from hexacal_identify import cli
from hexacal_identify.core.architectures import parameters_for
from hexacal_identify.core.machine.kinematics import inverse_kinematics, rotation_matrices
from hexacal_identify.core.machine.live import home_pose, solve_pose
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.parameters_file import read_parameters_file
import numpy as np
import pytest

GS_FILE = Path(hexacal_identify.__file__).parent / 'data' / 'gough_stewart_default.yaml'
SETP = re.compile(r'^setp genhexkins\.(base|platform)\.([0-5])\.([xyz]) +(-?[0-9.]+)$')
CONVERGENCE_CRITERION = 1e-9  # genhexkins.convergence-criterion default (machine units)
MAX_ERROR = 500.0  # genhexkins.max-error default
LIMIT_ITERATIONS = 120  # genhexkins.limit-iterations default


@dataclass
class Outcome:
    """What genhexkins' forward kinematics returns: converged or not, the pose, why not."""

    converged: bool
    pose: np.ndarray  # X Y Z (machine units) A B C (deg)
    iterations: int
    reason: str = ''


def rpy_matrix(a_deg: float, b_deg: float, c_deg: float) -> np.ndarray:
    """Return Rz(C) Ry(B) Rx(A), built from the three elementary rotations."""
    a, b, c = np.radians([a_deg, b_deg, c_deg])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx


def genhexkins_inverse(base, platform, pose) -> np.ndarray:
    """Return the strut lengths |p + R a - b| of pose X Y Z A B C."""
    rotation = rpy_matrix(*pose[3:])
    return np.linalg.norm(pose[:3] + platform @ rotation.T - base, axis=1)


def genhexkins_forward(base, platform, joints, start) -> Outcome:
    """Run genhexkins' forward kinematics (module doc) from ``start`` (X Y Z A B C)."""
    if np.any(np.asarray(joints) <= 0.0):
        return Outcome(False, np.full(6, np.nan), 0, 'a joint <= 0')
    position = np.array(start[:3], dtype=float)
    rpy = np.radians(np.array(start[3:], dtype=float))
    error_sum, iteration = 1.0, 0
    while True:
        if abs(error_sum) > MAX_ERROR or not np.isfinite(error_sum):
            return Outcome(False, np.full(6, np.nan), iteration, 'max-error exceeded')
        iteration += 1
        if iteration > LIMIT_ITERATIONS:
            return Outcome(False, np.full(6, np.nan), iteration, 'limit-iterations exceeded')
        rotation = rpy_matrix(*np.degrees(rpy))
        rotated = platform @ rotation.T  # R a_i, (6, 3)
        struts = position + rotated - base
        lengths = np.linalg.norm(struts, axis=1)
        if np.any(lengths == 0.0):
            return Outcome(False, np.full(6, np.nan), iteration, 'a strut of zero length')
        units = struts / lengths[:, None]
        errors = lengths - np.asarray(joints)
        rows = np.hstack([units, np.cross(rotated, units)])
        try:
            delta = np.linalg.solve(rows, errors)
        except np.linalg.LinAlgError:
            return Outcome(False, np.full(6, np.nan), iteration, 'singular Jacobian')
        position -= delta[:3]
        rpy -= delta[3:]
        error_sum = float(np.sum(np.abs(errors)))
        if np.all(np.abs(errors) <= CONVERGENCE_CRITERION):
            return Outcome(True, np.concatenate([position, np.degrees(rpy)]), iteration)


def export_pair(tmp_path: Path, *extra: str) -> tuple[dict, configparser.ConfigParser]:
    """Export the default hexapod; return (its HAL setp values, its INI)."""
    hal = tmp_path / 'hexapod.hal'
    code = cli.main(['export', str(GS_FILE), '--format', 'linuxcnc', '--out', str(hal), *extra])
    assert code == 0
    setps = {}
    for line in hal.read_text().splitlines():
        match = SETP.match(line)
        if match:
            setps[(match[1], int(match[2]), match[3])] = float(match[4])
    ini = configparser.ConfigParser(comment_prefixes=('#',), inline_comment_prefixes=None)
    ini.optionxform = str  # LinuxCNC keys are upper case
    ini.read_string((tmp_path / 'hexapod.ini').read_text())
    return setps, ini


def joint_points(setps: dict) -> tuple[np.ndarray, np.ndarray]:
    """Return (base, platform) joint centres (6, 3) as the HAL file sets them."""
    base = np.array([[setps[('base', n, axis)] for axis in 'xyz'] for n in range(6)])
    platform = np.array([[setps[('platform', n, axis)] for axis in 'xyz'] for n in range(6)])
    return base, platform


def traj_home(ini: configparser.ConfigParser) -> np.ndarray:
    return np.array([float(word) for word in ini['TRAJ']['HOME'].split()])


@pytest.fixture(scope='module')
def default_machine():
    contents = read_parameters_file(GS_FILE)
    return parameters_for(contents.model, contents.vector)


def test_ini_sections_are_what_genhexkins_needs(tmp_path, capsys, default_machine):
    setps, ini = export_pair(tmp_path)
    assert ini['KINS']['KINEMATICS'] == 'genhexkins' and ini['KINS']['JOINTS'] == '6'
    assert ini['TRAJ']['COORDINATES'] == 'X Y Z A B C'
    assert ini['TRAJ']['LINEAR_UNITS'] == 'mm' and ini['TRAJ']['ANGULAR_UNITS'] == 'degree'
    home = traj_home(ini)
    # the workspace centre, hanging below the base: [0, 0, -L] level
    np.testing.assert_array_equal(home, [0.0, 0.0, -750.0, 0.0, 0.0, 0.0])
    base, platform = joint_points(setps)
    struts = genhexkins_inverse(base, platform, home)
    offsets = default_machine.leg_offsets * 1e3
    for n in range(6):
        joint = ini[f'JOINT_{n}']
        assert joint['TYPE'] == 'LINEAR'
        assert float(joint['HOME']) == pytest.approx(struts[n], abs=5e-6)
        assert float(joint['HOME_OFFSET']) == pytest.approx(offsets[n], abs=5e-7)
        assert float(joint['MIN_LIMIT']) == pytest.approx(offsets[n], abs=5e-7)
        assert float(joint['MAX_LIMIT']) == pytest.approx(offsets[n] + 500.0, abs=5e-7)
        assert float(joint['MIN_LIMIT']) <= float(joint['HOME']) <= float(joint['MAX_LIMIT'])


def test_traj_home_leads_genhexkins_to_hexacals_pose(tmp_path, capsys, default_machine):
    """
    Homed at [TRAJ] HOME, genhexkins tracks the machine to hexacal's pose, to ~1 nm.

    As LinuxCNC runs it: homing puts every joint at its [JOINT_N] HOME and the
    first solve starts from [TRAJ] HOME; every later solve starts from the pose
    before (a move is many servo cycles).  Each move here goes from the home
    pose to a workspace posture in 25 steps.
    """
    setps, ini = export_pair(tmp_path)
    base, platform = joint_points(setps)
    start = traj_home(ini)
    homed = genhexkins_forward(
        base, platform, [float(ini[f'JOINT_{n}']['HOME']) for n in range(6)], start
    )
    assert homed.converged and homed.iterations <= 2
    np.testing.assert_allclose(homed.pose, start, atol=1e-5)
    params = default_machine
    workspace = params.architecture.default_workspace()
    centre = home_pose(workspace.link_length)
    poses = sample_poses(params, 12, np.random.default_rng(20), 'sphere', workspace)
    offsets = params.leg_offsets
    for target in poses:
        path = centre + np.linspace(0.0, 1.0, 26)[1:, None] * (target - centre)
        readings = inverse_kinematics(params, path)
        pose = homed.pose
        for reading in readings:
            outcome = genhexkins_forward(base, platform, (reading + offsets) * 1e3, pose)
            assert outcome.converged, outcome.reason
            pose = outcome.pose
        expected = solve_pose(params, readings[-1], centre)
        np.testing.assert_allclose(expected, target, atol=1e-12)  # hexacal's FK: the target
        np.testing.assert_allclose(pose[:3] / 1e3, expected[:3], atol=2e-9)
        rotation = rpy_matrix(*pose[3:])
        np.testing.assert_allclose(
            rotation, rotation_matrices(expected[None, 3:])[0], atol=2e-8
        )  # 2e-8 rad x 0.2 m platform radius = 4 nm at the joints


def test_all_zero_start_misses_the_hanging_machine(tmp_path, capsys, default_machine):
    """From all zeros (LinuxCNC's default) genhexkins misses the working pose; from HOME not."""
    setps, ini = export_pair(tmp_path)
    base, platform = joint_points(setps)
    params = default_machine
    working = np.array([0.02, -0.01, -0.78, 0.05, -0.04, 0.06])
    joints = (inverse_kinematics(params, working[None])[0] + params.leg_offsets) * 1e3
    from_home = genhexkins_forward(base, platform, joints, traj_home(ini))
    assert from_home.converged and from_home.pose[2] == pytest.approx(-780.0, abs=1e-6)
    from_zero = genhexkins_forward(base, platform, joints, np.zeros(6))
    assert not from_zero.converged or from_zero.pose[2] > 0.0, from_zero
    # Started above the base, it converges - to the mirror assembly, not the machine.
    above = genhexkins_forward(base, platform, joints, [0.0, 0.0, 750.0, 0.0, 0.0, 0.0])
    assert above.converged and above.pose[2] > 0.0


def test_compliances_are_named_as_what_genhexkins_cannot_represent(tmp_path, capsys):
    from hexacal_msgs_py.parameters_file import compliance_extras, save_parameters

    contents = read_parameters_file(GS_FILE)
    rigid_hal = tmp_path / 'rigid' / 'hexapod.hal'
    rigid_hal.parent.mkdir()
    assert cli.main(['export', str(GS_FILE), '--format', 'linuxcnc', '--out', str(rigid_hal)]) == 0
    assert 'NOT REPRESENTED' not in rigid_hal.with_suffix('.ini').read_text()
    assert 'genhexkins' not in capsys.readouterr().err
    loaded = tmp_path / 'loaded.yaml'
    extras = {**contents.extras, **compliance_extras({'chains': 2e-8, 'link': 1e-7})}
    save_parameters(loaded, contents.vector, extras=extras, model=contents.model)
    hal = tmp_path / 'hexapod.hal'
    assert cli.main(['export', str(loaded), '--format', 'linuxcnc', '--out', str(hal)]) == 0
    ini = (tmp_path / 'hexapod.ini').read_text()
    assert '# NOT REPRESENTED by genhexkins:' in ini and 'chains 2e-08 m/N' in ini
    assert 'link' not in ini.split('NOT REPRESENTED')[1].splitlines()[1]  # the link is not used
    assert 'not represented by genhexkins: axial compliances' in capsys.readouterr().err
    # The geometry is exported exactly as without the compliances.
    assert hal.read_text().splitlines()[2:] == rigid_hal.read_text().splitlines()[2:]
