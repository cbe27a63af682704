"""
The moves between a plan's postures as the executor takes them, on the nominal.

A move runs along the link sphere (``paths.sphere_path``: great circle, Euler angles linear) if
the nominal IK of all six stays inside the stroke there, else by way of the centre (the fixed
point, zero angles), as ``paths.route_command`` commands it; sampled at most ``step_m`` apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT, fixed_point
from ..walk.platform_paths import sphere_path


@dataclass(frozen=True)
class Move:
    """One move: its poses (M, 6) on the sphere, their nominal IK (M, 6; NaN out of reach)."""

    poses: np.ndarray
    actuators: np.ndarray
    via_centre: bool = False


def nominal_actuators(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """Return the nominal IK (M, 6), NaN rows where a pose is out of reach."""
    arch = params.architecture
    legs = arch.legs(arch.chains(params), poses)
    return np.where(legs.reachable()[:, None], legs.actuators, np.nan)


def inside_stroke(actuators: np.ndarray, low: float, high: float) -> np.ndarray:
    """Return the mask of actuator values within [low, high] (NaN: outside)."""
    with np.errstate(invalid='ignore'):
        return (actuators >= low) & (actuators <= high)


def move(
    params: KinematicParameters,
    previous: np.ndarray | None,
    pose: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    step_m: float,
    mount: str = DEFAULT_MOUNT,
) -> Move:
    """Return the move from `previous` (None: the posture alone) to `pose`, both ends included."""
    pose = np.asarray(pose, dtype=float)
    if previous is None:
        return Move(pose[None], nominal_actuators(params, pose[None]))
    previous = np.asarray(previous, dtype=float)
    path = np.concatenate([previous[None], sphere_path(previous, pose, link_length, step_m)])
    actuators = nominal_actuators(params, path)
    if np.all(inside_stroke(actuators, *stroke_m)):
        return Move(path, actuators)
    centre = np.concatenate([fixed_point(link_length, mount), np.zeros(3)])
    around = np.concatenate(
        [
            previous[None],
            sphere_path(previous, centre, link_length, step_m),
            sphere_path(centre, pose, link_length, step_m),
        ]
    )
    return Move(around, nominal_actuators(params, around), True)


__all__ = ['Move', 'inside_stroke', 'move', 'nominal_actuators']
