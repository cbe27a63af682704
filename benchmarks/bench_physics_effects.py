#!/usr/bin/env python3
"""
What the physics does to a calibration, effect by effect, on the MuJoCo machine (ROS-free).

The machine hexacal did not write: hexacal_driver.physics_machine.PhysicsMachine built from the
TRUE parameters (the model's default machine) and the physical description
(hexacal_msgs_py.physical_file.default_physical) with the effects switched on one at a time:

- ``rigid_weightless``: gravity off, no springs, no friction (the geometric model's machine);
- ``servo``: gravity through the servo stiffness only (the encoders see that sag);
- ``+structure``: plus the axial spring between each encoder and its joint centres;
- ``+link``: plus the measuring link's axial spring;
- ``+friction``: plus the released actuator's friction (= the shipped defaults);
- ``defaults_rigid``: the shipped defaults made rigid (gravity, servo, friction; no springs):
  the "same machine made rigid" the compliant fit is judged by;
- ``3x_softer``: the shipped defaults with kp and every stiffness divided by 3;
- ``link_only``: gravity, servos and the link's spring (legs rigid, no friction);
- ``link_only_light``: the same with massless sliders / extending rods: the actuators' moving
  mass (MassModel's ``actuator_moving_mass``: the released slider's weight along the Hexa
  Slide's inclined rail, the Gough-Stewart's extending rods) taken away.  (With the legs'
  springs massless sliders make the simulation unstable.)

Passive_actuator measuring mode: ``--postures`` sphere postures and ``--fresh`` verification
postures (sample_poses; the released chain of each posture the one leaving the passive system
best conditioned, release_conditions).  A posture that has not come to rest (every joint slower
than 1e-7 m/s or rad/s) within the settle time is not used, as a collector would not take it
(the ``settled`` column counts those used).  At each posture the machine is assembled at the pose
with the servos commanded there, settles under gravity with every actuator powered, then one
actuator is released and it settles again; the encoders, the accelerometer inclinometer and the
rotary sensor are read.  The readings (exact) are cached in ``--cache`` (npz per model and
effect), so a second run only identifies.  Noise is added at identification: +-2 um on the
actuators, +-5 urad on every angle (uniform, the NoiseModel the fit is whitened by).

Each row identifies from nominal parameter set 2 (core.model.nominal_set): ``none`` (the rigid
geometric fit), ``shared`` (one chain compliance and the link's, from the static loads of the
physical description's masses, core/fit/compliance.py) and, where the released actuator has
friction, ``shared+f`` (the same with the description's friction bound weighed as a noise source
of each posture: ComplianceModel.released_friction), in the modes' table also ``shared+p`` (the
chains' compliance given as a datasheet prior, the truth +-20 %, with the friction) and, in the
compliant mode, ``shared=`` (the load shared by equal drives and a rigid link, the rule before
the drives' gain and the compliances shared it: ``shared`` takes the description's
``drives.kp``, ComplianceModel.drive_stiffness), and prints the pose error against the MuJoCo
machine's true geometry on 200 fresh poses (core/assessment/validation.py), the verification of
the calibration on the fresh simulated postures (core/assessment/verification.py), the variance
factor and the adequacy verdict (core/assessment/adequacy.py) and the identified compliances
(+- std) beside the truth (1 / stiffness).

Then the measuring modes (``--modes``, default all three) at the shipped defaults and on the
same machine made rigid (``defaults_rigid``), the same postures: passive_actuator as above;
lvdt (every actuator powered, the link a telescopic LVDT without spring read +-1 um, a term the
fit's noise model does not hold) and compliant (every actuator powered, the link with its spring);
in both the servos are commanded to the pose by the true geometry (the targets a refined
procedure comes within microns of).  One table: the pose error, verification, variance factor,
adequacy, the largest axial force at the link's platform joint (PhysicsMachine.link_force) and
the pose error over the rigid machine's rigid fit in the same mode.

Run: ``.venv/bin/python benchmarks/bench_physics_effects.py [--models hexa_slide gough_stewart]
[--effects ...] [--modes passive_actuator lvdt compliant] [--postures 30] [--fresh 8]
[--cache /tmp/hexacal_physics_effects] [--json]`` (``--effects`` or ``--modes`` with no name
skips that part; a walk is about 0.5 s of CPU per posture, cached per model, mode and effect).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import json
from pathlib import Path
import time

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.errors import RankDeficientError, TooFewPosturesError
from hexacal_identify.core.fit.compliance import ComplianceModel
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.assessment.verification import verify
from hexacal_identify.core.machine.device import DeviceModel
from hexacal_identify.core.machine.measurements import Measurements, NoiseModel
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
from hexacal_msgs_py.physical_file import default_physical, PhysicalDescription
import numpy as np

MODELS = ('hexa_slide', 'gough_stewart')
EFFECTS = (
    'rigid_weightless', 'servo', '+structure', '+link', '+friction', 'defaults_rigid',
    '3x_softer', 'link_only', 'link_only_light',
)
NOISE = NoiseModel(actuator_m=2e-6, angle_rad=5e-6)
LVDT_NOISE_M = 1e-6  # +- on the LVDT's reading of the link's length (not in the fit's weights)
PASSIVE, LVDT, COMPLIANT = 'passive_actuator', 'lvdt', 'compliant'
MEASURING_MODES = (PASSIVE, LVDT, COMPLIANT)
LINK_LENGTH = DeviceModel().link_length
LOCKED_SETTLE_S, RELEASED_SETTLE_S = 1.5, 3.0


def physical_for(model: str, effect: str) -> PhysicalDescription:
    """Return the physical description of one row (module doc)."""
    shipped = default_physical(model)
    if effect == 'rigid_weightless':
        return replace(shipped.weightless().made_rigid(), released_coulomb=0.0)
    if effect == 'servo':
        return replace(shipped.made_rigid(), released_coulomb=0.0)
    if effect == '+structure':
        return replace(shipped, link_axial_stiffness=None, released_coulomb=0.0)
    if effect == '+link':
        return replace(shipped, released_coulomb=0.0)
    if effect == '+friction':
        return shipped
    if effect == 'defaults_rigid':
        return shipped.made_rigid()
    if effect == '3x_softer':
        return replace(
            shipped,
            drive_kp=tuple(k / 3.0 for k in shipped.drive_kp),
            structure_axial_stiffness=tuple(k / 3.0 for k in shipped.structure_axial_stiffness),
            link_axial_stiffness=shipped.link_axial_stiffness / 3.0,
        )
    if effect == 'link_only':
        return replace(shipped, structure_axial_stiffness=None, released_coulomb=0.0)
    if effect == 'link_only_light':
        return replace(
            shipped, structure_axial_stiffness=None, released_coulomb=0.0,
            actuator_moving_mass=0.0,
        )
    raise ValueError(f'unknown effect {effect!r}; choose one of {", ".join(EFFECTS)}')


RELEASES = ('conditioning', 'load')
# --release load: the least link load among the releases conditioned within this factor of the
# best (the planner keeps conditioning first: a jam faults the drives).
LOAD_CONDITION_FACTOR = 2.0


def postures(
    model: str, n: int, seed: int, release: str = 'conditioning'
) -> tuple[np.ndarray, np.ndarray]:
    """Return sphere poses and the released chain of each (best-conditioned, or least load)."""
    true = architecture(model).default_parameters()
    poses = sample_poses(
        true, n, np.random.default_rng(seed), 'sphere', true.architecture.default_workspace()
    )
    conditions = release_conditions(true, poses, LINK_LENGTH)
    if release == 'conditioning':
        return poses, np.argmin(conditions, axis=1)
    from hexacal_identify.core.modes.link_load import released_link_forces

    forces = released_link_forces(
        true, poses, MassModel.from_physical(default_physical(model))
    )
    good = conditions <= LOAD_CONDITION_FACTOR * conditions.min(axis=1, keepdims=True)
    return poses, np.argmin(np.where(good, forces, np.inf), axis=1)


def simulate(
    model: str, effect: str, poses: np.ndarray, released: np.ndarray,
    mode: str = PASSIVE,
) -> dict:
    """Walk the postures on the MuJoCo machine; return its exact readings and true poses."""
    from hexacal_driver.physics_machine import PhysicsError, PhysicsMachine

    true = architecture(model).default_parameters()
    physical = physical_for(model, effect)
    n = len(poses)
    out = {
        'actuators': np.zeros((n, 6)), 'inclinometer': np.zeros((n, 2)), 'rotary': np.zeros(n),
        'link_length': np.zeros(n), 'poses': np.zeros((n, 6)), 'settled': np.zeros(n, bool),
        'link_force': np.zeros(n), 'simulated_s': 0.0, 'cpu_s': 0.0,
    }
    for i, (pose, chain) in enumerate(zip(poses, released)):
        # lvdt and compliant: the servos commanded to the pose by the true geometry (targets a
        # refined procedure comes within microns of), every actuator powered.
        machine = PhysicsMachine(true, physical, pose, link_length=LINK_LENGTH, mode=mode)
        try:
            if mode == PASSIVE:
                machine.settle(LOCKED_SETTLE_S, speed=1e-6)
                machine.release(int(chain))
            out['settled'][i] = machine.settle(RELEASED_SETTLE_S)
        except PhysicsError:  # unstable: not at rest, not used (counted in ``settled``)
            out['unstable'] = out.get('unstable', 0) + 1
            continue
        out['link_force'][i] = machine.link_force()
        readings = machine.readings()
        out['actuators'][i] = readings.actuators_m
        out['inclinometer'][i] = (readings.alpha_rad, readings.beta_rad)
        out['rotary'][i] = readings.phi_rad
        out['link_length'][i] = readings.link_length_m
        out['poses'][i] = machine.pose()
        out['simulated_s'] += machine.time_s
        out['cpu_s'] += machine.cpu_s
    return out


def cached_walk(
    cache: Path, model: str, effect: str, n: int, seed: int, mode: str = PASSIVE,
    release: str = 'conditioning',
) -> dict:
    """Return the walk's readings, simulating only when the cache does not hold them."""
    prefix = model if mode == PASSIVE else f'{model}_{mode}'
    if mode == PASSIVE and release != 'conditioning':
        prefix += f'_{release}'
    path = cache / f'{prefix}_{effect.strip("+")}_{n}_{seed}.npz'
    if path.exists():
        with np.load(path) as data:
            if 'link_force' in data.files:  # a walk cached before the link's force: walk again
                return {key: data[key] for key in data.files}
    poses, released = postures(model, n, seed, release)
    walk = simulate(model, effect, poses, released, mode)
    walk['released'] = released
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(path, **walk)
    return walk


