"""
``hexacal study`` sections beyond the paper.

Device defects and the Monte Carlo check of the uncertainty.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from .command_line import Progress
from ..core.machine.device import DEVICE_PARAMETER_NAMES, DeviceDefects, DevicePrior

if TYPE_CHECKING:
    from ..core.architectures import KinematicParameters

# The device study and the Monte Carlo check are imported where they run: `hexacal calibrate`
# imports this module for device_names_argument.
UM, DEG, URAD = 1e6, math.degrees(1.0), 1e6
DEFECTS_HELP = (
    'device defects of the simulated device, SI units, e.g. dL=0.0005,alpha0=2e-4,beta0=-1.5e-4,'
    'gamma=1e-4,phi0=1e-4 (dL link-length offset m; alpha0/beta0 inclinometer zero offsets about '
    'X/Y rad; '
    'gamma non-perpendicularity of the inclinometer axes rad; phi0 rotary zero offset rad)'
)


def _defects(text: str) -> DeviceDefects:
    try:
        return DeviceDefects.parse(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def device_prior_argument(text: str) -> DevicePrior:
    """
    Parse --device-prior NAME=VALUE:STD[,...] (SI units) into a DevicePrior.

    STD[,...] (SI units) -> DevicePrior; a bad text is an argparse error.
    """
    try:
        return DevicePrior.parse(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def device_names_argument(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(',') if n.strip())
    unknown = [n for n in names if n not in DEVICE_PARAMETER_NAMES]
    if unknown:
        raise argparse.ArgumentTypeError(
            f'unknown device parameter(s) {unknown}; choose from {DEVICE_PARAMETER_NAMES}'
        )
    return names


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..core.fit.identification import ROBUST_LOSSES

    parser.add_argument('--device-defects', type=_defects, default=None, help=DEFECTS_HELP)
    parser.add_argument(
        '--identify-device',
        type=device_names_argument,
        default=(),
        help='device defects to identify jointly in the configured run, e.g. dL,alpha0,gamma',
    )
    parser.add_argument(
        '--weighted',
        action='store_true',
        help='weight residuals by the known reading noise (configured run)',
    )
    parser.add_argument(
        '--robust', choices=ROBUST_LOSSES, default=None, help='robust loss for the configured run'
    )
    parser.add_argument(
        '--lvdt', action='store_true', help='LVDT variant: the link length is measured per posture'
    )
    parser.add_argument(
        '--monte-carlo',
        type=int,
        default=100,
        metavar='SEEDS',
        help='noise seeds for the uncertainty check (default 100; 0 skips it)',
    )
    parser.add_argument(
        '--defect-seeds',
        type=int,
        default=10,
        help='seeds per row of the device-defect table (default 10)',
    )
    parser.add_argument(
        '--procedure',
        choices=('none', 'reversal', 'quarter-turns'),
        default='none',
        help='configured run: turn the device about its link axis between walks of the plan '
        '(reversal: 0/180 deg; quarter-turns: 0/90/180/270 deg); identify beta0 with it '
        '(--identify-device dL,alpha0,beta0,gamma)',
    )
    parser.add_argument(
        '--device-prior',
        type=device_prior_argument,
        default=DevicePrior(),
        metavar='NAME=VALUE:STD',
        help='configured run: prior knowledge of the device, SI units, e.g. dL=5e-4:10e-6 (a '
        'caliper reading of the link, +-10 um); needs --weighted',
    )


def print_sections(args, progress: Progress, truth: KinematicParameters | None = None) -> None:
    """
    Print the device-defect table and the Monte Carlo check on ``truth``.

    The device-defect table and the Monte Carlo check on ``truth`` (default: the Table 1 Hexa
    Slide).
    """
    from ..studies.defective_device import DEFAULT_DEFECTS

    print_device_defects(
        args.device_defects or DEFAULT_DEFECTS,
        args.noise_um,
        args.defect_seeds,
        progress,
        truth,
        args.monte_carlo,
    )
    if args.monte_carlo > 0:
        print_monte_carlo(args.monte_carlo, args.noise_um, progress, truth)


def print_device_defects(
    defects: DeviceDefects,
    noise_um: float,
    seeds: int,
    progress: Progress,
    truth: KinematicParameters | None = None,
    efficiency_seeds: int = 100,
) -> None:
    """
    Print the device table: every remedy on the same seeds.

    Every remedy on the same seeds, the issue's claims met / NOT met, the estimator's efficiency.
    """
    import numpy as np

    from ..studies.device_procedure import (
        CLAIM_EFFICIENCY,
        claims,
        device_table,
        estimator_efficiency,
        RECOMMENDED_PROCEDURE,
    )

    print(
        f'\nDevice defects ({defects.describe()}), 50 postures (random, or planned per seed: '
        'I-optimal on the nominal machine with the device columns, priors and turns), '
        f'+-{noise_um:g} um / urad noise, weighted by it, nominal set 2, {seeds} seeds; mean '
        'position error over 50 validation postures (um) in the device frames '
        "(base frame of the inclinometer's zero, platform frame of the rotary zero) and in the "
        'true frames '
        "(gravity-aligned base frame, origin at the device's joint O):"
    )
    outcomes = device_table(defects, range(seeds), 50, noise_um, truth, progress.step)
    reference = outcomes[0].mean(outcomes[0].true_frame_position_m)
    print(
        f'  {"method":<56} {"device fr.":>10} {"true fr.":>9} {"x ref":>6} {"origin-al.":>10} '
        f'{"orient. urad":>12}  device errors rms (um, urad)'
    )
    for outcome in outcomes:
        true_frames = outcome.mean(outcome.true_frame_position_m)
        rmse = outcome.device_rmse()
        identified = set(outcome.row.identify) | {name for name, _ in outcome.row.caliper}
        errors = (
            ', '.join(
                f'{name} {rmse[i] * URAD:.1f}'
                for i, name in enumerate(DEVICE_PARAMETER_NAMES)
                if name in identified
            )
            or '-'
        )
        failures = f'  failed: {"; ".join(outcome.failures)}' if outcome.failures else ''
        print(
            f'  {outcome.row.label:<56} '
            f'{outcome.mean(outcome.device_frame_position_m) * UM:>10.1f} '
            f'{true_frames * UM:>9.1f} {true_frames / reference:>6.2f} '
            f'{outcome.mean(outcome.origin_aligned_position_m) * UM:>10.1f} '
            f'{outcome.mean(outcome.true_frame_orientation_rad) * URAD:>12.1f}  {errors}{failures}'
        )
    print(
        "  x ref: true-frame position error / the ideal device's with random postures.  "
        'origin-al.: true frames after removing the '
        "mean position error, i.e. with the base frame's origin O re-referenced.  beta0 and phi0 "
        'are held at 0 '
        "unless identified: without a turning procedure beta0 is the device base frame's tilt "
        'about Y, phi0 is '
        "always the platform frame's zero yaw (it moves no position)."
    )
    for claim in claims(outcomes):
        print(
            f'  claim: {claim.text}: {claim.value:.2f}x the ideal device with random postures, '
            f'the baseline ({"met" if claim.met else "NOT met"}); {claim.like_for_like:.2f}x an '
            'ideal device calibrated the same way '
            f'({"met" if claim.met_like_for_like else "NOT met"})'
        )
    if efficiency_seeds > 1:
        from ..core.errors import CalibrationError

        try:
            summary = estimator_efficiency(
                efficiency_seeds,
                RECOMMENDED_PROCEDURE,
                defects=defects,
                noise_um=noise_um,
                true_params=truth,
                progress=progress.step,
            )
        except CalibrationError as error:
            # A machine whose readings carry no length (a rotary hexapod's angles) cannot tell
            # dL from its own size: the joint problem is rank-deficient, said, not raised.
            reason = ' | '.join(line.strip() for line in str(error).splitlines() if line.strip())
            print(f'  joint estimator ({RECOMMENDED_PROCEDURE}): not run on this machine: '
                  f'{reason}')
            return
        print(
            f'  joint estimator ({RECOMMENDED_PROCEDURE}, {", ".join(summary.identified)}) over '
            f'{summary.seeds} noise seeds, same postures: CRB std / RMS error / bias per device '
            'parameter (um, urad):'
        )
        for name, crb, rmse, bias, eff in zip(
            summary.identified, summary.crb_std, summary.rmse, summary.bias, summary.efficiency
        ):
            print(
                f'    {name:<7} {crb * URAD:8.2f} {rmse * URAD:8.2f} {bias * URAD:+8.2f}  '
                f'efficiency {eff:.2f} ({"met" if eff >= CLAIM_EFFICIENCY else "NOT met"})'
            )
        pose = summary.pose_efficiency
        print(
            '    validation position: predicted rms '
            f'{np.sqrt(summary.predicted_position_ms_m2) * UM:.2f} um, '
            f'Monte Carlo {np.sqrt(summary.position_ms_m2) * UM:.2f} um, efficiency {pose:.2f} '
            f'({"met" if pose >= CLAIM_EFFICIENCY else "NOT met"}); sampling error of an '
            'efficiency over '
            f'{summary.seeds} seeds ~{100 * np.sqrt(2 / max(summary.seeds - 1, 1)):.0f}%'
            + (f'; {summary.failures} seed(s) failed' if summary.failures else '')
        )


def print_monte_carlo(
    seeds: int, noise_um: float, progress: Progress, truth: KinematicParameters | None = None
) -> None:
    import numpy as np

    from ..core.assessment.uncertainty import monte_carlo

    print(
        f'\nUncertainty check: one calibration (50 postures, +-{noise_um:g} um / urad, '
        f'noise-weighted) repeated over {seeds} noise seeds:'
    )
    summary = monte_carlo(
        seeds=seeds, noise_um=noise_um, progress=progress.step, true_params=truth
    )
    ratio = summary.std_ratio
    within = int(np.sum(np.abs(ratio - 1) <= 0.2))
    print(
        f'  empirical / predicted std per parameter: median {np.median(ratio):.3f}, range '
        f'{ratio.min():.3f}-{ratio.max():.3f}, {within}/{len(ratio)} within 20% (sampling error '
        f'of a std over {seeds} seeds: ~{100 / np.sqrt(2 * (seeds - 1)):.0f}%)'
    )
    pose_ratio = summary.pose_error_mean_m / summary.predicted_pose_error_mean_m
    print(
        f'  mean pose error {summary.pose_error_mean_m * UM:.2f} um, linearised prediction '
        f'{summary.predicted_pose_error_mean_m * UM:.2f} um (ratio {pose_ratio:.3f}); orientation '
        f'{summary.orientation_error_mean_rad * DEG:.5f} vs '
        f'{summary.predicted_orientation_error_mean_rad * DEG:.5f} deg'
    )
    print(
        '  efficiency (Cramer-Rao variance for Gaussian noise of the same variance / empirical '
        f'MSE): median {np.median(summary.efficiency):.3f}, range '
        f'{summary.efficiency.min():.2f}-{summary.efficiency.max():.2f}; variance factor '
        f'{summary.variance_factor_mean:.3f} (1 = the noise model fits)'
    )
