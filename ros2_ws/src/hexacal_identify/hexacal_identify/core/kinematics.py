"""Inverse and forward kinematics of the Hexa Slide, batched over postures.

A pose is ``X = [x, y, z, theta, psi, phi]`` (eq. 1): the position of the
platform frame origin P in the base frame and three Euler angles with
``R = R_Y(theta) R_X(psi) R_z(phi)`` (eq. 2): psi about the global X axis,
theta about the global Y axis, phi about the rotated local z axis.

For one chain, with ``d = P + R B - A0`` (the vector A0 -> B), the slider
position solves ``|d - lambda a| = l``; eq. 3 takes the smaller root
``lambda = a.d - sqrt(l^2 - |d|^2 + (a.d)^2)``.  The leg vector is
``e = d - lambda a`` (slider joint A -> spherical joint B) and ``w = a.e``
equals the square root in eq. 3.  Differentiating ``|d - lambda a|^2 = l^2``
gives every derivative used here in closed form:

* d lambda / d d  = e / w
* d lambda / d A0 = -e / w,  d lambda / d B = R^T e / w
* d lambda / d l  = -l / w,  d lambda / d a = -lambda e / w
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import ForwardKinematicsError, InvalidMeasurementError, UnreachablePoseError
from .model import AXY_SLICE, FIELDS_PER_CHAIN, N_CHAINS, HexaParameters

POSE_LABELS = ("x", "y", "z", "theta", "psi", "phi")


def rotation_matrices(angles: np.ndarray) -> np.ndarray:
    """R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2) for angles (N, 3) = [theta, psi, phi]."""
    angles = np.asarray(angles, dtype=float)
    ct, cp, cf = np.cos(angles.T)
    st, sp, sf = np.sin(angles.T)
    rot = np.empty(angles.shape[:-1] + (3, 3))
    rot[..., 0, 0] = ct * cf + st * sp * sf
    rot[..., 0, 1] = -ct * sf + st * sp * cf
    rot[..., 0, 2] = st * cp
    rot[..., 1, 0] = cp * sf
    rot[..., 1, 1] = cp * cf
    rot[..., 1, 2] = -sp
    rot[..., 2, 0] = -st * cf + ct * sp * sf
    rot[..., 2, 1] = st * sf + ct * sp * cf
    rot[..., 2, 2] = ct * cp
    return rot


def euler_rate_axes(angles: np.ndarray) -> np.ndarray:
    """Unit axes (N, 3, 3), columns = rotation axes of d theta, d psi, d phi in the base frame.

    omega = e_Y dtheta + R_Y(theta) e_X dpsi + R_Y(theta) R_X(psi) e_z dphi.
    """
    angles = np.asarray(angles, dtype=float)
    ct, cp = np.cos(angles[:, 0]), np.cos(angles[:, 1])
    st, sp = np.sin(angles[:, 0]), np.sin(angles[:, 1])
    axes = np.zeros((len(angles), 3, 3))
    axes[:, 1, 0] = 1.0
    axes[:, 0, 1] = ct
    axes[:, 2, 1] = -st
    axes[:, 0, 2] = st * cp
    axes[:, 1, 2] = -sp
    axes[:, 2, 2] = ct * cp
    return axes


@dataclass
class LegGeometry:
    """Everything IK computes for N postures x 6 chains, reused by the Jacobians."""

    rotations: np.ndarray  # (N, 3, 3)
    rotated_platform_points: np.ndarray  # R B, (N, 6, 3)
    slider_positions: np.ndarray  # lambda, (N, 6)
    leg_vectors: np.ndarray  # e = B - A, (N, 6, 3)
    rail_leg_dot: np.ndarray  # w = a.e, (N, 6); zero at a singular leg
    discriminant: np.ndarray  # l^2 - |d|^2 + (a.d)^2, (N, 6); negative = unreachable


def leg_geometry(params: HexaParameters, poses: np.ndarray) -> LegGeometry:
    """Eq. 3 for every chain and posture, keeping the intermediate vectors."""
    poses = np.asarray(poses, dtype=float)
    rotations = rotation_matrices(poses[:, 3:6])
    rotated_b = np.einsum("nij,cj->nci", rotations, params.platform_points)
    d = poses[:, None, :3] + rotated_b - params.base_points[None]
    rails = params.rail_directions
    a_dot_d = np.einsum("ncj,cj->nc", d, rails)
    discriminant = params.leg_lengths**2 - np.einsum("ncj,ncj->nc", d, d) + a_dot_d**2
    root = np.sqrt(np.maximum(discriminant, 0.0))
    sliders = a_dot_d - root
    legs = d - sliders[..., None] * rails[None]
    return LegGeometry(rotations, rotated_b, sliders, legs, root, discriminant)


def inverse_kinematics(params: HexaParameters, poses: np.ndarray) -> np.ndarray:
    """Slider positions lambda (N, 6) for poses (N, 6) (eq. 3).

    Raises UnreachablePoseError naming the postures whose legs cannot reach.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    if poses.shape[-1] != 6:
        raise InvalidMeasurementError(f"poses must have 6 columns [x y z theta psi phi], got {poses.shape}")
    if not np.all(np.isfinite(poses)):
        bad = np.flatnonzero(~np.all(np.isfinite(poses), axis=1))
        raise InvalidMeasurementError(f"non-finite pose(s) at index {bad.tolist()}", bad)
    geometry = leg_geometry(params, poses)
    unreachable = np.any(geometry.discriminant < 0.0, axis=1)
    if np.any(unreachable):
        bad = np.flatnonzero(unreachable)
        raise UnreachablePoseError(
            f"{bad.size} pose(s) unreachable (a leg is shorter than its distance to the rail), "
            f"indices {bad[:10].tolist()}{' ...' if bad.size > 10 else ''}",
            bad,
        )
    return geometry.slider_positions


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis: np.cross's products, without its per-call axis handling (FK calls this often)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def pose_jacobian(geometry: LegGeometry, angles: np.ndarray) -> np.ndarray:
    """J_inv = d lambda / d X, (N, 6 chains, 6 pose coordinates).

    Position columns: e / w.  Angle column k: axis_k . (R B x e) / w, since
    d(R B) = axis_k x R B for a rate about axis_k.
    """
    with np.errstate(divide="ignore", invalid="ignore"):  # w = 0 only where a leg cannot reach: flagged by FK
        unit = geometry.leg_vectors / geometry.rail_leg_dot[..., None]
        moment = _cross(geometry.rotated_platform_points, unit)
    axes = euler_rate_axes(angles)
    return np.concatenate([unit, np.einsum("ncj,njk->nck", moment, axes)], axis=2)


