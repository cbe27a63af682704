"""
Test planning and the report on a Gough-Stewart platform (#10): the model comes from the files.

Names come from its layout.

* ``hexacal plan --nominal GS.yaml`` plans within the Gough-Stewart workspace (leg extension
  0-0.5 m, +-250 mm, +-20 deg), records the model in the plan file and beats random postures of
  the same count; options given replace the architecture's defaults, and the U/S joint limits act
  through the architecture's joint angles.
* ``hexacal report`` of a Gough-Stewart calibration (a saved result, a plain ``--json`` output,
  and the result object the calibrate command and the identify node pass) names A, B, l0 and the
  legs, never the Hexa Slide's A0, a, l or its sliders.
"""

from __future__ import annotations

import html
import json
import re

from hexacal_identify.cli import main
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.measurements import (
    FIXED,
    Measurements,
    NoiseModel,
    simulate_measurements,
    SPHERE,
)
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.planner import Plan
from hexacal_identify.core.planning.posture_limits import PostureLimits
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.parameters_file import save_parameters
import matplotlib
import numpy as np
import pytest
from system_support import hexacal

GS = architecture('gough_stewart')
TRUE = GS.default_parameters()
NOMINAL = nominal_set(2, model='gough_stewart')
STROKE = (0.0, 0.5)  # the default Gough-Stewart machine's leg extension, m
HEXA_SLIDE_WORDS = (
    'A0',
    'slider',
    'rail',
)  # the other model's names: must not label a Gough-Stewart page


@pytest.fixture(scope='module')
def nominal_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('gs') / 'nominal.yaml'
    save_parameters(path, NOMINAL.vector, model='gough_stewart')
    return path


def _plan(nominal_file, out, *extra):
    code = main(
        [
            'plan',
            '--nominal',
            str(nominal_file),
            '--postures',
            '20',
            '--index',
            'O1',
            '--candidates',
            '600',
            '--seed',
            '1',
            '--out',
            str(out),
            '--json',
            *extra,
        ]
    )
    assert code == 0
    return Plan.load(out)


def test_gough_stewart_plan_records_the_model_stays_in_its_workspace_and_beats_random(
    nominal_file, tmp_path, capsys
):
    out = tmp_path / 'plan.yaml'
    plan = _plan(nominal_file, out)
    summary = json.loads(capsys.readouterr().out)
    assert summary['model'] == 'gough_stewart' and plan.model == 'gough_stewart'
    assert (
        '\n  model: gough_stewart\n' in out.read_text()
    )  # in the plan mapping, for the driver to check
    assert plan.metadata['model'] == 'gough_stewart' and plan.metadata['weighting'].startswith(
        'noise leg '
    )
    assert len(plan) == 20 and summary['rank'] == 42  # every Gough-Stewart parameter observed
    # Defaults are the architecture's workspace, not the Hexa Slide's (0.4 m, 35 deg, 0-0.9 m).
    workspace = GS.default_workspace()
    limits = plan.metadata['limits']
    assert (
        limits['actuator_stroke_m'] == list(STROKE)
        and limits['xy_range_m'] == workspace.xy_range_m
    )
    assert np.all(np.abs(plan.poses[:, :2]) <= workspace.xy_range_m + 1e-12)
    assert np.all(np.abs(plan.poses[:, 3:]) <= workspace.rotation_range_rad + 1e-12)
    legs = inverse_kinematics(NOMINAL, plan.poses)
    assert legs.shape == (20, 6) and np.all((legs >= STROKE[0]) & (legs <= STROKE[1]))
    assert GS.acceptable_poses(NOMINAL, plan.poses, workspace).all()
    # Planned beats random postures of the same count from the same candidates (20 random draws).
    random = summary['random_mean_indices']
    assert summary['indices']['O1'] > 1.3 * random['O1']
    assert summary['indices']['O3'] > random['O3']
    assert summary['indices']['I'] < random['I']  # predicted RMS position error, m


def test_given_options_replace_the_architecture_defaults_and_joint_limits_bite(
    nominal_file, tmp_path, capsys
):
    plan = _plan(
        nominal_file,
        tmp_path / 'narrow.yaml',
        '--stroke-m',
        '0.1',
        '0.4',
        '--max-u-joint-deg',
        '35',
        '--xy-range-mm',
        '150',
    )
    capsys.readouterr()
    legs = inverse_kinematics(NOMINAL, plan.poses)
    assert np.all((legs >= 0.1) & (legs <= 0.4))
    assert np.all(np.abs(plan.poses[:, :2]) <= 0.150 + 1e-12)
    base_cos, _ = GS.joint_cosines(NOMINAL, plan.poses)
    assert np.all(base_cos >= np.cos(np.radians(35.0)))
    # The 35 deg limit acts: the default workspace has postures beyond it.
    poses = sample_poses(NOMINAL, 400, np.random.default_rng(3), 'sphere', GS.default_workspace())
    base_cos, _ = GS.joint_cosines(NOMINAL, poses)
    assert not np.all(base_cos >= np.cos(np.radians(35.0)))
    limits = PostureLimits.for_machine(NOMINAL, max_u_joint_angle_rad=np.radians(35.0))
    assert not limits.check(NOMINAL, poses)['u_joint_angle'].all()
    # The old option name still works.
    plan = _plan(nominal_file, tmp_path / 'old.yaml', '--slider-stroke-m', '0.05', '0.45')
    capsys.readouterr()
    assert plan.metadata['limits']['actuator_stroke_m'] == [0.05, 0.45]


