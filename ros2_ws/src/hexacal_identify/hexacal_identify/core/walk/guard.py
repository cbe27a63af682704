"""
The executor's guard (ROS-free): predict a move before it is sent, on the model.

A real drive faults when a commanded actuator cannot follow, and a measuring link bends or
reaches its end stop; the executor must stop before, never after. Before a command is sent,
`predict_move` follows it on the model the targets come from (the nominal one until a
calibration refines it) the way the controller moves: linearly in joint space from the measured
actuators through each point, sampled at most ``sample_step_m`` apart, each sample solved from
the previous one (continuation on the machine's branch):

* ``lvdt``: the link's extension |P| - L with the six at the sample (forward kinematics,
  core/modes/lvdt.py) must stay within ``lvdt_stroke_m`` less ``lvdt_margin_m``;
* ``compliant``: the force of the most loaded servo, ``servo_stiffness_n_per_m`` x its strain
  (where the link lets the machine stand, core/modes/compliant.py, minus the sample), must stay
  within ``max_force_n``, and the link's tension those servos load it with
  (core/modes/compliant.link_tension) within ``max_link_force_n``.  The first sample is the
  measured standing: on the model it is strained by what the model misses there, so the
  prediction carries the current mismatch; what it misses at the next standing the defaults
  leave room for (the limits are GUARD_FORCE_FRACTION of the drives', hexacal_msgs_py.
  measuring_modes);
* ``passive_actuator`` (from the model's standing at the start pose, not the measured
  actuators): the five commanded plus the link must have a solution near the previous one
  (core/modes/passive_actuator.py: no jam at a singularity) and the released actuator must stay
  inside the actuator stroke less ``released_margin_m``.

What the prediction misses (the model's error) the guard on the measured readings catches: the
driver's own status (a fault pauses the plan) and the LVDT length.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from hexacal_msgs_py.measuring_modes import (
    COMPLIANT_SERVO_STIFFNESS_N_PER_M,
    DEFAULT_LVDT_STROKE_M,
    GUARD_FORCE_FRACTION,
    LINK_FORCE_LIMIT_N,
    MeasuringMode,
)
import numpy as np

from ..architectures import KinematicParameters
from ..errors import CalibrationError
from ..machine.device import DEFAULT_MOUNT
from ..machine.kinematics import forward_kinematics, inverse_kinematics
from ..modes.compliant import ConstraintError, device_constrained_pose, link_tension
from ..modes.passive_actuator import solve_passive

MAX_SAMPLES = 400  # per move: a long move is sampled coarser


@dataclass(frozen=True)
class GuardSettings:
    """The limits the guard keeps a move within (SI units)."""

    lvdt_stroke_m: float = DEFAULT_LVDT_STROKE_M
    lvdt_margin_m: float = 1e-3
    servo_stiffness_n_per_m: float = COMPLIANT_SERVO_STIFFNESS_N_PER_M
    # Inside the drives' fault limits (the driver's max_force_n and max_link_force_n, both the
    # link's LINK_FORCE_LIMIT_N) by the margin the model's error needs.
    max_force_n: float = GUARD_FORCE_FRACTION * LINK_FORCE_LIMIT_N
    max_link_force_n: float = GUARD_FORCE_FRACTION * LINK_FORCE_LIMIT_N
    released_margin_m: float = 1e-3
    sample_step_m: float = 1e-3


@dataclass(frozen=True)
class MovePrediction:
    """The worst predicted value along a move (m or N), its limit, and what was predicted."""

    what: str  # 'link extension', 'servo force', 'link force', 'released actuator'
    worst: float
    limit: float
    problem: str  # '' when the move stays inside its limit


def joint_samples(current: np.ndarray, points: np.ndarray, step_m: float) -> np.ndarray:
    """Return the joint-space samples (M, 6) from `current` through `points`, <= step_m apart."""
    path = np.vstack([np.asarray(current, dtype=float)[None], np.atleast_2d(points)])
    lengths = np.max(np.abs(np.diff(path, axis=0)), axis=1)
    step = max(step_m, float(np.sum(lengths)) / MAX_SAMPLES, 1e-9)
    samples = [path[:1]]
    for start, end, length in zip(path[:-1], path[1:], lengths):
        count = max(1, math.ceil(length / step))
        fractions = np.arange(1, count + 1)[:, None] / count
        samples.append(start + fractions * (end - start))
    return np.concatenate(samples)


def predict_move(
    model: KinematicParameters,
    mode: MeasuringMode,
    current: np.ndarray,
    start_pose: np.ndarray,
    points: np.ndarray,
    link_length: float,
    stroke: tuple[float, float],
    settings: GuardSettings,
    released: int | None = None,
    mount: str = DEFAULT_MOUNT,
) -> MovePrediction:
    """Return what the move from `current` through `points` does on `model` (module doc)."""
    pose = np.asarray(start_pose, dtype=float)
    if mode == MeasuringMode.PASSIVE_ACTUATOR and released is not None:
        # From where the model stands at the start: the measured actuators (the true machine's,
        # the released one where the link put it) are not a standing of the model, and five of
        # them with the link may close nowhere near on it.
        current = inverse_kinematics(model, pose[None])[0]
        samples = joint_samples(current, points, settings.sample_step_m)
        return _passive(model, samples, pose, released, link_length, stroke, settings, mount)
    samples = joint_samples(current, points, settings.sample_step_m)
    if mode == MeasuringMode.LVDT:
        return _lvdt(model, samples, pose, link_length, settings)
    return _compliant(model, samples, pose, link_length, settings, mount)


def _lvdt(model, samples, pose, link_length, settings) -> MovePrediction:
    limit = settings.lvdt_stroke_m - settings.lvdt_margin_m
    worst = 0.0
    for sample in samples:
        solved = forward_kinematics(model, sample[None], pose[None])
        if not bool(solved.converged[0]):
            return MovePrediction(
                'link extension', math.inf, limit,
                'the model cannot tell where the link would be on the way (forward kinematics '
                'failed)',
            )
        pose = solved.poses[0]
        extension = float(np.linalg.norm(pose[:3])) - link_length
        if abs(extension) > abs(worst):
            worst = extension
    problem = (
        f'the link would be {"stretched" if worst > 0 else "compressed"} by '
        f'{abs(worst) * 1e3:.3f} mm on the way, beyond the LVDT stroke +-'
        f'{settings.lvdt_stroke_m * 1e3:g} mm less the {settings.lvdt_margin_m * 1e3:g} mm margin'
        if abs(worst) > limit
        else ''
    )
    return MovePrediction('link extension', worst, limit, problem)


def _compliant(model, samples, pose, link_length, settings, mount) -> MovePrediction:
    poses = np.empty_like(samples)
    standing = np.empty_like(samples)
    for index, sample in enumerate(samples):
        try:
            pose, standing[index] = device_constrained_pose(
                model, sample, pose, link_length, mount
            )
        except (CalibrationError, ConstraintError, ValueError, FloatingPointError) as error:
            return MovePrediction(
                'servo force', math.inf, settings.max_force_n,
                f'the model cannot tell where the link would hold the machine ({error})',
            )
        poses[index] = pose
    stiffness = settings.servo_stiffness_n_per_m
    strain = float(np.max(np.abs(standing - samples)))
    force = stiffness * strain
    tension = link_tension(model, poses, standing, samples, stiffness)
    link = float(tension[np.argmax(np.abs(tension))])
    # The servos' strain, stiffness and effort in the actuators' units (mm, N/m, N for sliders;
    # deg, N m/rad, N m for cranks); the link's force is in N for every machine.
    units = model.layout.actuator_quantities
    strained = f'strain {units.shown(strain, 3)} at {stiffness:g} {units.stiffness_unit}'
    if force > settings.max_force_n:
        return MovePrediction(
            'servo force', force, settings.max_force_n,
            f'a servo would carry {force:.4g} {units.effort_unit} on the way ({strained}), '
            f'beyond max_force_n {settings.max_force_n:g} {units.effort_unit}',
        )
    if abs(link) > settings.max_link_force_n:
        return MovePrediction(
            'link force', link, settings.max_link_force_n,
            f'the servos would load the measuring link with {abs(link):.4g} N of '
            f'{"tension" if link > 0 else "compression"} on the way ({strained}), beyond '
            f'max_link_force_n {settings.max_link_force_n:g} N',
        )
    return MovePrediction('servo force', force, settings.max_force_n, '')


def _passive(model, samples, pose, released, link_length, stroke, settings, mount):
    low, high = stroke[0] + settings.released_margin_m, stroke[1] - settings.released_margin_m
    worst = -math.inf  # how far beyond the stroke less the margin (<= 0: inside)
    limit = 0.0
    for sample in samples:
        solved = solve_passive(model, sample[None], released, pose[None], link_length, mount)
        if not bool(solved.converged[0]):
            return MovePrediction(
                'released actuator', math.inf, limit,
                'the five commanded actuators and the link would jam on the way (no pose near '
                'the previous one: a singularity of the passive system with this actuator '
                'released)',
            )
        pose = solved.poses[0]
        position = float(solved.actuators[0, released])
        worst = max(worst, low - position, position - high)
    units = model.layout.actuator_quantities  # the stroke and margin: m, or rad for cranks
    problem = (
        f'the released actuator would leave its stroke [{stroke[0]:g}, {stroke[1]:g}] '
        f'{units.unit} less the {units.shown(settings.released_margin_m, 3)} margin by '
        f'{units.shown(worst, 3)} on the way'
        if worst > limit
        else ''
    )
    return MovePrediction('released actuator', worst, limit, problem)


def move_guard(
    model: KinematicParameters,
    mode: MeasuringMode,
    link_length: float,
    stroke: tuple[float, float],
    settings: GuardSettings,
    mount: str = DEFAULT_MOUNT,
):
    """Return core.walk's guard: the problem of a move on `model` in `mode` ('' = none)."""

    def guard(
        current: np.ndarray, start: np.ndarray, points: np.ndarray, released: int | None
    ) -> str:
        return predict_move(
            model, mode, current, start, points, link_length, stroke, settings, released, mount
        ).problem

    return guard


__all__ = ['GuardSettings', 'MovePrediction', 'joint_samples', 'move_guard', 'predict_move']
