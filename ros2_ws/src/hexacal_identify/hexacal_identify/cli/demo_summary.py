"""
The demo's summary: what the drives went through and how well it calibrated (ROS-free).

``hexacal demo`` writes ``summary.json`` into its work directory (docs/formats.md, summary.json):
the measuring mode, the postures, the simulated drives' figures from the driver's status
``hexacal driver`` (the TRUE positions of the commanded actuators vs their setpoints at rest,
the force of compliant servos, the extension of an LVDT link), the pose errors against the
simulated truth (the demo's pose table) and the verification figures as identify kept them in
the calibration store: the object of ``hexacal verify --json`` (VerificationResult.to_json, one
owner of those keys). SI units; a figure that does not apply to the mode is null.  The
actuator figures keep their slider names (``max_actuator_deviation_m``, ``max_force_n``) and are
in the model's actuator units, which ``actuator_unit`` names: m and N, or rad and N m for
actuators that turn.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

from hexacal_msgs_py.files import atomic_write
from hexacal_msgs_py.measuring_modes import LINK_FORCE_LIMIT_N, MeasuringMode
from hexacal_msgs_py.models import MODELS

SUMMARY_FILE = 'summary.json'
UM = 1e6


def status_number(values: Mapping[str, str], key: str) -> float | None:
    """Return a status value as a finite float; None when missing, empty or not a number."""
    try:
        number = float(values.get(key, '') or 'nan')
    except ValueError:
        return None
    return number if math.isfinite(number) else None


def driver_figures(values: Mapping[str, str], mode: str) -> dict[str, float | None]:
    """
    Return the drives' figures of a measuring mode from the driver's status values (SI).

    The largest true deviation of a commanded actuator from its setpoint at rest; the largest
    link extension (lvdt, else None), the largest actuator force and the largest force of the
    measuring link (the compliant drives' modelled one, or the MuJoCo machine's in any mode; a
    driver that does not report it: None).
    """
    return {
        'max_actuator_deviation_m': status_number(values, 'max_actuator_deviation_m'),
        'max_link_extension_m': (
            status_number(values, 'max_link_extension_m') if mode == MeasuringMode.LVDT else None
        ),
        'max_force_n': (
            status_number(values, 'max_force_n') if mode == MeasuringMode.COMPLIANT else None
        ),
        # The compliant drives' modelled force, or the MuJoCo link's in every mode.
        'max_link_force_n': status_number(values, 'max_link_force_n'),
    }


def build_summary(
    *,
    model: str,
    measuring_mode: str,
    postures: int,
    driver_values: Mapping[str, str],
    pose_errors: Mapping[str, Any],
    verification: Mapping[str, Any] | None,
    refinement: Mapping[str, Any] | None = None,
    physics: str = 'kinematic',
    fit: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """
    Return the summary.json object (docs/formats.md).

    ``pose_errors``: the calibrated model's PoseErrors.summary() against the simulated truth;
    ``verification``: the ``hexacal verify --json`` object (None: no verification);
    ``refinement``: the figures before / after target refinement (demo_refinement.py; None:
    the key is left out); ``physics``: the machine the driver simulated (kinematic, mujoco);
    ``fit``: identify's calibration status values (its ``adequacy.*`` keys; None or without
    them: the verdict is unknown).
    """
    return {
        'model': model,
        'actuator_unit': MODELS[model].actuator_unit,
        'measuring_mode': str(measuring_mode),
        'postures': int(postures),
        **driver_figures(driver_values, str(measuring_mode)),
        'pose_error_mean_m': float(pose_errors['position_mean_m']),
        'pose_error_max_m': float(pose_errors['position_max_m']),
        'orientation_error_mean_rad': float(pose_errors['orientation_mean_rad']),
        'orientation_error_max_rad': float(pose_errors['orientation_max_rad']),
        'verification': None if verification is None else dict(verification),
        'physics': str(physics),
        'adequacy': fit_adequacy(fit or {}),
        **({} if refinement is None else {'refinement': dict(refinement)}),
    }


def fit_adequacy(values: Mapping[str, str]) -> dict[str, Any]:
    """Return the fit's adequacy (verdict, variance_factor) from its status values."""
    return {
        'verdict': values.get('adequacy.verdict') or 'unknown',
        'variance_factor': status_number(values, 'adequacy.variance_factor'),
    }


def summary_lines(summary: Mapping[str, Any]) -> list[str]:
    """
    Return the drives' figures of a summary as the lines the demo prints.

    Deviations in um and forces in N for linear actuators, urad and N m for those that turn
    (the summary's model says which); the link's extension in um.
    """
    units = MODELS[summary['model']].actuator_quantities
    deviation = summary['max_actuator_deviation_m']
    lines = [
        '',
        f'Drives ({summary["measuring_mode"]}), the simulated truth at rest',
        'largest deviation of a commanded actuator from its setpoint: '
        + ('n/a' if deviation is None else units.shown_small(deviation)),
    ]
    if summary['max_force_n'] is not None:
        lines.append(
            f'largest actuator {units.effort}: {summary["max_force_n"]:.1f} {units.effort_unit}'
        )
    link_force = summary.get('max_link_force_n')
    if link_force is not None:
        # The driver's peak over the whole walk: the moves' loads, not only the rests'.
        lines.append(f'largest measuring-link force: {link_force:.1f} N (moves included)')
        if link_force > LINK_FORCE_LIMIT_N:
            lines.append(
                f'  beyond the {LINK_FORCE_LIMIT_N:g} N a measuring link of the documented kind '
                'bears: a lighter payload, or the lvdt mode (the link then carries no load)'
            )
    if summary['max_link_extension_m'] is not None:
        lines.append(f'largest link extension: {summary["max_link_extension_m"] * UM:.1f} um')
    return lines


def write_summary(path: Path, summary: Mapping[str, Any]) -> Path:
    """Write the summary as JSON, atomically (NaN refused: every figure is a number or null)."""
    return atomic_write(path, json.dumps(summary, indent=2, allow_nan=False) + '\n')