def noisy(walk: dict, rng: np.random.Generator, mode: str = PASSIVE) -> Measurements:
    """Return the measurements with the reading noise added (NOISE, uniform; lvdt: the link)."""
    n = len(walk['actuators'])
    actuators = walk['actuators'] + rng.uniform(-NOISE.actuator_m, NOISE.actuator_m, (n, 6))
    angles = walk['inclinometer'] + rng.uniform(-NOISE.angle_rad, NOISE.angle_rad, (n, 2))
    rotary = walk['rotary'] + rng.uniform(-NOISE.angle_rad, NOISE.angle_rad, n)
    lengths = None
    if mode == LVDT:
        lengths = walk['link_length'] + rng.uniform(-LVDT_NOISE_M, LVDT_NOISE_M, n)
    return Measurements(actuators, angles, rotary, link_lengths=lengths)


def truth(physical: PhysicalDescription) -> dict[str, float]:
    """Return the true compliances (m/N) of the description (0 for a rigid member)."""
    structure = physical.structure_axial_stiffness
    chains = 0.0 if structure is None else float(np.mean([1.0 / k for k in structure]))
    link = physical.link_axial_stiffness
    return {'chains': chains, 'link': 0.0 if link is None else 1.0 / link}


def at_rest(walk: dict) -> dict:
    """Return the postures of a walk that came to rest (a collector takes no moving posture)."""
    keep = walk['settled'].astype(bool)
    n = len(keep)
    return {
        key: value[keep] if isinstance(value, np.ndarray) and value.ndim and len(value) == n
        else value
        for key, value in walk.items()
    }


