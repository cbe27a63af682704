"""Start-up imports only what a command uses (#12 item 2); the times are in benchmarks/bench_startup.py.

Each check runs the command in a fresh interpreter (``hexacal_identify.cli.main``,
what the ``hexacal`` script calls) and reads ``sys.modules`` afterwards:
`hexacal --help` imports neither numpy nor scipy, `hexacal calibrate` neither
matplotlib nor the studies (it imports scipy's least_squares and QR where it
solves), and the node modules no scipy.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[1]
BAG = REPO / 'bags' / 'sphere50_noise10'

# Modules of the simulation studies and their figures: only `hexacal study` (and `plan`, `report`) need them.
STUDY_MODULES = (
    'hexacal_identify.studies.accuracy',
    'hexacal_identify.studies.defective_device',
    'hexacal_identify.core.assessment.uncertainty',
    'hexacal_identify.core.fit.baseline',
    'hexacal_identify.studies.planning',
    'hexacal_identify.report.figures',
)
HEAVY = ('matplotlib', 'scipy.optimize', *STUDY_MODULES)

_SCRIPT = r"""
import json, os, sys
from hexacal_identify import cli
try:
    code = cli.main(sys.argv[1:])
except SystemExit as exit:
    code = exit.code
with open(os.environ["HEXACAL_TEST_MODULES_OUT"], "w") as out:
    json.dump({"code": code, "modules": sorted(sys.modules)}, out)
"""


def modules_after(tmp_path: Path, *argv: str) -> tuple[int, list[str], str]:
    """(exit code, sys.modules after the command, its stdout + stderr)."""
    out = tmp_path / 'modules.json'
    completed = subprocess.run(
        [sys.executable, '-c', _SCRIPT, *argv],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ, HEXACAL_TEST_MODULES_OUT=str(out)),
    )
    assert out.exists(), completed.stdout + completed.stderr
    payload = json.loads(out.read_text())
    return payload['code'], payload['modules'], completed.stdout + completed.stderr


def imported(modules: list[str], names: tuple[str, ...]) -> list[str]:
    """The modules among `modules` that are one of `names` or inside one of them."""
    return [m for m in modules if any(m == name or m.startswith(name + '.') for name in names)]


def test_help_imports_neither_numpy_nor_scipy_nor_the_studies(tmp_path):
    code, modules, output = modules_after(tmp_path, '--help')
    assert code == 0, output
    assert 'calibrate' in output and 'study' in output
    assert imported(modules, ('numpy', 'scipy', 'rclpy', *HEAVY)) == []


@pytest.mark.parametrize('command', ['calibrate', 'bag-info', 'plan', 'params'])
def test_command_help_imports_no_matplotlib_nor_studies(tmp_path, command):
    code, modules, output = modules_after(tmp_path, command, '--help')
    assert code == 0, output
    assert imported(modules, ('matplotlib', 'scipy.optimize', 'rclpy', *STUDY_MODULES)) == []


def test_calibrate_imports_no_matplotlib_or_studies(tmp_path):
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_msgs_py.parameters_file import save_parameters

    nominal, output_file = tmp_path / 'nominal2.yaml', tmp_path / 'calibrated.yaml'
    save_parameters(nominal, nominal_set(2, seed=0).vector)
    code, modules, output = modules_after(
        tmp_path, 'calibrate', str(BAG), '--nominal', str(nominal), '--output', str(output_file)
    )
    assert code == 0, output
    assert output_file.exists(), output  # it did calibrate
    assert 'hexacal_identify.core.fit.identification' in modules
    assert 'hexacal_identify.core.assessment.identifiability' in modules
    assert 'scipy.optimize' in modules and 'scipy.linalg' in modules  # the solve's libraries
    assert imported(modules, ('rclpy', 'matplotlib', *STUDY_MODULES)) == []


def test_refused_calibration_imports_no_matplotlib_or_studies(tmp_path):
    """The sphere cost is rank 53: the refusal names the combination and what to fix."""
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_msgs_py.parameters_file import save_parameters

    nominal = tmp_path / 'nominal2.yaml'
    save_parameters(nominal, nominal_set(2, seed=0).vector)
    code, modules, output = modules_after(
        tmp_path,
        'calibrate',
        str(BAG),
        '--nominal',
        str(nominal),
        '--output',
        str(tmp_path / 'calibrated.yaml'),
        '--cost',
        'sphere',
    )
    assert code == 2, output
    assert 'rank 53 of 54' in output and 'A0z' in output
    assert imported(modules, ('matplotlib', *STUDY_MODULES)) == []


def test_the_check_sees_lazily_imported_modules(tmp_path):
    """`hexacal study --help` fills the study parser from the study modules: the check must see them."""
    code, modules, output = modules_after(tmp_path, 'study', '--help')
    assert code == 0, output
    assert '--monte-carlo' in output
    assert 'hexacal_identify.studies.planning' in imported(modules, HEAVY)


def test_node_modules_import_no_scipy_matplotlib_or_studies():
    script = (
        'import json, sys\n'
        'import hexacal_identify.nodes.collector, hexacal_identify.nodes.identify, hexacal_driver.driver_node\n'
        'print(json.dumps(sorted(sys.modules)))\n'
    )
    completed = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
    modules = json.loads(completed.stdout)
    assert 'rclpy' in modules
    assert imported(modules, ('scipy', *HEAVY)) == []
