"""``hexacal study --measuring-mode M``: the accuracy of each measuring mode."""

from __future__ import annotations

import json
from typing import Callable

from hexacal_msgs_py.models import ActuatorQuantities, LINEAR_ACTUATOR

UM = 1e6


def mode_runs(args, load_params: Callable) -> list:
    """Return the runs the options ask for; ``all`` adds the compliant run as the baseline."""
    from ..core.architectures import default_parameters
    from ..studies.measuring_mode_accuracy import (
        DEFAULT_SERVO_STIFFNESS_N_PER_M,
        ModeStudyRun,
        selected_modes,
    )

    truth = load_params(args.true_params) if args.true_params else default_parameters(args.model)
    nominal = load_params(args.nominal_params) if args.nominal_params else None
    stiffness = args.servo_stiffness_n_per_m
    if stiffness is None:  # the model's: 2e6 N/m at the actuator's joint (N m/rad for a crank)
        stiffness = truth.architecture.actuator_limit(DEFAULT_SERVO_STIFFNESS_N_PER_M, 'stiffness')
    common = {
        'true_params': truth,
        'nominal_params': nominal,
        'nominal_set_number': args.nominal_set,
        'postures': args.postures,
        'noise_um': args.noise_um,
        'lvdt_noise_m': args.lvdt_noise_m,
        'lvdt_stroke_m': args.lvdt_stroke_m,
        'servo_stiffness_n_per_m': stiffness,
        'seed': args.seed,
        'cost': args.cost,
        'validation_postures': args.validation_postures,
        'first_calibration': args.first_calibration,
    }
    runs = [ModeStudyRun(mode=mode, refine=args.refine, **common)
            for mode in selected_modes(args.measuring_mode)]
    if args.measuring_mode == 'all' and args.refine:  # the baseline: the demo without refinement
        runs.append(ModeStudyRun(mode='compliant', refine=False, **common))
    return runs


def run(args, load_params: Callable) -> int:
    """Run the measuring-mode study and print its table (or, with --json, its JSON)."""
    from ..studies.measuring_mode_accuracy import run_mode

    outcomes = [run_mode(study) for study in mode_runs(args, load_params)]
    payloads = [outcome.to_json() for outcome in outcomes]
    if args.json:
        print(json.dumps(payloads[0] if len(payloads) == 1 else payloads))
        return 0
    first = outcomes[0].run
    units = first.true_params.architecture.actuator_quantities
    print(
        f'Measuring modes on the simulated {first.true_params.model} (nominal set '
        f'{first.nominal_set_number}, {first.postures} postures, +-{first.noise_um:g} '
        f'{units.small} noise, '
        f'seed {first.seed}); targets from the nominal model'
        + (', then refined from intermediate calibrations' if args.refine else '')
        + ':'
    )
    print_table(payloads, units)
    return 0


def _um(value: float | None, scale: float = UM) -> str:
    return '-' if value is None else f'{value * scale:.1f}'


def _kn(value: float | None) -> str:
    return '-' if value is None else f'{value:.0f}'


def _position_rms(rms: dict[str, float]) -> float | None:
    """Return the rms of the position residuals (x, y, z), m, or None if the cost has none."""
    values = [rms[axis] for axis in ('x', 'y', 'z') if axis in rms]
    return (sum(v * v for v in values) / len(values)) ** 0.5 if values else None


def _label(payload: dict) -> str:
    refined = 'refined' if payload['refine'] else 'nominal targets'
    return f'{payload["measuring_mode"]} ({refined})'


def print_table(payloads: list[dict], units: ActuatorQuantities = LINEAR_ACTUATOR) -> None:
    """
    Print one row per mode: before -> after refinement figures, then the accuracy.

    The actuators' deviations and the released one's offsets and travel in `units` (um and
    mm for sliders, urad and deg for cranks), their efforts in N or N m.
    """
    small, effort = units.small, units.effort_unit

    def actuator(value: float | None) -> str:
        return _um(value, units.small_scale)

    print(
        f'  {"mode":<30} {"postures":>8} {"deviation " + small:>18} '
        f'{units.effort + " " + effort:>14} '
        f'{"extension um":>18} {"released " + small:>18} {"pose err mean/max um":>21} '
        f'{"rms xyz um":>11} {"rank":>5} {"failed":>6}'
    )
    for payload in payloads:
        before, after = payload['before_refinement'], payload['after_refinement']

        def pair(key: str, show: Callable = _um) -> str:
            return f'{show(before[key])} -> {show(after[key])}'

        mean, largest = payload['pose_error_mean_m'], payload['pose_error_max_m']
        accuracy = f'{mean * UM:.1f} / {largest * UM:.1f}'
        rms = _position_rms(payload['rms_residual'])
        print(
            f'  {_label(payload):<30} {payload["postures"]:>8} '
            f'{pair("max_actuator_deviation_m", actuator):>18} {pair("max_force_n", _kn):>14} '
            f'{pair("max_link_extension_m"):>18} {pair("max_released_offset_m", actuator):>18} '
            f'{accuracy:>21} {_um(rms):>11} {payload["rank"]:>5} {payload["failed_postures"]:>6}'
        )
    print(
        '  deviation: the largest |true position - setpoint| of a commanded actuator at rest; '
        "released: the released actuator's\n  largest |reading - the model's prediction|; "
        'before -> after refinement (- where none); pose error on fresh validation poses\n'
        '  against the truth; failed: postures the procedure could not measure on the true '
        'machine (skipped).'
    )
    for payload in payloads:
        if payload['lvdt_inside_stroke'] is not None:
            print(
                f'  lvdt: largest extension {_um(payload["max_link_extension_m"])} um, stroke '
                f'+-{payload["lvdt_stroke_m"] * UM:.0f} um: '
                + ('inside' if payload['lvdt_inside_stroke'] else
                   f'OUTSIDE the stroke at {payload["lvdt_postures_outside_stroke"]} posture(s)')
            )
        if payload['released_travel_max_m'] is not None:
            print(
                f'  passive_actuator: the released actuators travel up to '
                f'{units.shown(payload["released_travel_max_m"], 1)} along a move (nominal plan)'
            )