def evaluate(
    model: str, effect: str, walked: dict, fresh: dict, seed: int, mode: str = PASSIVE,
    with_prior: bool = False,
) -> list[dict]:
    """Identify the walk rigid and with shared compliances; the row of each (module doc)."""
    fit, fresh = at_rest(walked), at_rest(fresh)
    true = architecture(model).default_parameters()
    nominal = nominal_set(2, seed=seed, exact=true)
    physical = physical_for(model, effect)
    rng = np.random.default_rng([seed, 7])
    measurements, verification_set = noisy(fit, rng, mode), noisy(fresh, rng, mode)
    check_poses = validation_poses(true, 200, seed)
    rows = []
    friction = physical.released_coulomb if mode == PASSIVE else 0.0
    fits: list[tuple[str, str, float, dict]] = [
        ('none', 'none', 0.0, {}), ('shared', 'shared', 0.0, {})
    ]
    if mode == COMPLIANT:
        # The load shared by equal drives and a rigid link, the rule before the stiffnesses.
        fits.append(('shared=', 'shared', 0.0, {}))
    if friction > 0.0:
        # The released actuator's stiction weighed as a noise source (compliance.py).
        fits.append(('shared+f', 'shared', friction, {}))
    chains = truth(physical)['chains']
    if with_prior and chains > 0.0:
        # A datasheet figure of the chains' compliance, +-20 % (and the friction, if any).
        fits.append(('shared+p', 'shared', friction, {'chains': (chains, 0.2 * chains)}))
    for label, choice, friction, prior in fits:
        masses = MassModel.from_physical(physical)
        released = fit['released'].astype(int) if mode == PASSIVE else None
        # compliant: the drives' gain shares the load with the compliances (statics.py).
        drives = physical.drive_kp if mode == COMPLIANT and label != 'shared=' else None
        compliance = ComplianceModel(
            choice, masses, mode, released, prior=prior, released_friction=friction,
            drive_stiffness=drives,
        )
        started = time.perf_counter()
        try:
            result = identify(
                nominal, measurements, SolverOptions(noise=NOISE, compliance=compliance)
            )
        except (RankDeficientError, TooFewPosturesError) as error:
            # No weight: no load tells a compliance; an unstable machine: no posture at rest.
            lines = str(error).splitlines()
            rows.append({
                'model': model, 'mode': mode, 'effect': effect, 'compliance': label,
                'refused': lines[min(1, len(lines) - 1)].strip(),
            })
            continue
        errors = pose_errors(true, result.parameters, check_poses)
        calibrated_compliance = None
        if compliance.active:
            values = np.array([result.compliance[name] for name in compliance.names])
            fresh_released = fresh['released'].astype(int) if mode == PASSIVE else None
            calibrated_compliance = (replace(compliance, released=fresh_released), values)
        verification = verify(
            nominal, result.parameters, verification_set, noise=NOISE,
            calibrated_compliance=calibrated_compliance,
        )
        figures = verification.calibrated.figures()
        adequacy = result.adequacy
        rows.append({
            'model': model,
            'mode': mode,
            'effect': effect,
            'compliance': label,
            'pose_mean_um': float(np.nanmean(errors.position_m)) * 1e6,
            'pose_max_um': float(np.nanmax(errors.position_m)) * 1e6,
            'orientation_mean_urad': float(np.nanmean(errors.orientation_rad)) * 1e6,
            'verification_rms_um': figures['position_rms_m'] * 1e6,
            'verification_verdict': verification.verdict,
            'variance_factor': result.variance_factor,
            'adequacy': adequacy.verdict.value,
            'compliances': {
                name: {
                    'identified': value,
                    'std': result.compliance_std[name],
                    'true': truth(physical)[name],
                }
                for name, value in result.compliance.items()
            },
            'settled': int(walked['settled'].sum()),
            'postures': len(walked['settled']),
            'link_stretch_um': float(np.ptp(fit['link_length'])) * 1e6,
            'max_link_force_n': float(np.max(np.abs(walked.get('link_force', np.nan)))),
            'identify_s': time.perf_counter() - started,
        })
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--models', nargs='+', default=list(MODELS), choices=MODELS)
    parser.add_argument('--effects', nargs='*', default=list(EFFECTS), choices=EFFECTS)
    parser.add_argument(
        '--modes', nargs='*', default=list(MEASURING_MODES), choices=MEASURING_MODES,
        help='measuring modes compared at the shipped defaults (none: skip the comparison)',
    )
    parser.add_argument('--postures', type=int, default=30)
    parser.add_argument('--fresh', type=int, default=8)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--cache', type=Path, default=Path('/tmp/hexacal_physics_effects'))
    parser.add_argument(
        '--release', choices=RELEASES, default='conditioning',
        help='passive_actuator: the released chain of each posture, the best-conditioned '
        '(default) or the least link load among those within 2x of the best conditioning',
    )
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    rows, mode_rows = [], []
    for model in args.models:
        for effect in args.effects:
            fit = cached_walk(args.cache, model, effect, args.postures, args.seed)
            fresh = cached_walk(args.cache, model, effect, args.fresh, args.seed + 1000)
            done = len(rows)
            rows.extend(evaluate(model, effect, fit, fresh, args.seed))
            if not args.json:
                print_rows(rows[done:], header=done == 0)
    for model in args.models:
        for mode in args.modes:
            for effect in MODE_EFFECTS:
                fit = cached_walk(
                    args.cache, model, effect, args.postures, args.seed, mode, args.release
                )
                fresh = cached_walk(
                    args.cache, model, effect, args.fresh, args.seed + 1000, mode, args.release
                )
                mode_rows.extend(
                    evaluate(model, effect, fit, fresh, args.seed, mode, with_prior=True)
                )
    if args.json:
        print(json.dumps({'effects': rows, 'modes': mode_rows}, indent=2))
    elif mode_rows:
        print_modes(mode_rows)
    return 0


