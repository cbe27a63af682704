"""
Posture plans: which postures the simulated machine visits, in which order (ROS-free).

A plan is a list of platform poses ``[x, y, z, theta, psi, phi]`` (m, rad, the
paper's eq. 1), each of one kind:

* ``sphere``: the measuring link is free, so the platform lies on the sphere of
  radius L (the link length) below the base joint O;
* ``fixed``: the inclinometer reads zero, so the platform sits at ``[0, 0, -L]``
  and only its orientation varies (section 3.2's second procedure).

With the device mount ``standing`` (core/machine/device.py: an upright machine, the
platform above the device's base joint) sphere postures lie on the upper half
of the sphere and the fixed position is ``[0, 0, +L]``.

The plan file format (YAML, SI units; an optional ``device_turn`` per posture,
rad: the device turned about its link axis while the driver walks that posture,
else the driver's ``device_turn`` parameter) is read and written by
hexacal_msgs_py.plan_file, its one owner; `PosturePlan` adds the checks that
need the device model.

`load_plan` checks everything it can without a machine model and raises
`PlanError` naming the file, the posture and the problem; `check_reachable`
then checks a plan against a machine's parameters, and `resolve_plan` refuses a
plan made for another model or device mount than the driver's. Plans are the same for every
architecture (poses of the platform); generated plans draw their poses in the
architecture's default workspace (Hexa Slide: the paper's; Gough-Stewart: a
smaller one, legs within their stroke) and a plan is reachable when every
actuator of that machine stays within the workspace's stroke.
"""

from __future__ import annotations

from dataclasses import replace
import math
import os

from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.errors import UnreachablePoseError
from hexacal_identify.core.machine.device import (
    DEFAULT_LINK_LENGTH_M,
    DEFAULT_MOUNT,
    fixed_point,
    inclinometer_angles,
)
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.measurements import FIXED, MeasurementLimits, SPHERE
from hexacal_identify.core.machine.postures import sample_poses, Workspace
from hexacal_msgs_py.plan_file import (
    plan_document,
    PlanError,
    PlanFile,
    read_plan_file,
    write_plan_file,
)
import numpy as np

RANDOM_PLAN = 'random'  # sphere postures only
FIXED_PLAN = 'fixed'  # fixed-position postures only
MIXED_PLAN = 'mixed'  # 3 sphere : 1 fixed, interleaved
GENERATED_PLANS = (RANDOM_PLAN, FIXED_PLAN, MIXED_PLAN)

# A posture of a plan file must be on the link sphere (or at [0, 0, -L]) to within this:
# the device makes any other position physically impossible. Files written by save_plan
# (repr floats) are exact.
POSITION_TOLERANCE_M = 1e-6
MAX_TILT_RAD = math.pi / 2  # |theta|, |psi|: beyond this the Euler angles are ambiguous
_LIMITS = MeasurementLimits()

__all__ = [
    'check_reachable',
    'generated_plan',
    'GENERATED_PLANS',
    'load_plan',
    'machine_workspace',
    'plan_document',
    'PlanError',
    'PosturePlan',
    'resolve_plan',
    'save_plan',
]


class PosturePlan(PlanFile):
    """
    A plan file's postures where the device lets the platform stand (hexacal_msgs_py.plan_file).

    Beyond the format's checks: sphere postures on the link sphere on the mount's side of O
    within the inclinometer's range, fixed ones at the fixed-position point, tilts within
    +-pi/2 and phi within the rotary sensor's range.
    """

    def posture_problem(self, pose: np.ndarray, kind: str) -> str | None:
        """Return what is wrong with a finite pose of a known kind on this device, or None."""
        return _posture_problem(pose, kind, float(self.link_length), _LIMITS, self.mount)


