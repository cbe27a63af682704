"""
The platform-position error a parameter covariance predicts, at poses and over the workspace.

Linearised: the position covariance at a pose is J_p C J_p^T, J_p = dP/du there, C the
parameter covariance.  The calibration report maps its trace over the workspace; the Monte
Carlo check (``uncertainty``) compares it with repeated calibrations.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..architectures import architecture, KinematicParameters
from ..machine.device import DEFAULT_MOUNT, fixed_point
from ..machine.kinematics import pose_sensitivities
from ..machine.postures import acceptable_poses

MAP_GRID = 41  # cells per axis of the predicted pose-error map


def position_covariances(
    params: KinematicParameters,
    covariance: np.ndarray,
    poses: np.ndarray,
    wrt_parameters: np.ndarray | None = None,
) -> np.ndarray:
    """
    Return the (N, 3, 3) platform-position covariances J_p C J_p^T at ``poses`` (m^2, linearised).

    J_p = dP/du at each pose, C the parameter covariance (its kinematic block: device defects
    after the n kinematic parameters are ignored). ``wrt_parameters``: dX/du (N, 6, n) at
    ``poses`` when the caller has it already.
    """
    n = params.layout.n_parameters
    covariance = np.asarray(covariance)[:n, :n]
    if wrt_parameters is None:
        wrt_parameters = pose_sensitivities(params, poses).wrt_parameters
    position = wrt_parameters[:, :3]
    return np.einsum('nik,kl,njl->nij', position, covariance, position)


def predicted_position_error_map(
    parameters: np.ndarray,
    covariance: np.ndarray,
    link_length: float,
    grid: int = MAP_GRID,
    xy_range_m: float | None = None,
    model: str | None = None,
    mount: str = DEFAULT_MOUNT,
):
    """
    (x, y, std) of the linearised position error, sqrt(trace(J_p C J_p^T)), on an x, y grid (m).

    J_p = dP/du at (x, y, -sqrt(L^2 - x^2 - y^2), 0, 0, 0) (+sqrt standing); cells the machine
    cannot reach (its architecture's default workspace, on this link) are NaN.  Parameters without
    a variance count as exact.  ``model`` None = the Hexa Slide; ``xy_range_m`` None = the
    workspace's.
    """
    arch = architecture(model)
    n = arch.layout.n_parameters
    params = arch.parameters(np.asarray(parameters, dtype=float)[:n])
    workspace = replace(arch.default_workspace(), link_length=link_length)
    if xy_range_m is None:
        xy_range_m = workspace.xy_range_m
    axis = np.linspace(-xy_range_m, xy_range_m, grid)
    x, y = np.meshgrid(axis, axis)
    radius2 = link_length**2 - x**2 - y**2
    side = np.sign(
        fixed_point(link_length, mount)[2]
    )  # -1 hanging, +1 standing: the platform's side of O
    poses = np.column_stack(
        [
            x.ravel(),
            y.ravel(),
            side * np.sqrt(np.maximum(radius2, 0.0)).ravel(),
            np.zeros((x.size, 3)),
        ]
    )
    ok = (radius2.ravel() > 0) & acceptable_poses(params, poses, workspace)
    std = np.full(x.size, np.nan)
    if np.any(ok):
        cov = np.nan_to_num(np.asarray(covariance, dtype=float)[:n, :n], nan=0.0, posinf=0.0)
        variance = np.trace(position_covariances(params, cov, poses[ok]), axis1=1, axis2=2)
        std[ok] = np.sqrt(np.maximum(variance, 0.0))
    return x, y, std.reshape(x.shape)


__all__ = ['MAP_GRID', 'position_covariances', 'predicted_position_error_map']