MODE_EFFECTS = ('+friction', 'defaults_rigid')  # the shipped defaults, and made rigid


def print_modes(rows: list[dict]) -> None:
    """Print the measuring modes at the shipped defaults beside the machine made rigid."""
    print(
        'Measuring modes at the shipped defaults (the machine made rigid: structure and link '
        'without springs)'
    )
    print(
        f'{"model":<14}{"mode":<18}{"machine":<9}{"fit":<8}{"pose mean um":>13}{"max um":>9}'
        f'{"orient urad":>12}{"verif rms um":>13}{"verdict":>8}{"var.factor":>12}'
        f'  adequacy{"max link N":>11}{"x rigid":>9}'
    )
    for row in rows:
        machine = 'rigid' if row['effect'] == 'defaults_rigid' else 'defaults'
        head = f'{row["model"]:<14}{row["mode"]:<18}{machine:<9}{row["compliance"]:<8}'
        if 'refused' in row:
            print(f'{head}  refused: {row["refused"]}')
            continue
        rigid = [
            r for r in rows
            if r['model'] == row['model'] and r['mode'] == row['mode']
            and r['effect'] == 'defaults_rigid' and r['compliance'] == 'none'
        ]
        ratio = row['pose_mean_um'] / rigid[0]['pose_mean_um'] if rigid else float('nan')
        print(
            f'{head}{row["pose_mean_um"]:>13.2f}{row["pose_max_um"]:>9.2f}'
            f'{row["orientation_mean_urad"]:>12.2f}{row["verification_rms_um"]:>13.2f}'
            f'{row["verification_verdict"]:>8}{row["variance_factor"]:>12.3g}  '
            f'{row["adequacy"]:<8}{row["max_link_force_n"]:>11.1f}{ratio:>9.2f}'
        )
    print(
        "  max link N: the largest |axial force| at the link's platform joint over the walk "
        "(tension > 0); x rigid: the pose error over the rigid machine's rigid fit, same mode"
    )