def parameter_jacobian_blocks(params: HexaParameters, geometry: LegGeometry) -> np.ndarray:
    """d lambda_c / d u_c for each chain's own 9 parameters, (N, 6, 9).

    lambda_c depends only on chain c's parameters, so the full (N, 6, 54)
    matrix is block diagonal; these are its blocks, in PARAMETER_FIELDS order.
    """
    legs, w = geometry.leg_vectors, geometry.rail_leg_dot
    unit = legs / w[..., None]
    blocks = np.empty(legs.shape[:2] + (FIELDS_PER_CHAIN,))
    blocks[..., 0:3] = -unit
    blocks[..., 3:6] = np.einsum("nji,ncj->nci", geometry.rotations, unit)
    blocks[..., 6] = -params.leg_lengths[None] / w
    # a_z = -sqrt(1 - ax^2 - ay^2) => d a_z / d a_x = -a_x / a_z (and likewise for y).
    rails = params.rail_directions
    dz_dxy = -rails[:, :2] / rails[:, 2:3]
    d_rail = -geometry.slider_positions[..., None] * unit  # d lambda / d a (full vector)
    blocks[..., 7:9] = d_rail[..., :2] + d_rail[..., 2:3] * dz_dxy[None]
    return blocks


@dataclass
class ForwardKinematicsResult:
    """Batched FK outcome: poses, which converged, and why the others did not."""

    poses: np.ndarray  # (N, 6); NaN rows where failed
    converged: np.ndarray  # (N,) bool
    iterations: np.ndarray  # (N,) Newton iterations used
    failures: dict[int, str] = field(default_factory=dict)  # index -> reason

    def raise_if_failed(self) -> None:
        if self.failures:
            first = sorted(self.failures.items())[:5]
            detail = "; ".join(f"#{i}: {why}" for i, why in first)
            raise ForwardKinematicsError(
                f"forward kinematics failed for {len(self.failures)} posture(s): {detail}", sorted(self.failures)
            )