def _posture_problem(
    pose: np.ndarray,
    kind: str,
    link_length: float,
    limits: MeasurementLimits,
    mount: str = DEFAULT_MOUNT,
) -> str | None:
    """Return where the device makes `pose` impossible, or None (kind and finiteness checked)."""
    position = pose[:3]
    side = 1.0 if mount == DEFAULT_MOUNT else -1.0  # hanging: below O (z < 0); standing: above
    if kind == FIXED:
        offset = float(np.linalg.norm(position - fixed_point(link_length, mount)))
        if offset > POSITION_TOLERANCE_M:
            sign = '-' if side > 0 else ''
            return (
                f'a fixed posture must be at [0, 0, {sign}{link_length:g}] m, got '
                f'{position.tolist()} ({offset:.3g} m away)'
            )
    else:
        radius = float(np.linalg.norm(position))
        if side * position[2] >= 0 or abs(radius - link_length) > POSITION_TOLERANCE_M:
            horizontal = float(position[0] ** 2 + position[1] ** 2)
            expected = (
                f'z = {-side * math.sqrt(link_length**2 - horizontal)!r} for this x, y'
                if horizontal < link_length**2
                else 'x^2 + y^2 < L^2'
            )
            where = 'below' if side > 0 else 'above'
            return (
                f'a sphere posture must lie on the link sphere |p| = {link_length:g} m '
                f'{where} O ({expected}), got |p| = {radius!r} m, z = {position[2]!r} m'
            )
        alpha, beta = inclinometer_angles(position[None], mount)
        tilt = max(abs(float(alpha[0])), abs(float(beta[0])))
        if tilt > limits.inclinometer_range_rad:
            return (
                f'inclinometer angle {math.degrees(tilt):.1f} deg is beyond its range of '
                f'+-{math.degrees(limits.inclinometer_range_rad):.0f} deg'
            )
    theta, psi, phi = pose[3:]
    if max(abs(theta), abs(psi)) >= MAX_TILT_RAD:
        return f'theta and psi must be within +-pi/2 rad, got {theta!r}, {psi!r}'
    if abs(phi) > limits.rotary_range_rad:
        return f'phi must be within +-pi rad (rotary sensor range), got {phi!r}'
    return None


# --------------------------------------------------------------------------- generated plans


def machine_workspace(
    params: KinematicParameters,
    link_length: float = DEFAULT_LINK_LENGTH_M,
    mount: str = DEFAULT_MOUNT,
) -> Workspace:
    """
    Return the workspace plans are drawn and checked in.

    The architecture's default, with this link length (and device mount; the Workspace's
    default, hanging, is left as it is).
    """
    workspace = replace(params.architecture.default_workspace(), link_length=float(link_length))
    if mount != DEFAULT_MOUNT:
        workspace = replace(workspace, mount=mount)
    return workspace


def generated_plan(
    which: str,
    params: KinematicParameters,
    count: int,
    seed: int,
    link_length: float = DEFAULT_LINK_LENGTH_M,
    mount: str = DEFAULT_MOUNT,
) -> PosturePlan:
    """
    'random' (sphere), 'fixed' or 'mixed' (3 sphere : 1 fixed) postures drawn with `seed`.

    Poses come from the architecture's default workspace (machine_workspace) on the
    device mount's side of O.
    """
    if which not in GENERATED_PLANS:
        raise PlanError(
            f'plan must be one of {list(GENERATED_PLANS)} or a plan file, got {which!r}'
        )
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise PlanError(f'the number of postures must be a positive integer, got {count!r}')
    if which == MIXED_PLAN:
        fixed_count = count // 4
        counts = {SPHERE: count - fixed_count, FIXED: fixed_count}
    else:
        counts = {
            SPHERE: count if which == RANDOM_PLAN else 0,
            FIXED: count if which == FIXED_PLAN else 0,
        }
    rng = np.random.default_rng([int(seed), 0x9A7])
    workspace = machine_workspace(params, link_length, mount)
    try:
        drawn = {
            kind: list(sample_poses(params, n, rng, kind, workspace)) if n else []
            for kind, n in counts.items()
        }
    except RuntimeError as error:  # sample_poses: this machine has too few acceptable poses
        raise PlanError(f'cannot draw a {which} plan of {count} postures: {error}') from error
    poses, kinds = [], []
    for index in range(count):
        # Every fourth posture is a fixed one while there are some left: S S S F S S S F ...
        kind = FIXED if (index % 4 == 3 and drawn[FIXED]) or not drawn[SPHERE] else SPHERE
        poses.append(drawn[kind].pop(0))
        kinds.append(kind)
    return PosturePlan(
        f'{which}-{count}-seed{seed}',
        float(link_length),
        np.array(poses),
        tuple(kinds),
        params.model,
        mount,
    )


