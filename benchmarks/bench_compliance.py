#!/usr/bin/env python3
"""
Compliance benchmark: the rigid and the compliant fit of a machine loaded by its weights.

Synthetic data from hexacal's own loaded forward model (core/fit/compliance.py
``simulate_loaded_measurements``): each built-in model with a 20 kg platform, 2 kg legs, a
1.5 kg link, legs of 5e7 N/m (compliance 2e-8 m/N, 0.6x..1.4x per chain for ``per_chain``)
and a 1e7 N/m link (1e-7 m/N), ``--postures`` sphere postures (the released chain of each: the
one leaving the passive system best conditioned), readings +-2 um / +-2 urad (uniform), started
from the true geometry plus 0.2 mm / 0.2 mrad errors.  For each measuring mode (passive_actuator:
the link carries part of the weight; lvdt: it carries none) and compliance choice (none, shared,
per_chain) it prints, in one run:

- the same procedure on the same machine made rigid (no compliance; its own noise draws), the
  target a compliant fit is judged by;
- the pose error against the true geometry on 200 fresh poses (FK of the identified parameters
  at the true machine's joint coordinates: mean position um / orientation urad);
- the fit's variance factor and adequacy verdict;
- each identified compliance with its standard deviation beside the true value.

Run: ``.venv/bin/python benchmarks/bench_compliance.py [--postures 50] [--seed 1] [--json]``.
"""

from __future__ import annotations

import argparse
import json

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.kinematics import forward_kinematics, inverse_kinematics
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
import numpy as np

MASSES = MassModel(platform_mass=20.0, leg_mass=2.0, link_mass=1.5)
CHAIN, LINK = 2e-8, 1e-7
NOISE = NoiseModel.from_microns(2.0)


def pose_error(true, identified, fresh) -> tuple[float, float]:
    """Mean position (m) and orientation (rad) error of `identified` at the true joints."""
    fk = forward_kinematics(identified, inverse_kinematics(true, fresh), fresh)
    ok = fk.converged
    position = np.linalg.norm(fk.poses[ok, :3] - fresh[ok, :3], axis=1)
    angle = np.linalg.norm(fk.poses[ok, 3:] - fresh[ok, 3:], axis=1)
    return float(position.mean()), float(angle.mean())


def run(model: str, mode: str, postures: int, seed: int) -> list[dict]:
    arch = architecture(model)
    true = arch.default_parameters()
    rng = np.random.default_rng(seed)
    poses = sample_poses(true, postures, rng, 'sphere', arch.default_workspace())
    fresh = sample_poses(true, 200, rng, 'sphere', arch.default_workspace())
    released = np.argmin(release_conditions(true, poses, 0.75), axis=1)
    truth_chains = CHAIN * np.linspace(0.6, 1.4, 6)
    generator = ComplianceModel('per_chain', MASSES, mode, released)
    truth = np.concatenate([truth_chains, [LINK]]) if generator.has_link else truth_chains
    measurements, _ = simulate_loaded_measurements(
        true, poses, generator, truth, noise=NOISE, rng=rng
    )
    nominal = true.with_vector(true.vector + rng.normal(0.0, 2e-4, true.vector.size))
    # The same procedure on the same machine made rigid (its own noise draws): the target.
    rigid_machine, _ = simulate_loaded_measurements(
        true, poses, generator, truth * 0.0, noise=NOISE, rng=np.random.default_rng(seed)
    )
    baseline = identify(nominal, rigid_machine, SolverOptions(noise=NOISE))
    position, angle = pose_error(true, baseline.parameters, fresh)
    rows = [
        {
            'model': model,
            'measuring_mode': mode,
            'compliance': 'rigid machine',
            'pose_error_um': position * 1e6,
            'orientation_error_urad': angle * 1e6,
            'variance_factor': baseline.variance_factor,
            'adequacy': baseline.adequacy.verdict.value,
            'compliances': {},
        }
    ]
    for choice in ('none', 'shared', 'per_chain'):
        compliance = ComplianceModel(choice, MASSES, mode, released)
        result = identify(nominal, measurements, SolverOptions(noise=NOISE, compliance=compliance))
        position, angle = pose_error(true, result.parameters, fresh)
        true_values = {f'chain_{c + 1}': truth_chains[c] for c in range(6)}
        true_values.update(chains=float(truth_chains.mean()), link=LINK)
        rows.append(
            {
                'model': model,
                'measuring_mode': mode,
                'compliance': choice,
                'pose_error_um': position * 1e6,
                'orientation_error_urad': angle * 1e6,
                'variance_factor': result.variance_factor,
                'adequacy': result.adequacy.verdict.value,
                'compliances': {
                    name: {
                        'true': true_values[name],
                        'identified': value,
                        'std': result.compliance_std[name],
                    }
                    for name, value in result.compliance.items()
                },
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--postures', type=int, default=50)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    rows = [
        row
        for model in ('hexa_slide', 'gough_stewart')
        for mode in ('passive_actuator', 'lvdt')
        for row in run(model, mode, args.postures, args.seed)
    ]
    if args.json:
        print(json.dumps(rows))
        return
    print(
        f'{"model":<14}{"mode":<18}{"compliance":<15}{"pose um":>9}{"orient urad":>12}'
        f'{"var.factor":>12}  adequacy'
    )
    for row in rows:
        print(
            f'{row["model"]:<14}{row["measuring_mode"]:<18}{row["compliance"]:<15}'
            f'{row["pose_error_um"]:>9.2f}{row["orientation_error_urad"]:>12.2f}'
            f'{row["variance_factor"]:>12.3g}  {row["adequacy"]}'
        )
        for name, entry in row['compliances'].items():
            z = (entry['identified'] - entry['true']) / entry['std']
            print(
                f'{"":<14}{name:<10} true {entry["true"]:.3e}  identified '
                f'{entry["identified"]:.3e} +- {entry["std"]:.2e} m/N  ({z:+.2f} std)'
            )


if __name__ == '__main__':
    main()
