"""
Draw the candidate postures of a plan within the limits every planned posture respects.

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
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, cast

import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import check_mount, DeviceModel, fixed_point, inclinometer_angles, sphere_z
from ..machine.measurements import FIXED, SPHERE
from ..machine.postures import Workspace

# The dataclass defaults: section 4's workspace (the Hexa Slide's default).
_PAPER_WORKSPACE = Workspace()


@dataclass(frozen=True)
class PostureLimits:
    """
    Everything a planned posture must respect (SI units; module doc).

    The field defaults are ``postures.Workspace``'s (the paper's workspace) plus
    the device and joint limits; ``for_machine(params)`` takes the workspace of
    the nominal machine's architecture instead, which is what ``plan_postures``
    uses when it is given no limits.
    """

    link_length: float = _PAPER_WORKSPACE.link_length
    xy_range_m: float = float(_PAPER_WORKSPACE.xy_range_m)
    rotation_range_rad: float = float(_PAPER_WORKSPACE.rotation_range_rad)
    inclinometer_range_rad: float = float(np.radians(45.0))
    # Workspace's name for it: actuator_stroke_m.
    actuator_stroke_m: tuple[float, float] = _PAPER_WORKSPACE.actuator_stroke_m
    max_u_joint_angle_rad: float = float(np.radians(60.0))  # base-side passive joint
    max_s_joint_angle_rad: float = float(np.radians(90.0))  # platform-side spherical joint
    max_condition: float = float(_PAPER_WORKSPACE.max_condition)
    min_leg_cosine: float = float(
        _PAPER_WORKSPACE.min_joint_cosine
    )  # away from singular legs (architecture's)
    mount: str = (
        _PAPER_WORKSPACE.mount
    )  # the device's (device.py): hanging = postures below O, standing = above

    def __post_init__(self) -> None:
        check_mount(self.mount)

    @classmethod
    def from_workspace(cls, workspace: Workspace, **overrides) -> 'PostureLimits':
        """
        Return a workspace's limits, the device and joint limits at their defaults.

        ``overrides`` replace fields.
        """
        values: dict[str, Any] = {
            'link_length': float(workspace.link_length),
            'xy_range_m': float(workspace.xy_range_m),
            'rotation_range_rad': float(workspace.rotation_range_rad),
            'actuator_stroke_m': tuple(float(v) for v in workspace.actuator_stroke_m),
            'max_condition': float(workspace.max_condition),
            'min_leg_cosine': float(workspace.min_joint_cosine),
            'mount': workspace.mount,
        }
        values.update(overrides)
        return cls(**values)

    @classmethod
    def for_machine(cls, params: KinematicParameters, **overrides) -> 'PostureLimits':
        """Return the default limits for planning on ``params``: its architecture's workspace."""
        return cls.from_workspace(params.architecture.default_workspace(), **overrides)

    def device(self) -> DeviceModel:
        return DeviceModel(self.link_length, self.mount)

    def workspace(self) -> Workspace:
        return Workspace(
            self.link_length,
            self.xy_range_m,
            self.rotation_range_rad,
            cast(tuple[float, float], tuple(self.actuator_stroke_m)),
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
            # reachable, actuator stroke, singular legs and condition number, as the architecture
            # defines them
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
    """
    Return the share of fixed-position candidates: only where the cost function uses them.

    As study.posture_split.

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
    """
    Return n feasible candidate postures (poses (n, 6), kinds (n,)): sphere ones first.

    Then the fixed ones.

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
        else:
            # Bad input (limits that exclude the machine's workspace), not a failure: a ValueError.
            raise InfeasibleLimitsError(
                f'could not find {count} feasible {kind} postures within the limits: {found} of '
                f'{drawn} drawn were feasible for the {params.layout.title} with a {limits.mount} '
                'device (check the workspace, stroke and joint limits against the nominal machine)'
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
