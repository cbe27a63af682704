"""
Rehearse a passive-actuator move on machines that differ from the nominal.

With one actuator released, the five commanded ones and the link decide where the platform
goes, and on the true machine that is not where the nominal model says: millimetres of model
error move the platform by centimetres on a Hexa Slide, and a move that is well conditioned on
the nominal can pass a singularity of the passive system on the true machine, where the five
commanded chains and the link jam (the drive faults).  A release is therefore judged on
machines whose geometry departs from the nominal as a machine built to its drawing does: the
nominal plus ``count`` draws of independent normal errors of ``error_m`` RMS on every parameter
(by default the architecture's Table 2 set 2 RMS, 1.45 mm on both shipped models; rail-direction
components 1.45e-3).  Each machine walks the move the way the drive does: from its standing at
the previous posture (the actuator released there locked where the link put it), the commanded
setpoints carry that offset to zero along the move (as the executor commands a move,
core/paths.py), sampled at most ``step_m`` apart in joint space, each sample solved from the
previous pose (``passive_actuator.solve_passive``: continuation on the machine's branch).  A
candidate survives on a machine if every sample closes and its released actuator stays inside
the stroke less the margin; its score is the worst condition number of the passive system met
on the way, over all machines.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .architectures import KinematicParameters
from .device import DEFAULT_MOUNT
from .kinematics import inverse_kinematics
from .passive_actuator import release_conditions, solve_passive

DEFAULT_MODEL_SAMPLES = 8  # machines besides the nominal a release is rehearsed on
DEFAULT_JOINT_STEP_M = 0.01  # a continuation step that follows the branch; the drive's is 5 mm
# Closing to 1 nm is plenty to follow a branch (the driver closes to 1e-12 m): fewer iterations.
REHEARSAL_TOLERANCE_M = 1e-9
NOMINAL_ERROR_SET = 2  # Table 2's set of a machine built to its drawing


def model_error_rms_m(nominal: KinematicParameters) -> float:
    """Return the default RMS parameter error (m) of the nominal's architecture (module doc)."""
    stats = nominal.architecture.nominal_error_stats_mm
    return float(stats[NOMINAL_ERROR_SET][2]) * 1e-3


def sampled_machines(
    nominal: KinematicParameters, count: int, error_m: float, seed: int = 0
) -> tuple[KinematicParameters, ...]:
    """Return the nominal and `count` machines with normal parameter errors of RMS `error_m`."""
    rng = np.random.default_rng([seed, 18])
    base = nominal.vector
    drawn = tuple(
        nominal.with_vector(base + rng.normal(0.0, error_m, len(base))) for _ in range(count)
    )
    return (nominal, *drawn)


@dataclass
class Standings:
    """Where each machine stands (K machines): poses (K, 6) and actuators (K, 6)."""

    poses: np.ndarray
    actuators: np.ndarray


@dataclass(frozen=True)
class Rehearsal:
    """
    A move rehearsed for candidate releases on K machines.

    ``survived`` (C,) on how many machines each candidate closes all along and stays inside
    its stroke; ``worst`` (C,) the worst condition number met on the machines it survived on
    (inf if none);
    ``ends`` the standings after the move per candidate (a machine that jammed: NaN rows).
    """

    candidates: np.ndarray
    survived: np.ndarray
    worst: np.ndarray
    ends: tuple[Standings, ...]


def stand(
    machines: tuple[KinematicParameters, ...],
    setpoints: np.ndarray,
    released: int,
    pose: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> Standings:
    """Return each machine standing with `setpoints` and `released` free, near `pose`."""
    poses, actuators = [], []
    for machine in machines:
        solved = solve_passive(machine, setpoints[None], released, pose[None], link_length, mount)
        if bool(solved.converged[0]):
            poses.append(solved.poses[0])
            actuators.append(solved.actuators[0])
        else:  # it cannot stand there: rehearse it from the posture as planned
            poses.append(np.asarray(pose, dtype=float))
            actuators.append(inverse_kinematics(machine, pose[None])[0])
    return Standings(np.array(poses), np.array(actuators))


def setpoint_samples(offsets: np.ndarray, model_path: np.ndarray, step_m: float) -> np.ndarray:
    """
    Return the setpoints (S, K, 6) of K machines along `model_path` (M, 6), offsets fading.

    Machine k starts at model_path[0] + offsets[k] and ends at model_path[-1]; samples at most
    `step_m` apart along the path (max-norm), the offset carried to zero with the path
    fraction.
    """
    lengths = np.max(np.abs(np.diff(model_path, axis=0)), axis=1)
    total = float(np.sum(lengths))
    count = max(1, math.ceil(max(total, float(np.max(np.abs(offsets)))) / step_m))
    fractions = np.arange(1, count + 1) / count
    if total > 0:
        along = np.concatenate([[0.0], np.cumsum(lengths)]) / total
        points = np.column_stack(
            [np.interp(fractions, along, model_path[:, c]) for c in range(6)]
        )
    else:
        points = np.repeat(model_path[-1:], count, axis=0)
    return points[:, None, :] + (1.0 - fractions)[:, None, None] * offsets[None]


def rehearse(
    machines: tuple[KinematicParameters, ...],
    start: Standings,
    setpoints: np.ndarray,
    candidates: np.ndarray,
    link_length: float,
    stroke: tuple[float, float],
    margin_m: float,
    mount: str = DEFAULT_MOUNT,
) -> Rehearsal:
    """Rehearse releasing each candidate along `setpoints` (S, K, 6) on every machine."""
    candidates = np.asarray(candidates, dtype=int)
    count, machine_count = len(candidates), len(machines)
    poses = np.repeat(start.poses[None], count, axis=0)  # (C, K, 6)
    actuators = np.repeat(start.actuators[None], count, axis=0)
    alive = np.ones((count, machine_count), bool)
    worst = np.zeros((count, machine_count))
    low, high = stroke[0] + margin_m, stroke[1] - margin_m
    for sample in setpoints:
        for k, machine in enumerate(machines):
            rows = np.flatnonzero(alive[:, k])
            if not rows.size:
                continue
            released = candidates[rows]
            solved = solve_passive(
                machine, np.repeat(sample[k][None], len(rows), axis=0), released,
                poses[rows, k], link_length, mount, tolerance=REHEARSAL_TOLERANCE_M,
            )
            ok = solved.converged
            alive[rows[~ok], k] = False
            rows, released = rows[ok], released[ok]
            poses[rows, k] = solved.poses[ok]
            actuators[rows, k] = solved.actuators[ok]
            position = actuators[rows, k, released]
            alive[rows, k] &= (position >= low) & (position <= high)
            conditions = release_conditions(machine, poses[rows, k], link_length)
            picked = conditions[np.arange(len(rows)), released]
            worst[rows, k] = np.maximum(worst[rows, k], picked)
    poses[~alive] = np.nan
    actuators[~alive] = np.nan
    return Rehearsal(
        candidates,
        np.sum(alive, axis=1),
        _worst_alive(worst, alive),
        tuple(Standings(poses[c], actuators[c]) for c in range(count)),
    )


def _worst_alive(worst: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """Return the worst condition over the machines each candidate survived on (inf: none)."""
    masked = np.where(alive, worst, -np.inf)
    best = np.max(masked, axis=1)
    return np.where(np.any(alive, axis=1), best, np.inf)


__all__ = [
    'DEFAULT_JOINT_STEP_M',
    'DEFAULT_MODEL_SAMPLES',
    'Rehearsal',
    'Standings',
    'model_error_rms_m',
    'rehearse',
    'sampled_machines',
    'setpoint_samples',
    'stand',
]
