"""
The checks of a deploy: the verification, and the plausibility against the active calibration.

Each returns Refusals (a short reason slug and a sentence with the figures); none: it passes.
"""

from __future__ import annotations

from typing import Any

from hexacal_msgs_py import store_format as fmt

from .plausibility import DEFAULT_MAX_ROTATION_CHANGE_RAD
from .store_entry import Refusal, StoreEntry


def on_other_postures(record: dict[str, Any], verification: dict[str, Any] | None) -> bool:
    """Return whether a verification was on known postures other than the fit's."""
    verified_on = (verification or {}).get(fmt.VERIFICATION_POSTURES_DIGEST)
    fitted_on = record.get(fmt.RECORD_POSTURES_DIGEST)
    return bool(verified_on) and bool(fitted_on) and verified_on != fitted_on


def verification_refusals(entry: StoreEntry) -> list[Refusal]:
    """Return why an entry's verification does not allow a deploy (empty: it does)."""
    verification = entry.record.get(fmt.RECORD_VERIFICATION)
    if verification is None:
        return [Refusal('unverified', f'{entry.short_id} has no verification')]
    if entry.verdict != fmt.VERDICT_PASS:
        return [
            Refusal(
                'verification-failed',
                f'the verification of {entry.short_id} says {entry.verdict!r}, not pass',
            )
        ]
    verified_on = verification.get(fmt.VERIFICATION_POSTURES_DIGEST)
    fitted_on = entry.record.get(fmt.RECORD_POSTURES_DIGEST)
    if not verified_on or not fitted_on:
        unknown = 'verified' if not verified_on else 'fitted'
        return [
            Refusal(
                'postures-unknown',
                f'the store cannot tell whether {entry.short_id} was verified on postures '
                f"other than its fit's (no digest of the {unknown} postures)",
            )
        ]
    if verified_on == fitted_on:
        return [
            Refusal(
                'verified-on-fit-postures',
                f'{entry.short_id} was verified on the postures it was fitted to',
            )
        ]
    return []


def plausibility_refusals(
    previous: StoreEntry,
    entry: StoreEntry,
    max_parameter_change_m: float,
    max_pose_change_m: float,
    max_rotation_change_rad: float = DEFAULT_MAX_ROTATION_CHANGE_RAD,
) -> tuple[list[Refusal], dict[str, Any]]:
    """Return why `entry` is a surprising jump from `previous` (empty: it is not), and figures."""
    from .plausibility import compare

    change = compare(previous.id, previous.parameters_path, entry.parameters_path)
    checks = change.to_json()
    checks['max_parameter_change_m'] = max_parameter_change_m
    checks['max_pose_change_m'] = max_pose_change_m
    checks['max_rotation_change_rad'] = max_rotation_change_rad
    if not change.same_model:
        return [
            Refusal(
                'model-changed',
                f'{entry.short_id} is a {entry.record.get(fmt.RECORD_MODEL)}, the active '
                f'{previous.short_id} a {previous.record.get(fmt.RECORD_MODEL)}',
            )
        ], checks
    refusals = []
    assert change.parameter_change_m is not None and change.pose_change_m is not None
    if change.parameter_change_m > max_parameter_change_m:
        refusals.append(
            Refusal(
                'parameter-jump',
                f'{change.parameter_name} changes by {change.parameter_change_m * 1e3:.3f} mm '
                f'from the active {previous.short_id} (limit {max_parameter_change_m * 1e3:g} mm)',
            )
        )
    if change.pose_change_m > max_pose_change_m:
        moved = (
            f'{change.fk_failures} of {change.poses} poses not reached'
            if change.fk_failures
            else f'the platform moves by up to {change.pose_change_m * 1e3:.3f} mm'
        )
        refusals.append(
            Refusal(
                'pose-jump',
                f'{moved} at the same actuator readings as with the active {previous.short_id} '
                f'(limit {max_pose_change_m * 1e3:g} mm)',
            )
        )
    rotation = change.rotation_change_rad
    if not change.fk_failures and rotation is not None and rotation > max_rotation_change_rad:
        refusals.append(
            Refusal(
                'rotation-jump',
                f'the platform turns by up to {rotation * 1e3:.3f} mrad at the same actuator '
                f'readings as with the active {previous.short_id} (limit '
                f'{max_rotation_change_rad * 1e3:g} mrad)',
            )
        )
    return refusals, checks
