"""
The compliant measuring mode: where equally stiff servos put the platform on the link sphere.

In the ``compliant`` mode all six actuators are commanded against the rigid
measuring link: setpoints the true machine cannot reach on the link sphere strain it until the
actuators, equally stiff position loops, settle where the elastic energy is least.
`device_constrained_pose` solves that pose.  It lives in the core so that the simulated driver
and the studies (studies/measuring_mode_accuracy.py) share one model; the driver re-exports it.
"""

from __future__ import annotations

import math

import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT, fixed_point, inclinometer_angles, STANDING
from ..machine.kinematics import forward_kinematics, wrap_angle

_CONSTRAINT_ITERATIONS = 30
_CONSTRAINT_STEP_M = 1e-11  # Gauss-Newton stops when its step is below this (rad)
STRAIN_RETRY_M = (
    1e-3  # a strain above this is checked from a second start (device_constrained_pose)
)


class ConstraintError(RuntimeError):
    """No platform pose on the link sphere near the previous one fits the actuator setpoints."""


def device_constrained_pose(
    params: KinematicParameters,
    setpoints: np.ndarray,
    start: np.ndarray,
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return where the machine stands with its actuators at `setpoints` and the link attached.

    Where the machine stands with its actuators commanded to `setpoints` and the measuring link
    attached.

    The link (U joints at both ends, fixed length L) holds the platform on the sphere of radius
    L about O: 5 DOF for 6 position-controlled actuators. Setpoints that the true machine cannot
    reach on that sphere (those computed from an imperfect nominal model, millimetres off) strain
    the machine until the actuators, equally stiff servos, settle where the elastic energy is
    least: the pose on the sphere whose true inverse kinematics is nearest to the setpoints in the
    least-squares sense. The actuator encoders read that pose's true actuator positions, which
    differ from the setpoints by the strain; every reading is therefore exactly consistent with the
    true machine, as on a real one. Setpoints the true machine reaches on the sphere (the plan-
    walking mode's) give that pose exactly.

    Gauss-Newton over (alpha, beta, theta, psi, phi) from `start` (the previous pose: the solution
    stays on the branch the machine is on), the position on the sphere by eq. 4
    (core/machine/device.py). A strain above STRAIN_RETRY_M from there is checked against a start
    from the true forward kinematics of the setpoints (a long move can leave the warm start in a
    poor local minimum). Returns (pose (6,), true actuator readings (6,)); ConstraintError if
    `start` is out of reach.
    """
    setpoints = np.asarray(setpoints, dtype=float)
    start = np.asarray(start, dtype=float)
    arch = params.architecture
    chains = arch.chains(params)
    sign = -1.0 if mount == STANDING else 1.0  # standing: p = -p_hanging (core/machine/device.py)

    def evaluate(s: np.ndarray):
        ca, sa, cb, sb = math.cos(s[0]), math.sin(s[0]), math.cos(s[1]), math.sin(s[1])
        position = sign * link_length * np.array([ca * sb, -sa, -ca * cb])
        pose = np.concatenate([position, s[2:]])
        legs = arch.legs(chains, pose[None])
        if not bool(legs.reachable()[0]):
            return pose, legs, None, math.inf
        tangent = np.zeros((6, 5))
        tangent[:3, 0] = sign * link_length * np.array([-sa * sb, -ca, sa * cb])
        tangent[:3, 1] = sign * link_length * np.array([ca * cb, 0.0, ca * sb])
        tangent[3:, 2:] = np.eye(3)
        residual = legs.actuators[0] - setpoints
        return pose, legs, tangent, float(residual @ residual)

    def solve(near: np.ndarray):
        alpha, beta = inclinometer_angles(near[None, :3], mount)
        state = np.array([alpha[0], beta[0], *near[3:]])
        pose, legs, tangent, cost = evaluate(state)
        if not math.isfinite(cost):
            return pose, legs, cost
        for _ in range(_CONSTRAINT_ITERATIONS):
            jacobian = legs.pose_jacobian()[0] @ tangent
            step = np.linalg.lstsq(jacobian, legs.actuators[0] - setpoints, rcond=None)[0]
            if float(np.max(np.abs(step))) < _CONSTRAINT_STEP_M:
                break
            scale = 1.0
            for _halving in range(8):
                trial = evaluate(state - scale * step)
                if trial[3] <= cost:
                    break
                scale *= 0.5
            else:
                break  # no step reduces the strain: this is its minimum, to rounding
            state = state - scale * step
            pose, legs, tangent, cost = trial
        return pose, legs, cost

    pose, legs, cost = solve(start)
    if not math.isfinite(cost):
        raise ConstraintError('the previous pose is out of reach of the true machine')
    if cost > STRAIN_RETRY_M**2:
        home = np.concatenate([fixed_point(link_length, mount), np.zeros(3)])
        guesses = np.array([start, home])
        guesses[:, 3:] = wrap_angle(guesses[:, 3:])
        free = forward_kinematics(
            params,
            np.tile(setpoints, (2, 1)),
            guesses,
            branch_tolerance_m=math.inf,
            branch_tolerance_rad=math.inf,
        )
        for found in free.poses[free.converged]:
            other = solve(found)
            if other[2] < cost:
                pose, legs, cost = other
    pose = np.concatenate([pose[:3], wrap_angle(np.asarray(pose[3:], dtype=float))])
    return pose, legs.actuators[0].copy()


def link_tension(
    params: KinematicParameters,
    poses: np.ndarray,
    actuators: np.ndarray,
    setpoints: np.ndarray,
    stiffness_n_per_m: float,
) -> np.ndarray:
    """
    Return the measuring link's tension (N,), N, where compliant servos stand strained.

    Each servo pushes its actuator back towards its setpoint with the thrust
    ``stiffness (setpoint - position)`` along +lambda; the platform, at rest, is held by those
    thrusts and the link alone (weights aside: core/fit/statics.py adds them), so by virtual
    work J^T tau = T j_L with J = d lambda / d X and j_L = [P / |P|, 0, 0, 0]: the link's
    tension T is the force part of J^T tau along P (compression negative).  Where the standing
    is the least-energy one on the sphere (device_constrained_pose) J^T tau has no other part.
    """
    thrust = stiffness_n_per_m * (
        np.atleast_2d(np.asarray(setpoints, dtype=float))
        - np.atleast_2d(np.asarray(actuators, dtype=float))
    )
    return thrust_link_tension(params, poses, thrust)


def thrust_link_tension(
    params: KinematicParameters, poses: np.ndarray, thrust: np.ndarray
) -> np.ndarray:
    """Return the link's tension (N,), N, that holds the platform against the thrusts (N, 6)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    thrust = np.atleast_2d(np.asarray(thrust, dtype=float))
    arch = params.architecture
    jacobian = np.asarray(arch.legs(arch.chains(params), poses).pose_jacobian())
    generalised = np.einsum('ncx,nc->nx', jacobian, thrust)
    direction = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    return np.einsum('nx,nx->n', generalised[:, :3], direction)


__all__ = [
    'ConstraintError',
    'device_constrained_pose',
    'link_tension',
    'STRAIN_RETRY_M',
    'thrust_link_tension',
]
