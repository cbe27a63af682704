"""
Measurement postures over the paper's workspace (section 4).

Sphere postures: x, y uniform within +-400 mm, z on the L-sphere below the base
joint (z = -sqrt(L^2 - x^2 - y^2)), the three Euler angles uniform within
+-35 deg.  Fixed-position postures: the inclinometer reads zero, so the
platform sits at [0, 0, -L] and only the orientation varies.
Infeasible postures (a leg cannot reach, a slider outside its stroke) and
ill-conditioned ones (pose Jacobian condition number too large) are rejected
and redrawn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .device import DEFAULT_LINK_LENGTH_M, DEFAULT_MOUNT, fixed_point, sphere_z
from ..architectures import KinematicParameters


@dataclass(frozen=True)
class Workspace:
    """Where postures are drawn, and what makes one acceptable (SI units)."""

    link_length: float = DEFAULT_LINK_LENGTH_M
    xy_range_m: float = 0.400
    rotation_range_rad: float = np.radians(35.0)
    actuator_stroke_m: tuple[float, float] = (0.0, 0.9)
    max_condition: float = (
        80.0  # of the pose Jacobian with angles scaled by link_length; rejects ~4%
    )
    # Hexa Slide: w / l, legs far from perpendicular to their rail; Gough-Stewart: the least cosine
    # of a passive joint's angle (architectures/*.acceptable_poses).
    min_joint_cosine: float = 0.2
    mount: str = (
        DEFAULT_MOUNT  # the device's: the link sphere lies below (hanging) or above (standing) O
    )


def _sphere_candidates(rng: np.random.Generator, n: int, workspace: Workspace) -> np.ndarray:
    xy = rng.uniform(-workspace.xy_range_m, workspace.xy_range_m, (n, 2))
    z = sphere_z(xy, workspace.link_length, workspace.mount)
    angles = rng.uniform(-workspace.rotation_range_rad, workspace.rotation_range_rad, (n, 3))
    return np.column_stack([xy, z, angles])


def _fixed_candidates(rng: np.random.Generator, n: int, workspace: Workspace) -> np.ndarray:
    position = np.tile(fixed_point(workspace.link_length, workspace.mount), (n, 1))
    angles = rng.uniform(-workspace.rotation_range_rad, workspace.rotation_range_rad, (n, 3))
    return np.column_stack([position, angles])


def acceptable_poses(
    params: KinematicParameters, poses: np.ndarray, workspace: Workspace = Workspace()
) -> np.ndarray:
    """
    Return the mask of acceptable poses.

    Mask of poses that are reachable, inside the stroke and well conditioned (the architecture
    decides how).
    """
    return params.architecture.acceptable_poses(params, np.asarray(poses, dtype=float), workspace)


def sample_poses(
    params: KinematicParameters,
    n: int,
    rng: np.random.Generator,
    kind: str = 'sphere',
    workspace: Workspace = Workspace(),
) -> np.ndarray:
    """
    Draw n acceptable poses of the given kind.

    n acceptable poses of the given kind ('sphere' or 'fixed'), (n, 6).
    """
    draw = {'sphere': _sphere_candidates, 'fixed': _fixed_candidates}[kind]
    accepted: list[np.ndarray] = []
    count = 0
    for _ in range(1000):
        if count >= n:
            break
        candidates = draw(rng, max(2 * (n - count), 16), workspace)
        good = candidates[acceptable_poses(params, candidates, workspace)]
        accepted.append(good)
        count += len(good)
    else:
        raise RuntimeError(f'could not find {n} acceptable {kind} postures in the workspace')
    return np.concatenate(accepted)[:n]