def print_rows(rows: list[dict], header: bool) -> None:
    """Print rows of the table (module doc), compliances under their fit."""
    if header:
        print(
            f'{"model":<14}{"effects":<17}{"fit":<8}{"pose mean um":>13}{"max um":>9}'
            f'{"orient urad":>12}{"verif rms um":>13}{"verdict":>8}{"var.factor":>12}'
            f'  adequacy  at rest  link stretch um'
        )
    for row in rows:
        if 'refused' in row:
            print(f'{row["model"]:<14}{row["effect"]:<17}{row["compliance"]:<8}'
                  f'  refused: {row["refused"]}')
            continue
        print(
            f'{row["model"]:<14}{row["effect"]:<17}{row["compliance"]:<8}'
            f'{row["pose_mean_um"]:>13.2f}{row["pose_max_um"]:>9.2f}'
            f'{row["orientation_mean_urad"]:>12.2f}{row["verification_rms_um"]:>13.2f}'
            f'{row["verification_verdict"]:>8}{row["variance_factor"]:>12.3g}  '
            f'{row["adequacy"]:<8}  {row["settled"]}/{row["postures"]}'
            f'{row["link_stretch_um"]:>10.1f}'
        )
        for name, entry in row['compliances'].items():
            print(
                f'{"":<22}{name:<7} identified {entry["identified"]:.3e} +- {entry["std"]:.1e}'
                f' m/N, true {entry["true"]:.3e}'
            )
    print(flush=True)


if __name__ == '__main__':
    raise SystemExit(main())