def test_standing_mount_plans_above_the_device_joint(nominal_file, tmp_path, capsys):
    out = tmp_path / 'standing.yaml'
    plan = _plan(nominal_file, out, '--mount', 'standing', '--cost', 'sphere-fixed')
    capsys.readouterr()
    assert plan.mount == 'standing' and '\n  mount: standing\n' in out.read_text()
    fixed = plan.kinds == FIXED
    assert fixed.any() and (~fixed).any()
    np.testing.assert_array_equal(
        plan.poses[fixed, :3], np.tile([0.0, 0.0, 0.75], (fixed.sum(), 1))
    )
    assert np.all(plan.poses[:, 2] > 0.0)


def test_hexa_slide_plan_files_name_no_model(tmp_path, capsys):
    out = tmp_path / 'hexa.yaml'
    assert (
        main(['plan', '--postures', '12', '--candidates', '200', '--out', str(out), '--json']) == 0
    )
    assert json.loads(capsys.readouterr().out)['model'] == 'hexa_slide'
    text = out.read_text()
    assert (
        'model:' not in text.split('\n', 1)[1] and 'mount:' not in text
    )  # as before: only the metadata names it
    plan = Plan.load(out)
    assert (
        plan.model == 'hexa_slide'
        and plan.mount == 'hanging'
        and plan.metadata['model'] == 'hexa_slide'
    )


