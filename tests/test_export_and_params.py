"""``hexacal params`` for either model and ``hexacal export`` (LinuxCNC genhexkins HAL, yaml, json),
as a user runs them.

The commands run in-process through ``hexacal_identify.cli.main`` (what the
``hexacal`` script calls); the start-up import check runs a fresh interpreter.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import re
import subprocess
import sys

import hexacal_identify
from hexacal_identify import cli
from hexacal_identify.core.architectures import architecture, default_parameters
from hexacal_identify.core.machine.kinematics import inverse_kinematics, rotation_matrices
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.parameters_file import (
    chain_dict_to_parameters,
    read_parameters_file,
    save_parameters,
)
import numpy as np
import pytest

DATA = Path(hexacal_identify.__file__).parent / 'data'
GS_FILE = DATA / 'gough_stewart_default.yaml'
ROTARY_FILE = DATA / 'rotary_hexapod_default.yaml'
TABLE1_FILE = DATA / 'table1_exact.yaml'
MODELS = ('hexa_slide', 'gough_stewart', 'rotary_hexapod')
MODELS_UNIT = {'hexa_slide': 'm', 'gough_stewart': 'm', 'rotary_hexapod': 'rad'}
SETP = re.compile(r'^setp genhexkins\.(base|platform)\.([0-5])\.([xyz]) +(-?[0-9]+\.[0-9]+)$')
HOME_OFFSET = re.compile(r'^# \[JOINT_([0-5])\] HOME_OFFSET = (-?[0-9]+\.[0-9]+)$')


def run(capsys, *argv) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of `hexacal argv...`."""
    code = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(code: int, err: str, *fragments: str) -> None:
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert 'Traceback' not in err
    for fragment in fragments:
        assert fragment in err, err


# --- hexacal params ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize('model', MODELS)
def test_params_default_writes_the_default_machine_of_either_model(capsys, tmp_path, model):
    out = tmp_path / 'default.yaml'
    code, stdout, err = run(capsys, 'params', 'default', '--model', model, '--out', out)
    assert code == 0, err
    assert str(out) in stdout
    contents = read_parameters_file(out)
    assert contents.model == model
    np.testing.assert_array_equal(contents.vector, default_parameters(model).vector)
    assert contents.extras == {}
    assert contents.vector.size == {'hexa_slide': 54, 'gough_stewart': 42, 'rotary_hexapod': 66}[
        model
    ]


def test_hexa_slide_params_are_written_as_before(capsys, tmp_path):
    """Without --model: the Table 1 file, byte for byte the shipped one; `default` and --model hexa_slide agree."""
    files = {}
    for name, argv in {
        'table1': ('table1',),
        'default': ('default',),
        'table1 --model': ('table1', '--model', 'hexa_slide'),
    }.items():
        files[name] = tmp_path / f'{len(files)}.yaml'
        assert run(capsys, 'params', *argv, '--out', files[name])[0] == 0
    shipped = TABLE1_FILE.read_bytes()
    assert all(path.read_bytes() == shipped for path in files.values())
    assert b'model:' not in shipped  # a Hexa Slide file names no model, as before

    plain, explicit = tmp_path / 'n.yaml', tmp_path / 'n_model.yaml'
    assert run(capsys, 'params', 'nominal', '--set', '3', '--seed', '5', '--out', plain)[0] == 0
    assert (
        run(
            capsys,
            'params',
            'nominal',
            '--set',
            '3',
            '--seed',
            '5',
            '--model',
            'hexa_slide',
            '--out',
            explicit,
        )[0]
        == 0
    )
    assert plain.read_bytes() == explicit.read_bytes()
    assert plain.read_text().startswith(
        '# nominal set 3 (Table 1 + errors with Table 2 statistics, seed 5), SI units\n/**:\n'
    )
    np.testing.assert_array_equal(
        read_parameters_file(plain).vector, nominal_set(3, seed=5).vector
    )