# --------------------------------------------------------------------------- plan files


def load_plan(path: str | os.PathLike[str]) -> PosturePlan:
    """Read and check a plan file; PlanError names the file and the problem."""
    return read_plan_file(path, PosturePlan)


def save_plan(path: str | os.PathLike[str], plan: PlanFile) -> None:
    """Write a plan file that load_plan reads back exactly (repr floats)."""
    write_plan_file(path, plan)


# --------------------------------------------------------------------------- against a machine


def check_reachable(
    plan: PosturePlan, params: KinematicParameters, workspace: Workspace | None = None
) -> np.ndarray:
    """
    Return the actuator readings (N, 6) of every posture; PlanError if one is out of reach.

    Out of reach: a chain cannot close (Hexa Slide: a leg cannot reach its rail), or an
    actuator is outside the stroke of `workspace` (default: the architecture's default
    workspace, whose stroke is the machine's).
    """
    architecture = params.architecture
    if workspace is None:
        workspace = architecture.default_workspace()
    try:
        actuators = inverse_kinematics(params, plan.poses)
    except UnreachablePoseError as error:
        indices = [int(i) for i in error.indices[:10]]
        raise PlanError(
            f"plan '{plan.name}': posture(s) {indices} cannot be reached by this "
            f'machine ({architecture.unreachable_reason})'
        ) from error
    low, high = workspace.actuator_stroke_m
    outside = np.flatnonzero(np.any((actuators < low) | (actuators > high), axis=1))
    if outside.size:
        actuator, unit = architecture.layout.actuator_prefix, architecture.layout.actuator_unit
        raise PlanError(
            f"plan '{plan.name}': posture(s) {outside[:10].tolist()} need a {actuator} "
            f'outside the stroke [{low:g}, {high:g}] {unit}'
        )
    return actuators


def resolve_plan(
    spec: str,
    params: KinematicParameters,
    count: int,
    seed: int,
    link_length: float = DEFAULT_LINK_LENGTH_M,
    mount: str = DEFAULT_MOUNT,
) -> PosturePlan:
    """
    Return the plan of the driver's `plan` parameter: a generated plan's name or a file path.

    A plan file's link length must match the device's, its model the machine's and its
    mount the device's; the plan must be reachable.
    """
    if spec in GENERATED_PLANS:
        plan = generated_plan(spec, params, count, seed, link_length, mount)
    else:
        if not spec:
            raise PlanError(f'plan must be one of {list(GENERATED_PLANS)} or a plan file path')
        plan = load_plan(spec)
        if not math.isclose(plan.link_length, link_length, rel_tol=0.0, abs_tol=1e-9):
            raise PlanError(
                f'{spec}: plan.link_length {plan.link_length!r} m differs from the '
                f"device's link length {link_length!r} m"
            )
        if plan.model != params.model:
            raise PlanError(
                f'{spec}: the plan was made for a {plan.model} (plan.model; absent: '
                f'hexa_slide) but the machine is a {params.model}'
            )
        if plan.mount != mount:
            raise PlanError(
                f'{spec}: the plan is for a {plan.mount} device (plan.mount) but the '
                f'device is {mount}'
            )
    check_reachable(plan, params, machine_workspace(params, link_length, mount))
    return plan
