"""
The measuring link's load with each actuator released, from the weights (ROS-free).

With one actuator released the five commanded chains and the link hold the platform with
nothing to spare: the link is a load-bearing member, and which chain is released decides how
much it carries (core/fit/statics.py: ``static_loads`` in passive_actuator).  On the Hexa Slide
and the Gough-Stewart of the shipped physical descriptions, over 200 sphere postures, the
least-loaded release leaves the link a median 92 / 73 N, the median release 391 / 446 N, and
the best-conditioned one may load it past the 500 N a link of the documented kind bears.
`LinkLoad` is what a planner needs to keep the link under a limit at its postures: the masses
(from a physical description) and the limit; `released_link_forces` the predicted |tension|
of each release at each pose; `move_link_forces` the largest along each move of a plan, where
the link bears the next posture's release from the moment the executor swaps the releases, at
rest before the move (on the demo's 20-posture Hexa Slide plan, 1.2 kN at a swap whose
postures were each under 500 N).  Static loads: the executor's moves start and stop at rest
(walk/platform_paths.eased_command), which on the MuJoCo machine keeps the link near them.
"""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_msgs_py.measuring_modes import LINK_FORCE_LIMIT_N, MeasuringMode
import numpy as np

from .release_moves import move
from ..architectures import KinematicParameters
from ..fit.statics import MassModel, static_loads
from ..machine.device import DEFAULT_MOUNT
from ..walk.settings import ExecutionSettings

MOVE_STEP_M = ExecutionSettings().path_step_m  # a move's statics sampled as the executor paths it


@dataclass(frozen=True)
class LinkLoad:
    """The weights that load the link (masses, gravity) and the largest force it may carry (N)."""

    masses: MassModel
    max_force_n: float = LINK_FORCE_LIMIT_N  # a link of the documented kind

    def __post_init__(self) -> None:
        """Refuse a limit that is not a positive force."""
        if not (np.isfinite(self.max_force_n) and self.max_force_n > 0):
            raise ValueError(f'the link force limit must be > 0 N, got {self.max_force_n!r}')


def released_link_forces(
    params: KinematicParameters, poses: np.ndarray, masses: MassModel
) -> np.ndarray:
    """Return the link's predicted |tension| (M, 6), N, at `poses` (M, 6) with each chain free."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    count = len(poses)
    loads = static_loads(
        params,
        np.tile(poses, (6, 1)),
        masses,
        MeasuringMode.PASSIVE_ACTUATOR,
        np.repeat(np.arange(6), count),
    )
    return np.abs(loads.link).reshape(6, count).T


def move_link_forces(
    params: KinematicParameters,
    poses: np.ndarray,
    released: np.ndarray,
    masses: MassModel,
    link_length: float,
    stroke_m: tuple[float, float],
    mount: str = DEFAULT_MOUNT,
    step_m: float = MOVE_STEP_M,
) -> np.ndarray:
    """
    Return the link's largest predicted |tension| (K,), N, on the way to each posture.

    `poses` (K, 6) in walking order, `released` (K,) their chains (0-based): from the previous
    posture (where the executor swaps to this posture's release) along the move the executor
    commands (release_moves.move) to the posture; the first posture alone.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    paths = [
        move(params, poses[k - 1] if k else None, poses[k], link_length, stroke_m, step_m,
             mount).poses
        for k in range(len(poses))
    ]
    owner = np.repeat(np.arange(len(poses)), [len(path) for path in paths])
    loads = static_loads(
        params, np.concatenate(paths), masses, MeasuringMode.PASSIVE_ACTUATOR,
        np.asarray(released, dtype=int)[owner],
    )
    largest = np.zeros(len(poses))
    np.fmax.at(largest, owner, np.abs(loads.link))  # a pose out of reach (NaN) bears nothing
    return largest


__all__ = ['LinkLoad', 'move_link_forces', 'released_link_forces']