@pytest.mark.parametrize('model', MODELS)
@pytest.mark.parametrize('set_number', [1, 2, 3])
def test_params_nominal_round_trips_for_either_model(capsys, tmp_path, model, set_number):
    out = tmp_path / 'nominal.yaml'
    code, _, err = run(
        capsys,
        'params',
        'nominal',
        '--model',
        model,
        '--set',
        set_number,
        '--seed',
        7,
        '--out',
        out,
    )
    assert code == 0, err
    contents = read_parameters_file(out)
    assert contents.model == model
    np.testing.assert_array_equal(
        contents.vector, nominal_set(set_number, seed=7, model=model).vector
    )


@pytest.mark.parametrize('set_number', [1, 2, 3])
def test_gough_stewart_nominal_sets_have_table2_like_errors(capsys, tmp_path, set_number):
    """nominal - default: every parameter moved, max / mean magnitude / RMS equal the architecture's row."""
    exact = default_parameters('gough_stewart').vector
    max_mm, mean_mm, sigma_mm = architecture('gough_stewart').nominal_error_stats_mm[set_number]
    vectors = []
    for seed in (0, 1):
        out = tmp_path / f'nominal_{seed}.yaml'
        assert (
            run(
                capsys,
                'params',
                'nominal',
                '--model',
                'gough_stewart',
                '--set',
                set_number,
                '--seed',
                seed,
                '--out',
                out,
            )[0]
            == 0
        )
        vectors.append(read_parameters_file(out).vector)
    errors_mm = (vectors[0] - exact) * 1e3
    assert np.all(np.abs(errors_mm) > 1e-6)  # all 42 differ from the default machine
    assert np.max(np.abs(errors_mm)) == pytest.approx(max_mm, abs=1e-6)
    assert np.mean(np.abs(errors_mm)) == pytest.approx(mean_mm, abs=1e-6)
    assert np.sqrt(np.mean(errors_mm**2)) == pytest.approx(sigma_mm, abs=1e-6)
    assert np.any(errors_mm > 0) and np.any(errors_mm < 0)
    assert not np.array_equal(vectors[0], vectors[1])  # the seed matters


def test_table1_is_refused_for_a_gough_stewart(capsys, tmp_path):
    out = tmp_path / 't1.yaml'
    code, _, err = run(capsys, 'params', 'table1', '--model', 'gough_stewart', '--out', out)
    assert_one_line_error(code, err, 'table1', 'gough_stewart', 'default')
    assert not out.exists()


def test_shipped_rotary_hexapod_file_is_the_default_machine(capsys, tmp_path):
    contents = read_parameters_file(ROTARY_FILE)
    assert contents.model == 'rotary_hexapod' and contents.extras == {}
    np.testing.assert_array_equal(contents.vector, default_parameters('rotary_hexapod').vector)
    regenerated = tmp_path / 'rotary.yaml'
    assert (
        run(capsys, 'params', 'default', '--model', 'rotary_hexapod', '--out', regenerated)[0]
        == 0
    )
    assert regenerated.read_bytes() == ROTARY_FILE.read_bytes()
    text = ' '.join(line for line in ROTARY_FILE.read_text().splitlines() if line.startswith('#'))
    assert 'Rotary hexapod (6-RUS)' in text and 'Crank angle limits (-1.2, 1.2) rad' in text
    assert '0.40 m circle' in text and '0.15 m cranks' in text and '0.25 m circle' in text


