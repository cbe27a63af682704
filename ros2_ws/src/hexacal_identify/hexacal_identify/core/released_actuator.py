"""
Choose the actuator released at each posture of a passive-actuator plan (issue #18).

For each planned posture, among the six actuators, the released one is the one
that leaves the five commanded plus the link best conditioned (the smallest
condition number of the passive system's Jacobian at the posture,
``passive_actuator.release_conditions``) among those that stay inside their
stroke less a margin all along the move from the previous posture.  The move is
the executor's (``paths.route_command``): along the link sphere
(``paths.sphere_path``: great circle, Euler angles linear) if the nominal IK of
all six stays inside the stroke there, else by way of the centre (the fixed
point, zero angles); it is sampled at most ``step_m`` apart.  The released
actuator follows the five commanded ones wherever the link takes it, and on the
true machine that is up to millimetres from where the nominal model predicts
(the model error a first calibration removes), hence the margin
(``DEFAULT_MARGIN_M``): a released actuator must not run into its end stop.

The choice is per posture, and posture i's released actuator is the one released
during the move from posture i - 1 to posture i and during its measurement: the
executor swaps the released actuator after measuring posture i - 1, at rest
(locking the one released there at its measured position, which it has just
read, and releasing the next, which was standing at its setpoint).  So the
released actuator changes only at rest, by construction.  The first posture's
move starts where the machine is, unknown to the planner: only the posture
itself is checked (or the move from ``start`` if given).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .architectures import KinematicParameters
from .device import DEFAULT_MOUNT, fixed_point
from .errors import CalibrationError
from .passive_actuator import release_conditions
from .paths import sphere_path

DEFAULT_STEP_M = 0.01  # path samples at most this far apart (position; angles times L)
# Kept from both stroke ends by the released actuator along every move: the largest deviation
# of the true machine from a nominal model (the demo's strain, issue #18: up to 4 mm) and more.
DEFAULT_MARGIN_M = 0.005


class ReleaseError(CalibrationError, ValueError):
    """No actuator of a posture can be released: each leaves its stroke along the move."""

    reason = 'no-releasable-actuator'

    def __init__(self, message: str, posture: int):
        super().__init__(message)
        self.posture = posture


@dataclass(frozen=True)
class ReleaseChoice:
    """
    The released actuator per posture and why.

    ``released`` (K,) 0-based chain index; ``conditions`` (K, 6) the passive system's
    condition number with each chain released (angles scaled by L); ``inside`` (K, 6) whether
    that chain stays inside its stroke (less the margin) along the move to the posture;
    ``travel`` (K, 6) the range (max - min, m) each chain covers along that move;
    ``via_centre`` (K,) whether that move goes by way of the centre (the direct one leaves the
    stroke).
    """

    released: np.ndarray
    conditions: np.ndarray
    inside: np.ndarray
    travel: np.ndarray
    via_centre: np.ndarray

    @property
    def chosen_conditions(self) -> np.ndarray:
        """Return the condition number of the chosen release per posture (K,)."""
        return self.conditions[np.arange(len(self.released)), self.released]

    @property
    def worst_conditions(self) -> np.ndarray:
        """Return the worst release's condition number per posture (K,): what choosing avoids."""
        return np.max(self.conditions, axis=1)

    @property
    def released_travel(self) -> np.ndarray:
        """Return how far the released actuator moves on its way to each posture (K,), m."""
        return self.travel[np.arange(len(self.released)), self.released]

    def names(self, actuator_names: tuple[str, ...]) -> tuple[str, ...]:
        """Return the released actuators' joint names, one per posture."""
        return tuple(actuator_names[int(r)] for r in self.released)


