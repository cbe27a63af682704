"""
Checking a posture plan before anything moves: targets, stroke, paths (ROS-free).

Every target of the plan is the inverse kinematics of its pose with the
*nominal* parameters (the only model a user has before calibrating).  A pose
the nominal machine cannot reach, an actuator outside the stroke limits, a
posture that is not where its kind says (a sphere posture off the link sphere,
a fixed-position posture away from the fixed point) or, with paths, a path
from the previous posture that cannot be commanded refuses the whole plan
(`PlanRefusedError`, listing the postures).  Chosen over skipping them: a plan
that needs a target outside the stroke was made for another machine or other
limits, and walking what remains of it would measure a different plan than the
one asked for.
"""

from __future__ import annotations

from collections.abc import Iterable
import math

import numpy as np

from ..architectures import KinematicParameters
from ..errors import CalibrationError
from ..machine.device import DEFAULT_MOUNT, fixed_point
from ..machine.measurements import FIXED, POSTURE_KINDS, SPHERE
from ..walk.platform_paths import PathError, route_command

POSITION_CHECK_M = 1e-6  # a plan posture's position must be where its kind says, to within this


class PlanRefusedError(CalibrationError, ValueError):
    """The plan has postures the executor will not command; `problems`: posture index -> why."""

    reason = 'plan-refused'

    def __init__(self, message: str, problems: dict[int, str]):
        super().__init__(message)
        self.problems = dict(problems)


def default_stroke(nominal: KinematicParameters) -> tuple[float, float]:
    """Return the actuator stroke of the nominal model's architecture (default workspace), m."""
    low, high = nominal.architecture.default_workspace().actuator_stroke_m
    return float(low), float(high)


def plan_stroke(metadata: dict, nominal: KinematicParameters) -> tuple[tuple[float, float], str]:
    """
    Return the stroke a plan was made within, and which one it is.

    ``hexacal plan`` records its limits in the plan's metadata
    (``limits.actuator_stroke_m``); without them, the nominal model's.
    """
    limits = metadata.get('limits') if isinstance(metadata, dict) else None
    if isinstance(limits, dict) and 'actuator_stroke_m' in limits:
        try:
            return check_stroke(list(limits['actuator_stroke_m'])), "the plan's limits"
        except (TypeError, ValueError):
            pass
    return default_stroke(nominal), f"the {nominal.model}'s default workspace"


def check_stroke(stroke: tuple[float, float] | list[float]) -> tuple[float, float]:
    """Return (low, high) with low < high, both finite; ValueError naming the problem."""
    values = list(stroke)
    if (
        len(values) != 2
        or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in values
        )
        or values[0] >= values[1]
    ):
        raise ValueError(
            f'stroke limits must be two finite numbers [low, high] with low < high (m), '
            f'got {values!r}'
        )
    return float(values[0]), float(values[1])


