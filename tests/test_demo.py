"""
`hexacal demo` end to end (what `make demo` runs), small.

Plan, executor on the commanded machine, calibration, verification plan, verification, the
summary; everything under --out.  The compliant mode's drive figures before and after the
targets are refined are measured with real nodes in test_executor_refine.py and
test_measuring_modes_models.py, their summary in test_demo_refinement.py.
"""

from __future__ import annotations

import json
from pathlib import Path
import re

import pytest
from system_support import hexacal


@pytest.mark.slow
def test_demo_walks_plans_calibrates_verifies_and_keeps_everything_under_out(tmp_path):
    """
    `make demo`'s default is the paper's procedure: one actuator released per posture.

    The Hexa Slide walks its plan without a drive fault (the planner rehearsed every release),
    the commanded actuators stand at their setpoints, the calibration is sound, and the
    verification walk, without the truth, says so.
    """
    out = tmp_path / 'out'
    completed = hexacal(
        'demo', '--postures', '20', '--verify-postures', '8', '--out', out, timeout=900,
        cwd=tmp_path, script=True,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    text = completed.stdout
    assert 'the executor walks an O1 plan of 20 postures (mixed, passive_actuator)' in text, text
    # The calibration beats the nominal model against the simulated truth ...
    after = re.search(r'after \(calibrated\)\s+([\d.]+)', text)
    before = re.search(r'before \(nominal\)\s+([\d.]+)', text)
    assert after and before and float(after.group(1)) < 20.0 < 1000.0 < float(before.group(1)), (
        text
    )
    # ... and verification, without the truth, sees the same: mm before, the noise level after.
    nominal = re.search(r'^nominal\s+([\d.]+)', text, re.M)
    calibrated = re.search(r'^calibrated\s+([\d.]+)', text, re.M)
    assert nominal and calibrated, text
    assert float(nominal.group(1)) > 1000.0 and float(calibrated.group(1)) < 50.0, text
    assert re.search(r'threshold [\d.]+ um: pass', text), text
    # Everything under --out: the bag (closed), plans, parameters, the report; nothing in the
    # cwd's bags/.
    assert (out / 'bag' / 'metadata.yaml').exists()
    assert (out / 'plan.yaml').exists() and (out / 'verification_plan.yaml').exists()
    plan = (out / 'plan.yaml').read_text()
    assert 'measuring_mode: passive_actuator' in plan and 'released_actuator:' in plan
    assert (out / 'calibration.yaml').exists()
    page = Path(re.search(r'^report:\s+(\S+)', text, re.M).group(1))
    assert page.exists() and str(page).startswith(str(out)), page
    assert 'erification' in page.read_text()
    assert not (tmp_path / 'bags').exists()
    _check_summary(out / 'summary.json', text)


def _check_summary(path: Path, text: str) -> None:
    """summary.json holds what the demo printed, in SI units, with the figures of its mode."""
    summary = json.loads(path.read_text())
    assert summary['measuring_mode'] == 'passive_actuator', summary
    # A fixed posture may be given up after 5 inclinometer corrections (the released actuator
    # lets the platform drift centimetres before the first calibration); no sphere posture is.
    assert summary['postures'] >= 18, summary
    after = re.search(r'after \(calibrated\)\s+([\d.]+)\s+([\d.]+)', text)
    assert abs(summary['pose_error_mean_m'] * 1e6 - float(after.group(1))) <= 0.051, summary
    assert abs(summary['pose_error_max_m'] * 1e6 - float(after.group(2))) <= 0.051, summary
    # Stiff drives stand at their setpoints and report no force; there is no LVDT link.
    assert summary['max_force_n'] is None and summary['max_link_extension_m'] is None, summary
    deviation = re.search(r'from its setpoint: ([\d.]+) um', text)
    assert deviation, text
    assert abs(summary['max_actuator_deviation_m'] * 1e6 - float(deviation.group(1))) <= 0.051
    assert summary['max_actuator_deviation_m'] < 1e-6, summary
    # The verification as `hexacal verify --json` gives it, and as the table printed it.
    verification = summary['verification']
    assert {'model', 'postures', 'nominal', 'calibrated', 'improvement', 'threshold_m',
            'verdict'} <= set(verification), verification
    assert verification['postures'] >= 8 and verification['verdict'] == 'pass', verification
    calibrated = re.search(r'^calibrated\s+([\d.]+)', text, re.M)
    rms = verification['calibrated']['position_rms_m'] * 1e6
    assert abs(rms - float(calibrated.group(1))) <= 0.051, (verification, text)
    refinement = summary['refinement']
    # 20 postures stay below the Hexa Slide's first intermediate calibration (22): the
    # calibration plan is walked on nominal targets, the verification plan on the calibration's.
    assert refinement['refine_targets'] is True and refinement['rests_missed'] == 0, refinement
    assert refinement['targets_models'] == [], refinement
    assert refinement['verification_targets'] == 'calibration', refinement
    assert refinement['postures_on_nominal'] == summary['postures'], refinement
    assert refinement['postures_on_refined'] >= 8, refinement
    timings = summary['timings']
    stages = ('plan', 'walk', 'calibration', 'verification', 'report')
    assert set(timings) == {*stages, 'total'}, timings
    assert all(timings[stage] > 0 for stage in stages), timings  # each stage ran, and took time
    assert timings['total'] >= sum(timings[stage] for stage in stages), timings


@pytest.mark.slow
def test_demo_stops_on_a_drive_fault_naming_it(tmp_path):
    """
    Drives that fault stop the demo at once, naming the fault; it never hangs.

    The simulated drives' force limit set below what the rigid link makes compliant servos
    carry on the Hexa Slide (tens of newtons at the default 2e4 N/m before the targets are
    refined): the first move faults them, the executor pauses.
    """
    out = tmp_path / 'out'
    completed = hexacal(
        'demo', '--measuring-mode', 'compliant', '--driver-param', 'max_force_n=5.0',
        '--postures', '20', '--verify-postures', '0', '--out', out, timeout=300, cwd=tmp_path,
        script=True,
    )
    assert completed.returncode == 1, completed.stdout + completed.stderr
    assert re.search(
        r'the simulated drives faulted \(compliant\) while waiting for the executor to '
        r'walk the calibration plan: \S',
        completed.stderr,
    ), completed.stderr
    assert 'hexacal/driver/reset' in completed.stderr  # what the operator does next
    assert not (out / 'summary.json').exists()  # no summary of a run that did not calibrate