def _nominal_actuators(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """Return the nominal IK (M, 6), NaN rows where a pose is out of reach."""
    arch = params.architecture
    legs = arch.legs(arch.chains(params), poses)
    return np.where(legs.reachable()[:, None], legs.actuators, np.nan)


def _inside(actuators: np.ndarray, low: float, high: float) -> np.ndarray:
    """Return the mask of actuator values within [low, high] (NaN: outside)."""
    with np.errstate(invalid='ignore'):
        return (actuators >= low) & (actuators <= high)


def move_samples(
    params: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    step_m: float = DEFAULT_STEP_M,
    start: np.ndarray | None = None,
    mount: str = DEFAULT_MOUNT,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the nominal IK along every move of the plan (M, 6), each sample's posture and via.

    Move i runs from posture i - 1 (``start`` for i = 0; none: posture 0 alone) to posture i,
    both ends included, the way the executor goes (module doc); ``via`` (K,) says which moves
    go by way of the centre.
    """
    low, high = stroke_m
    centre = np.concatenate([fixed_point(link_length, mount), np.zeros(3)])
    samples, owners = [], []
    via = np.zeros(len(poses), bool)
    for i, pose in enumerate(poses):
        previous = start if i == 0 else poses[i - 1]
        if previous is None:
            path = _nominal_actuators(params, pose[None])
        else:
            previous = np.asarray(previous, dtype=float)
            direct = np.concatenate([previous[None], sphere_path(previous, pose, link_length,
                                                                 step_m)])
            path = _nominal_actuators(params, direct)
            if not np.all(_inside(path, low, high)):
                via[i] = True
                around = np.concatenate(
                    [
                        previous[None],
                        sphere_path(previous, centre, link_length, step_m),
                        sphere_path(centre, pose, link_length, step_m),
                    ]
                )
                path = _nominal_actuators(params, around)
        samples.append(path)
        owners.append(np.full(len(path), i))
    return np.concatenate(samples), np.concatenate(owners), via


def choose_released_actuators(
    params: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    *,
    margin_m: float = DEFAULT_MARGIN_M,
    step_m: float = DEFAULT_STEP_M,
    start: np.ndarray | None = None,
    mount: str = DEFAULT_MOUNT,
) -> ReleaseChoice:
    """
    Choose each posture's released actuator (module doc); ReleaseError if one has none.

    `poses` (K, 6) in plan order, planned on `params` (the nominal machine) and the link sphere
    of radius `link_length`; `stroke_m` the actuator stroke (low, high), m; `margin_m` kept
    from both ends along every move by the released actuator; `mount` the device's (the centre
    a move may go by).
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    conditions = release_conditions(params, poses, link_length)
    actuators, owners, via = move_samples(
        params, poses, link_length, stroke_m, step_m, start, mount
    )
    low, high = stroke_m
    outside = ~_inside(actuators, low + margin_m, high - margin_m)
    count = len(poses)
    inside = np.ones((count, 6), bool)
    lowest = np.full((count, 6), np.inf)
    highest = np.full((count, 6), -np.inf)
    np.logical_and.at(inside, owners, ~outside)
    np.minimum.at(lowest, owners, actuators)
    np.maximum.at(highest, owners, actuators)
    travel = highest - lowest
    ranked = np.where(inside, conditions, np.inf)
    released = np.argmin(ranked, axis=1)
    stuck = ~np.isfinite(ranked[np.arange(count), released])
    if np.any(stuck):
        posture = int(np.flatnonzero(stuck)[0])
        names = params.layout.actuator_names
        raise ReleaseError(
            f'posture {posture}: no actuator can be released - every one of '
            f'{", ".join(names)} leaves the stroke [{low + margin_m:g}, {high - margin_m:g}] m '
            f'(stroke less the {margin_m:g} m margin) at the posture or on the move to it, or '
            'makes the five commanded plus the link singular',
            posture,
        )
    return ReleaseChoice(released, conditions, inside, travel, via)


__all__ = [
    'DEFAULT_MARGIN_M',
    'DEFAULT_STEP_M',
    'ReleaseChoice',
    'ReleaseError',
    'choose_released_actuators',
    'move_samples',
]
