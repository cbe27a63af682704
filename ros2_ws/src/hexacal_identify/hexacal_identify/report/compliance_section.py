"""
The report's section of the axial compliances identified with the geometry.

Reads the ``compliance`` key of a result (``IdentificationResult.to_json()``: mode, unit,
values and standard deviations in m/N; absent for a rigid fit) and returns the HTML section:
each compliance with its standard deviation, the stiffness it means and the relative
uncertainty. A page of a rigid fit has no such section.
"""

from __future__ import annotations

import html
import math

COMPLIANCE_KEY = 'compliance'  # the result's key (core/fit/identification.py to_json)


def _finite(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def compliance_rows(compliance: dict) -> list[tuple[str, str, str, str, str]]:
    """
    Return one row per compliance: name, value, std (m/N), stiffness (N/m), relative std.

    Texts as the page shows them; 'n/a' where a figure is unknown (a held or unidentifiable
    compliance has no std, a compliance <= 0 no stiffness).
    """
    values = compliance.get('values') or {}
    stds = compliance.get('std') or {}
    rows = []
    for name, raw in values.items():
        value, std = _finite(raw), _finite(stds.get(name))
        stiffness = f'{1.0 / value:.4g}' if value is not None and value > 0 else 'n/a'
        relative = (
            f'{100.0 * std / abs(value):.1f} %' if std is not None and value else 'n/a'
        )
        rows.append((
            name,
            'n/a' if value is None else f'{value:.4g}',
            'n/a' if std is None else f'{std:.3g}',
            stiffness,
            relative,
        ))
    return rows


def compliance_section(payload: dict) -> str:
    """Return the HTML section of a result's identified compliances ('' for a rigid fit)."""
    compliance = payload.get(COMPLIANCE_KEY)
    if not compliance or not compliance.get('values'):
        return ''
    cells = ''.join(
        f"<tr id='compliance-{html.escape(name)}'>"
        + ''.join(f'<td>{html.escape(text)}</td>' for text in (name, *figures))
        + '</tr>'
        for name, *figures in compliance_rows(compliance)
    )
    mode = html.escape(str(compliance.get('mode', '')))
    note = (
        "<p class='note'>Axial compliances identified jointly with the geometry from the "
        'static load of each posture (the weights of the physical description through the '
        f'measuring mode), choice {mode}; +- one standard deviation. A chain compliance lies '
        "between the encoder and the joint centres; the link's is the measuring link's own "
        'stretch (calibration only). The kinematics node and hexacal verify use them with '
        'the weights of a physical description.</p>'
    )
    return (
        "<section><h2>Axial compliances</h2><table class='data' id='compliances'>"
        '<tr><th>compliance</th><th>identified (m/N)</th><th>std (m/N)</th>'
        '<th>stiffness (N/m)</th><th>relative std</th></tr>'
        f'{cells}</table>{note}</section>'
    )


__all__ = ['compliance_rows', 'compliance_section']
