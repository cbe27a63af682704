"""`hexacal demo` end to end (what `make demo` runs), small: plan, executor on the commanded machine,
calibration, verification plan, verification; everything under --out."""

from __future__ import annotations

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
    # Everything under --out: the bag (closed), plans, parameters, the report; nothing in the cwd's bags/.
    assert (out / 'bag' / 'metadata.yaml').exists()
    assert (out / 'plan.yaml').exists() and (out / 'verification_plan.yaml').exists()
    assert (out / 'calibration.yaml').exists()
    page = Path(re.search(r'^report:\s+(\S+)', text, re.M).group(1))
    assert page.exists() and str(page).startswith(str(out)), page
    assert 'erification' in page.read_text()
    assert not (tmp_path / 'bags').exists()
