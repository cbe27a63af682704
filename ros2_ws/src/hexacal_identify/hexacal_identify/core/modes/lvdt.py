"""
The LVDT link of the ``lvdt`` measuring mode (the paper's section 4): its predicted extension.

A spring-loaded telescopic link whose length L_m an LVDT measures lets all six actuators be
commanded: the platform goes where the six put it (forward kinematics) and the link follows,
extended by ``e = |P| - L`` from its nominal length L (O at the base origin,
core/machine/device.py). The stroke is limited (+-5 mm by default, ``DEFAULT_LVDT_STROKE_M`` of the
contract), so whoever commands the six must keep the extension of every target, and of every point
on the way, inside it.

`lvdt_extensions` predicts e for commanded actuators on a given machine (the true one in a
simulation, the current model for the executor); `extension_gains` says how much extension an
actuator error makes at a pose: ``de / d lambda = n^T J^-1`` with ``n = P / |P|`` (J the pose
Jacobian), so an error of at most ``delta`` on every actuator (a model error seen through IK)
extends the link by at most ``||n^T J^-1||_1 delta``.  At the nominal model's own postures on
the sphere the nominal prediction is zero; the gain is what a planner can check.
"""

from __future__ import annotations

import numpy as np

from ..architectures import KinematicParameters
from ..machine.kinematics import forward_kinematics


def lvdt_extensions(
    params: KinematicParameters,
    actuators: np.ndarray,
    start: np.ndarray,
    link_length: float,
) -> np.ndarray:
    """
    Return the link's extension |P| - L (N,), m, with the six actuators at `actuators` (N, 6).

    Forward kinematics of `params` from `start` (N, 6), the expected poses (a
    ForwardKinematicsError names the postures where it fails).
    """
    solved = forward_kinematics(params, np.atleast_2d(actuators), np.atleast_2d(start))
    solved.raise_if_failed()
    return np.linalg.norm(solved.poses[:, :3], axis=1) - link_length


def extension_sensitivity(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """Return de / d lambda (N, 6) at `poses`: n^T J^-1, n = P / |P| (module doc)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    arch = params.architecture
    jacobian = arch.legs(arch.chains(params), poses).pose_jacobian()
    normal = np.zeros((len(poses), 6))
    normal[:, :3] = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    # n^T J^-1 = (J^-T n)^T
    return np.linalg.solve(np.transpose(jacobian, (0, 2, 1)), normal[..., None])[..., 0]


def extension_gains(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """Return the largest extension per unit actuator error at each pose (N,), m/m (L1 norm)."""
    return np.sum(np.abs(extension_sensitivity(params, poses)), axis=1)


__all__ = ['extension_gains', 'extension_sensitivity', 'lvdt_extensions']