def forward_kinematics(
    params: HexaParameters,
    slider_positions: np.ndarray,
    initial_poses: np.ndarray,
    *,
    tolerance: float = 1e-12,
    max_iterations: int = 30,
    branch_tolerance_m: float = 0.05,
    branch_tolerance_rad: float = 0.35,
    fit_tilt_first: bool = False,
) -> ForwardKinematicsResult:
    """Newton iteration X <- X - J_inv^-1 (IK(X) - lambda) (section 2.2), batched.

    Converged when every |IK(X) - lambda| < tolerance (m).  A step that leaves
    the reachable set or increases the residual is halved (up to 10 times).  The
    branch check of section 3.3 rejects a solution whose position moved more
    than ``branch_tolerance_m`` from the initial guess, or whose phi moved more
    than ``branch_tolerance_rad``: the initial guess is the expected posture.
    With ``fit_tilt_first`` the two unmeasured angles (theta, psi) are first
    fitted with position and phi held at the guess, which brings Newton's start
    close to the solution when only position and phi are known (the device's case).
    """
    targets = np.atleast_2d(np.asarray(slider_positions, dtype=float))
    start = np.atleast_2d(np.asarray(initial_poses, dtype=float))
    poses = _fit_tilt(params, targets, start) if fit_tilt_first else start.copy()
    n = len(targets)
    converged = np.zeros(n, bool)
    iterations = np.zeros(n, int)
    failures: dict[int, str] = {}
    active = np.flatnonzero(np.all(np.isfinite(targets), axis=1) & np.all(np.isfinite(start), axis=1))
    for i in np.setdiff1d(np.arange(n), active):
        failures[int(i)] = "non-finite slider positions or initial pose"
    geometry = leg_geometry(params, poses[active])
    error = _slider_error(geometry, targets[active])
    for iteration in range(max_iterations + 1):
        done = error < tolerance
        converged[active[done]] = True
        active, error = active[~done], error[~done]
        if active.size == 0 or iteration == max_iterations:
            break
        geometry = _subset(geometry, ~done)
        iterations[active] += 1
        jac = pose_jacobian(geometry, poses[active, 3:6])
        residual = geometry.slider_positions - targets[active]
        step, solvable = _solve_batched(jac, residual)
        for i in active[~solvable]:
            failures[int(i)] = "singular pose Jacobian (the platform is at a singularity)"
        active, error, step = active[solvable], error[solvable], step[solvable]
        poses[active], geometry, error = _damped_update(params, poses[active], step, targets[active], error)
    for i in active:
        failures.setdefault(int(i), f"no convergence in {max_iterations} Newton iterations")
    _check_branch(poses, start, converged, failures, branch_tolerance_m, branch_tolerance_rad)
    poses[~converged] = np.nan
    return ForwardKinematicsResult(poses, converged, iterations, failures)


