"""
The calibration call shared by the identify node and ``hexacal calibrate``, and its status.

The node and the CLI both go through :func:`calibrate`, so a bag calibrated
offline gives the same parameters as the node that received the same postures.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

from hexacal_msgs_py.readings import PostureReading
import numpy as np

from .posture_checks import measurements_from_postures, scatter_count
from ..core.architectures import KinematicParameters
from ..core.fit.compliance import ComplianceModel
from ..core.fit.identification import IdentificationResult, identify, SolverOptions
from ..core.fit.statics import MassModel
from ..core.fit.weighting import AUTO, choose_weights, WeightChoice
from ..core.machine.device import DEFAULT_MOUNT, DEVICE_PARAMETER_NAMES, DeviceModel, DevicePrior
from ..core.machine.measurements import NoiseModel, ScatterFloor, Weights
from ..core.machine.model import parameter_names


def weight_choice(
    postures: Sequence[PostureReading],
    weights: str = AUTO,
    noise: NoiseModel | None = None,
    scatter_floor: ScatterFloor = ScatterFloor(),
    actuator_unit: str = 'm',
) -> WeightChoice:
    """Return what weighs a calibration of `postures` (core.weighting.choose_weights)."""
    return choose_weights(
        weights, scatter_count(postures), len(postures), noise, scatter_floor, actuator_unit
    )


def calibrate(
    nominal: KinematicParameters,
    postures: Sequence[PostureReading],
    *,
    cost: str = 'absolute',
    link_length: float = DeviceModel().link_length,
    allow_rank_deficient: bool = False,
    identify_device: Sequence[str] = (),
    noise: NoiseModel | None = None,
    robust_loss: str | None = None,
    mount: str = DEFAULT_MOUNT,
    device_prior: DevicePrior | None = None,
    weights: str = AUTO,
    scatter_floor: ScatterFloor = ScatterFloor(),
    compliance: ComplianceModel | None = None,
) -> IdentificationResult:
    """
    Identify the parameters from received postures: the one call behind the node and the CLI.

    ``nominal`` is the starting parameter set of any architecture (its model is the
    result's). ``identify_device`` names device defects to identify jointly (e.g. dL,
    alpha0, gamma).  ``weights`` (core.weighting: auto, scatter, noise-model, none) says what
    weighs the residuals: by default the postures' scatter where every posture carries it
    (each standard error raised to ``scatter_floor``), else ``noise`` (reading noise
    half-widths) when given; the result's ``weights`` / ``weights_note`` say which.
    ``mount`` is the device's (hanging, or standing for an upright machine).
    ``device_prior``: prior knowledge of device parameters (a caliper's dL = 0 +- 10 um, a
    certificate's alpha0 = 0 +- 50 urad; SI units): each such parameter is identified, its prior
    weighed against the data by ``noise``, which it therefore requires (ValueError naming both).
    A problem the postures do not determine raises RankDeficientError (never a
    number that means nothing) unless ``allow_rank_deficient``.  ``compliance``: axial
    compliances identified with the geometry from the postures' static loads
    (core/fit/compliance.py; None: the rigid model).
    """
    choice = weight_choice(
        postures, weights, noise, scatter_floor, nominal.layout.actuator_unit
    )
    options = SolverOptions(
        cost=cost,
        device=DeviceModel(link_length=link_length, mount=mount),
        allow_rank_deficient=allow_rank_deficient,
        free_device=tuple(identify_device),
        noise=noise if choice.weights == Weights.NOISE_MODEL else None,
        robust_loss=robust_loss,
        device_prior=device_prior if device_prior is not None else DevicePrior(),
        scatter_weights=choice.weights == Weights.SCATTER,
        scatter_floor=scatter_floor,
        compliance=compliance if compliance is not None else ComplianceModel(),
    )
    measurements = measurements_from_postures(postures, nominal_link_length=link_length)
    result = identify(nominal, measurements, options)
    result.weights_note = choice.note
    return result


def parse_compliance_prior(text: str) -> dict[str, tuple[float, float]]:
    """
    Parse datasheet compliances NAME=VALUE:STD,... (m/N); '' = none.

    The syntax of ``hexacal calibrate --compliance-prior`` and of the identify node's
    ``compliance_prior``; a bad item is a ValueError naming it.
    """
    prior = {}
    for item in filter(None, (part.strip() for part in text.split(','))):
        name, _, figures = item.partition('=')
        value, _, std = figures.partition(':')
        try:
            prior[name.strip()] = (float(value), float(std))
        except ValueError:
            raise ValueError(
                f'compliance prior {item!r}: expected NAME=VALUE:STD in m/N, e.g. link=1e-7:2e-8'
            ) from None
    return prior


def compliance_for_postures(
    choice: str,
    masses: MassModel,
    measuring_mode: str | None,
    released_joints: Sequence[str] | None,
    actuator_names: Sequence[str],
    prior: dict[str, tuple[float, float]] | None = None,
    label: str = 'compliance',
    released_friction: float = 0.0,
    drive_stiffness: tuple[float, ...] | None = None,
) -> ComplianceModel | None:
    """
    Return the ComplianceModel of a compliance choice for a set of postures (None: rigid).

    What ``hexacal calibrate --compliance`` and the identify node's ``compliance`` share:
    ``measuring_mode`` (None: unknown, refused) says who carries the weights, and in the
    passive_actuator mode ``released_joints`` (one actuator joint name per posture) which chain
    carries nothing. ``label`` names the option in the errors (ValueError).
    ``released_friction`` (N, passive_actuator): the released actuator's friction bound, the
    force it may hold where it stops, weighed as a noise source of each posture.
    ``drive_stiffness`` (compliant): the servos' gain the load is shared by (statics.py).
    """
    from ..core.fit.compliance import NONE

    if choice == NONE:
        return None
    if measuring_mode is None:
        raise ValueError(
            f'{label} {choice}: the measuring mode of the postures is not known, and the loads '
            'depend on it (which chains and whether the link carry the weight)'
        )
    released = None
    if measuring_mode == 'passive_actuator':
        names = list(actuator_names)
        joints = list(released_joints or ())
        missing = [i for i, joint in enumerate(joints) if joint not in names]
        if missing:
            raise ValueError(
                f'{label} {choice}: {len(missing)} of the {len(joints)} passive_actuator '
                f'postures name no released actuator of {", ".join(names)} '
                f'(first: posture {missing[0]})'
            )
        released = np.array([names.index(joint) for joint in joints])
    return ComplianceModel(
        choice, masses, measuring_mode, released, prior=prior or {},
        released_friction=released_friction if measuring_mode == 'passive_actuator' else 0.0,
        drive_stiffness=drive_stiffness if measuring_mode == 'compliant' else None,
    )


def identified_compliance(
    values: dict[str, float],
    masses: MassModel,
    measuring_mode: str | None,
    released_joints: Sequence[str] | None,
    actuator_names: Sequence[str],
    label: str,
    drive_stiffness: tuple[float, ...] | None = None,
) -> tuple[ComplianceModel, np.ndarray]:
    """
    Return a calibration's identified compliances as (model, values) for a verification.

    ``values`` (m/N) are a parameters file's compliance section: per chain when they name a
    chain, else shared; the postures' loads as compliance_for_postures gives them.
    """
    from ..core.fit.compliance import PER_CHAIN, SHARED

    per_chain = any(name.startswith('chain_') for name in values)
    model = compliance_for_postures(
        PER_CHAIN if per_chain else SHARED,
        masses,
        measuring_mode,
        released_joints,
        actuator_names,
        label=label,
        drive_stiffness=drive_stiffness,
    )
    assert model is not None  # PER_CHAIN and SHARED always give one
    return model, np.array([values.get(name, 0.0) for name in model.names])


def deflection_check(
    result: IdentificationResult,
    physical_path: str,
    measuring_mode: str | None,
    released_joints: Sequence[str] | None,
    *,
    cost: str = 'absolute',
    link_length: float = DeviceModel().link_length,
    mount: str = DEFAULT_MOUNT,
    identify_device: Sequence[str] = (),
):
    """
    Return the bias a physical description's compliances put into the rigid fit `result`.

    `physical_path` '' : the model's shipped description.

    core/assessment/deflection.py: the calibrated machine loaded by the description's weights
    and compliances (1 / each chain's structure stiffness, 1 / the link's) at the postures'
    measuring mode and releases, refitted rigid with the calibration's cost, device and
    unknowns.  ValueError: a file without the stiffnesses (a mass-only file), an unknown mode.
    """
    from ..core.assessment.deflection import deflection_bias
    from ..core.fit.compliance import PER_CHAIN
    from ..core.fit.statics import physical_source

    model = result.parameters.model
    physical, _ = _physical_of(physical_path, model)
    if physical is None:
        raise ValueError(
            f'{physical_path}: the deflection check needs the stiffnesses: a physical '
            'description that names its model (format: hexacal-physical/1)'
        )
    if measuring_mode is None:
        raise ValueError(
            'the deflection check: the measuring mode of the postures is not known, and the '
            'loads depend on it (which chains and whether the link carry the weight)'
        )
    names = list(result.parameters.layout.actuator_names)
    released = None
    if measuring_mode == 'passive_actuator':  # -1: no release recorded, left out of the check
        released = np.array([names.index(j) if j in names else -1 for j in released_joints or ()])
    compliance = ComplianceModel(
        PER_CHAIN, MassModel.from_physical(physical), measuring_mode, released,
        drive_stiffness=tuple(physical.drive_kp) if measuring_mode == 'compliant' else None,
    )
    chains = physical.structure_axial_stiffness
    values = np.array([
        (0.0 if chains is None else 1.0 / chains[int(name.split('_')[1]) - 1])
        if name.startswith('chain_') else
        (0.0 if physical.link_axial_stiffness is None else 1.0 / physical.link_axial_stiffness)
        for name in compliance.names
    ])
    options = SolverOptions(
        cost=cost, device=DeviceModel(link_length=link_length, mount=mount),
        free_device=tuple(identify_device),
    )
    return deflection_bias(
        result, options, compliance, values, physical_source(physical_path, model)
    )


def _physical_of(path: str | None, model: str):
    """
    Return (the complete description, or None; the file's mapping) of ``path`` (module doc).

    ``path`` None or '': the model's shipped description; a complete ``hexacal-physical/1``
    file through the contract's reader; else the file's mapping of (mass) keys.
    """
    from hexacal_msgs_py.physical_file import default_physical, read_physical_file
    import yaml

    if not path:
        return default_physical(model), None
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as error:
        raise ValueError(f'cannot read the physical description {path}: {error}') from error
    if isinstance(data, dict) and 'model' in data:
        return read_physical_file(path), None
    return None, data


def drive_stiffness_of(path: str | None, model: str) -> tuple[float, ...] | None:
    """
    Return the servos' gain (N/m or N m/rad, six) of a physical description, or None.

    As ``released_friction_of`` reads the file; a file of the mass keys only gives its
    ``drives.kp`` (one value or six), None when missing: the compliant mode's load is then
    shared by equal drives and a rigid link (core/fit/statics.py).
    """
    physical, data = _physical_of(path, model)
    if physical is not None:
        return tuple(physical.drive_kp)
    section = data.get('drives') if isinstance(data, dict) else None
    kp = (section or {}).get('kp') if isinstance(section, dict) else None
    if kp is None:
        return None
    try:
        gains = np.broadcast_to(np.asarray(kp, dtype=float), (6,))
    except (TypeError, ValueError):
        raise ValueError(f'{path}: drives.kp must be one gain or six, got {kp!r}') from None
    if not np.all(np.isfinite(gains) & (gains > 0)):
        raise ValueError(f'{path}: drives.kp must be > 0, got {kp!r}')
    return tuple(float(g) for g in gains)


def released_friction_of(path: str | None, model: str) -> float:
    """
    Return the released actuator's friction bound (N) of a physical description.

    ``path`` None or '': the model's shipped description; a complete ``hexacal-physical/1``
    file through the contract's reader; a file of the mass keys only: its
    ``released_friction.coulomb`` (0 when missing).  ValueError names an unreadable file.
    """
    physical, data = _physical_of(path, model)
    if physical is not None:
        return physical.released_coulomb
    section = data.get('released_friction') if isinstance(data, dict) else None
    try:
        friction = float((section or {}).get('coulomb', 0.0))
    except (AttributeError, TypeError, ValueError):
        raise ValueError(
            f'{path}: released_friction.coulomb must be a force in N, got {section!r}'
        ) from None
    if not np.isfinite(friction) or friction < 0.0:
        raise ValueError(f'{path}: released_friction.coulomb must be >= 0 N, got {friction!r}')
    return friction


def device_prior_json(prior: DevicePrior | None) -> dict[str, dict[str, float]]:
    """
    Return {name: {"value", "std"}} (SI units) of a device prior.

    {"value", "std"}} (SI units) of a device prior: what ``calibrate --json`` and the report carry.
    """
    if prior is None:
        return {}
    return {name: {'value': float(value), 'std': float(std)} for name, value, std in prior.entries}


def status_fields(
    result: IdentificationResult, device_prior: DevicePrior | None = None
) -> dict[str, str]:
    """
    Key/values for /hexacal/calibration_status (SI units, machine-readable).

    Identified device parameters: posterior ``device.<name>`` / ``std.device.<name>``; with a prior
    on
    one, also ``prior.device.<name>`` / ``prior_std.device.<name>``. The fit's adequacy
    (core.adequacy): ``adequacy.verdict`` / ``adequacy.reason`` always, the figures
    (``adequacy.variance_factor``, ``adequacy.expected_low`` / ``_high``, ``adequacy.dof``) and
    the worst ``adequacy.worst_postures`` / ``adequacy.worst_channels`` with a noise model.
    ``weights`` (scatter, noise_model, none) and ``weights_note``: what weighed the fit.
    Identified axial compliances (m/N): ``compliance_mode``, ``compliance.<name>`` /
    ``std.compliance.<name>``.
    """
    model = result.parameters.model
    fields = {
        'outcome': result.reason,
        'model': model,
        'cost': result.cost,
        'rank': str(result.rank),
        'condition_number': f'{result.condition_number:.6g}',
        'iterations': str(result.iterations),
        'postures_used': str(len(result.used_postures)),
        'postures_rejected': str(len(result.rejected_postures)),
        'solve_seconds': f'{result.solve_seconds:.6f}',
        'identifiable': str(result.identifiability.identifiable).lower(),
    }
    fields['identifiability'] = result.identifiability.verdict().replace('\n', ' ')
    fields.update({f'rms_residual.{k}': f'{v:.6g}' for k, v in result.rms_residual.items()})
    for index, name in enumerate(DEVICE_PARAMETER_NAMES):
        if name in result.free_device:
            fields[f'device.{name}'] = f'{result.device.vector[index]:.6g}'
            fields[f'std.device.{name}'] = f'{result.device_std[index]:.6g}'
        prior = device_prior.get(name) if device_prior is not None else None
        if prior is not None:
            fields[f'prior.device.{name}'] = f'{prior[0]:.6g}'
            fields[f'prior_std.device.{name}'] = f'{prior[1]:.6g}'
    fields.update(
        {f'std.{name}': f'{s:.6g}' for name, s in zip(parameter_names(model), result.std)}
    )
    for index, why in sorted(result.rejected_postures.items())[:20]:
        fields[f'rejected.{index}'] = why
    # The fit against its noise model (adequacy.verdict unknown without one).
    fields.update(result.adequacy.status_fields())
    fields['weights'] = result.weights
    if result.weights_note:
        fields['weights_note'] = result.weights_note
    # Identified compliances (m/N) as the device parameters: value and std (nan: unknown).
    if result.compliance:
        fields['compliance_mode'] = result.compliance_mode
    for name, value in result.compliance.items():
        fields[f'compliance.{name}'] = f'{value:.6g}'
        fields[f'std.compliance.{name}'] = f'{result.compliance_std.get(name, math.nan):.6g}'
    return fields
