"""``hexacal plan --measuring-mode M`` as a user runs it (a subprocess), on both models (#18)."""

import json
from pathlib import Path
import re
import subprocess
import sys

from hexacal_identify.core.planning.planner import Plan
from hexacal_msgs_py.plan_file import read_plan_file
import pytest


def hexacal(*args):
    return subprocess.run(
        [sys.executable, '-m', 'hexacal_identify.cli', *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
    )


def _nominal(tmp_path: Path, model: str) -> Path:
    path = tmp_path / f'{model}.yaml'
    done = hexacal('params', 'default', '--model', model, '--out', path)
    assert done.returncode == 0, done.stderr
    return path


@pytest.mark.parametrize('model', ['hexa_slide', 'gough_stewart'])
def test_plan_in_passive_actuator_mode_writes_and_names_the_released_actuators(tmp_path, model):
    out = tmp_path / 'passive.yaml'
    common = ('--postures', 10, '--candidates', 200, '--nominal', _nominal(tmp_path, model))
    done = hexacal('plan', *common, '--measuring-mode', 'passive_actuator', '--out', out)
    assert done.returncode == 0, done.stderr
    contents = read_plan_file(out)
    assert contents.measuring_mode == 'passive_actuator'
    released = contents.released_actuators
    prefix = 'slider' if model == 'hexa_slide' else 'leg'
    assert len(released) == 10 and all(name.startswith(f'{prefix}_') for name in released)
    assert 'measuring mode passive_actuator' in done.stdout
    for index, name in enumerate(released):  # the text names each posture's released actuator
        assert f' {index:>3} {name} (' in done.stdout
    assert 'chosen max' in done.stdout and 'the worst actuator to release' in done.stdout
    # Off a terminal, a line per stage on stderr; the report gives each stage's time (#28).
    stages = [line for line in done.stderr.splitlines() if line.startswith('hexacal plan: ')]
    assert stages == ['hexacal plan: candidates', 'hexacal plan: selection',
                      'hexacal plan: rehearsal of the releases']
    assert re.search(r'candidates [\d.]+ s, selection [\d.]+ s, rehearsal [\d.]+ s',
                     done.stdout)
    assert Plan.load(out).released_actuators == released
    summary = hexacal('plan', *common, '--out', tmp_path / 'j.yaml', '--json')
    assert summary.returncode == 0, summary.stderr
    data = json.loads(summary.stdout)
    assert data['measuring_mode'] == 'passive_actuator'  # the default
    assert data['released_actuators'] == list(released)
    assert data['released_condition_max'] < data['worst_condition_max']
    assert data['rehearsal_seconds'] > 0 and summary.stderr == ''  # --json: no progress lines


def test_plan_in_lvdt_and_compliant_modes(tmp_path):
    lvdt = hexacal(
        'plan', '--postures', 8, '--candidates', 200, '--measuring-mode', 'lvdt',
        '--lvdt-stroke-m', 0.004, '--out', tmp_path / 'lvdt.yaml', '--json',
    )
    assert lvdt.returncode == 0, lvdt.stderr
    data = json.loads(lvdt.stdout)
    assert data['measuring_mode'] == 'lvdt' and data['lvdt_stroke_m'] == 0.004
    assert len(data['lvdt_extension_m']) == 8 and data['lvdt_inside']
    plan = read_plan_file(tmp_path / 'lvdt.yaml')
    assert plan.measuring_mode == 'lvdt' and plan.released_actuators == ()
    text = hexacal(
        'plan', '--postures', 8, '--candidates', 200, '--measuring-mode', 'compliant',
        '--out', tmp_path / 'compliant.yaml',
    )
    assert text.returncode == 0, text.stderr
    assert 'measuring mode compliant' in text.stdout and 'released' not in text.stdout
    assert 'rehearsal' not in text.stdout and 'hexacal plan: selection' in text.stderr
    assert read_plan_file(tmp_path / 'compliant.yaml').measuring_mode == 'compliant'
    refused = hexacal(
        'plan', '--postures', 8, '--measuring-mode', 'rigid', '--out', tmp_path / 'x.yaml'
    )
    assert refused.returncode == 2 and "invalid choice: 'rigid'" in refused.stderr


@pytest.mark.slow
def test_plan_reports_the_links_predicted_load_with_the_weights(tmp_path):
    from hexacal_identify.core.architectures import default_parameters
    from hexacal_identify.core.fit.statics import MassModel
    from hexacal_identify.core.modes.link_load import released_link_forces
    from hexacal_msgs_py.physical_file import default_physical, write_physical_file

    physical = write_physical_file(tmp_path / 'physical.yaml', default_physical('hexa_slide'))

    def plan(limit_n: float, out: Path) -> dict:
        done = hexacal(
            'plan', '--postures', 10, '--candidates', 200, '--physical', physical,
            '--max-link-force-n', limit_n, '--out', out, '--json',
        )
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout)

    free = plan(1e9, tmp_path / 'free.yaml')  # as chosen for the conditioning alone
    out = tmp_path / 'loaded.yaml'
    data = plan(400.0, out)
    forces, moves = data['link_force_n'], data['link_move_force_n']
    assert len(forces) == 10 and data['link_force_limit_n'] == 400.0
    # Postures whose release loads the link beyond the limit, there or on the way (from the
    # swap of the releases at the posture before), were left out, and chosen again.
    assert max(free['link_move_force_n']) > 400.0 >= max(moves) >= max(forces), (free, data)
    assert data['link_move_force_max_n'] == max(moves)
    assert data['link_overloaded_postures'] == []
    plan_file = Plan.load(out)
    assert plan_file.metadata['link_overloaded_left_out'] > 0
    # The load of each posture with its release, as the statics give it on the plan's nominal
    # (Table 1 without --nominal).
    chains = [f'slider_{i}' for i in range(1, 7)]
    released = [chains.index(name) for name in plan_file.released_actuators]
    expected = released_link_forces(
        default_parameters('hexa_slide'), plan_file.poses, MassModel.load(physical)
    )[range(10), released]
    assert forces == pytest.approx(expected.tolist(), rel=1e-9)
    # A move starts where the posture before stands, this posture's release already swapped in.
    swaps = released_link_forces(
        default_parameters('hexa_slide'), plan_file.poses[:-1], MassModel.load(physical)
    )[range(9), released[1:]]
    assert moves[0] == forces[0] and all(
        move >= max(force, swap) - 1e-9 for move, force, swap in zip(moves[1:], forces[1:], swaps)
    )
    missing = tmp_path / 'missing.yaml'
    refused = hexacal('plan', '--postures', 4, '--physical', missing, '--out', tmp_path / 'x.yaml')
    assert refused.returncode == 2 and 'missing.yaml' in refused.stderr, refused.stderr