def _fit_tilt(params: HexaParameters, targets: np.ndarray, start: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Gauss-Newton on (theta, psi) alone: least squares over the 6 sliders, 2 unknowns."""
    poses = start.copy()
    finite = np.all(np.isfinite(targets), axis=1) & np.all(np.isfinite(start), axis=1)
    for _ in range(iterations):
        geometry = leg_geometry(params, poses[finite])
        if not np.all(geometry.discriminant >= 0.0):
            break
        jac = pose_jacobian(geometry, poses[finite, 3:6])[:, :, 3:5]
        residual = geometry.slider_positions - targets[finite]
        normal = np.einsum("nci,ncj->nij", jac, jac)
        rhs = np.einsum("nci,nc->ni", jac, residual)
        try:
            step = np.linalg.solve(normal, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        poses[finite, 3:5] -= np.clip(step, -0.3, 0.3)
    return np.where(np.isfinite(poses), poses, start)


def _slider_error(geometry: LegGeometry, targets: np.ndarray) -> np.ndarray:
    error = np.max(np.abs(geometry.slider_positions - targets), axis=1)
    return np.where(np.all(geometry.discriminant >= 0.0, axis=1), error, np.inf)


def _subset(geometry: LegGeometry, mask: np.ndarray) -> LegGeometry:
    return LegGeometry(*(getattr(geometry, f)[mask] for f in LegGeometry.__dataclass_fields__))


def _solve_batched(jac: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve J step = residual per posture; flag postures whose J is singular."""
    try:
        step = np.linalg.solve(jac, residual[..., None])[..., 0]
        solvable = np.all(np.isfinite(step), axis=1)
    except np.linalg.LinAlgError:  # rare: solve each posture on its own to find the singular ones
        step = np.zeros_like(residual)
        solvable = np.zeros(len(jac), bool)
        for i in range(len(jac)):
            try:
                step[i] = np.linalg.solve(jac[i], residual[i])
                solvable[i] = np.all(np.isfinite(step[i]))
            except np.linalg.LinAlgError:
                pass
    return step, solvable


def _damped_update(params, poses, step, targets, error):
    """Take X - step, halving the step where it does not reduce the slider error."""
    scale = np.ones(len(poses))
    trial = poses - step
    geometry = leg_geometry(params, trial)
    trial_error = _slider_error(geometry, targets)
    for _ in range(10):
        worse = ~(trial_error < error) & (error > 0)
        if not np.any(worse):
            break
        scale[worse] *= 0.5
        trial[worse] = poses[worse] - scale[worse, None] * step[worse]
        sub = leg_geometry(params, trial[worse])
        geometry = _replace_rows(geometry, worse, sub)
        trial_error[worse] = _slider_error(sub, targets[worse])
    return trial, geometry, trial_error


def _replace_rows(geometry: LegGeometry, mask: np.ndarray, rows: LegGeometry) -> LegGeometry:
    for name in LegGeometry.__dataclass_fields__:
        getattr(geometry, name)[mask] = getattr(rows, name)
    return geometry


def _check_branch(poses, start, converged, failures, tol_m, tol_rad) -> None:
    jump = np.linalg.norm(poses[:, :3] - start[:, :3], axis=1)
    phi_jump = np.abs(_wrap(poses[:, 5] - start[:, 5]))
    wrong = converged & ((jump > tol_m) | (phi_jump > tol_rad))
    for i in np.flatnonzero(wrong):
        failures[int(i)] = (
            f"converged to another branch: {jump[i] * 1e3:.1f} mm / {np.degrees(phi_jump[i]):.1f} deg "
            "from the expected posture"
        )
    converged &= ~wrong


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


@dataclass
class PoseSensitivity:
    """Derivatives of FK poses: w.r.t. the 54 parameters and w.r.t. the 6 slider readings."""

    wrt_parameters: np.ndarray  # dX/du, (N, 6, 54)
    wrt_sliders: np.ndarray  # dX/d lambda = J_inv^-1, (N, 6, 6)


def pose_sensitivities(params: HexaParameters, poses: np.ndarray) -> PoseSensitivity:
    """dX/du and dX/d lambda at FK solutions, by implicit differentiation of IK(X, u) = lambda.

    J_inv dX = d lambda - (d lambda/d u) du, so dX/d lambda = J_inv^-1 and
    dX/du = -J_inv^-1 d lambda/d u.  d lambda/d u is block diagonal, so column
    block c of dX/du is the outer product of column c of J_inv^-1 with chain c's
    9-vector of derivatives.
    """
    geometry = leg_geometry(params, poses)
    jac_inverse = np.linalg.inv(pose_jacobian(geometry, poses[:, 3:6]))
    blocks = parameter_jacobian_blocks(params, geometry)
    wrt_parameters = -jac_inverse[:, :, :, None] * blocks[:, None, :, :]
    return PoseSensitivity(wrt_parameters.reshape(len(poses), 6, N_CHAINS * FIELDS_PER_CHAIN), jac_inverse)


def pose_parameter_sensitivity(params: HexaParameters, poses: np.ndarray) -> tuple[np.ndarray, LegGeometry]:
    """dX/du (N, 6, 54) at FK solutions (see ``pose_sensitivities``) and the leg geometry there."""
    return pose_sensitivities(params, poses).wrt_parameters, leg_geometry(params, poses)


def rail_xy_slice(chain: int) -> slice:
    """Vector slice of chain's (ax, ay) components (chain counted from 0)."""
    start = chain * FIELDS_PER_CHAIN
    return slice(start + AXY_SLICE.start, start + AXY_SLICE.stop)