def test_shipped_gough_stewart_file_is_the_default_machine(capsys, tmp_path):
    """The data file equals default_parameters('gough_stewart') and is what `hexacal params default` writes."""
    contents = read_parameters_file(GS_FILE)
    assert contents.model == 'gough_stewart' and contents.extras == {}
    np.testing.assert_array_equal(contents.vector, default_parameters('gough_stewart').vector)
    regenerated = tmp_path / 'gs.yaml'
    assert (
        run(capsys, 'params', 'default', '--model', 'gough_stewart', '--out', regenerated)[0] == 0
    )
    assert regenerated.read_bytes() == GS_FILE.read_bytes()
    header = [line for line in GS_FILE.read_text().splitlines() if line.startswith('#')]
    text = ' '.join(header)
    assert (
        'Gough-Stewart' in text
        and 'Stroke limits (0, 0.5) m' in text
        and 'legs 0.60-1.10 m' in text
    )
    assert '0.50 m circle' in text and '0.20 m circle' in text
    # The header's leg range is the shipped l0 plus the stroke.
    low, high = architecture('gough_stewart').default_workspace().actuator_stroke_m
    offsets = contents.vector.reshape(6, 7)[:, 6]
    assert f'{offsets.min() + low:.2f}-{offsets.max() + high:.2f}' == '0.60-1.10'


# --- hexacal export -----------------------------------------------------------------------------------------------


@pytest.fixture
def gs_calibrated(tmp_path):
    """A Gough-Stewart parameters file with non-round values (nominal set 2) and an extra parameter."""
    path = tmp_path / 'gs_calibrated.yaml'
    save_parameters(
        path,
        nominal_set(2, seed=3, model='gough_stewart').vector,
        extras={'bag': 'bags/gs'},
        header_comment='hexacal calibrate (test)',
        model='gough_stewart',
    )
    return path


def parse_hal(text: str) -> tuple[dict[tuple[str, int, str], float], dict[int, float]]:
    """setp values {(base|platform, N, axis): value} and the commented HOME_OFFSET values {N: value}."""
    setps, homes = {}, {}
    for line in text.splitlines():
        if line.startswith('setp'):
            match = SETP.match(line)
            assert match, line
            key = (match[1], int(match[2]), match[3])
            assert key not in setps, line
            setps[key] = float(match[4])
        elif HOME_OFFSET.match(line):
            match = HOME_OFFSET.match(line)
            homes[int(match[1])] = float(match[2])
        else:
            assert line == '' or line.startswith('#'), (
                line
            )  # nothing else a HAL file would execute
    return setps, homes


@pytest.mark.parametrize(
    'unit, scale, tolerance', [(None, 1e3, 5e-7), ('mm', 1e3, 5e-7), ('m', 1.0, 5e-10)]
)
def test_linuxcnc_export_holds_the_files_joints(
    capsys, tmp_path, gs_calibrated, unit, scale, tolerance
):
    out = tmp_path / 'hexapod.hal'
    argv = ['export', gs_calibrated, '--format', 'linuxcnc', '--out', out]
    if unit:
        argv += ['--length-unit', unit]
    code, _, err = run(capsys, *argv)
    assert code == 0, err
    text = out.read_text()
    assert sum(line.startswith('setp') for line in text.splitlines()) == 36
    setps, homes = parse_hal(text)
    assert len(setps) == 36 and sorted(homes) == list(range(6))
    chains = read_parameters_file(gs_calibrated).vector.reshape(6, 7)
    for leg in range(6):  # leg 1 = N 0
        for k, axis in enumerate('xyz'):
            assert setps[('base', leg, axis)] == pytest.approx(
                chains[leg, k] * scale, abs=tolerance
            )
            assert setps[('platform', leg, axis)] == pytest.approx(
                chains[leg, 3 + k] * scale, abs=tolerance
            )
        assert homes[leg] == pytest.approx(chains[leg, 6] * scale, abs=tolerance)
    header = text.split('\nsetp', 1)[0]
    assert 'genhexkins' in header and str(gs_calibrated) in header
    assert f'Lengths in {unit or "mm"}' in header


