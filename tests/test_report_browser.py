"""The calibration report opens offline in a real browser: every image decodes, the key numbers are on the page.

Runs a small identification, saves the result file, runs ``hexacal report`` as a
subprocess and loads the page in headless Chromium (Debian's package, installed
by scripts/ensure_chromium.sh from ``make test``).  Without Chromium the test
skips and says why.
"""

from __future__ import annotations

import html
import os
import re
import shutil
import subprocess

from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.machine.measurements import (
    FIXED,
    Measurements,
    NoiseModel,
    simulate_measurements,
    SPHERE,
)
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.report.page import save_result
from hexacal_msgs_py.result_file import read_result_file
import numpy as np
import pytest
from system_support import hexacal

TRUE = table1_parameters()
CHROMIUM_FLAGS = [
    '--headless',
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    '--disable-extensions',
    '--allow-file-access-from-files',
]


def _chromium() -> str:
    for candidate in (
        '/usr/bin/chromium',
        shutil.which('chromium'),
        shutil.which('chromium-browser'),
    ):
        if candidate and os.access(candidate, os.X_OK):
            return candidate
    pytest.skip(
        'Chromium is not installed (/usr/bin/chromium missing; scripts/ensure_chromium.sh installs it '
        'as root with apt-get): the report was not checked in a browser'
    )


@pytest.fixture(scope='module')
def calibration(tmp_path_factory):
    """A small sphere + fixed-position calibration with noise, truth known; saved with save_result."""
    rng = np.random.default_rng(11)
    noise = NoiseModel.from_microns(5.0)
    parts = [
        simulate_measurements(
            TRUE, sample_poses(TRUE, count, rng, kind), kind, noise=noise, rng=rng
        )
        for kind, count in ((SPHERE, 30), (FIXED, 10))
    ]
    measurements = Measurements.concatenate(parts)
    result = identify(nominal_set(1, seed=3), measurements, SolverOptions(cost='sphere-fixed'))
    assert result.reason == CONVERGED
    path = tmp_path_factory.mktemp('result') / 'result.json'
    save_result(
        path,
        result,
        {'source': 'test_report_browser'},
        measurements=measurements,
        true_parameters=TRUE,
    )
    return result, path


def test_result_file_is_a_superset_of_the_json_output(calibration):
    result, path = calibration
    payload = read_result_file(path)
    for key, value in result.to_json().items():
        assert key in payload, key
    data = payload['report_data']
    assert len(data['parameters']) == 54 and len(data['covariance']) == 54
    assert len(data['poses']) == len(result.used_postures) == len(data['kinds'])
    assert data['true_parameters'] is not None and data['verdict']


def test_write_report_takes_a_result_directly(calibration, tmp_path):
    """What the identify node calls after a calibration: no result file needed."""
    from hexacal_identify.report.page import write_report

    result, _ = calibration
    page = write_report(result, tmp_path / 'node-report', title='after calibration')
    text = page.read_text()
    assert 'after calibration' in text and f'{result.rank} of 54' in text
    assert 'Not shown: the true parameters are not known' in text


