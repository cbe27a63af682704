"""
The user guide's offline examples, run as printed (docs/user-guide.md).

Every ``hexacal`` line of the guide that needs no running machine runs here, as written, in a
directory dressed as the guide's: `nominal.yaml` (nominal set 2), `bags/measure`,
`bags/verify` and `bags/measure2` (the sample bags of bags/, recorded by the real nodes from
the same Table 1 machine). The placeholder ids of the store example (`3f2a91c0`, ...) are the
ids the store gives, in the order the example names them. The guide's own-machine lines that
walk a machine (bringup, ros2 launch, and the commands on what they leave) run in
tests/test_own_machine.py.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import re
import shlex

from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.parameters_file import save_parameters
import pytest
from system_support import hexacal

REPO = Path(__file__).resolve().parents[1]
GUIDE = REPO / 'docs' / 'user-guide.md'
BAGS = {
    'measure': REPO / 'bags' / 'sphere50_noise10',
    'verify': REPO / 'bags' / 'sphere60_fixed20_noise10',
    'measure2': REPO / 'bags' / 'sphere30_nonoise',
}
PLAN_TIMEOUT_S = 1800.0
PLACEHOLDER_ID = re.compile(r'^[0-9a-f]{8}$')


def section(heading: str) -> str:
    """Return the text of the guide's section `heading` (up to the next heading)."""
    text = GUIDE.read_text()
    start = text.index(f'\n{heading}\n')
    end = text.index('\n#', start + 1)
    return text[start:end]


def hexacal_lines(text: str) -> list[str]:
    """Return every ``hexacal ...`` line of the fenced blocks of `text` (continuations joined)."""
    lines = []
    for block in re.findall(r'```(?:sh|console)\n(.*?)```', text, re.S):
        for line in block.replace('\\\n', ' ').splitlines():
            command = line.split('  #')[0].strip()
            if command.startswith('hexacal '):
                lines.append(command)
    return lines


@pytest.fixture
def guide_directory(tmp_path, monkeypatch) -> Path:
    save_parameters(tmp_path / 'nominal.yaml', nominal_set(2, seed=0).vector)
    (tmp_path / 'bags').mkdir()
    for name, bag in BAGS.items():
        os.symlink(bag, tmp_path / 'bags' / name)
    (tmp_path / 'out').mkdir()
    # Where `--store` alone would keep a calibration: nowhere of the user's.
    monkeypatch.setenv('HEXACAL_STORE', str(tmp_path / 'machine-stores'))
    return tmp_path


def run(argv: list[str], directory: Path, timeout: float = 300.0):
    assert argv[0] == 'hexacal'
    completed = hexacal(*argv[1:], cwd=directory, timeout=timeout)
    assert completed.returncode == 0, (argv, completed.stdout, completed.stderr)
    return completed


@pytest.mark.slow
def test_the_offline_calibration_runs_as_printed_and_joins_no_store(guide_directory):
    (line,) = [
        line for line in hexacal_lines(section('### Measure and calibrate')) if 'calibrate' in line
    ]
    completed = run(shlex.split(line), guide_directory)
    assert (guide_directory / 'out' / 'offline.yaml').is_file()
    assert 'not stored in a calibration store' in completed.stdout
    assert not (guide_directory / 'machine-stores').exists()


@pytest.mark.slow
def test_the_store_example_runs_as_printed_and_its_rollback_rolls_back(guide_directory):
    lines = hexacal_lines(section('### Keep, deploy, roll back'))
    assert lines[-1].startswith('hexacal rollback'), lines
    placeholders: dict[str, str] = {}
    outputs = []
    for line in lines:
        argv = shlex.split(line)
        for index, word in enumerate(argv):
            if PLACEHOLDER_ID.match(word) and argv[0:2] == ['hexacal', 'deploy']:
                if word not in placeholders:  # the next calibration the example has not named
                    history = json.loads(
                        run(['hexacal', 'history', '--store', 'store', '--json'], guide_directory)
                        .stdout
                    )
                    placeholders[word] = history[len(placeholders)]['short_id']
                argv[index] = placeholders[word]
        outputs.append(run(argv, guide_directory).stdout)
    assert len(placeholders) == 2, placeholders  # two calibrations deployed in turn
    first, second = placeholders.values()
    assert f'rolled back to {first}' in outputs[-1]
    states = {
        entry['short_id']: entry['state']
        for entry in json.loads(
            run(['hexacal', 'history', '--store', 'store', '--json'], guide_directory).stdout
        )
    }
    assert states == {first: 'active', second: 'rolled-back'}


@pytest.mark.slow
def test_the_guides_plans_run_as_printed_with_no_inf_and_say_what_a_short_plan_is_for(
    guide_directory,
):
    lines = [line for line in hexacal_lines(section('### Plan')) if 'hexacal plan' in line]
    assert len(lines) == 2, lines  # the measurement's plan, the verification's
    # Planning rehearses every release on several machines: minutes, far more on a busy machine.
    outputs = [run(shlex.split(line), guide_directory, PLAN_TIMEOUT_S).stdout for line in lines]
    for output in outputs:
        assert not re.search(r'\binf\b', output), output
    # 8 postures cannot identify the 54 parameters: said as what it means for a verification.
    verification = outputs[1]
    assert 'of 54 parameters' in verification, verification
    assert 'as a verification plan that is fine' in verification, verification
    assert (guide_directory / 'plan.yaml').is_file()
    assert (guide_directory / 'verify_plan.yaml').is_file()