def test_plan_loader_refuses_an_unknown_model(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text(
        'plan: {name: x, link_length: 0.75, model: delta_robot}\n'
        'postures: [{kind: sphere, pose: [0, 0, -0.75, 0, 0, 0]}]\n'
    )
    with pytest.raises(ValueError, match='delta_robot'):
        Plan.load(path)
    path.write_text(
        'plan: {name: x, link_length: 0.75, mount: sideways}\n'
        'postures: [{kind: sphere, pose: [0, 0, -0.75, 0, 0, 0]}]\n'
    )
    with pytest.raises(ValueError, match='sideways'):
        Plan.load(path)


# --------------------------------------------------------------------------- the report
@pytest.fixture(scope='module')
def calibration(tmp_path_factory):
    """Calibrate the default hexapod from nominal set 1 with noisy sphere + fixed postures."""
    # The truth is known.
    rng = np.random.default_rng(5)
    workspace = GS.default_workspace()
    noise = NoiseModel.from_microns(5.0)
    parts = [
        simulate_measurements(
            TRUE, sample_poses(TRUE, count, rng, kind, workspace), kind, noise=noise, rng=rng
        )
        for kind, count in ((SPHERE, 40), (FIXED, 12))
    ]
    measurements = Measurements.concatenate(parts)
    result = identify(
        nominal_set(1, seed=2, exact=TRUE), measurements, SolverOptions(cost='sphere-fixed')
    )
    assert result.reason == CONVERGED and result.parameters.model == 'gough_stewart'
    from hexacal_identify.report.page import save_result

    path = tmp_path_factory.mktemp('gs-result') / 'result.json'
    save_result(
        path,
        result,
        {'source': 'test_gough_stewart_plan_report'},
        measurements=measurements,
        true_parameters=TRUE,
    )
    return result, measurements, path


def _text(page: str) -> str:
    body = re.sub(r'<(script|style)[^>]*>.*?</\1>', ' ', page, flags=re.S)
    return re.sub(r'\s+', ' ', html.unescape(re.sub(r'<[^>]+>', ' ', body)))


def _assert_gough_stewart_page(text: str, all_parameters: bool = True) -> None:
    assert 'Gough-Stewart platform (6-UPS): 42 parameters, actuators leg_1..leg_6' in text
    assert 'Identified parameters: Gough-Stewart platform (6-UPS)' in text
    assert 'A [mm] B [mm] l0 [mm]' in text and 'leg_6' in text
    if (
        all_parameters
    ):  # the corrections table (needs the initial parameters: not in a plain --json output)
        for name in ('chain_1.Ax', 'chain_3.Bz', 'chain_6.l0'):
            assert name in text, name
    for word in HEXA_SLIDE_WORDS:
        assert word not in text, word


@pytest.mark.slow
def test_hexacal_report_of_a_gough_stewart_result(calibration, tmp_path):
    result, _, path = calibration
    out = tmp_path / 'report'
    completed = hexacal('report', str(path), '--out', str(out))
    assert completed.returncode == 0, completed.stderr
    page = (out / 'index.html').read_text(encoding='utf-8')
    text = _text(page)
    _assert_gough_stewart_page(text)
    assert f'Rank {result.rank} of 42' in text and 'All 42 parameters' in text
    # The per-leg table: A, B, l0 in mm, one row per leg with its actuator.
    table = re.search(
        r"<table class='data' id='identified-parameters'>(.*?)</table>", page, re.S
    ).group(1)
    assert re.findall(r'>(\w+) \[mm\]</th>', table) == ['A', 'B', 'l0']
    rows = re.findall(r'<tr><td>(chain_\d)</td><td>(leg_\d)</td>(.*?)</tr>', table)
    assert [(c, a) for c, a, _ in rows] == [(f'chain_{i}', f'leg_{i}') for i in range(1, 7)]
    l0_mm = [float(re.findall(r'<td>([-\d.]+)</td>', cells)[-1]) for _, _, cells in rows]
    np.testing.assert_allclose(l0_mm, result.parameters.per_chain[:, 6] * 1e3, atol=1e-4)
    for name in (
        'corrections',
        'parameter_errors',
        'chain_errors',
        'residuals',
        'singular_values',
        'pose_error_map',
        'postures',
    ):
        assert (out / f'{name}.png').stat().st_size > 1000, name
    # The workspace map covers the Gough-Stewart workspace (+-250 mm) and finds feasible cells
    # there.
    assert 'Median' in text and 'over the feasible cells' in text


def test_report_of_a_plain_gough_stewart_json_output(calibration, tmp_path):
    result, _, _ = calibration
    plain = tmp_path / 'plain.json'
    plain.write_text(json.dumps(result.to_json()))
    assert main(['report', str(plain), '--out', str(tmp_path / 'r')]) == 0
    page = (tmp_path / 'r' / 'index.html').read_text()
    text = _text(page)
    _assert_gough_stewart_page(text, all_parameters=False)
    # The parameters are read back from the chain dict with the model's keys (A, B, l0).
    l0 = result.parameters.per_chain[:, 6] * 1e3
    assert all(f'{value:.4f}' in text for value in l0)
    assert 'Not shown: the result file has no initial parameters' in text


def test_the_report_calibrate_and_identify_write_for_a_gough_stewart_result(calibration, tmp_path):
    """write_report(result, ...): what `hexacal calibrate --report` and the identify node call."""
    from hexacal_identify.report.page import write_report

    result, measurements, _ = calibration
    page = write_report(
        result,
        tmp_path / 'node',
        title='after calibration',
        measurements=measurements,
        link_length=0.75,
        extras={'source': 'bag'},
    )
    text = _text(page.read_text())
    _assert_gough_stewart_page(text)
    assert 'after calibration' in text and 'Not shown: the true parameters are not known' in text


@pytest.mark.slow
def test_calibrate_report_of_the_gough_stewart_sample_bag(nominal_file, tmp_path):
    """
    Run `hexacal calibrate BAG --nominal GS.yaml --report DIR` on the recorded hexapod bag.

    The page is a Gough-Stewart one.
    """
    from pathlib import Path

    bag = Path(__file__).resolve().parents[1] / 'bags' / 'gs_sphere50_noise10'
    if not bag.is_dir():
        pytest.skip(f'{bag} is not in this checkout')
    out = tmp_path / 'calibrate-report'
    completed = hexacal(
        'calibrate',
        str(bag),
        '--nominal',
        str(nominal_file),
        '--output',
        str(tmp_path / 'calibrated.yaml'),
        '--report',
        str(out),
    )
    assert completed.returncode == 0, completed.stderr
    text = _text((out / 'index.html').read_text(encoding='utf-8'))
    _assert_gough_stewart_page(text)
    assert 'Rank 42 of 42' in text and 'Postures used 50' in text
    assert (out / 'pose_error_map.png').stat().st_size > 1000


def test_a_result_whose_vectors_do_not_fit_its_model_is_refused(calibration, tmp_path):
    _, _, path = calibration
    payload = json.loads(path.read_text())
    payload['model'] = 'hexa_slide'  # 42 values under a 54-parameter model
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps(payload))
    completed = hexacal('report', str(bad), '--out', str(tmp_path / 'r'))
    assert completed.returncode == 2 and 'has 54 parameters' in completed.stderr


def test_parameter_figures_are_labelled_with_the_models_fields(monkeypatch, tmp_path):
    from hexacal_identify.report import figures as figures

    seen = []
    monkeypatch.setattr(figures, '_save', lambda fig, path: seen.append(fig) or path)
    errors = np.linspace(-1e-3, 1e-3, 42)
    figures.chain_errors(errors, errors / 100, 'chains', tmp_path / 'c.png')
    figures.parameter_errors(errors, errors / 100, 'errors', tmp_path / 'e.png')
    figures.parameter_corrections(errors, np.full(42, 1e-5), tmp_path / 'k.png')
    chains, per_parameter, corrections = seen
    fields = list(MODELS['gough_stewart'].fields)
    assert len(chains.axes) == 6
    assert [t.get_text() for t in chains.axes[0].get_xticklabels()] == fields
    assert (
        per_parameter.axes[0].get_xlabel()
        == 'parameter (chain-major: Ax Ay Az Bx By Bz l0 per chain)'
    )
    assert (
        corrections.axes[0].get_title() == 'Identified corrections'
    )  # no dimensionless field to scale
    for fig in seen:
        matplotlib.pyplot.close(fig)
