"""
The demo's printed report: parameter and pose errors vs the simulated truth, the verification.

``report`` gives the text ``hexacal demo`` prints at the end: the parameter errors before and
after calibration per file key, the pose errors over fresh validation postures (both against the
simulated truth), identify's verification table (no truth needed), the summary lines
(demo_summary.py, demo_refinement.py) and where everything was written. ``stored_verification``
reads the verification identify kept with its calibration in the store (summary.json).
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING

from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS

from .demo_refinement import refinement_lines
from .demo_summary import summary_lines

if TYPE_CHECKING:  # numpy is imported where the report is made, not at `hexacal` start-up
    import numpy as np

    from .demo_run import DemoPaths


def stored_verification(values: dict[str, str], model: str) -> dict | None:
    """
    Return the verification identify attached to its calibration in the store.

    The object of ``hexacal verify --json`` (VerificationResult.to_json, the one owner of its
    keys) with identify's provenance keys; None (with a warning) when it is not there.
    """
    from ..store import CalibrationStore, default_store_dir, StoreError

    entry_id = values.get('calibration_id')
    if not entry_id:
        print('hexacal demo: warning: the verification is not in the calibration store: '
              f'{values.get("store_error", "no calibration_id")}', file=sys.stderr)
        return None
    root = values.get('calibration_store') or default_store_dir(model)
    try:
        figures = CalibrationStore(root).get(entry_id).record.get('verification')
    except (StoreError, OSError) as error:
        print(f'hexacal demo: warning: calibration store {root}: {error}', file=sys.stderr)
        return None
    return dict(figures) if figures else None


def parameter_error_rows(
    true_vector: np.ndarray, vector: np.ndarray, model: str = DEFAULT_MODEL
) -> dict[str, tuple[float, float]]:
    """
    Return per file key of the model (Hexa Slide: A0, B, l, a) the (max, mean) |error| in mm.

    The Hexa Slide's a: unit-vector components x 1000.
    """
    import numpy as np

    layout = MODELS[model]
    groups = layout.key_slices
    errors = np.abs(np.asarray(vector) - np.asarray(true_vector)).reshape(
        layout.n_chains, layout.fields_per_chain
    ) * 1e3
    return {
        name: (float(errors[:, columns].max()), float(errors[:, columns].mean()))
        for name, columns in groups.items()
    }


def verification_table(values: dict[str, str]) -> list[str]:
    """Return the verification figures (identify's status values) as a table, um / urad."""

    def number(key: str) -> float:
        try:
            return float(values.get(key, 'nan'))
        except ValueError:
            return float('nan')

    lines = [
        '',
        f'Verification on {values.get("postures", "?")} fresh postures: what the device measured '
        '(eq. 4, rotary) vs forward kinematics at the measured actuators - no ground truth',
        f'{"":<20}{"position rms":>14}{"position max":>14}{"rotary rms":>12}',
        f'{"":<20}{"(um)":>14}{"(um)":>14}{"(urad)":>12}',
    ]
    for label, name in (('nominal', 'nominal'), ('calibrated', 'calibrated')):
        lines.append(
            f'{label:<20}{number(name + ".position_rms_m") * 1e6:>14.1f}'
            f'{number(name + ".position_max_m") * 1e6:>14.1f}'
            f'{number(name + ".rotary_rms_rad") * 1e6:>12.1f}'
        )
    lines.append(
        f'improvement {number("improvement"):.0f}x, threshold {number("threshold_m") * 1e6:.1f} '
        f'um: {values.get("verdict", "?")}'
    )
    return lines


def report(
    true_params,
    nominal,
    calibrated,
    args,
    paths: DemoPaths,
    wall_s: float,
    verification: dict[str, str] | None = None,
    *,
    poses: dict[str, dict] | None = None,
    summary: dict | None = None,
) -> str:
    from ..bag import open_bag

    model = true_params.model
    arch, layout = true_params.architecture, true_params.layout
    groups = layout.key_slices
    before = parameter_error_rows(true_params.vector, nominal.vector, model)
    after = parameter_error_rows(true_params.vector, calibrated.vector, model)
    title = (
        f'Parameter errors vs the simulated truth ({arch.machine_label}), |error| in mm'
        f'{arch.error_table_note}'
    )
    lines = [
        '',
        title,
        f'{"group":<6}{"count":>6}{"before max":>13}{"before mean":>13}'
        f'{"after max":>12}{"after mean":>12}',
    ]
    for name, columns in groups.items():
        count = layout.n_chains * (columns.stop - columns.start)
        lines.append(
            f'{name:<6}{count:>6}{before[name][0]:>13.3f}{before[name][1]:>13.3f}'
            f'{after[name][0]:>12.4f}{after[name][1]:>12.4f}'
        )
    if poses is None:
        poses = pose_summaries(true_params, nominal, calibrated, args)
    lines += [
        '',
        f'Pose errors over {args.validation_postures} validation postures',
        f'{"":<20}{"position mean":>15}{"position max":>14}{"orientation mean":>18}'
        f'{"orientation max":>17}',
        f'{"":<20}{"(um)":>15}{"(um)":>14}{"(deg)":>18}{"(deg)":>17}',
    ]
    for label, errors in poses.items():
        lines.append(
            f'{label:<20}{errors["position_mean_m"] * 1e6:>15.1f}'
            f'{errors["position_max_m"] * 1e6:>14.1f}'
            f'{math.degrees(errors["orientation_mean_rad"]):>18.5f}'
            f'{math.degrees(errors["orientation_max_rad"]):>17.5f}'
            + (
                f'  ({errors["failed_postures"]} FK failures)'
                if errors['failed_postures']
                else ''
            )
        )
    bag_text = str(paths.bag)
    try:
        info = open_bag(paths.bag).info()
        postures = sum(t.count for name, t in info.topics.items() if name.endswith('/posture'))
        bag_text += f'  ({info.message_count} messages, {postures} postures)'
    except Exception as error:  # noqa: BLE001 - the report still prints, with the path
        bag_text += f'  (unreadable: {error})'
    if verification:
        lines += verification_table(verification)
    if summary is not None:
        units = MODELS[summary['model']].actuator_quantities
        lines += summary_lines(summary) + refinement_lines(summary.get('refinement'), units)
    page = _report_page(paths, verification)
    lines += [
        '',
        f'bag:        {bag_text}',
        f'report:     {page}',
        f'calibrated: {paths.calibration}',
        f'summary:    {paths.summary}',
        f'nominal:    {paths.nominal}',
        f'truth:      {paths.true_params}',
        f'logs:       {paths.logs}',
        f'wall time:  {wall_s:.0f} s',
    ]
    return '\n'.join(lines)


def pose_summaries(true_params, nominal, calibrated, args) -> dict[str, dict]:
    """Return the pose errors (PoseErrors.summary) of nominal and calibrated vs the truth."""
    from ..core.assessment.validation import pose_errors, validation_poses

    poses = validation_poses(
        true_params,
        args.validation_postures,
        args.seed,
        true_params.architecture.default_workspace(),
    )
    return {
        label: pose_errors(true_params, model, poses).summary()
        for label, model in (('before (nominal)', nominal), ('after (calibrated)', calibrated))
    }


def _report_page(paths: DemoPaths, verification: dict[str, str] | None) -> str:
    """Return the HTML report identify wrote (the verification's page when it has one)."""
    if verification and verification.get('report'):
        return verification['report']
    pages = sorted(paths.report.rglob('index.html')) if paths.report.exists() else []
    return str(pages[0]) if pages else f'{paths.report} (not written)'
