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
    return _rotation_from_trig(np.cos(angles.T), np.sin(angles.T))


def _rotation_from_trig(cosines: np.ndarray, sines: np.ndarray) -> np.ndarray:
    """rotation_matrices from cos and sin of [theta, psi, phi] (each (3, ...))."""
    ct, cp, cf = cosines
    st, sp, sf = sines
    rot = np.empty(cosines.shape[1:] + (3, 3))
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


class _Chains:
    """One parameter set's per-chain constants, coordinate-major ((3, 6) arrays: row = x, y, z)."""

    __slots__ = ("base", "platform", "rails", "lengths", "lengths_squared", "rail_z_slope")

    def __init__(self, params: HexaParameters):
        per_chain = params.per_chain
        self.base = np.ascontiguousarray(per_chain[:, 0:3].T)
        self.platform = np.ascontiguousarray(per_chain[:, 3:6].T)
        self.rails = np.ascontiguousarray(params.rail_directions.T)
        self.lengths = per_chain[:, 6].copy()
        self.lengths_squared = self.lengths**2
        # a_z = -sqrt(1 - ax^2 - ay^2) => d a_z / d a_x = -a_x / a_z (and likewise for y): (2, 6).
        self.rail_z_slope = -self.rails[:2] / self.rails[2]


class _Legs:
    """Eq. 3 for N postures x 6 chains, coordinate-major: vectors are (3, N, 6), one (N, 6) array per axis.

    The arithmetic is written out per coordinate (no small-dimension einsums): FK
    evaluates this several times per identification iteration.
    """

    __slots__ = ("tilt_trig", "rotations", "rotated", "sliders", "legs", "rail_dot", "discriminant")

    def __init__(self, chains: _Chains, poses: np.ndarray):
        angles = poses[:, 3:6].T
        cosines, sines = np.cos(angles), np.sin(angles)
        self.tilt_trig = np.stack([cosines[0], sines[0], cosines[1], sines[1]])  # ct, st, cp, sp: (4, N)
        self.rotations = _rotation_from_trig(cosines, sines)  # (N, 3, 3)
        rotated = np.matmul(self.rotations, chains.platform).transpose(1, 0, 2)  # R B, (3, N, 6)
        d = rotated + (poses[:, :3].T[:, :, None] - chains.base[:, None, :])  # A0 -> B
        rails = chains.rails
        a_dot_d = rails[0] * d[0] + rails[1] * d[1] + rails[2] * d[2]
        discriminant = chains.lengths_squared - (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + a_dot_d * a_dot_d
        root = np.sqrt(np.maximum(discriminant, 0.0))
        sliders = a_dot_d - root
        self.rotated = rotated
        self.sliders = sliders
        self.legs = d - sliders * rails[:, None, :]
        self.rail_dot = root
        self.discriminant = discriminant

    def subset(self, mask: np.ndarray) -> "_Legs":
        out = object.__new__(_Legs)
        out.tilt_trig, out.rotations = self.tilt_trig[:, mask], self.rotations[mask]
        out.rotated, out.legs = self.rotated[:, mask], self.legs[:, mask]
        out.sliders, out.rail_dot, out.discriminant = self.sliders[mask], self.rail_dot[mask], self.discriminant[mask]
        return out

    def replace_rows(self, mask: np.ndarray, rows: "_Legs") -> None:
        for name in ("rotations", "sliders", "rail_dot", "discriminant"):
            getattr(self, name)[mask] = getattr(rows, name)
        self.tilt_trig[:, mask] = rows.tilt_trig
        self.rotated[:, mask] = rows.rotated
        self.legs[:, mask] = rows.legs

    def reachable(self) -> np.ndarray:
        return np.all(self.discriminant >= 0.0, axis=1)

    def unit_legs(self) -> np.ndarray:
        """e / w, (3, N, 6) (inf/NaN at a singular leg, which FK flags)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.legs / self.rail_dot

    def pose_jacobian(self, unit: np.ndarray | None = None) -> np.ndarray:
        """J_inv = d lambda / d X, (N, 6 chains, 6 pose coordinates); see ``pose_jacobian``."""
        unit = self.unit_legs() if unit is None else unit
        rb = self.rotated
        with np.errstate(invalid="ignore"):
            mx = rb[1] * unit[2] - rb[2] * unit[1]  # (R B) x (e / w), per coordinate
            my = rb[2] * unit[0] - rb[0] * unit[2]
            mz = rb[0] * unit[1] - rb[1] * unit[0]
            ct, st, cp, sp = self.tilt_trig[:, :, None]
            jac = np.empty(unit.shape[1:] + (6,))
            jac[:, :, 0:3] = unit.transpose(1, 2, 0)
            # Rotation axes of d theta, d psi, d phi (euler_rate_axes): e_Y, (ct, 0, -st), (st cp, -sp, ct cp).
            jac[:, :, 3] = my
            jac[:, :, 4] = ct * mx - st * mz
            jac[:, :, 5] = (st * cp) * mx - sp * my + (ct * cp) * mz
        return jac

    def parameter_blocks(self, chains: _Chains, unit: np.ndarray | None = None) -> np.ndarray:
        """d lambda_c / d u_c, (N, 6, 9); see ``parameter_jacobian_blocks``."""
        unit = self.unit_legs() if unit is None else unit
        blocks = np.empty(unit.shape[1:] + (FIELDS_PER_CHAIN,))
        blocks[..., 0:3] = -unit.transpose(1, 2, 0)
        # R^T (e / w): (N, 3, 3)^T @ (N, 3, 6) -> (N, 3, 6)
        blocks[..., 3:6] = np.matmul(self.rotations.transpose(0, 2, 1), unit.transpose(1, 0, 2)).transpose(0, 2, 1)
        blocks[..., 6] = -chains.lengths / self.rail_dot
        d_rail = -self.sliders * unit  # d lambda / d a (full vector), (3, N, 6)
        blocks[..., 7] = d_rail[0] + d_rail[2] * chains.rail_z_slope[0]
        blocks[..., 8] = d_rail[1] + d_rail[2] * chains.rail_z_slope[1]
        return blocks

    def as_geometry(self) -> LegGeometry:
        return LegGeometry(self.rotations, self.rotated.transpose(1, 2, 0), self.sliders,
                           self.legs.transpose(1, 2, 0), self.rail_dot, self.discriminant)


def leg_geometry(params: HexaParameters, poses: np.ndarray) -> LegGeometry:
    """Eq. 3 for every chain and posture, keeping the intermediate vectors."""
    return _Legs(_Chains(params), np.asarray(poses, dtype=float)).as_geometry()


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
        return np.concatenate([unit, np.matmul(moment, euler_rate_axes(angles))], axis=2)


def parameter_jacobian_blocks(params: HexaParameters, geometry: LegGeometry) -> np.ndarray:
    """d lambda_c / d u_c for each chain's own 9 parameters, (N, 6, 9).

    lambda_c depends only on chain c's parameters, so the full (N, 6, 54)
    matrix is block diagonal; these are its blocks, in PARAMETER_FIELDS order.
    """
    legs, w = geometry.leg_vectors, geometry.rail_leg_dot
    unit = legs / w[..., None]
    blocks = np.empty(legs.shape[:2] + (FIELDS_PER_CHAIN,))
    blocks[..., 0:3] = -unit
    blocks[..., 3:6] = np.matmul(unit, geometry.rotations)  # R^T e / w, as rows: (e/w)^T R
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
    chains = _Chains(params)
    poses = _fit_tilt(chains, targets, start) if fit_tilt_first else start.copy()
    n = len(targets)
    converged = np.zeros(n, bool)
    iterations = np.zeros(n, int)
    failures: dict[int, str] = {}
    finite = np.all(np.isfinite(targets), axis=1) & np.all(np.isfinite(start), axis=1)
    for i in np.flatnonzero(~finite):
        failures[int(i)] = "non-finite slider positions or initial pose"
    active = np.flatnonzero(finite)
    target = targets[active]
    legs = _Legs(chains, poses[active])
    error = _slider_error(legs, target)
    for iteration in range(max_iterations + 1):
        done = error < tolerance
        if done.any():
            converged[active[done]] = True
            keep = ~done
            active, error, target = active[keep], error[keep], target[keep]
            if active.size:
                legs = legs.subset(keep)
        if active.size == 0 or iteration == max_iterations:
            break
        iterations[active] += 1
        step, solvable = _solve_batched(legs.pose_jacobian(), legs.sliders - target)
        if not solvable.all():
            for i in active[~solvable]:
                failures[int(i)] = "singular pose Jacobian (the platform is at a singularity)"
            active, error, step, target = active[solvable], error[solvable], step[solvable], target[solvable]
        poses[active], legs, error = _damped_update(chains, poses[active], step, target, error)
    for i in active:
        failures.setdefault(int(i), f"no convergence in {max_iterations} Newton iterations")
    _check_branch(poses, start, converged, failures, branch_tolerance_m, branch_tolerance_rad)
    poses[~converged] = np.nan
    return ForwardKinematicsResult(poses, converged, iterations, failures)


def _fit_tilt(chains: _Chains, targets: np.ndarray, start: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Gauss-Newton on (theta, psi) alone: least squares over the 6 sliders, 2 unknowns."""
    poses = start.copy()
    finite = np.all(np.isfinite(targets), axis=1) & np.all(np.isfinite(start), axis=1)
    fitted, target = poses[finite], targets[finite]
    for _ in range(iterations):
        legs = _Legs(chains, fitted)
        if not np.all(legs.discriminant >= 0.0):
            break
        jac = legs.pose_jacobian()[:, :, 3:5]
        residual = legs.sliders - target
        # 2 x 2 normal equations per posture, written out.
        a = np.sum(jac[:, :, 0] * jac[:, :, 0], axis=1)
        b = np.sum(jac[:, :, 0] * jac[:, :, 1], axis=1)
        c = np.sum(jac[:, :, 1] * jac[:, :, 1], axis=1)
        normal = np.stack([a, b, b, c], axis=1).reshape(-1, 2, 2)
        rhs = np.stack([np.sum(jac[:, :, 0] * residual, axis=1), np.sum(jac[:, :, 1] * residual, axis=1)], axis=1)
        try:
            step = np.linalg.solve(normal, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        fitted[:, 3:5] -= np.clip(step, -0.3, 0.3)
    poses[finite] = fitted
    return np.where(np.isfinite(poses), poses, start)


def _slider_error(legs: _Legs, targets: np.ndarray) -> np.ndarray:
    error = np.max(np.abs(legs.sliders - targets), axis=1)
    return np.where(legs.reachable(), error, np.inf)


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


def _damped_update(chains: _Chains, poses: np.ndarray, step: np.ndarray, targets: np.ndarray, error: np.ndarray):
    """Take X - step, halving the step where it does not reduce the slider error."""
    trial = poses - step
    legs = _Legs(chains, trial)
    trial_error = _slider_error(legs, targets)
    scale = None
    for _ in range(10):
        worse = ~(trial_error < error) & (error > 0)
        if not np.any(worse):
            break
        if scale is None:
            scale = np.ones(len(poses))
        scale[worse] *= 0.5
        trial[worse] = poses[worse] - scale[worse, None] * step[worse]
        sub = _Legs(chains, trial[worse])
        legs.replace_rows(worse, sub)
        trial_error[worse] = _slider_error(sub, targets[worse])
    return trial, legs, trial_error


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


class PoseSensitivity:
    """Derivatives of FK poses: w.r.t. the 54 parameters and w.r.t. the 6 slider readings.

    Kept factored: dX/du[n, k, 9 c + f] = -wrt_sliders[n, k, c] * slider_blocks[n, c, f]
    (d lambda / d u is block diagonal), so a cost function can form just the rows
    it needs (``rows``, ``combined``) in one pass; ``wrt_parameters`` is the full
    (N, 6, 54) array, formed on first use.
    """

    def __init__(self, wrt_sliders: np.ndarray, slider_blocks: np.ndarray):
        self.wrt_sliders = wrt_sliders  # dX/d lambda = J_inv^-1, (N, 6, 6)
        self.slider_blocks = slider_blocks  # d lambda_c / d u_c, (N, 6, 9)
        self._wrt_parameters = None

    @property
    def wrt_parameters(self) -> np.ndarray:
        """dX/du, (N, 6, 54)."""
        if self._wrt_parameters is None:
            full = -self.wrt_sliders[:, :, :, None] * self.slider_blocks[:, None, :, :]
            self._wrt_parameters = full.reshape(len(full), 6, N_CHAINS * FIELDS_PER_CHAIN)
        return self._wrt_parameters

    def _pick(self, index: np.ndarray | None):
        if index is None:
            return self.wrt_sliders, self.slider_blocks
        return self.wrt_sliders[index], self.slider_blocks[index]

    def rows(self, index: np.ndarray | None, coordinates: slice, factor: float) -> np.ndarray:
        """factor * dX[coordinates]/du for postures ``index`` (None: all), (k, m, 54)."""
        inverse, blocks = self._pick(index)
        # factor * (-M b) = (-factor M) b: the sign is exact, so with factor -1 this is M b bit for bit.
        weights = inverse[:, coordinates, :] * -factor
        out = weights[:, :, :, None] * blocks[:, None, :, :]
        return out.reshape(len(out), out.shape[1], N_CHAINS * FIELDS_PER_CHAIN)

    def combined(self, index: np.ndarray | None, weights: np.ndarray) -> np.ndarray:
        """sum_k weights[:, k] dX_k/du for postures ``index`` (None: all); weights (k, 6) -> (k, 54)."""
        inverse, blocks = self._pick(index)
        mixed = -np.matmul(weights[:, None, :], inverse)  # (k, 1, 6)
        out = mixed[:, 0, :, None] * blocks
        return out.reshape(len(out), N_CHAINS * FIELDS_PER_CHAIN)



def pose_sensitivities(params: HexaParameters, poses: np.ndarray) -> PoseSensitivity:
    """dX/du and dX/d lambda at FK solutions, by implicit differentiation of IK(X, u) = lambda.

    J_inv dX = d lambda - (d lambda/d u) du, so dX/d lambda = J_inv^-1 and
    dX/du = -J_inv^-1 d lambda/d u.  d lambda/d u is block diagonal, so column
    block c of dX/du is the outer product of column c of J_inv^-1 with chain c's
    9-vector of derivatives.
    """
    chains = _Chains(params)
    legs = _Legs(chains, np.asarray(poses, dtype=float))
    unit = legs.unit_legs()
    return PoseSensitivity(np.linalg.inv(legs.pose_jacobian(unit)), legs.parameter_blocks(chains, unit))


def pose_parameter_sensitivity(params: HexaParameters, poses: np.ndarray) -> tuple[np.ndarray, LegGeometry]:
    """dX/du (N, 6, 54) at FK solutions (see ``pose_sensitivities``) and the leg geometry there."""
    return pose_sensitivities(params, poses).wrt_parameters, leg_geometry(params, poses)


def rail_xy_slice(chain: int) -> slice:
    """Vector slice of chain's (ax, ay) components (chain counted from 0)."""
    start = chain * FIELDS_PER_CHAIN
    return slice(start + AXY_SLICE.start, start + AXY_SLICE.stop)