def test_linuxcnc_strut_lengths_are_hexacals_leg_lengths(capsys, tmp_path, gs_calibrated):
    """genhexkins' strut |p + R platform.N - base.N| from the HAL values = hexacal's lambda + l0 (IK)."""
    out = tmp_path / 'hexapod.hal'
    assert run(capsys, 'export', gs_calibrated, '--format', 'linuxcnc', '--out', out)[0] == 0
    setps, homes = parse_hal(out.read_text())
    base = np.array([[setps[('base', n, a)] for a in 'xyz'] for n in range(6)]) / 1e3
    platform = np.array([[setps[('platform', n, a)] for a in 'xyz'] for n in range(6)]) / 1e3
    params = architecture('gough_stewart').parameters(read_parameters_file(gs_calibrated).vector)
    poses = np.array([[0.0, 0.0, -0.75, 0.0, 0.0, 0.0], [0.03, -0.02, -0.82, 0.05, -0.08, 0.1]])
    lengths = inverse_kinematics(params, poses) + np.array([homes[n] for n in range(6)]) / 1e3
    for pose, expected in zip(poses, lengths):
        rotation = rotation_matrices(pose[None, 3:])[0]
        struts = np.linalg.norm(pose[:3] + platform @ rotation.T - base, axis=1)
        np.testing.assert_allclose(struts, expected, atol=2e-9)


def test_linuxcnc_export_refuses_a_hexa_slide(capsys, tmp_path):
    out = tmp_path / 'slide.hal'
    code, _, err = run(capsys, 'export', TABLE1_FILE, '--format', 'linuxcnc', '--out', out)
    assert_one_line_error(code, err, 'hexa_slide', 'genhexkins', 'gough_stewart')
    assert not out.exists()


@pytest.mark.parametrize('model', MODELS)
def test_yaml_export_round_trips(capsys, tmp_path, model):
    source = tmp_path / 'source.yaml'
    vector = nominal_set(1, seed=2, model=model).vector
    save_parameters(source, vector, extras={'bag': 'bags/x', 'rank': 42}, model=model)
    out = tmp_path / 'exported.yaml'
    code, _, err = run(capsys, 'export', source, '--format', 'yaml', '--out', out)
    assert code == 0, err
    contents = read_parameters_file(out)
    assert contents.model == model
    np.testing.assert_array_equal(contents.vector, vector)
    assert contents.extras == {'bag': 'bags/x', 'rank': 42}
    assert out.read_text().startswith('# ') and str(source) in out.read_text().splitlines()[0]


@pytest.mark.parametrize('model', MODELS)
def test_json_export_round_trips(capsys, tmp_path, model):
    source = tmp_path / 'source.yaml'
    vector = nominal_set(3, seed=4, model=model).vector
    save_parameters(source, vector, extras={'bag': 'bags/x'}, model=model)
    out = tmp_path / 'exported.json'
    code, _, err = run(capsys, 'export', source, '--format', 'json', '--out', out)
    assert code == 0, err
    payload = json.loads(out.read_text())
    assert set(payload) == {'model', 'parameters'} and payload['model'] == model
    assert sorted(payload['parameters']) == [f'chain_{n}' for n in range(1, 7)]
    keys = {
        'hexa_slide': {'A0', 'B', 'a', 'l'},
        'gough_stewart': {'A', 'B', 'l0'},
        'rotary_hexapod': {'A', 'B', 'axis', 'r', 'l', 'alpha0'},
    }[model]
    assert all(set(chain) == keys for chain in payload['parameters'].values())
    np.testing.assert_array_equal(
        chain_dict_to_parameters(payload['parameters'], model=payload['model']), vector
    )


