"""
The stroke margin a planned posture keeps for the model change between planning and walking.

A plan is made on the nominal model, but its targets are walked on a better model once there is
one: the executor refines the remaining calibration targets from intermediate calibrations, and
the verification plan is walked on the calibration's targets.  Those targets differ from the
nominal ones by what the nominal's parameter errors move them: on a Hexa Slide a posture whose
nominal slider target was 0.8 mm inside the stroke needed -5.5 mm on the calibrated machine
(nominal set 2 of seed 1), and the executor refused the plan.  So a candidate posture keeps each
target at least ``MARGIN_SIGMAS`` standard deviations of that change inside the stroke: with
independent normal errors of RMS ``error_m`` on the chain's parameters (the architecture's
Table 2 set 2 RMS by default, as the release rehearsal's machines), the first-order change of
target c has the standard deviation ``error_m * |d lambda_c / d u_c|``.
"""

from __future__ import annotations

import numpy as np

from ..architectures import KinematicParameters

MARGIN_SIGMAS = 4.0  # standard deviations of the model change kept inside the stroke


def model_change_margins(
    nominal: KinematicParameters, poses: np.ndarray, error_m: float
) -> np.ndarray:
    """
    Return each target's margin (N, 6), m: MARGIN_SIGMAS x its standard deviation (module doc).

    Inf where the nominal cannot reach the pose.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    arch = nominal.architecture
    chains = arch.chains(nominal)
    legs = arch.legs(chains, poses)
    with np.errstate(invalid='ignore', over='ignore'):
        blocks = legs.parameter_blocks(chains)
        spread = error_m * np.sqrt(np.sum(blocks * blocks, axis=2))
    margins = MARGIN_SIGMAS * spread
    margins[~legs.reachable()] = np.inf
    return np.where(np.isfinite(margins), margins, np.inf)


def keep_model_margin(
    nominal: KinematicParameters,
    poses: np.ndarray,
    stroke: tuple[float, float],
    error_m: float,
) -> np.ndarray:
    """
    Return the mask of poses (N,) whose nominal targets keep their model-change margins.

    Every target lies within [low + margin, high - margin] (``model_change_margins``); with
    ``error_m`` 0 that is the stroke itself.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    if error_m < 0 or not np.isfinite(error_m):
        raise ValueError(f'the model error must be a finite length >= 0 m, got {error_m!r}')
    arch = nominal.architecture
    targets = arch.legs(arch.chains(nominal), poses).actuators
    margins = model_change_margins(nominal, poses, error_m)
    low, high = stroke
    with np.errstate(invalid='ignore'):
        inside = (targets - margins >= low) & (targets + margins <= high)
    return np.all(inside, axis=1)


__all__ = ['MARGIN_SIGMAS', 'keep_model_margin', 'model_change_margins']