@pytest.mark.slow
def test_report_loads_in_headless_chromium_with_every_image_and_the_key_numbers(
    calibration, tmp_path
):
    result, path = calibration
    out = tmp_path / 'report'
    completed = hexacal('report', str(path), '--out', str(out))
    assert completed.returncode == 0, completed.stderr
    page = out / 'index.html'
    assert page.is_file() and f'wrote {page}' in completed.stdout
    source = page.read_text(encoding='utf-8')
    # Self-contained: nothing to fetch (images are data URIs; no remote script, style or font).
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", source, re.I)
    expected_images = len(re.findall(r'<img\b', source))
    assert (
        expected_images >= 7
    )  # corrections, 2 truth figures, residuals, singular values, error map, postures
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

    browser = _chromium()
    profile = tmp_path / 'chromium-profile'
    dumped = subprocess.run(
        [
            browser,
            *CHROMIUM_FLAGS,
            f'--user-data-dir={profile}',
            '--virtual-time-budget=10000',
            '--dump-dom',
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=180,
        env={**os.environ, 'HOME': str(tmp_path)},
    )
    assert dumped.returncode == 0, dumped.stderr[-2000:]
    dom = dumped.stdout
    body = re.search(r'<body([^>]*)>', dom)
    assert body, dom[:500]
    loaded = re.search(r'data-images-loaded="(\d+)"', body.group(1))
    total = re.search(r'data-images-total="(\d+)"', body.group(1))
    assert loaded and total, f"the page's image check did not run: <body{body.group(1)}>"
    assert int(total.group(1)) == expected_images
    assert int(loaded.group(1)) == expected_images, 'an image did not decode in the browser'

    text = html.unescape(
        re.sub(r'<[^>]+>', ' ', re.sub(r'<(script|style)[^>]*>.*?</\1>', ' ', dom, flags=re.S))
    )
    text = re.sub(r'\s+', ' ', text)
    assert f'Rank {result.rank} of 54' in text
    assert f'Outcome {result.reason}' in text
    for channel, value in result.rms_residual.items():
        unit = 'urad' if channel.startswith('phi') else 'um'
        assert f'RMS residual {channel} {value * 1e6:.3f} {unit}' in text, channel
    assert f'{result.condition_number:.4g}' in text
    assert 'all 54 parameters identifiable' in text


def test_report_of_a_plain_json_output_says_what_is_missing(calibration, tmp_path):
    import json

    result, _ = calibration
    plain = tmp_path / 'plain.json'
    plain.write_text(json.dumps(result.to_json()))
    completed = hexacal('report', str(plain), '--out', str(tmp_path / 'r'))
    assert completed.returncode == 0, completed.stderr
    page = (tmp_path / 'r' / 'index.html').read_text()
    assert 'Not shown' in page and 'singular_values' in page
    bad = tmp_path / 'bad.json'
    bad.write_text('{}')
    completed = hexacal('report', str(bad), '--out', str(tmp_path / 'r2'))
    assert completed.returncode == 2 and 'not a hexacal result' in completed.stderr


@pytest.mark.slow
def test_report_with_a_verification_section_loads_in_headless_chromium(calibration, tmp_path):
    """What identify writes after hexacal/verify: the calibration's page with the verification section and its
    figure; every image decodes and the verification figures are on the page in um / urad."""
    from hexacal_identify.core.assessment.verification import verify
    from hexacal_identify.report.page import write_report

    result, _ = calibration
    rng = np.random.default_rng(12)
    fresh = simulate_measurements(
        TRUE,
        sample_poses(TRUE, 20, rng, SPHERE),
        SPHERE,
        noise=NoiseModel.from_microns(5.0),
        rng=rng,
    )
    checked = verify(result.initial_parameters, result.parameters, fresh)
    out = tmp_path / 'verified'
    page = write_report(
        result,
        out,
        title='after verification',
        measurements=None,
        verification=checked.to_json(per_posture=True),
    )
    assert (out / 'verification.png').stat().st_size > 1000
    source = page.read_text(encoding='utf-8')
    expected_images = len(re.findall(r'<img\b', source))
    browser = _chromium()
    dumped = subprocess.run(
        [
            browser,
            *CHROMIUM_FLAGS,
            f'--user-data-dir={tmp_path / "profile"}',
            '--virtual-time-budget=10000',
            '--dump-dom',
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=180,
        env={**os.environ, 'HOME': str(tmp_path)},
    )
    assert dumped.returncode == 0, dumped.stderr[-2000:]
    body = re.search(r'<body([^>]*)>', dumped.stdout)
    assert body and f'data-images-loaded="{expected_images}"' in body.group(1), body
    text = html.unescape(
        re.sub(
            r'<[^>]+>',
            ' ',
            re.sub(r'<(script|style)[^>]*>.*?</\1>', ' ', dumped.stdout, flags=re.S),
        )
    )
    text = re.sub(r'\s+', ' ', text)
    figures = checked.to_json()
    assert 'Verification on fresh postures' in text
    assert (
        f'Position error rms {figures["nominal"]["position_rms_m"] * 1e6:.2f} um '
        f'{figures["calibrated"]["position_rms_m"] * 1e6:.2f} um'
    ) in text
    assert f'Rotary error rms {figures["nominal"]["rotary_rms_rad"] * 1e6:.2f} urad' in text
    assert f'Verdict {checked.verdict_reason()}' in text