@pytest.mark.parametrize(
    'case',
    ['missing file', 'bad yaml', 'unknown format', 'unknown unit', 'unit with json', 'bad key'],
)
def test_bad_export_input_is_one_line_and_writes_nothing(capsys, tmp_path, gs_calibrated, case):
    source, extra = gs_calibrated, []
    fmt = 'linuxcnc'
    if case == 'missing file':
        source = tmp_path / 'nope.yaml'
    elif case == 'bad yaml':
        source = tmp_path / 'bad.yaml'
        source.write_text('/**:\n  ros__parameters: [unclosed\n')
    elif case == 'unknown format':
        fmt = 'xml'
    elif case == 'unknown unit':
        extra = ['--length-unit', 'inch']
    elif case == 'unit with json':
        fmt, extra = 'json', ['--length-unit', 'm']
    elif case == 'bad key':  # a Hexa Slide key in a Gough-Stewart file
        source = tmp_path / 'mixed.yaml'
        source.write_text(gs_calibrated.read_text().replace('chain_3.A:', 'chain_3.A0:'))
    out = tmp_path / 'out.hal'
    out.write_text('previous contents\n')
    code, stdout, err = run(capsys, 'export', source, '--format', fmt, '--out', out, *extra)
    assert_one_line_error(code, err, 'hexacal export: error:')
    assert {
        'missing file': 'nope.yaml',
        'bad yaml': 'invalid YAML',
        'unknown format': 'xml',
        'unknown unit': 'inch',
        'unit with json': '--length-unit',
        'bad key': 'chain_3.A0',
    }[case] in err
    assert out.read_text() == 'previous contents\n'
    assert (
        sorted(p.name for p in tmp_path.iterdir() if p.name.startswith('.')) == []
    )  # no temp file left


