"""
``hexacal ik`` / ``hexacal fk`` for either model, as a script runs them (#11 section 4).

In-process through ``hexacal_identify.cli.main`` (what the ``hexacal`` script
calls); the start-up import check runs a fresh interpreter.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from hexacal_identify import cli
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses, Workspace
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np
import pytest

POSE_KEYS = ['x', 'y', 'z', 'theta', 'psi', 'phi']


def run(capsys, *argv) -> tuple[int, str, str]:
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def csv(values) -> str:
    return ','.join(repr(float(v)) for v in values)


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and 'Traceback' not in err, err
    return lines[0]


@pytest.fixture
def files(tmp_path):
    """Return model -> (true file, nominal set 2 file)."""
    out = {}
    for model in MODELS:
        arch = architecture(model)
        true_path, nominal_path = tmp_path / f'{model}.yaml', tmp_path / f'{model}_nominal.yaml'
        save_parameters(true_path, arch.default_parameters().vector, model=model)
        save_parameters(nominal_path, nominal_set(2, seed=0, model=model).vector, model=model)
        out[model] = (true_path, nominal_path)
    return out


def workspace_poses(model: str, n: int, mount: str = 'hanging') -> np.ndarray:
    arch = architecture(model)
    workspace = arch.default_workspace()
    if mount != 'hanging':
        workspace = Workspace(**{**workspace.__dict__, 'mount': mount})
    return sample_poses(
        arch.default_parameters(), n, np.random.default_rng(11), 'sphere', workspace
    )


@pytest.mark.parametrize('model', sorted(MODELS))
def test_ik_fk_round_trip_json(capsys, files, model):
    path = files[model][0]
    params = architecture(model).default_parameters()
    names = list(MODELS[model].actuator_names)
    for pose in workspace_poses(model, 8):
        code, out, err = run(capsys, 'ik', path, '--pose', csv(pose), '--json')
        assert code == 0, err
        ik = json.loads(out)
        assert list(ik) == ['model', 'pose', 'actuators']
        assert ik['model'] == model
        assert list(ik['pose']) == POSE_KEYS and list(ik['actuators']) == names
        assert [ik['pose'][k] for k in POSE_KEYS] == pose.tolist()
        readings = [ik['actuators'][n] for n in names]
        assert readings == inverse_kinematics(params, pose[None])[0].tolist()  # full precision
        # fk from the default guess (the workspace centre) finds the pose back.
        code, out, err = run(capsys, 'fk', path, '--actuators', csv(readings), '--json')
        assert code == 0, err
        fk = json.loads(out)
        assert list(fk) == ['model', 'pose', 'actuators'] and fk['model'] == model
        assert list(fk['actuators']) == names and [fk['actuators'][n] for n in names] == readings
        assert np.allclose([fk['pose'][k] for k in POSE_KEYS], pose, atol=1e-9, rtol=0)


def test_the_model_of_the_file_decides(capsys, files):
    pose = workspace_poses('gough_stewart', 1)[0]
    outputs = {}
    for model in MODELS:
        for path in files[model]:
            code, out, err = run(capsys, 'ik', path, '--pose', csv(pose), '--json')
            assert code == 0, err
            outputs[path] = json.loads(out)
            assert outputs[path]['model'] == model
    # The nominal machine needs other readings than the true one for the same pose (mm apart;
    # a crank's reading: mm over its 0.15 m, some 1e-2 rad).
    for model in MODELS:
        true_path, nominal_path = files[model]
        a = np.array(list(outputs[true_path]['actuators'].values()))
        b = np.array(list(outputs[nominal_path]['actuators'].values()))
        assert 1e-5 < np.abs(a - b).max() < (2e-2 if MODELS[model].actuator_unit == 'm' else 0.1)


def test_text_output_and_guess(capsys, files):
    path = files['hexa_slide'][0]
    pose = np.array([-0.1, 0.05, -0.7, 0.1, -0.05, 0.2])  # negative first value: not an option
    code, out, err = run(capsys, 'ik', path, '--pose', csv(pose))
    assert code == 0, err
    lines = dict(line.split(None, 1) for line in out.strip().splitlines())
    assert lines['model'] == 'hexa_slide'
    assert lines['theta'].startswith('0.1000') and '(5.729578 deg)' in lines['theta']
    readings = [float(lines[f'slider_{i}'].split()[0]) for i in range(1, 7)]
    assert np.allclose(
        readings,
        inverse_kinematics(architecture().default_parameters(), pose[None])[0],
        atol=1e-12,
    )
    code, out, err = run(
        capsys, 'fk', path, '--actuators', csv(readings), '--guess', csv(pose + 0.01)
    )
    assert code == 0, err
    lines = dict(line.split(None, 1) for line in out.strip().splitlines())
    assert np.allclose([float(lines[k].split()[0]) for k in POSE_KEYS], pose, atol=1e-9)


def test_crank_readings_print_in_rad_with_degrees(capsys, files):
    path = files['rotary_hexapod'][0]
    pose = workspace_poses('rotary_hexapod', 1)[0]
    code, out, err = run(capsys, 'ik', path, '--pose', csv(pose))
    assert code == 0, err
    lines = dict(line.split(None, 1) for line in out.strip().splitlines())
    expected = inverse_kinematics(architecture('rotary_hexapod').default_parameters(), pose[None])
    for i, value in enumerate(expected[0], start=1):
        number, unit, degrees = lines[f'crank_{i}'].split(None, 2)
        assert unit == 'rad' and abs(float(number) - value) < 1e-11
        assert degrees == f'({np.degrees(value):.6f} deg)'


def test_standing_device_guess_is_above_the_base(capsys, tmp_path):
    path = tmp_path / 'standing.yaml'
    arch = architecture('gough_stewart')
    save_parameters(
        path,
        arch.default_parameters().vector,
        model='gough_stewart',
        extras={'device.mount': 'standing'},
    )
    pose = workspace_poses('gough_stewart', 1, mount='standing')[0]
    assert pose[2] > 0
    readings = inverse_kinematics(arch.default_parameters(), pose[None])[0]
    code, out, err = run(capsys, 'fk', path, '--actuators', csv(readings), '--json')
    assert code == 0, err
    assert np.allclose(list(json.loads(out)['pose'].values()), pose, atol=1e-9)


@pytest.mark.parametrize(
    'argv, words',
    [
        (
            ['ik', '{p}', '--pose', '0,0,-0.7,0,0'],
            ['--pose', 'six comma-separated numbers', 'got 5'],
        ),
        (['ik', '{p}', '--pose', '0,0,-0.7,0,0,a'], ['--pose', 'six comma-separated numbers']),
        (['ik', '{p}', '--pose', '0,0,nan,0,0,0'], ['--pose', 'finite']),
        (['fk', '{p}', '--actuators', '0.1,0.1,0.1,0.1,0.1'], ['--actuators', 'got 5']),
        (['fk', '{p}', '--actuators', '0.1,0.1,0.1,0.1,0.1,inf'], ['--actuators', 'finite']),
        (
            ['fk', '{p}', '--actuators', '0.1,0.1,0.1,0.1,0.1,0.1', '--guess', '0,0'],
            ['--guess', 'got 2'],
        ),
        (['ik', '{missing}', '--pose', '0,0,-0.7,0,0,0'], ['missing.yaml', 'cannot read']),
        (['fk', '{bad}', '--actuators', '0.1,0.1,0.1,0.1,0.1,0.1'], ['bad.yaml']),
    ],
)
def test_bad_input_is_one_line_and_exit_2(capsys, files, tmp_path, argv, words):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    model: hexa_slide\n    chain_1.l: 1.0\n')
    names = {'p': files['hexa_slide'][0], 'missing': tmp_path / 'missing.yaml', 'bad': bad}
    code, out, err = run(capsys, *(a.format(**names) for a in argv))
    assert code == 2 and out == ''
    line = one_line(err)
    assert line.startswith(f'hexacal {argv[0]}: error: ')
    for word in words:
        assert word in line, line


def test_unreachable_pose_and_fk_failure_are_named(capsys, files):
    # Hexa Slide: a leg shorter than its distance to the rail; Gough-Stewart: a leg of zero length.
    gs = architecture('gough_stewart').default_parameters()
    on_a_base_joint = np.concatenate([gs.base_points[0] - gs.platform_points[0], np.zeros(3)])
    for model, pose in (('hexa_slide', '3,0,-0.7,0,0,0'), ('gough_stewart', csv(on_a_base_joint))):
        code, out, err = run(capsys, 'ik', files[model][0], '--pose', pose)
        assert code == 2 and out == ''
        assert one_line(err).startswith('hexacal ik: error: unreachable-pose: ')
    code, out, err = run(capsys, 'fk', files['hexa_slide'][0], '--actuators', '5,5,5,5,5,5')
    assert code == 1 and out == ''
    assert one_line(err).startswith('hexacal fk: error: forward-kinematics-failed: ')


def test_the_script_takes_negative_values_and_help_imports_no_numpy(files):
    script = os.path.join(os.path.dirname(sys.executable), 'hexacal')
    done = subprocess.run(
        [
            script,
            'ik',
            str(files['hexa_slide'][0]),
            '--pose',
            '-0.1,-0.05,-0.7,-0.1,0,0',
            '--json',
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)['pose']['x'] == -0.1
    probe = (
        'import sys; from hexacal_identify import cli\n'
        'try:\n    cli.main(sys.argv[1:])\nexcept SystemExit:\n    pass\n'
        'print(sorted(m for m in sys.modules if m.split(".")[0] in ("numpy", "rclpy", "scipy")))'
    )
    for command in ('ik', 'fk'):
        done = subprocess.run(
            [sys.executable, '-c', probe, command, '--help'],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert done.returncode == 0, done.stderr
        assert done.stdout.strip().splitlines()[-1] == '[]', done.stdout


# --- --angles linuxcnc (issue #20): genhexkins' A, B, C on both sides ---------------------------


def test_linuxcnc_angles_agree_with_hexacals(capsys, files):
    """The same R as a,b,c (deg) or theta,psi,phi gives the same ik; fk prints a,b,c back."""
    from hexacal_identify.core.machine.angle_conventions import linuxcnc_from_pose

    true_path, _ = files['gough_stewart']
    pose = np.array([0.03, -0.02, -0.8, 0.15, -0.1, 0.2])
    abc = linuxcnc_from_pose(pose)[3:]
    assert not np.allclose(abc, np.degrees(pose[3:]), atol=1e-3)  # two conventions, two sets
    code, out, err = run(capsys, 'ik', true_path, '--pose', csv(pose), '--json')
    assert code == 0, err
    hexacal = json.loads(out)
    linuxcnc_pose = csv([*pose[:3], *abc])
    argv = ['ik', true_path, '--pose', linuxcnc_pose, '--angles', 'linuxcnc', '--json']
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    payload = json.loads(out)
    assert list(payload['pose']) == ['x', 'y', 'z', 'a', 'b', 'c']
    np.testing.assert_allclose(
        list(payload['actuators'].values()), list(hexacal['actuators'].values()), atol=1e-12
    )
    readings = csv(payload['actuators'].values())
    argv = ['fk', true_path, '--actuators', readings, '--angles', 'linuxcnc', '--json']
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    back = json.loads(out)['pose']
    np.testing.assert_allclose([back[k] for k in 'xyz'], pose[:3], atol=1e-10)
    np.testing.assert_allclose([back[k] for k in 'abc'], abc, atol=1e-8)
    code, out, err = run(capsys, 'fk', true_path, '--actuators', readings, '--angles', 'linuxcnc')
    assert code == 0, err
    lines = out.splitlines()
    assert lines[4].startswith('a ') and lines[4].endswith(' deg') and 'theta' not in out


def test_default_angles_print_as_before(capsys, files):
    true_path, _ = files['gough_stewart']
    argv = ['ik', true_path, '--pose', '0.01,0.02,-0.8,0.1,0.2,0.3']
    code, default_out, _ = run(capsys, *argv)
    assert code == 0
    assert run(capsys, *argv, '--angles', 'hexacal')[1] == default_out
    assert default_out.splitlines()[4] == 'theta     0.100000000000 rad  (5.729578 deg)'


def test_unknown_angles_is_one_line(capsys, files):
    true_path, _ = files['gough_stewart']
    code, _, err = run(capsys, 'ik', true_path, '--pose', '0,0,-0.8,0,0,0', '--angles', 'zyx')
    assert code == 2 and 'zyx' in one_line(err) and 'linuxcnc' in err
