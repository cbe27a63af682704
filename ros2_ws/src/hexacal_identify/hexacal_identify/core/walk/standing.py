"""
Where the machine stands, and a move started from where its drive stands (ROS-free).

* `estimate_pose`: the platform's pose from the measured actuators (nominal forward kinematics
  moved onto the link sphere); a move along the sphere starts there.
* `blend_from_setpoints`: a move starts where the drive's setpoints are (the last command's
  target, a chain locked where the link put it, an earlier model's targets); their offset
  from the model's standing at the path's start fades to zero over the move
  (`platform_paths.blend_command`), the target stays the model's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .platform_paths import blend_command, Command, on_sphere
from ..architectures import KinematicParameters
from ..errors import CalibrationError


def estimate_pose(
    nominal: KinematicParameters,
    actuators: np.ndarray,
    guesses: Sequence[np.ndarray],
    link_length: float,
    mount: str,
) -> tuple[np.ndarray | None, str]:
    """
    Return where the platform stands, on the link sphere, and '' (else None and why not).

    Nominal forward kinematics of the measured `actuators` from each of `guesses` in turn;
    the last guess is the device's centre pose.
    """
    from ..machine.kinematics import forward_kinematics
    from ..machine.live import solve_pose

    found = forward_kinematics(
        nominal, np.tile(actuators, (len(guesses), 1)), np.array(guesses)
    )
    for converged_pose, converged in zip(found.poses, found.converged):
        if converged:
            return on_sphere(converged_pose, link_length, mount), ''
    # Newton from each guess refuses a pose far from it (another branch, or phi beyond its
    # branch tolerance: a fresh walk after another plan's tilted last posture); continue
    # from the centre's actuators to the measured ones instead (core/machine/live.py).
    try:
        pose = solve_pose(nominal, actuators.tolist(), guesses[-1].tolist())
    except (CalibrationError, ValueError) as error:
        return None, (
            'cannot tell where the platform stands (nominal forward kinematics of '
            f'the measured actuators failed: {error}): one-point command'
        )
    return on_sphere(pose, link_length, mount), ''


def blend_from_setpoints(
    nominal: KinematicParameters,
    command: Command,
    start: np.ndarray,
    setpoints: np.ndarray,
    released: int | None,
    speed_m_s: float,
    stroke: tuple[float, float],
) -> Command:
    """
    Return the move `command` (from pose `start`) starting at the drive's `setpoints`.

    The drive interpolates from its setpoints to the first point: after a swap (the locked
    chain's setpoint is where the link put it) or a new model (the setpoints are the old
    model's targets) they are not the model's inverse kinematics of the path's start.
    """
    arch = nominal.architecture
    legs = arch.legs(arch.chains(nominal), start[None])
    if not bool(legs.reachable()[0]):
        return command  # no model standing at the start to blend from
    offset = setpoints - legs.actuators[0]
    if released is not None:
        offset[released] = 0.0  # not commanded: the drive has no setpoint for it
    return blend_command(command, setpoints, offset, speed_m_s, stroke)


__all__ = ['blend_from_setpoints', 'estimate_pose']