_MODULES_SCRIPT = r"""
import json, sys
from hexacal_identify import cli
try:
    code = cli.main(sys.argv[1:])
except SystemExit as exit:
    code = exit.code
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def test_export_help_is_fast_and_imports_no_numerics():
    completed = subprocess.run(
        [sys.executable, '-c', _MODULES_SCRIPT, 'export', '--help'],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ),
    )
    assert completed.returncode == 0, completed.stderr
    help_text, payload = (
        completed.stdout.rsplit('\n', 2)[0],
        json.loads(completed.stdout.splitlines()[-1]),
    )
    assert payload['code'] == 0
    assert '--format' in help_text and 'linuxcnc' in help_text and '--length-unit' in help_text
    heavy = ('matplotlib', 'scipy', 'numpy', 'rclpy', 'hexacal_identify.core')
    assert [
        m for m in payload['modules'] if any(m == h or m.startswith(h + '.') for h in heavy)
    ] == []


# --- issue #20: the INI beside the HAL file, controller files ------------------------------------


def read_ini(path: Path):
    import configparser

    ini = configparser.ConfigParser(comment_prefixes=('#',), inline_comment_prefixes=None)
    ini.optionxform = str
    ini.read_string(path.read_text())
    return ini


def test_linuxcnc_export_writes_the_ini_beside_the_hal(capsys, tmp_path, gs_calibrated):
    out = tmp_path / 'machine.hal'
    code, stdout, err = run(capsys, 'export', gs_calibrated, '--format', 'linuxcnc', '--out', out)
    assert code == 0, err
    assert stdout.splitlines() == [f'wrote {out}', f'wrote {tmp_path / "machine.ini"}']
    ini = read_ini(tmp_path / 'machine.ini')
    assert ini['KINS']['KINEMATICS'] == 'genhexkins'
    text = (tmp_path / 'machine.ini').read_text()
    assert 'Rz(C) Ry(B) Rx(A)' in text and 'R_Y(theta) R_X(psi) R_z(phi)' in text
    assert 'machine.hal' in text and str(gs_calibrated) in text
    offsets = read_parameters_file(gs_calibrated).vector.reshape(6, 7)[:, 6]
    for n in range(6):
        assert float(ini[f'JOINT_{n}']['HOME_OFFSET']) == pytest.approx(offsets[n] * 1e3, abs=5e-7)


def test_linuxcnc_home_options_move_the_homes(capsys, tmp_path, gs_calibrated):
    from hexacal_identify.core.machine.angle_conventions import linuxcnc_from_pose

    out = tmp_path / 'machine.hal'
    pose = [-0.01, -0.02, -0.8, 0.05, 0.02, -0.1]  # a negative first value is a value
    switches = [0.01, 0.02, 0.03, 0.04, 0.05, 0.06]
    argv = ['export', gs_calibrated, '--format', 'linuxcnc', '--out', out, '--length-unit', 'm']
    argv += ['--home-pose', ','.join(map(str, pose))]
    argv += ['--home-actuators', ','.join(map(str, switches)), '--stroke', '0.005,0.45']
    code, _, err = run(capsys, *argv)
    assert code == 0, err
    ini = read_ini(tmp_path / 'machine.ini')
    assert 'LINEAR_UNITS' not in ini['TRAJ']  # LinuxCNC has no metre unit: said in a comment
    home = [float(word) for word in ini['TRAJ']['HOME'].split()]
    np.testing.assert_allclose(home, linuxcnc_from_pose(np.array(pose)), atol=1e-9)
    params = architecture('gough_stewart').parameters(read_parameters_file(gs_calibrated).vector)
    offsets = params.leg_offsets
    struts = inverse_kinematics(params, [pose])[0] + offsets
    for n in range(6):
        joint = ini[f'JOINT_{n}']
        assert float(joint['HOME']) == pytest.approx(struts[n], abs=5e-10)
        assert float(joint['HOME_OFFSET']) == pytest.approx(offsets[n] + switches[n], abs=5e-10)
        assert float(joint['MIN_LIMIT']) == pytest.approx(offsets[n] + 0.005, abs=5e-10)
        assert float(joint['MAX_LIMIT']) == pytest.approx(offsets[n] + 0.45, abs=5e-10)


@pytest.mark.parametrize(
    'extra, fragment',
    [
        (['--home-pose', '0,0,-0.45,0,0,0'], 'outside the stroke'),
        (['--home-pose', '0,0,-0.8,0,0'], '--home-pose'),
        (['--home-actuators', '0,0,0,0,0,0.7'], '--home-actuators'),
        (['--stroke', '0.4,0.1'], '--stroke'),
        (['--stroke', 'a,b'], '--stroke'),
        (['--format', 'json', '--home-pose', '0,0,-0.8,0,0,0'], 'linuxcnc only'),
    ],
)
def test_bad_linuxcnc_home_options_write_nothing(capsys, tmp_path, gs_calibrated, extra, fragment):
    out = tmp_path / 'machine.hal'
    fmt = [] if '--format' in extra else ['--format', 'linuxcnc']
    code, _, err = run(capsys, 'export', gs_calibrated, *fmt, '--out', out, *extra)
    assert_one_line_error(code, err, 'hexacal export: error:', fragment)
    assert sorted(tmp_path.iterdir()) == [gs_calibrated]


def test_linuxcnc_out_must_not_be_the_ini(capsys, tmp_path, gs_calibrated):
    out = tmp_path / 'machine.ini'
    code, _, err = run(capsys, 'export', gs_calibrated, '--format', 'linuxcnc', '--out', out)
    assert_one_line_error(code, err, 'NAME.hal')
    assert not out.exists()


def _ik_from_description(payload: dict, pose: dict) -> np.ndarray:
    """Actuator readings by the formula the controller JSON states, from its chains alone."""
    p = np.array([pose['x'], pose['y'], pose['z']])
    rotation = rotation_matrices(np.array([[pose['theta'], pose['psi'], pose['phi']]]))[0]
    readings = []
    for chain in payload['chains']:
        if payload['model'] == 'hexa_slide':
            d = p + rotation @ np.array(chain['B']) - np.array(chain['A0'])
            a = np.array(chain['a'])
            readings.append(a @ d - np.sqrt(chain['l'] ** 2 - d @ d + (a @ d) ** 2))
        elif payload['model'] == 'rotary_hexapod':
            d = p + rotation @ np.array(chain['B']) - np.array(chain['A'])
            n, h = np.array(chain['n']), np.array(chain['h'])
            w = np.cross(n, h)
            k = (d @ d + chain['r'] ** 2 - chain['l'] ** 2) / (2 * chain['r'])
            phi = np.arctan2(d @ w, d @ h) + np.arccos(k / np.hypot(d @ h, d @ w))
            readings.append(np.mod(phi - chain['alpha0'] + np.pi, 2 * np.pi) - np.pi)
        else:
            d = p + rotation @ np.array(chain['B']) - np.array(chain['A'])
            readings.append(np.linalg.norm(d) - chain['l0'])
    return np.array(readings)


@pytest.mark.parametrize('model', MODELS)
def test_controller_json_describes_the_machine(capsys, tmp_path, model):
    source = tmp_path / 'calibrated.yaml'
    vector = nominal_set(2, seed=5, model=model).vector
    save_parameters(source, vector, model=model)
    out = tmp_path / 'controller.json'
    code, _, err = run(capsys, 'export', source, '--format', 'controller', '--out', out)
    assert code == 0, err
    payload = json.loads(out.read_text())
    assert payload['format'] == 'hexacal-controller' and payload['version'] == 1
    assert payload['model'] == model and payload['units'] == {'length': 'm', 'angle': 'rad'}
    assert 'R_Y(theta) R_X(psi) R_z(phi)' in payload['pose']['rotation']
    np.testing.assert_array_equal(
        chain_dict_to_parameters(payload['parameters'], model=model), vector
    )
    if model == 'hexa_slide':
        rails = np.array([chain['a'] for chain in payload['chains']])
        np.testing.assert_allclose(np.linalg.norm(rails, axis=1), 1.0, atol=1e-15)
        assert np.all(rails[:, 2] < 0)  # the sign a controller could not guess
    assert payload['actuator_unit'] == MODELS_UNIT[model]
    low, high = payload['stroke']
    assert low <= min(payload['home']['actuators']) and max(payload['home']['actuators']) <= high
    assert len(payload['checks']) >= 5
    for check in [payload['home'], *payload['checks']]:
        np.testing.assert_allclose(
            _ik_from_description(payload, check['pose']), check['actuators'], atol=1e-12
        )


def test_kinematics_node_file_names_a_copy_of_the_parameters(capsys, tmp_path):
    import yaml

    from hexacal_identify.calibration_steps.machine_files import load_machine_and_mount

    source = tmp_path / 'calibrated.yaml'
    vector = nominal_set(1, seed=6).vector
    save_parameters(source, vector, extras={'device.mount': 'standing'})
    out = tmp_path / 'node.yaml'
    code, stdout, err = run(capsys, 'export', source, '--format', 'kinematics-node', '--out', out)
    assert code == 0, err
    copy = tmp_path / 'node.parameters.yaml'
    assert stdout.splitlines() == [f'wrote {copy}', f'wrote {out}']
    settings = yaml.safe_load(out.read_text())['/**/kinematics']['ros__parameters']
    assert settings['parameters'] == str(copy.resolve())
    assert settings['follow_calibrations'] is False
    assert settings['stroke_limits'] == [0.0, 0.9] and settings['mount'] == 'standing'
    assert settings['link_length'] == 0.75
    params, mount = load_machine_and_mount(settings['parameters'])
    np.testing.assert_array_equal(params.vector, vector)
    assert mount == 'standing'


def test_kinematics_node_file_reaches_the_node_in_any_namespace(capsys, tmp_path):
    """Rcl gives the file's settings to a node named kinematics, namespaced or not."""
    import rclpy
    from rclpy.node import Node

    source = tmp_path / 'calibrated.yaml'
    save_parameters(source, nominal_set(1, seed=7).vector)
    out = tmp_path / 'node.yaml'
    assert run(capsys, 'export', source, '--format', 'kinematics-node', '--out', out)[0] == 0
    for namespace in ('', 'cell_2'):
        context = rclpy.Context()
        rclpy.init(args=['--ros-args', '--params-file', str(out)], context=context)
        try:
            node = Node(
                'kinematics',
                namespace=namespace,
                context=context,
                automatically_declare_parameters_from_overrides=True,
            )
            values = {name: node.get_parameter(name).value for name in ('parameters', 'mount')}
            node.destroy_node()
        finally:
            rclpy.shutdown(context=context)
        assert values == {
            'parameters': str((tmp_path / 'node.parameters.yaml').resolve()),
            'mount': 'hanging',
        }
