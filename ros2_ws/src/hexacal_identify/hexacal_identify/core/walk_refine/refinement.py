"""
Targets refined from a first calibration, ROS-free.

A plan's targets are the nominal model's inverse kinematics of its poses; on the true machine
they are millimetres off, and whatever resolves the over-constraint (a released actuator, an
LVDT link, compliant servos) absorbs those millimetres.  Once the postures measured so far allow
a calibration of full rank, a calibration of them is better than the nominal model by orders of
magnitude, and the remaining targets computed with it land micrometres from where the true
machine can go.  `walk_refined` walks a plan that way, in batches between checkpoints:

* measure the postures up to the next checkpoint with the targets of the current model;
* at the checkpoint calibrate everything measured so far; a calibration that is not of full rank
  (``calibrate`` returns None) leaves the current model in place until the next checkpoint;
* the remaining targets come from the newest model.

`refinement_checkpoints` spaces the checkpoints geometrically (again later if it helps: each
re-calibration uses at least ``growth`` times the postures of the previous one, so a plan of K
postures is calibrated O(log K) times).  Everything the walk needs is a callable, so the study
(studies/measuring_mode_accuracy.py) and an executor share the logic: ``targets(model,
indices)`` the setpoints of postures ``indices`` under ``model``, ``measure(indices, setpoints)``
what the machine read there, ``calibrate(measured)`` a model or None.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Callable, Generic, TypeVar

import numpy as np

Model = TypeVar('Model')
Measured = TypeVar('Measured')

DEFAULT_GROWTH = 2.0  # a re-calibration uses at least this many times the previous postures


def full_rank_postures(n_parameters: int) -> int:
    """Return the postures of a first calibration: equations for every parameter, twice over."""
    return math.ceil(2 * int(n_parameters) / 5)  # 5 equations per posture


def refinement_checkpoints(
    total: int, first: int | None, growth: float = DEFAULT_GROWTH
) -> tuple[int, ...]:
    """
    Return the posture counts after which the walk calibrates (ascending, each < `total`).

    `first` the count at which a full-rank calibration is first tried (None: never, the plan is
    walked on its nominal targets), then every `growth` times more, while postures remain.
    """
    if first is None or first >= total:
        return ()
    if first < 1 or not growth > 1.0:
        raise ValueError(f'first must be >= 1 and growth > 1, got {first} and {growth}')
    counts = [first]
    while True:
        following = max(counts[-1] + 1, math.ceil(counts[-1] * growth))
        if following >= total:
            return tuple(counts)
        counts.append(following)


@dataclass
class RefinedWalk(Generic[Model, Measured]):
    """
    The outcome of `walk_refined`.

    ``stages`` (K,) which model each posture's targets came from (0: the starting model, s: the
    s-th accepted calibration); ``models`` the starting model then each accepted calibration;
    ``calibrated_at`` (S,) the posture count each accepted calibration used; ``batches`` what
    ``measure`` returned, in walking order, with ``batch_indices`` their postures.
    """

    stages: np.ndarray
    models: list[Model]
    calibrated_at: list[int]
    batches: list[Measured]
    batch_indices: list[np.ndarray]

    @property
    def refined(self) -> np.ndarray:
        """Return the mask of postures (K,) whose targets came from a calibration."""
        return self.stages > 0


def walk_refined(
    count: int,
    start_model: Model,
    targets: Callable[[Model, np.ndarray], np.ndarray],
    measure: Callable[[np.ndarray, np.ndarray], Measured],
    calibrate: Callable[[list[Measured]], Model | None],
    checkpoints: tuple[int, ...] = (),
) -> RefinedWalk[Model, Measured]:
    """Walk `count` postures in order, re-targeting after each accepted calibration (module)."""
    bounds = [c for c in checkpoints if 0 < c < count] + [count]
    stages = np.zeros(count, int)
    models, calibrated_at = [start_model], []
    batches: list[Measured] = []
    batch_indices: list[np.ndarray] = []
    done = 0
    for bound in bounds:
        indices = np.arange(done, bound)
        stages[indices] = len(models) - 1
        batches.append(measure(indices, targets(models[-1], indices)))
        batch_indices.append(indices)
        done = bound
        if bound < count:
            model = calibrate(batches)
            if model is not None:
                models.append(model)
                calibrated_at.append(bound)
    return RefinedWalk(stages, models, calibrated_at, batches, batch_indices)


__all__ = [
    'DEFAULT_GROWTH',
    'RefinedWalk',
    'full_rank_postures',
    'refinement_checkpoints',
    'walk_refined',
]
