#!/usr/bin/env python3
"""
Real-sensor benchmark (issue #19): postures found and calibration accuracy, before and after.

For each sensor effect of the simulated driver alone (hexacal_driver.sensor_models: lag,
quantisation, clock, drops, spikes, drift), with none (ideal sensors) and with all together,
one recording of the same plan walk is simulated with the driver's own code
(hexacal_driver.recording.simulate_recording: what the node publishes, message for message)
and written as a real MCAP bag of raw streams. Each bag is then read twice, in the same run:

- before: the previous weighting (the uniform noise model of the driver's noise,
  ``weights='noise-model'``) on the settled detector's postures (the window detector it was
  first compared with was removed in 0.2.0: its numbers stay in docs/results.md);
- after: today's defaults (the settled detector; weights from the postures' scatter).

Printed per row: postures found of those planned, the largest deviation of a found posture from
the settled truth (actuators um, angles urad: what ideal sensors read at rest, matched by the
actuator readings), the calibration's pose errors against the simulated truth on fresh
validation postures (mean / max, um), the variance factor and the adequacy verdict.
Run: ``.venv/bin/python benchmarks/bench_sensors.py [--postures 50] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys
import tempfile
import time

# (label, sensor_effects, sensor parameters): each effect alone at its default, none, all; then
# a slower inclinometer filter (0.3 s, still settled within the 2.5 s dwell) alone and with all.
EFFECTS = (
    ('ideal', '', {}),
    ('lag', 'lag', {}),
    ('quantisation', 'quantisation', {}),
    ('clock', 'clock', {}),
    ('drops', 'drops', {}),
    ('spikes', 'spikes', {}),
    ('drift', 'drift', {}),
    ('all', 'all', {}),
    ('lag 0.3 s', 'lag', {'inclinometer_time_constant_s': 0.3}),
    ('all, lag 0.3 s', 'all', {'inclinometer_time_constant_s': 0.3}),
)
UM = 1e6
MATCH_M = 2e-4  # a found posture belongs to the settled posture within 0.2 mm on every actuator
VARIANTS = {
    'before': {'detector': 'settled', 'weights': 'noise-model'},
    'after': {'detector': 'settled', 'weights': 'auto'},
}


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--postures', type=int, default=50, help='postures of the plan (50)')
    parser.add_argument('--dwell-s', type=float, default=2.5, help='stand still (s, 2.5)')
    parser.add_argument('--settle-s', type=float, default=1.0, help='move time (s, 1.0)')
    parser.add_argument('--seed', type=int, default=3, help='seed of plan and noise (3)')
    parser.add_argument('--model', default='hexa_slide', help='hexa_slide or gough_stewart')
    parser.add_argument('--validation', type=int, default=200, help='validation postures')
    parser.add_argument('--json', action='store_true', help='print the rows as JSON')
    return parser.parse_args()


def _posture_deviation(found, settled) -> tuple[int, float, float]:
    """Return (found postures matched to a settled one, largest actuator / angle deviation)."""
    import numpy as np

    values = np.array([p.values() for p in found], dtype=float).reshape(-1, 9)
    matched, actuator, angle = 0, 0.0, 0.0
    for row in values:
        distance = np.max(np.abs(settled[:, :6] - row[:6]), axis=1)
        k = int(np.argmin(distance))
        if distance[k] > MATCH_M:
            continue
        matched += 1
        actuator = max(actuator, float(np.max(np.abs(row[:6] - settled[k, :6]))))
        angle = max(angle, float(np.max(np.abs(row[6:] - settled[k, 6:]))))
    return matched, actuator, angle


def _row(recording, bag: Path, variant: str, args) -> dict:
    """Detect, calibrate and judge one bag with one variant's detector and weights."""
    from hexacal_identify.core.machine.model import nominal_set
    from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
    from hexacal_identify.calibration_steps.calibration_run import calibrate

    options = VARIANTS[variant]
    started = time.perf_counter()
    found = postures_from_bag(bag, detector=options['detector']).postures
    matched, actuator_m, angle_rad = _posture_deviation(found, recording.settled_readings)
    truth = recording.true_params
    nominal = nominal_set(2, seed=0, exact=truth)
    row = {
        'variant': variant,
        'postures_found': len(found),
        'postures_matched': matched,
        'max_actuator_deviation_um': actuator_m * UM,
        'max_angle_deviation_urad': angle_rad * UM,
    }
    try:
        result = calibrate(
            nominal,
            found,
            noise=recording.noise,
            weights=options['weights'],
            mount=recording.mount,
        )
    except Exception as error:  # noqa: B902 - a failed fit is a row of the table too
        row['error'] = f'{type(error).__name__}: {error}'
        return row
    poses = validation_poses(truth, args.validation, seed=7)
    errors = pose_errors(truth, result.parameters, poses).summary()
    adequacy = result.adequacy
    row.update(
        pose_error_mean_um=errors['position_mean_m'] * UM,
        pose_error_max_um=errors['position_max_m'] * UM,
        weights=str(getattr(result, 'weights', '')),
        variance_factor=adequacy.variance_factor,
        verdict=str(adequacy.verdict),
        seconds=time.perf_counter() - started,
    )
    return row


def _line(name: str, row: dict) -> str:
    if 'error' in row:
        return f'{name:15s} {row["variant"]:6s} {row["postures_found"]:4d}  fit failed: {row["error"]}'
    factor = row['variance_factor']
    factor_text = '-' if factor is None or not math.isfinite(factor) else f'{factor:9.2f}'
    return (
        f'{name:15s} {row["variant"]:6s} {row["postures_found"]:4d} {row["postures_matched"]:4d} '
        f'{row["max_actuator_deviation_um"]:9.2f} {row["max_angle_deviation_urad"]:9.2f} '
        f'{row["pose_error_mean_um"]:9.2f} {row["pose_error_max_um"]:9.2f} '
        f'{factor_text} {row["verdict"]:7s} {row["weights"]}'
    )


def main() -> int:
    args = _arguments()
    from hexacal_driver.recording import simulate_recording, write_recording_bag

    rows = []
    if not args.json:
        print(
            f'{args.postures} planned postures, dwell {args.dwell_s:g} s, seed {args.seed}, '
            f'{args.model}; pose errors on {args.validation} validation postures\n'
            'effects         detector found match  act[um] angle[urad] mean[um]  max[um]'
            '  s0^2/dof verdict weights'
        )
    with tempfile.TemporaryDirectory() as work:
        for number, (label, effects, sensor_parameters) in enumerate(EFFECTS):
            recording = simulate_recording(
                model=args.model,
                postures=args.postures,
                dwell_s=args.dwell_s,
                settle_s=args.settle_s,
                seed=args.seed,
                sensor_effects=effects,
                **sensor_parameters,
            )
            bag = write_recording_bag(Path(work) / f'recording_{number}', recording)
            for variant in VARIANTS:
                row = _row(recording, bag, variant, args)
                row['effects'] = label
                rows.append(row)
                if not args.json:
                    print(_line(label, row), flush=True)
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
