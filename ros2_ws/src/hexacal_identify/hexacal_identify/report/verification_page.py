"""
The verification section (fresh postures, no ground truth) and the page that shows it alone.

``hexacal verify --report`` writes the page; a calibration report shows the section when its
result carries a verification.
"""

from __future__ import annotations

import html
from pathlib import Path

from hexacal_msgs_py.files import atomic_write
from hexacal_msgs_py.models import DEFAULT_MODEL
import numpy as np

from .markup import embedded_figure, MM, page, UM, vector, vector_or_none
from ..core.architectures import architecture
from ..core.jsonsafe import json_safe as _plain
from ..core.machine.device import DEFAULT_LINK_LENGTH_M, DEFAULT_MOUNT


def verification_section(verification: dict, figure) -> str:
    """
    Return the verification section.

    Nominal vs calibrated figures, verdict, and the per-posture figure.

    ``verification`` is ``VerificationResult.to_json(per_posture=True)`` (SI units, null for NaN);
    ``figure(name, draw)`` embeds a PNG (``_Sections.figure``).
    """
    title = 'Verification on fresh postures (no ground truth)'
    sets = {name: verification.get(name) or {} for name in ('nominal', 'calibrated')}

    def cell(name: str, key: str, scale: float, unit: str) -> str:
        value = sets[name].get(key)
        return 'n/a' if value is None else f'{value * scale:.2f} {unit}'

    rows = [
        ('Position error rms', 'position_rms_m', UM, 'um'),
        ('Position error max', 'position_max_m', UM, 'um'),
        ('Rotary error rms', 'rotary_rms_rad', UM, 'urad'),
    ]
    table = '<tr><th></th><th>nominal</th><th>calibrated</th></tr>'
    for label, key, scale, unit in rows:
        table += (
            f'<tr><th>{label}</th><td '
            f"id='verification-nominal-{key}'>{cell('nominal', key, scale, unit)}</td>"
            f"<td id='verification-calibrated-{key}'>"
            f'{cell("calibrated", key, scale, unit)}</td></tr>'
        )
    table += (
        '<tr><th>Forward kinematics failed</th>'
        + ''.join(
            f"<td id='verification-{name}-fk-failures'>"
            f'{int(sets[name].get("fk_failures") or 0)}</td>'
            for name in sets
        )
        + '</tr>'
    )
    improvement = verification.get('improvement')
    threshold = verification.get('threshold_m')
    summary_rows = [
        ('Postures', verification.get('postures'), 'verification-postures'),
        (
            'Improvement (nominal rms / calibrated rms)',
            'n/a' if improvement is None else f'{improvement:.1f} x',
            'verification-improvement',
        ),
        (
            'Threshold',
            ('n/a' if threshold is None else f'{threshold * UM:.2f} um')
            + (
                f' ({verification["threshold_source"]})'
                if verification.get('threshold_source')
                else ''
            ),
            'verification-threshold',
        ),
    ]
    noise = verification.get('expected_noise')
    if noise and noise.get('position_rms_m') is not None:
        summary_rows.append(
            (
                'Expected from reading noise alone',
                f'{noise["position_rms_m"] * UM:.2f} um, '
                f'{(noise.get("rotary_rms_rad") or 0) * UM:.2f} urad',
                'verification-expected-noise',
            )
        )
    summary_rows.append(
        (
            'Verdict',
            verification.get('verdict_reason') or verification.get('verdict'),
            'verification-verdict',
        )
    )
    summary = ''.join(
        f"<tr><th>{html.escape(str(k))}</th><td id='{i}'>{html.escape(str(v))}</td></tr>"
        for k, v, i in summary_rows
    )
    failures = ''
    for name in sets:
        failed = sets[name].get('failed_postures') or []
        if failed:
            items = ''.join(
                f'<li>posture {f.get("index")}: {html.escape(str(f.get("reason")))}</li>'
                for f in failed
            )
            failures += (
                f'<h3>Forward kinematics failed with the {name} parameters</h3><ul>{items}</ul>'
            )
    image = ''
    per_posture = verification.get('per_posture') or {}
    if per_posture.get('nominal_position_error_m') is not None:
        from . import figures

        # Written together (core.assessment.verification): both sets' errors are there.
        before = vector(per_posture['nominal_position_error_m'])
        after = vector(per_posture['calibrated_position_error_m'])
        rotary = [per_posture.get(f'{name}_rotary_error_rad') for name in sets]
        image = figure(
            'verification.png',
            lambda path: figures.verification_errors(
                before,
                after,
                threshold if threshold is not None else float('nan'),
                path,
                kinds=np.asarray(per_posture.get('kinds') or ['sphere'] * len(before)),
                nominal_rotary_rad=vector_or_none(rotary[0]),
                calibrated_rotary_rad=vector_or_none(rotary[1]),
            ),
        )
    text = (
        '<p>Fresh postures, not used in the fit: what the device measured (position by eq. 4, the '
        'fixed point for fixed-position postures; phi from the rotary sensor) against forward '
        'kinematics at the measured actuator readings, with the nominal and with the calibrated '
        'parameters.</p>'
    )
    return (
        f"<section id='verification'><h2>{title}</h2>{text}<table class='data' "
        "id='verification-figures'>"
        f"{table}</table><table class='summary'>{summary}</table>{failures}{image}</section>"
    )


def write_verification_report(
    verification: dict, out_dir: Path | str, *, title: str | None = None
) -> Path:
    """
    Write DIR/index.html with the verification section alone.

    DIR/index.html (+ verification.png) with the verification section alone (``hexacal verify
    --report``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    verification = _plain(verification)
    layout = architecture(verification.get('model') or DEFAULT_MODEL).layout

    def figure(name: str, draw) -> str:
        return embedded_figure(out, name, draw)

    rows = [
        ('Machine model', f'{layout.title}'),
        ('Source', verification.get('source') or 'n/a'),
        ('Nominal parameters', verification.get('nominal_file') or 'n/a'),
        ('Calibrated parameters', verification.get('calibrated_file') or 'n/a'),
        (
            'Device',
            f'link {(verification.get("link_length_m") or DEFAULT_LINK_LENGTH_M) * MM:.1f} mm, '
            f'{verification.get("mount") or DEFAULT_MOUNT}',
        ),
    ]
    header = ''.join(
        f'<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>' for k, v in rows
    )
    sections = [
        f"<section><h2>Summary</h2><table class='summary'>{header}</table></section>",
        verification_section(verification, figure),
    ]
    return atomic_write(
        out / 'index.html', page(title or 'hexacal verification report', sections, layout)
    )