def plan_targets(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: Iterable[str],
    stroke: tuple[float, float],
    link_length: float,
    mount: str = DEFAULT_MOUNT,
) -> tuple[np.ndarray, dict[int, str]]:
    """
    Return the nominal actuator targets (N, 6) of every planned pose and each posture's problem.

    Problems map the index of each posture that cannot be commanded to why;
    its row is NaN where it has no targets.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    kinds = [str(kind) for kind in kinds]
    low, high = check_stroke(stroke)
    arch = nominal.architecture
    names = nominal.layout.actuator_names
    problems: dict[int, str] = {}
    targets = np.full((len(poses), 6), np.nan)
    finite = np.all(np.isfinite(poses), axis=1)
    for bad in np.flatnonzero(~finite):
        problems[int(bad)] = 'the pose is not finite'
    if finite.any():
        legs = arch.legs(arch.chains(nominal), np.where(finite[:, None], poses, 0.0))
        reachable = legs.reachable() & finite
        targets[reachable] = legs.actuators[reachable]
        for unreachable in np.flatnonzero(finite & ~reachable):
            problems[int(unreachable)] = (
                f'the nominal machine cannot reach it ({arch.unreachable_reason})'
            )
    point = fixed_point(link_length, mount)
    for index, (pose, kind) in enumerate(zip(poses, kinds)):
        if index in problems:
            continue
        if kind not in POSTURE_KINDS:
            problems[index] = f'kind {kind!r} is not one of {list(POSTURE_KINDS)}'
        elif kind == FIXED and np.linalg.norm(pose[:3] - point) > POSITION_CHECK_M:
            problems[index] = (
                f'a fixed-position posture must be at {point.tolist()} m, got {pose[:3].tolist()}'
            )
        elif kind == SPHERE and abs(np.linalg.norm(pose[:3]) - link_length) > POSITION_CHECK_M:
            problems[index] = (
                f'a sphere posture must be on the link sphere |p| = {link_length:g} m, '
                f'got |p| = {np.linalg.norm(pose[:3]):.9g} m'
            )
        else:
            unit = nominal.layout.actuator_unit
            outside = [
                f'{names[c]} {targets[index, c]:.4f} {unit}'
                for c in range(6)
                if not low <= targets[index, c] <= high
            ]
            if outside:
                problems[index] = (
                    f'target outside the stroke [{low:g}, {high:g}] {unit}: ' + ', '.join(outside)
                )
    return targets, problems


def path_problems(
    nominal: KinematicParameters,
    poses: np.ndarray,
    stroke: tuple[float, float],
    link_length: float,
    step_m: float,
    skip: Iterable[int] = frozenset(),
    mount: str = DEFAULT_MOUNT,
) -> dict[int, str]:
    """
    Return the postures whose path from the previous posture cannot be commanded, and why.

    The path goes along the link sphere, directly or by way of the centre
    (`route_command`); none is checked for step_m = 0 (one-point commands).
    """
    problems: dict[int, str] = {}
    if step_m <= 0:
        return problems
    skip = set(skip)
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    for index in range(1, len(poses)):
        if index in skip or index - 1 in skip:
            continue
        try:
            route_command(
                nominal,
                np.zeros(6),
                poses[index - 1],
                poses[index],
                stroke,
                1.0,
                link_length,
                step_m,
                mount,
            )
        except PathError as error:
            problems[index] = f'the path from posture {index}: {error}'
    return problems


def refusal_message(problems: dict[int, str], total: int, shown: int = 10) -> str:
    """Return one line naming the refused postures (1-based, as progress counts them) and why."""
    items = sorted(problems.items())
    listed = '; '.join(f'posture {index + 1}: {why}' for index, why in items[:shown])
    more = f'; ... and {len(items) - shown} more' if len(items) > shown else ''
    return (
        f'plan refused before anything moved: {len(items)} of {total} postures cannot be '
        f'commanded (postures {[index + 1 for index, _ in items]}): {listed}{more}'
    )


def plan_problems(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: Iterable[str],
    stroke: tuple[float, float],
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    path_step_m: float = 0.0,
) -> tuple[np.ndarray, dict[int, str]]:
    """
    Return the targets of every posture and the problem of each that cannot be commanded.

    With path_step_m > 0 also each whose path from the previous posture cannot.
    """
    targets, problems = plan_targets(nominal, poses, kinds, stroke, link_length, mount)
    problems.update(
        path_problems(nominal, poses, stroke, link_length, path_step_m, set(problems), mount)
    )
    return targets, problems


def check_plan(
    nominal: KinematicParameters,
    poses: np.ndarray,
    kinds: Iterable[str],
    stroke: tuple[float, float],
    link_length: float,
    mount: str = DEFAULT_MOUNT,
    path_step_m: float = 0.0,
) -> np.ndarray:
    """Return the targets of every posture, or raise PlanRefusedError listing each problem."""
    targets, problems = plan_problems(
        nominal, poses, kinds, stroke, link_length, mount, path_step_m
    )
    if problems:
        raise PlanRefusedError(refusal_message(problems, len(targets)), problems)
    return targets
