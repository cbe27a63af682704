"""
`hexacal demo` end to end (what `make demo` runs), small.

Plan, executor on the commanded machine, calibration, verification plan, verification, the
summary; everything under --out.
"""

from __future__ import annotations

import json
from pathlib import Path
import re
import subprocess

import pytest
from rosproc import venv_executable


@pytest.mark.slow
def test_demo_walks_plans_calibrates_verifies_and_keeps_everything_under_out(tmp_path):
    out = tmp_path / 'out'
    completed = subprocess.run(
        [
            venv_executable('hexacal'),
            'demo',
            '--postures',
            '20',
            '--verify-postures',
            '8',
            # compliant is the demo's default while passive plans can jam (#18).
            '--measuring-mode',
            'compliant',
            '--out',
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    text = completed.stdout
    assert 'the executor walks an O1 plan of 20 postures' in text
    # The calibration beats the nominal model against the simulated truth ...
    after = re.search(r'after \(calibrated\)\s+([\d.]+)', text)
    before = re.search(r'before \(nominal\)\s+([\d.]+)', text)
    assert after and before and float(after.group(1)) < 50.0 < 1000.0 < float(before.group(1)), (
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
    assert (out / 'calibration.yaml').exists()
    page = Path(re.search(r'^report:\s+(\S+)', text, re.M).group(1))
    assert page.exists() and str(page).startswith(str(out)), page
    assert 'erification' in page.read_text()
    assert not (tmp_path / 'bags').exists()
    _check_summary(out / 'summary.json', text)


def _check_summary(path: Path, text: str) -> None:
    """summary.json holds what the demo printed, in SI units, with the figures of its mode."""
    summary = json.loads(path.read_text())
    assert summary['measuring_mode'] == 'compliant' and summary['postures'] == 20, summary
    after = re.search(r'after \(calibrated\)\s+([\d.]+)\s+([\d.]+)', text)
    assert abs(summary['pose_error_mean_m'] * 1e6 - float(after.group(1))) <= 0.051, summary
    assert abs(summary['pose_error_max_m'] * 1e6 - float(after.group(2))) <= 0.051, summary
    # Compliant servos carry a force; there is no LVDT link to extend.
    assert summary['max_force_n'] > 0 and summary['max_link_extension_m'] is None, summary
    deviation = re.search(r'from its setpoint: ([\d.]+) um', text)
    assert deviation, text
    assert abs(summary['max_actuator_deviation_m'] * 1e6 - float(deviation.group(1))) <= 0.051
    assert summary['max_actuator_deviation_m'] > 0  # the rigid link strains compliant servos
    force = re.search(r'largest actuator force: ([\d.]+) N', text)
    assert force and abs(summary['max_force_n'] - float(force.group(1))) <= 0.051, text
    # The verification as `hexacal verify --json` gives it, and as the table printed it.
    verification = summary['verification']
    assert {'model', 'postures', 'nominal', 'calibrated', 'improvement', 'threshold_m',
            'verdict'} <= set(verification), verification
    assert verification['postures'] == 8 and verification['verdict'] == 'pass', verification
    calibrated = re.search(r'^calibrated\s+([\d.]+)', text, re.M)
    rms = verification['calibrated']['position_rms_m'] * 1e6
    assert abs(rms - float(calibrated.group(1))) <= 0.051, (verification, text)
    _check_refinement(summary, text)
    timings = summary['timings']
    stages = ('plan', 'walk', 'calibration', 'verification', 'report')
    assert set(timings) == {*stages, 'total'}, timings
    assert all(timings[stage] > 0 for stage in stages), timings  # each stage ran, and took time
    assert timings['total'] >= sum(timings[stage] for stage in stages), timings


def _check_refinement(summary: dict, text: str) -> None:
    """
    Check the drive figures before -> after target refinement (#18), from the driver's rests.

    20 postures stay below the Hexa Slide's first intermediate calibration (22): the
    calibration plan is walked on nominal targets, the verification plan on the calibration's,
    where the rigid link barely strains the compliant servos.
    """
    refinement = summary['refinement']
    assert refinement['refine_targets'] is True and refinement['rests_missed'] == 0, refinement
    assert refinement['targets_models'] == [], refinement
    assert refinement['verification_targets'] == 'calibration', refinement
    assert refinement['postures_on_nominal'] == 20, refinement
    assert refinement['postures_on_refined'] == 8, refinement
    before, after = refinement['before'], refinement['after']
    assert before['rests'] >= 20 and after['rests'] >= 8, refinement  # corrections stop too
    # The largest deviation of the run is on nominal targets; on the calibration's it is gone.
    assert before['max_actuator_deviation_m'] == pytest.approx(
        summary['max_actuator_deviation_m'], rel=1e-6
    )
    assert after['max_actuator_deviation_m'] < 50e-6 < 1e-3 < before['max_actuator_deviation_m']
    assert after['max_force_n'] < 0.05 * before['max_force_n'], refinement
    assert before['max_move_force_n'] >= before['max_force_n'] > 0, refinement
    assert before['max_link_extension_m'] is None and after['max_link_extension_m'] is None
    assert 'before -> after refinement (20 postures on nominal targets -> 8 on refined ones)' in (
        text
    ), text


@pytest.mark.slow
def test_demo_stops_on_a_drive_fault_naming_it(tmp_path):
    """
    Drives that fault stop the demo at once, naming the fault; it never hangs.

    The simulated drives' force limit set below what the rigid link makes compliant servos
    carry on the Hexa Slide (tens of newtons at the default 2e4 N/m before the targets are
    refined): the first move faults them, the executor pauses.
    """
    out = tmp_path / 'out'
    completed = subprocess.run(
        [
            venv_executable('hexacal'),
            'demo',
            '--measuring-mode',
            'compliant',
            '--driver-param',
            'max_force_n=5.0',
            '--postures',
            '20',
            '--verify-postures',
            '0',
            '--out',
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert completed.returncode == 1, completed.stdout + completed.stderr
    assert re.search(
        r'the simulated drives faulted \(compliant\) while waiting for the executor to '
        r'walk the calibration plan: \S',
        completed.stderr,
    ), completed.stderr
    assert 'hexacal/driver/reset' in completed.stderr  # what the operator does next
    assert not (out / 'summary.json').exists()  # no summary of a run that did not calibrate


@pytest.mark.slow
def test_the_demo_measures_with_a_released_actuator_by_default(tmp_path):
    """
    `make demo`'s default is the paper's procedure: one actuator released per posture.

    The Hexa Slide walks its plan without a drive fault (the planner rehearsed every release),
    the commanded actuators stand at their setpoints, and the calibration is sound.
    """
    out = tmp_path / 'out'
    completed = subprocess.run(
        [venv_executable('hexacal'), 'demo', '--postures', '20', '--verify-postures', '0',
         '--out', str(out)],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    assert '(mixed, passive_actuator)' in completed.stdout, completed.stdout
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['measuring_mode'] == 'passive_actuator', summary
    # A fixed posture may be given up after 5 inclinometer corrections (the released actuator
    # lets the platform drift centimetres before the first calibration); no sphere posture is.
    assert summary['postures'] >= 18, summary
    assert summary['max_actuator_deviation_m'] < 1e-6, summary  # stiff drives, no strain
    assert summary['max_force_n'] is None and summary['max_link_extension_m'] is None
    assert summary['pose_error_mean_m'] < 20e-6, summary
    plan = (out / 'plan.yaml').read_text()
    assert 'measuring_mode: passive_actuator' in plan and 'released_actuator:' in plan
