"""Posture planning: choose the K measuring postures that best determine the model's parameters.

Measuring a posture costs machine time, so the postures are chosen, not drawn:
from a large set of feasible candidates (sphere and fixed-position postures,
section 3.2), K are picked to maximise an observability index of the
identification Jacobian (eq. 6 / 9 / 11) at the nominal parameters.  Every
architecture plans the same way: the nominal parameters name their
architecture (``params.architecture``), which supplies the IK, the
workspace check and the passive-joint angles; n below is its number of
parameters (54 for the Hexa Slide, 42 for the Gough-Stewart platform).

Candidates and limits (``PostureLimits``, SI units).  By default the limits are
the nominal machine's own workspace (``PostureLimits.for_machine``: the
architecture's ``default_workspace()``, so the Hexa Slide keeps the paper's
section 4 workspace and the default Gough-Stewart platform gets its own),
plus the device and joint limits below, which reject almost nothing of either:

* x, y within the workspace's range on the L-sphere (Hexa Slide +-400 mm,
  Gough-Stewart +-250 mm), the three Euler angles within its rotation range
  (+-35 deg, +-20 deg);
* inclinometer range +-45 deg: the Hexa Slide's +-400 mm square needs up to
  42.5 deg at its corners (|alpha|, |beta| <= 37.3 deg on the feasible part),
  so a common +-45 deg biaxial sensor covers it;
* actuator stroke (Hexa Slide sliders 0..0.9 m, Gough-Stewart leg extension
  0..0.5 m), pose-Jacobian condition number < 80 (angles scaled by L) and the
  architecture's distance from singular legs (``postures.Workspace``);
* base-side passive joint (the U joint: on the slider of a Hexa Slide, on the
  base of a Gough-Stewart leg): its angle <= 60 deg, measured from the rail
  direction (Hexa Slide; the feasible workspace needs <= 52 deg) or from the
  base normal (Gough-Stewart; its workspace needs <= 51 deg);
* platform-side joint (the S joint): angle between the leg (B -> A) and the
  platform normal z' <= 90 deg (rejects 0.8 % of the Hexa Slide's feasible
  workspace, where the median posture already needs 62 deg on its worst leg;
  nothing of the Gough-Stewart one, which needs <= 74 deg).

The joint angles come from ``Architecture.joint_cosines``.

Observability indices (Sun & Hollerbach 2008; sigma = singular values of the
column-scaled identification Jacobian, n parameters, m = postures):

* O1 = (sigma_1 ... sigma_n)^(1/n) / sqrt(m)  (Borm & Menq; D-optimal, the default)
* O2 = sigma_min / sigma_max                  (inverse condition number, Driels & Pathre)
* O3 = sigma_min                              (Nahvi & Hollerbach)
* O4 = sigma_min^2 / sigma_max                (noise amplification index, Nahvi & Hollerbach)

and, beyond them, I (I-optimal): the least predicted mean squared position error
over the workspace, trace(W M^-1), with M = J^T J the information of the plan and
W the mean of dP/du^T dP/du over the sphere candidates (drawn like validation
postures).  It targets what a calibration is judged by; ``hexacal study --plan``
measures it against O1.

Noise weighting (``noise``, on by default in ``hexacal plan``): each posture's rows
are whitened by the covariance its reading noise propagates to its residuals.
Unweighted, the indices favour postures near singularities, where dX/du is large
but so is the amplified actuator noise; weighted, M is the Fisher information and
sqrt(trace(W M^-1)) is the predicted RMS position error in metres.

Column scaling: every design is scaled by the same column scales, the RMS
per-posture column norm over the whole candidate set, so indices of different
designs compare (a design's own unit-norm scaling would give each design its own
yardstick).  O1's ranking of designs does not depend on the scaling at all.

Selection: greedy (add the candidate that maximises the index, one at a time;
the information matrix gets a rank-r update per posture, and all candidates
are scored at once with batched r x r determinants or n x n eigenvalues) and
Fedorov-style exchange (from the greedy design, swap a design posture for the
candidate that improves the index most, until a whole pass swaps nothing).
While the design has fewer rows than parameters every index is zero; the D
criterion with a tiny ridge (log det(M + delta I)) then chooses, whatever index
was asked for, because it rewards each new independent direction.

The relative cost (eqs. 12, 13) differences consecutive postures of the same
kind, so a posture's rows depend on its predecessor: greedy appends in plan
order (exact), exchange swaps within a kind in place (also exact).

Planning for an imperfect device (``device_columns``, ``device_prior``,
``procedure``; absolute cost).  The rows gain the columns of the device
parameters identified with the machine, the information starts from the
priors' (1 / std^2 on their columns), and every sphere candidate is offered
once per device turn of the procedure (``studies.device_procedure.PROCEDURES``:
0 / 180 deg, or 0 / 90 / 180 / 270 deg), so the plan chooses which postures
to measure in which mounting.  I then predicts the position error with the
device parameters' uncertainty marginalised: W weighs the kinematic columns
only.  The plan's postures carry their ``device_turn`` and are ordered by turn
(one remount per turn), each turn's postures in a travel tour.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
import hashlib
from pathlib import Path
import time
from typing import Callable

from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.plan_file import (
    json_safe,
    METADATA_PREFIX,
    PLAN_MODEL_KEY,
    PLAN_MOUNT_KEY,
    plan_file_text,
    PlanFile,
    read_plan_file,
    write_plan_file,
)
import numpy as np

from .architectures import KinematicParameters
from .device import (
    check_mount,
    DEFAULT_MOUNT,
    DEVICE_PARAMETER_NAMES,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
    fixed_point,
    inclinometer_angles,
    sphere_z,
    STANDING,
)
from .kinematics import pose_parameter_sensitivity, pose_sensitivities
from .measurements import FIXED, NoiseModel, POSTURE_KINDS, simulate_measurements, SPHERE
from .postures import Workspace
from .residuals import ChannelSigma, CostFunction, COSTS

INDICES = ('O1', 'O2', 'O3', 'O4')
PREDICTION = 'I'  # I-optimal: least predicted mean squared position error over the workspace
CRITERIA = INDICES + (PREDICTION,)
METHODS = ('greedy', 'exchange')
RIDGE = 1e-8  # delta of log det(M + delta I), relative to the mean per-posture information
RANK_TOLERANCE = (
    1e-9  # eigenvalue of M (= sigma^2) relative to the largest: below counts as missing
)
Progress = Callable[[str], None]


def _quiet(_: str) -> None:
    pass


# --------------------------------------------------------------------------- limits and candidates
_PAPER_WORKSPACE = (
    Workspace()
)  # the dataclass defaults: section 4's workspace (the Hexa Slide's default)


@dataclass(frozen=True)
class PostureLimits:
    """Everything a planned posture must respect (SI units; module doc).

    The field defaults are ``postures.Workspace``'s (the paper's workspace) plus
    the device and joint limits; ``for_machine(params)`` takes the workspace of
    the nominal machine's architecture instead, which is what ``plan_postures``
    uses when it is given no limits.
    """

    link_length: float = _PAPER_WORKSPACE.link_length
    xy_range_m: float = float(_PAPER_WORKSPACE.xy_range_m)
    rotation_range_rad: float = float(_PAPER_WORKSPACE.rotation_range_rad)
    inclinometer_range_rad: float = float(np.radians(45.0))
    actuator_stroke_m: tuple[float, float] = tuple(
        _PAPER_WORKSPACE.slider_stroke_m
    )  # Workspace's name for it
    max_u_joint_angle_rad: float = float(np.radians(60.0))  # base-side passive joint
    max_s_joint_angle_rad: float = float(np.radians(90.0))  # platform-side spherical joint
    max_condition: float = float(_PAPER_WORKSPACE.max_condition)
    min_leg_cosine: float = float(
        _PAPER_WORKSPACE.min_leg_rail_cosine
    )  # away from singular legs (architecture's)
    mount: str = (
        _PAPER_WORKSPACE.mount
    )  # the device's (device.py): hanging = postures below O, standing = above

    def __post_init__(self) -> None:
        check_mount(self.mount)

    @classmethod
    def from_workspace(cls, workspace: Workspace, **overrides) -> 'PostureLimits':
        """A workspace's limits, the device and joint limits at their defaults; ``overrides`` replace fields."""
        values = dict(
            link_length=float(workspace.link_length),
            xy_range_m=float(workspace.xy_range_m),
            rotation_range_rad=float(workspace.rotation_range_rad),
            actuator_stroke_m=tuple(float(v) for v in workspace.slider_stroke_m),
            max_condition=float(workspace.max_condition),
            min_leg_cosine=float(workspace.min_leg_rail_cosine),
            mount=workspace.mount,
        )
        values.update(overrides)
        return cls(**values)

    @classmethod
    def for_machine(cls, params: KinematicParameters, **overrides) -> 'PostureLimits':
        """The default limits for planning on ``params``: its architecture's default workspace."""
        return cls.from_workspace(params.architecture.default_workspace(), **overrides)

    def device(self) -> DeviceModel:
        return DeviceModel(self.link_length, self.mount)

    def workspace(self) -> Workspace:
        return Workspace(
            self.link_length,
            self.xy_range_m,
            self.rotation_range_rad,
            tuple(self.actuator_stroke_m),
            self.max_condition,
            self.min_leg_cosine,
            self.mount,
        )

    def to_json(self) -> dict:
        payload = asdict(self)
        payload['actuator_stroke_m'] = list(self.actuator_stroke_m)
        return payload

    def check(self, params: KinematicParameters, poses: np.ndarray) -> dict[str, np.ndarray]:
        """One mask per limit (True = respected), for N poses (N, 6)."""
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        arch = params.architecture
        reachable = arch.legs(arch.chains(params), poses).reachable()
        alpha, beta = inclinometer_angles(poses[:, :3], self.mount)
        with np.errstate(invalid='ignore'):
            u_cos, s_cos = arch.joint_cosines(params, poses)
        tolerance = 1e-9  # the sphere radius is recomputed from x, y; allow its rounding
        on_sphere = np.abs(np.linalg.norm(poses[:, :3], axis=1) - self.link_length) < tolerance
        return {
            'on_link_sphere': on_sphere,
            'xy_range': np.all(np.abs(poses[:, :2]) <= self.xy_range_m + tolerance, axis=1),
            'rotation_range': np.all(
                np.abs(poses[:, 3:6]) <= self.rotation_range_rad + tolerance, axis=1
            ),
            'inclinometer_range': np.maximum(np.abs(alpha), np.abs(beta))
            <= self.inclinometer_range_rad,
            # reachable, actuator stroke, singular legs and condition number, as the architecture defines them
            'workspace': arch.acceptable_poses(params, poses, self.workspace()),
            'u_joint_angle': reachable
            & np.all(u_cos >= np.cos(self.max_u_joint_angle_rad), axis=1),
            's_joint_angle': reachable
            & np.all(s_cos >= np.cos(self.max_s_joint_angle_rad), axis=1),
        }

    def feasible(self, params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
        checks = self.check(params, poses)
        return np.logical_and.reduce(list(checks.values()))


class InfeasibleLimitsError(ValueError):
    """The limits leave (almost) no feasible candidate posture on the nominal machine."""


def default_fixed_fraction(cost: str) -> float:
    """Share of fixed-position candidates: only where the cost function uses them (as study.posture_split).

    Fixed-position postures cost more to take (the actuators are adjusted until the
    inclinometer reads zero, section 3.2), so costs that gain nothing from them get none.
    """
    return {'fixed': 1.0, 'sphere-fixed': 0.25, 'relative': 0.25}.get(cost, 0.0)


def generate_candidates(
    params: KinematicParameters,
    n: int,
    rng: np.random.Generator,
    limits: PostureLimits | None = None,
    fixed_fraction: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """n feasible candidate postures (poses (n, 6), kinds (n,)): sphere ones first, then fixed.

    ``limits`` None = ``PostureLimits.for_machine(params)``.
    """
    if limits is None:
        limits = PostureLimits.for_machine(params)
    n_fixed = int(round(n * fixed_fraction))
    parts, kinds = [], []
    for kind, count in ((SPHERE, n - n_fixed), (FIXED, n_fixed)):
        accepted, found, drawn = [], 0, 0
        for _ in range(200):
            if found >= count:
                break
            draws = _draw(kind, rng, max(2 * (count - found), 64), limits)
            good = draws[limits.feasible(params, draws)]
            accepted.append(good)
            found += len(good)
            drawn += len(draws)
        else:  # bad input (limits that exclude the machine's workspace), not a failure: a ValueError
            raise InfeasibleLimitsError(
                f'could not find {count} feasible {kind} postures within the limits: {found} of {drawn} drawn '
                f'were feasible for the {params.layout.title} with a {limits.mount} device (check the '
                'workspace, stroke and joint limits against the nominal machine)'
            )
        if count:
            parts.append(np.concatenate(accepted)[:count])
            kinds.append(np.full(count, kind))
    if not parts:
        return np.zeros((0, 6)), np.zeros(0, dtype=str)
    return np.concatenate(parts), np.concatenate(kinds)


def _draw(kind: str, rng: np.random.Generator, n: int, limits: PostureLimits) -> np.ndarray:
    angles = rng.uniform(-limits.rotation_range_rad, limits.rotation_range_rad, (n, 3))
    if (
        kind == FIXED
    ):  # inclinometer at zero: the platform sits at [0, 0, -L] ([0, 0, +L] standing)
        return np.column_stack(
            [np.tile(fixed_point(limits.link_length, limits.mount), (n, 1)), angles]
        )
    xy = rng.uniform(-limits.xy_range_m, limits.xy_range_m, (n, 2))
    return np.column_stack([xy, sphere_z(xy, limits.link_length, limits.mount), angles])


# --------------------------------------------------------------------------- observability indices
def observability_indices(singular_values: np.ndarray, n_postures: int) -> dict[str, float]:
    """O1..O4 from the singular values of a column-scaled identification Jacobian (module doc)."""
    sigma = np.sort(np.asarray(singular_values, dtype=float))[::-1]
    largest, smallest = float(sigma[0]), float(sigma[-1])
    if smallest <= 0.0:
        return {'O1': 0.0, 'O2': 0.0, 'O3': 0.0, 'O4': 0.0}
    return {
        'O1': float(np.exp(np.mean(np.log(sigma))) / np.sqrt(n_postures)),
        'O2': smallest / largest,
        'O3': smallest,
        'O4': smallest**2 / largest,
    }


def observability_index(
    jacobian: np.ndarray, n_postures: int, index: str = 'O1', scales: np.ndarray | None = None
) -> float:
    """One index of a Jacobian (rows x n parameters); ``scales`` None = unit-norm columns (as identifiability.analyze)."""
    if index not in INDICES:
        raise ValueError(
            f'unknown observability index {index!r}; choose one of {", ".join(INDICES)}'
        )
    if scales is None:
        norms = np.linalg.norm(jacobian, axis=0)
        scales = np.where(norms > 0, norms, 1.0)
    singular = np.linalg.svd(jacobian / scales, compute_uv=False)
    singular = np.concatenate([singular, np.zeros(jacobian.shape[1] - len(singular))])
    return observability_indices(singular, n_postures)[index]


def _index_from_eigenvalues(eigenvalues: np.ndarray, n_postures: int, index: str) -> np.ndarray:
    """Index of information matrices from their eigenvalues (..., n), ascending."""
    sigma = np.sqrt(np.maximum(eigenvalues, 0.0))
    smallest, largest = sigma[..., 0], sigma[..., -1]
    deficient = eigenvalues[..., 0] <= RANK_TOLERANCE * eigenvalues[..., -1]
    if index == 'O1':
        with np.errstate(divide='ignore'):
            value = np.exp(np.mean(np.log(sigma), axis=-1)) / np.sqrt(n_postures)
    elif index == 'O2':
        value = smallest / largest
    elif index == 'O3':
        value = smallest
    else:
        value = smallest**2 / largest
    return np.where(deficient, 0.0, value)


# --------------------------------------------------------------------------- the design problem
@dataclass
class CandidateSet:
    """Candidates and their identification-Jacobian rows at the nominal parameters (column-scaled).

    For every cost but 'relative', ``rows[i]`` are posture i's rows (zero-padded to
    the same count).  For 'relative', ``rows[i]`` is posture i's phi row and
    ``difference_rows[i]`` its position (fixed) or link-length (sphere) rows,
    which enter as differences with the previous posture of the same kind.
    """

    poses: np.ndarray
    kinds: np.ndarray
    cost: str
    scales: np.ndarray  # (n,), n = the model's parameters
    rows: np.ndarray  # (N, r, n)
    difference_rows: np.ndarray | None = None  # (N, r', n), relative cost only
    # mean of dP/du^T dP/du over the sphere candidates (column-scaled): what the position error weighs
    position_weight: np.ndarray | None = None
    prior_information: np.ndarray | None = (
        None  # (n, n) information of the device priors (column-scaled)
    )
    turns: np.ndarray | None = None  # (N,) device turn of each candidate, rad (None: all normal)
    device_columns: tuple[
        str, ...
    ] = ()  # device parameters after the model's, in DEVICE_PARAMETER_NAMES order

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def n_parameters(self) -> int:
        return len(self.scales)

    @property
    def relative(self) -> bool:
        return self.difference_rows is not None

    def slot_rows(
        self, candidates: np.ndarray, previous: np.ndarray, following: np.ndarray
    ) -> np.ndarray:
        """Rows candidate c adds in a plan slot between ``previous`` and ``following`` (same kind; -1 = none)."""
        candidates = np.asarray(candidates, dtype=int)
        own = self.rows[candidates]
        if not self.relative:
            return own
        previous = np.broadcast_to(previous, candidates.shape)
        following = np.broadcast_to(following, candidates.shape)
        diff = self.difference_rows
        before = np.where(
            (previous >= 0)[:, None, None], diff[candidates] - diff[np.maximum(previous, 0)], 0.0
        )
        after = np.where(
            (following >= 0)[:, None, None], diff[np.maximum(following, 0)] - diff[candidates], 0.0
        )
        return np.concatenate([own, before, after], axis=1)

    def design_jacobian(self, design: np.ndarray) -> np.ndarray:
        """Stacked (scaled) rows of a plan, in plan order."""
        design = np.asarray(design, dtype=int)
        blocks = []
        for slot, candidate in enumerate(design):
            previous, following = _neighbours(self.kinds, design, slot)
            rows = self.slot_rows(np.array([candidate]), np.array([previous]), np.array([-1]))[0]
            blocks.append(rows)
        stacked = np.concatenate(blocks) if blocks else np.zeros((0, self.n_parameters))
        return stacked[np.any(stacked != 0.0, axis=1)]

    def information(self, design: np.ndarray) -> np.ndarray:
        jacobian = self.design_jacobian(design)
        return jacobian.T @ jacobian + self.start_information()

    def start_information(self) -> np.ndarray:
        """The information before any posture: the device priors' (zero without priors)."""
        if self.prior_information is not None:
            return self.prior_information.copy()
        return np.zeros((self.n_parameters, self.n_parameters))

    def rank(self, design: np.ndarray) -> int:
        eigenvalues = np.linalg.eigvalsh(self.information(design))
        return int(np.sum(eigenvalues > RANK_TOLERANCE * eigenvalues[-1]))

    def indices(self, design: np.ndarray) -> dict[str, float]:
        """O1..O4 of a plan (on this set's column scales)."""
        eigenvalues = np.linalg.eigvalsh(self.information(design))
        return {
            name: float(_index_from_eigenvalues(eigenvalues, len(design), name))
            for name in INDICES
        }

    def predicted_position_error(self, design: np.ndarray) -> float:
        """sqrt(trace(W M^-1)): predicted RMS position error over the workspace, linearised.

        In metres when the rows are noise-weighted (M is then the Fisher information),
        per unit residual noise otherwise; infinite when the plan is rank deficient.
        """
        information = self.information(design)
        if not _full_rank(information):
            return float('inf')
        return float(np.sqrt(np.trace(self.position_weight @ np.linalg.inv(information))))


def _neighbours(kinds: np.ndarray, design: np.ndarray, slot: int) -> tuple[int, int]:
    """Previous and next design entries of the same kind as design[slot] (-1 = none)."""
    kind = kinds[design[slot]]
    same_before = [c for c in design[:slot] if kinds[c] == kind]
    same_after = [c for c in design[slot + 1 :] if kinds[c] == kind]
    return (int(same_before[-1]) if same_before else -1, int(same_after[0]) if same_after else -1)


def build_candidate_set(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: np.ndarray,
    cost: str = 'absolute',
    device: DeviceModel = DeviceModel(),
    sigma: ChannelSigma = ChannelSigma(),
    noise: NoiseModel | None = None,
    device_columns: tuple[str, ...] = (),
    device_prior: DevicePrior = DevicePrior(),
    turns: np.ndarray | None = None,
) -> CandidateSet:
    """Analytic identification-Jacobian rows of every candidate (pose_parameter_sensitivity + CostFunction).

    With ``noise``, each posture's rows are whitened by the covariance the reading
    noise propagates to its residuals (actuator noise through FK, inclinometer
    noise through eq. 4, rotary noise): near a singularity a posture's rows look
    large, but so does its actuator noise, and whitening tells the two apart.
    Not for the relative cost (its rows mix two postures' noise).
    """
    if cost not in COSTS:
        raise ValueError(f'unknown cost function {cost!r}; choose one of {", ".join(COSTS)}')
    if noise is not None and cost == 'relative':
        raise ValueError('noise weighting of the plan is not available for the relative cost')
    if device_columns or device_prior or turns is not None:
        return _device_candidate_set(
            nominal, poses, kinds, cost, device, sigma, noise, device_columns, device_prior, turns
        )
    # At the nominal parameters the commanded pose is where the model puts the platform,
    # so noise-free simulated readings there are the expected measurements.
    measurements = simulate_measurements(nominal, poses, kinds, device)
    sensitivity, legs = pose_parameter_sensitivity(nominal, poses)
    own_cost = 'sphere-fixed' if cost == 'relative' else cost
    function = CostFunction(own_cost, measurements, device, sigma)
    block = function.residuals(poses, sensitivity)
    phi = block.channels == 'phi'
    if cost == 'relative':
        rows = _rows_per_posture(block.jacobian[phi], block.postures[phi], len(poses))
        difference = _rows_per_posture(block.jacobian[~phi], block.postures[~phi], len(poses))
        stacked = np.concatenate([rows, difference], axis=1)
    else:
        rows = _rows_per_posture(block.jacobian, block.postures, len(poses))
        difference = None
        if noise is not None:
            rows = _whiten(rows, _noise_rows(function, poses, legs, block, sigma, device), noise)
        stacked = rows
    # RMS per-posture column norm over all candidates: one yardstick for every design.
    norms = np.sqrt(np.einsum('nrk,nrk->k', stacked, stacked) / max(len(poses), 1))
    scales = np.where(norms > 0, norms, 1.0)
    # Validation postures are drawn like the sphere candidates: their mean dP/du^T dP/du weighs the error.
    sphere = np.asarray(kinds) == SPHERE
    position = sensitivity[sphere if np.any(sphere) else slice(None), :3, :]
    weight = np.einsum('nik,nil->kl', position, position) / max(len(position), 1)
    return CandidateSet(
        poses,
        np.asarray(kinds).astype(str),
        cost,
        scales,
        rows / scales,
        None if difference is None else difference / scales,
        weight / np.outer(scales, scales),
    )


def _device_candidate_set(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: np.ndarray,
    cost: str,
    device: DeviceModel,
    sigma: ChannelSigma,
    noise: NoiseModel | None,
    device_columns: tuple[str, ...],
    device_prior: DevicePrior,
    turns: np.ndarray | None,
) -> CandidateSet:
    """Candidates with device columns, priors and device turns (module doc): rows of the absolute cost."""
    if cost != 'absolute':
        raise ValueError(
            f'planning for device parameters or device turns needs the absolute cost (eq. 7), got {cost}'
        )
    if device_prior and noise is None:
        raise ValueError(
            'a device prior is weighed against the reading noise: plan with the noise model'
        )
    columns = tuple(
        name
        for name in DEVICE_PARAMETER_NAMES
        if name in set(device_columns) | set(device_prior.names)
    )
    measurements = simulate_measurements(nominal, poses, kinds, device, device_turn=turns)
    sensitivity = pose_sensitivities(nominal, poses)
    function = CostFunction(cost, measurements, device, sigma)
    block = function.residuals(poses, sensitivity, DeviceDefects(), with_device=True)
    n = nominal.layout.n_parameters
    keep = np.concatenate([np.ones(n, bool), np.isin(DEVICE_PARAMETER_NAMES, columns)])
    rows = _rows_per_posture(block.jacobian[:, keep], block.postures, len(poses))
    if noise is not None:
        rows = _whiten(
            rows, _rows_per_posture(block.noise_jacobian, block.postures, len(poses)), noise
        )
    norms = np.sqrt(np.einsum('nrk,nrk->k', rows, rows) / max(len(poses), 1))
    scales = np.where(norms > 0, norms, 1.0)
    sphere = np.asarray(kinds) == SPHERE
    position = sensitivity.wrt_parameters[sphere if np.any(sphere) else slice(None), :3, :]
    weight = np.zeros((len(scales), len(scales)))
    weight[:n, :n] = np.einsum('nik,nil->kl', position, position) / max(len(position), 1)
    prior = np.zeros_like(weight)
    for name, _, std in device_prior.entries:
        column = n + columns.index(name)
        prior[column, column] = 1.0 / std**2
    scale_square = np.outer(scales, scales)
    return CandidateSet(
        poses,
        np.asarray(kinds).astype(str),
        cost,
        scales,
        rows / scales,
        None,
        weight / scale_square,
        prior / scale_square if device_prior else None,
        None if turns is None else np.asarray(turns, dtype=float),
        columns,
    )


def _noise_rows(
    function: CostFunction,
    poses: np.ndarray,
    legs,
    block,
    sigma: ChannelSigma,
    device: DeviceModel,
) -> np.ndarray:
    """d residual / d readings (rows, 9): 6 actuators, alpha, beta, phi, in the order of ``block``'s rows."""
    actuator_sensitivity = np.linalg.inv(legs.pose_jacobian())  # dX / d lambda
    wrt_actuators = function.residuals(poses, actuator_sensitivity).jacobian
    wrt_readings = np.zeros((len(block.channels), 3))
    is_phi = block.channels == 'phi'
    wrt_readings[is_phi, 2] = 1.0 / sigma.angle_rad  # r = phi_m - phi_c
    measured_xyz = np.isin(block.channels, ('x', 'y', 'z')) & (function.cost == 'absolute')
    if np.any(measured_xyz):  # eq. 4: the measured position moves with alpha and beta
        alpha, beta = inclinometer_angles(poses[:, :3], device.mount)
        # eq. 4's derivatives; a standing link's end is p = -p_hanging(alpha, beta) (device.py)
        length = -device.link_length if device.mount == STANDING else device.link_length
        d_alpha = np.column_stack(
            [
                -length * np.sin(alpha) * np.sin(beta),
                -length * np.cos(alpha),
                length * np.sin(alpha) * np.cos(beta),
            ]
        )
        d_beta = np.column_stack(
            [
                length * np.cos(alpha) * np.cos(beta),
                np.zeros_like(alpha),
                length * np.cos(alpha) * np.sin(beta),
            ]
        )
        axis = np.searchsorted(['x', 'y', 'z'], block.channels[measured_xyz])
        posture = block.postures[measured_xyz]
        wrt_readings[measured_xyz, 0] = d_alpha[posture, axis] / sigma.position_m
        wrt_readings[measured_xyz, 1] = d_beta[posture, axis] / sigma.position_m
    return _rows_per_posture(
        np.column_stack([wrt_actuators, wrt_readings]), block.postures, len(poses)
    )


def _whiten(rows: np.ndarray, noise_rows: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """L^-1 rows per posture, with L L^T the residual covariance (padding rows keep unit variance)."""
    actuators = noise_rows.shape[2] - 3  # the readings: one per actuator, then alpha, beta, phi
    std = np.array([noise.slider_m] * actuators + [noise.angle_rad] * 3) / np.sqrt(
        3.0
    )  # +-a uniform
    weighted = noise_rows * std
    covariance = weighted @ weighted.transpose(0, 2, 1)
    padding = ~np.any(rows != 0.0, axis=2) & ~np.any(noise_rows != 0.0, axis=2)
    covariance += np.einsum('nr,rs->nrs', padding.astype(float), np.eye(rows.shape[1]))
    return np.linalg.solve(np.linalg.cholesky(covariance), rows)


def _rows_per_posture(jacobian: np.ndarray, postures: np.ndarray, n: int) -> np.ndarray:
    """Scatter Jacobian rows into (n, max rows per posture, columns), zero-padded."""
    order = np.argsort(postures, kind='stable')
    postures = postures[order]
    counts = np.bincount(postures, minlength=n)
    width = int(counts.max()) if len(counts) else 0
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    position = np.arange(len(postures)) - starts[postures]
    out = np.zeros((n, max(width, 1), jacobian.shape[1]))
    out[postures, position] = jacobian[order]
    return out


# --------------------------------------------------------------------------- scoring
def _score(
    base: np.ndarray,
    added: np.ndarray,
    n_postures: int,
    index: str,
    ridge: float,
    use_d_criterion: bool,
    weight: np.ndarray | None = None,
) -> np.ndarray:
    """Criterion of base + A_c^T A_c for every candidate c (higher is better)."""
    if index == PREDICTION and not use_d_criterion:
        # -trace(W (B + A^T A)^-1) by Woodbury: trace(W B^-1) - trace(S^-1 A B^-1 W B^-1 A^T), S = I + A B^-1 A^T.
        inverse = np.linalg.inv(base + ridge * np.eye(len(base)))
        projected = added @ inverse
        inner = projected @ added.transpose(0, 2, 1) + np.eye(added.shape[1])
        weighted = projected @ weight @ projected.transpose(0, 2, 1)
        reduction = np.trace(np.linalg.solve(inner, weighted), axis1=1, axis2=2)
        return reduction - np.trace(weight @ inverse)
    if use_d_criterion or index == 'O1':
        # log det(B + A^T A) = log det B + log det(I + A B^-1 A^T): r x r determinants per candidate.
        regularised = base + ridge * np.eye(len(base))
        inverse = np.linalg.inv(regularised)
        inner = (added @ inverse) @ added.transpose(0, 2, 1) + np.eye(added.shape[1])
        return np.linalg.slogdet(regularised)[1] + np.linalg.slogdet(inner)[1]
    eigenvalues = np.linalg.eigvalsh(base[None] + added.transpose(0, 2, 1) @ added)
    return _index_from_eigenvalues(eigenvalues, n_postures, index)


def _full_rank(information: np.ndarray) -> bool:
    eigenvalues = np.linalg.eigvalsh(information)
    return bool(eigenvalues[0] > RANK_TOLERANCE * eigenvalues[-1])


def greedy_design(
    candidates: CandidateSet,
    n_postures: int,
    index: str = 'O1',
    progress: Progress = _quiet,
    kind_counts: dict[str, int] | None = None,
    screen: int = 300,
) -> tuple[np.ndarray, list[float]]:
    """Add, one at a time, the candidate that maximises the index; returns (design, D-criterion history).

    The history holds log det(M + delta I) after each pick: it never decreases.
    ``kind_counts`` caps the postures of each kind.  The relative cost needs it:
    there, a kind's first posture adds only its phi row (its differences need a
    partner), so one-step greedy would never start the fixed-position kind.
    For O2-O4 only the ``screen`` candidates with the best D-criterion gain are
    scored exactly (n x n eigenvalues each); O1 and I score every candidate.
    """
    _check_index(index)
    n = len(candidates)
    if n_postures > n:
        raise ValueError(f'cannot choose {n_postures} postures from {n} candidates')
    available = np.ones(n, bool)
    remaining = dict(kind_counts) if kind_counts is not None else None
    ridge = RIDGE * _mean_posture_information(candidates)
    information = candidates.start_information()
    design: list[int] = []
    last_of_kind = {kind: -1 for kind in POSTURE_KINDS}
    history = []
    if remaining is not None:
        if sum(remaining.values()) < n_postures:
            raise ValueError(f'kind_counts {remaining} allow fewer than {n_postures} postures')
        available &= np.isin(candidates.kinds, [k for k, count in remaining.items() if count > 0])
    for step in range(n_postures):
        pool = np.flatnonzero(available)
        if not len(pool):
            raise ValueError(f'only {step} candidates fit the kind counts; {n_postures} requested')
        previous = np.array([last_of_kind[k] for k in candidates.kinds[pool]])
        added = candidates.slot_rows(pool, previous, np.full(len(pool), -1))
        d_phase = not _full_rank(information)
        if not (d_phase or index in ('O1', PREDICTION)) and len(pool) > screen:
            keep = np.argsort(_score(information, added, step + 1, index, ridge, True))[-screen:]
            pool, added = pool[keep], added[keep]
        scores = _score(
            information, added, step + 1, index, ridge, d_phase, candidates.position_weight
        )
        best = int(np.argmax(scores))
        choice = int(pool[best])
        design.append(choice)
        available[choice] = False
        if remaining is not None:
            kind = candidates.kinds[choice]
            remaining[kind] -= 1
            if remaining[kind] <= 0:
                available &= candidates.kinds != kind
        last_of_kind[candidates.kinds[choice]] = choice
        information = information + added[best].T @ added[best]
        history.append(
            float(np.linalg.slogdet(information + ridge * np.eye(candidates.n_parameters))[1])
        )
        progress(f'greedy {index}: {step + 1}/{n_postures} postures')
    return np.array(design, dtype=int), history


def exchange_design(
    candidates: CandidateSet,
    start: np.ndarray,
    index: str = 'O1',
    max_passes: int = 10,
    progress: Progress = _quiet,
    screen: int = 300,
) -> tuple[np.ndarray, list[float]]:
    """Fedorov-style exchange from ``start``: swap a plan posture for the best candidate while the index improves.

    Returns (design, criterion after each accepted swap), strictly increasing.  For
    O2-O4 each slot scores the ``screen`` candidates with the best D-criterion gain
    exactly (eigenvalues); O1 scores every candidate.  The relative cost swaps
    within a kind, in place, so each posture keeps its neighbours.
    """
    _check_index(index)
    design = np.array(start, dtype=int)
    ridge = RIDGE * _mean_posture_information(candidates)
    information = candidates.information(design)
    use_d = not _full_rank(information)
    current = _design_criterion(
        information, len(design), index, ridge, use_d, candidates.position_weight
    )
    history = [current]
    for sweep in range(max_passes):
        swapped = False
        for slot in range(len(design)):
            previous, following = _neighbours(candidates.kinds, design, slot)
            old = candidates.slot_rows(
                design[slot : slot + 1], np.array([previous]), np.array([following])
            )[0]
            base = information - old.T @ old
            pool = np.setdiff1d(np.arange(len(candidates)), design)
            if (
                candidates.relative
            ):  # keep the kind sequence: the differences stay between the same slots
                pool = pool[candidates.kinds[pool] == candidates.kinds[design[slot]]]
            if not len(pool):
                continue
            added = candidates.slot_rows(
                pool, np.full(len(pool), previous), np.full(len(pool), following)
            )
            if not (use_d or index in ('O1', PREDICTION)) and len(pool) > screen:
                d_gain = _score(base, added, len(design), index, ridge, True)
                keep = np.argsort(d_gain)[-screen:]
                pool, added = pool[keep], added[keep]
            scores = _score(
                base, added, len(design), index, ridge, use_d, candidates.position_weight
            )
            best = int(np.argmax(scores))
            if scores[best] > current + 1e-12 * max(abs(current), 1.0):
                design[slot] = pool[best]
                information = base + added[best].T @ added[best]
                current = float(scores[best])
                history.append(current)
                swapped = True
        progress(f'exchange {index}: pass {sweep + 1}, {len(history) - 1} swaps')
        if not swapped:
            break
    return design, history


def _design_criterion(
    information: np.ndarray,
    n_postures: int,
    index: str,
    ridge: float,
    use_d: bool,
    weight: np.ndarray | None = None,
) -> float:
    if index == PREDICTION and not use_d:
        return -float(
            np.trace(weight @ np.linalg.inv(information + ridge * np.eye(len(information))))
        )
    if use_d or index == 'O1':
        return float(np.linalg.slogdet(information + ridge * np.eye(len(information)))[1])
    return float(_index_from_eigenvalues(np.linalg.eigvalsh(information), n_postures, index))


def _mean_posture_information(candidates: CandidateSet) -> float:
    """Mean eigenvalue of one posture's information: the unit of the ridge."""
    stacked = (
        candidates.rows
        if not candidates.relative
        else np.concatenate([candidates.rows, candidates.difference_rows], axis=1)
    )
    return float(
        np.einsum('nrk,nrk->', stacked, stacked) / (len(candidates) * candidates.n_parameters)
    )


def _check_index(index: str) -> None:
    if index not in CRITERIA:
        raise ValueError(
            f'unknown observability index {index!r}; choose one of {", ".join(CRITERIA)}'
        )


def _turn_order(turns: np.ndarray | None, design: np.ndarray, order: np.ndarray) -> np.ndarray:
    """``order`` (a travel order of ``design``) regrouped by device turn, stably: one remount per turn."""
    if turns is None:
        return order
    return order[np.argsort(turns[design][order], kind='stable')]


def travel_order(
    poses: np.ndarray, kinds: np.ndarray, link_length: float, keep_order_within_kind: bool
) -> np.ndarray:
    """Plan order: sphere postures first, then fixed ones (section 3.2's procedure); within a kind a
    nearest-neighbour tour (angles weighted by L) to shorten the moves, unless the order must stay."""
    order = []
    for kind in POSTURE_KINDS:
        members = np.flatnonzero(kinds == kind)
        if keep_order_within_kind or len(members) < 3:
            order.extend(members.tolist())
            continue
        weighted = np.column_stack([poses[members, :3], poses[members, 3:6] * link_length])
        remaining = list(range(len(members)))
        current = int(np.argmin(np.linalg.norm(weighted[:, :2], axis=1)))  # start near the centre
        tour = [current]
        remaining.remove(current)
        while remaining:
            distance = np.linalg.norm(weighted[remaining] - weighted[current], axis=1)
            current = remaining[int(np.argmin(distance))]
            tour.append(current)
            remaining.remove(current)
        order.extend(members[tour].tolist())
    return np.array(order, dtype=int)


# --------------------------------------------------------------------------- the plan


@dataclass
class Plan:
    """Hold the planned postures (m, rad) and the planner's metadata; read and written as a plan file.

    The file format has one owner, hexacal_msgs_py.plan_file (what the driver and
    the executor read too).  ``model`` names the machine model the postures were
    planned for, ``mount`` the device mount; the metadata rides in the file's
    ``# hexacal-plan:`` comment with the plan's fingerprint, and the default name
    ends with that fingerprint, so a bag that records the plan name says exactly
    which postures it followed.  ``device_turns`` (rad, written only where
    non-zero): the device turned about its link axis for the posture (a turning
    procedure, module doc); postures without one are taken in the normal mounting.
    """

    name: str
    link_length: float
    poses: np.ndarray
    kinds: np.ndarray
    metadata: dict = field(default_factory=dict)
    model: str = DEFAULT_MODEL
    mount: str = DEFAULT_MOUNT
    device_turns: np.ndarray | None = (
        None  # (K,) rad per posture; None = every posture in the normal mounting
    )

    def __post_init__(self) -> None:
        self.poses = np.atleast_2d(np.asarray(self.poses, dtype=float)).reshape(-1, 6)
        if self.device_turns is not None:
            self.device_turns = np.asarray(self.device_turns, dtype=float).reshape(-1)
            if self.device_turns.shape != (len(self.poses),) or not np.all(
                np.isfinite(self.device_turns)
            ):
                raise ValueError(
                    f'plan device_turn: one finite angle (rad) per posture, got {self.device_turns!r}'
                )
            if not np.any(self.device_turns):
                self.device_turns = None
        self.kinds = np.asarray(self.kinds).astype(str).reshape(-1)
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError('plan name must be a non-empty string')
        if len(self.kinds) != len(self.poses) or not len(self.poses):
            raise ValueError(
                f'plan needs postures and one kind each: {len(self.poses)} poses, {len(self.kinds)} kinds'
            )
        unknown = sorted(set(self.kinds) - set(POSTURE_KINDS))
        if unknown:
            raise ValueError(f'unknown posture kind(s) {unknown}; expected one of {POSTURE_KINDS}')
        if not np.all(np.isfinite(self.poses)):
            raise ValueError('plan poses must be finite numbers')
        if not (np.isfinite(self.link_length) and self.link_length > 0):
            raise ValueError(
                f'plan link_length must be a positive length in m, got {self.link_length}'
            )
        if self.model not in MODELS:
            raise ValueError(
                f'plan model {self.model!r} is not a machine model hexacal knows '
                f'({", ".join(sorted(MODELS))})'
            )
        check_mount(self.mount)

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def turns(self) -> np.ndarray:
        """(K,) device turn per posture, rad (zeros when none is turned)."""
        return self.device_turns if self.device_turns is not None else np.zeros(len(self.poses))

    def fingerprint(self) -> str:
        """First 8 hex digits of the sha256 of kinds, poses (to 1e-12) and device turns: names the postures."""
        text = ';'.join(
            f'{k}:' + ','.join(f'{v:.12e}' for v in pose) + (f'@{turn:.12e}' if turn else '')
            for k, pose, turn in zip(self.kinds, self.poses, self.turns)
        )
        return hashlib.sha256(text.encode()).hexdigest()[:8]

    def plan_file(self) -> PlanFile:
        """Return the plan-file contents: the metadata with the fingerprint, turns only where set."""
        return PlanFile(
            self.name,
            float(self.link_length),
            self.poses,
            tuple(self.kinds),
            self.model,
            self.mount,
            tuple(float(turn) if turn else None for turn in self.turns),
            dict(json_safe(self.metadata), fingerprint=self.fingerprint()),
        )

    def to_text(self) -> str:
        """Return the plan file's text (hexacal_msgs_py.plan_file)."""
        return plan_file_text(self.plan_file())

    def save(self, path: Path | str) -> Path:
        """Write atomically (temporary file in the same directory, fsync, rename)."""
        return write_plan_file(path, self.plan_file())

    @classmethod
    def load(cls, path: Path | str) -> 'Plan':
        """Read a plan file (hexacal_msgs_py.plan_file.read_plan_file; PlanError is a ValueError)."""
        contents = read_plan_file(path)
        metadata = dict(contents.metadata or {})
        metadata.pop('fingerprint', None)
        return cls(
            contents.name,
            contents.link_length,
            contents.poses.copy(),
            np.array(contents.kinds),
            metadata,
            contents.model,
            contents.mount,
            np.array([contents.device_turn(i) for i in range(len(contents))]),
        )


@dataclass
class PlanningResult:
    plan: Plan
    candidates: CandidateSet
    design: np.ndarray  # candidate indices, in plan order
    selection_order: np.ndarray  # the same indices in the order greedy / exchange chose them
    indices: dict[
        str, float
    ]  # O1..O4 of the plan, and I: its predicted RMS position error (see CandidateSet)
    rank: int  # of its identification Jacobian: below the model's parameter count every index is 0
    greedy_history: list[float]
    exchange_history: list[float]
    candidate_seconds: float
    selection_seconds: float

    def random_indices(self, draws: int = 20, seed: int = 0) -> dict[str, float]:
        """Mean O1..O4 and I of random plans of the same size and kind mix from the same candidates."""
        rng = np.random.default_rng(seed)
        kinds = self.candidates.kinds
        counts = {k: int(np.sum(self.plan.kinds == k)) for k in POSTURE_KINDS}
        designs = [
            np.concatenate(
                [
                    rng.choice(np.flatnonzero(kinds == k), c, replace=False)
                    for k, c in counts.items()
                    if c
                ]
            )
            for _ in range(draws)
        ]
        values = [self.candidates.indices(design) for design in designs]
        errors = [self.candidates.predicted_position_error(d) for d in designs]
        means = {name: float(np.mean([v[name] for v in values])) for name in INDICES}
        means[PREDICTION] = float(np.mean(errors))
        return means


def plan_postures(
    nominal: KinematicParameters,
    n_postures: int,
    *,
    index: str = 'O1',
    method: str = 'greedy',
    n_candidates: int = 2000,
    cost: str = 'absolute',
    limits: PostureLimits | None = None,
    fixed_fraction: float | None = None,
    seed: int = 0,
    sigma: ChannelSigma = ChannelSigma(),
    noise: NoiseModel | None = None,
    name: str | None = None,
    progress: Progress = _quiet,
    device_columns: tuple[str, ...] = (),
    device_prior: DevicePrior = DevicePrior(),
    device_turns: tuple[float, ...] = (0.0,),
) -> PlanningResult:
    """Candidates -> Jacobian rows at ``nominal`` -> greedy (and exchange) selection -> ordered Plan.

    ``nominal`` names its architecture; ``limits`` None = ``PostureLimits.for_machine(nominal)``.
    ``device_columns`` / ``device_prior``: device parameters identified with the machine (module doc);
    ``device_turns``: the mountings of a turning procedure, each sphere candidate offered in each.
    """
    _check_index(index)
    if limits is None:
        limits = PostureLimits.for_machine(nominal)
    if method not in METHODS:
        raise ValueError(f'unknown planning method {method!r}; choose one of {", ".join(METHODS)}')
    if n_postures < 1:
        raise ValueError(f'--postures must be positive, got {n_postures}')
    if n_candidates < n_postures:
        raise ValueError(
            f'need at least as many candidates ({n_candidates}) as postures ({n_postures})'
        )
    started = time.perf_counter()
    fraction = default_fixed_fraction(cost) if fixed_fraction is None else fixed_fraction
    device = limits.device()
    rng = np.random.default_rng([seed, 0x91A4])
    poses, kinds = generate_candidates(nominal, n_candidates, rng, limits, fraction)
    turns = None
    if len(device_turns) > 1 or any(device_turns):  # every sphere candidate in every mounting
        sphere = kinds == SPHERE
        turns = np.concatenate(
            [
                np.repeat(np.asarray(device_turns, float), int(sphere.sum())),
                np.zeros(int((~sphere).sum())),
            ]
        )
        poses = np.concatenate([np.tile(poses[sphere], (len(device_turns), 1)), poses[~sphere]])
        kinds = np.concatenate([np.tile(kinds[sphere], len(device_turns)), kinds[~sphere]])
    progress(f'{len(poses)} candidates')
    candidates = build_candidate_set(
        nominal,
        poses,
        kinds,
        cost,
        device,
        sigma,
        noise,
        tuple(device_columns),
        device_prior,
        turns,
    )
    candidate_seconds = time.perf_counter() - started
    started = time.perf_counter()
    kind_counts = None
    if (
        cost == 'relative'
    ):  # the paper's 3 sphere : 1 fixed (60 + 20, 30 + 10), as study.posture_split
        fixed = max(n_postures // 4, 1) if np.any(kinds == FIXED) else 0
        kind_counts = {SPHERE: n_postures - fixed, FIXED: fixed}
    design, greedy_history = greedy_design(candidates, n_postures, index, progress, kind_counts)
    exchange_history: list[float] = []
    if method == 'exchange':
        design, exchange_history = exchange_design(candidates, design, index, progress=progress)
    selection_seconds = time.perf_counter() - started
    selection_order = design.copy()
    order = _turn_order(
        turns,
        design,
        travel_order(
            poses[design],
            kinds[design],
            limits.link_length,
            keep_order_within_kind=cost == 'relative',
        ),
    )
    design = design[order]
    indices = candidates.indices(design)
    indices[PREDICTION] = candidates.predicted_position_error(design)
    rank = candidates.rank(design)
    actuator = nominal.layout.actuator_prefix
    weighting = (
        'none'
        if noise is None
        else f'noise {actuator} {noise.slider_m:g} m, angles {noise.angle_rad:g} rad'
    )
    metadata = {
        'planner': 'hexacal plan',
        'model': nominal.model,
        'index': index,
        'index_value': indices[index],
        'rank': rank,
        'method': method,
        'cost': cost,
        'weighting': weighting,
        'candidates': int(len(poses)),
        'seed': int(seed),
        'nominal_fingerprint': hashlib.sha256(np.round(nominal.vector, 12).tobytes()).hexdigest()[
            :16
        ],
        'limits': limits.to_json(),
    }
    if turns is not None or candidates.device_columns:
        metadata.update(
            device_columns=list(candidates.device_columns),
            device_turns=list(device_turns),
            device_prior={n: {'value': v, 'std': sd} for n, v, sd in device_prior.entries},
        )
    plan = Plan(
        name or 'plan',
        limits.link_length,
        poses[design],
        kinds[design],
        metadata,
        nominal.model,
        limits.mount,
        None if turns is None else turns[design],
    )
    if name is None:  # default name: what it is and which postures
        plan.name = f'{method}-{index}-{n_postures}-{plan.fingerprint()}'
    return PlanningResult(
        plan,
        candidates,
        design,
        selection_order,
        indices,
        rank,
        greedy_history,
        exchange_history,
        candidate_seconds,
        selection_seconds,
    )


__all__ = [
    'CRITERIA',
    'INDICES',
    'InfeasibleLimitsError',
    'METHODS',
    'PLAN_MODEL_KEY',
    'PLAN_MOUNT_KEY',
    'PREDICTION',
    'CandidateSet',
    'Plan',
    'PlanningResult',
    'PostureLimits',
    'build_candidate_set',
    'default_fixed_fraction',
    'exchange_design',
    'generate_candidates',
    'greedy_design',
    'observability_index',
    'observability_indices',
    'plan_postures',
    'travel_order',
]
