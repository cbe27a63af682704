"""Posture plans: which postures the simulated machine visits, in which order (ROS-free).

A plan is a list of platform poses ``[x, y, z, theta, psi, phi]`` (m, rad, the
paper's eq. 1), each of one kind:

* ``sphere``: the measuring link is free, so the platform lies on the sphere of
  radius L (the link length) below the base joint O;
* ``fixed``: the inclinometer reads zero, so the platform sits at ``[0, 0, -L]``
  and only its orientation varies (section 3.2's second procedure).

With the device mount ``standing`` (core/device.py: an upright machine, the
platform above the device's base joint) sphere postures lie on the upper half
of the sphere and the fixed position is ``[0, 0, +L]``.

Plan file (YAML, SI units)::

    plan:
      name: my-plan
      link_length: 0.75
      model: gough_stewart   # optional: the machine model planned for (absent: hexa_slide)
      mount: standing        # optional: the device mount (absent: hanging)
    postures:
      - {kind: sphere, pose: [0.1, -0.2, -0.7141428428542851, 0.1, 0.0, -0.2]}
      - {kind: fixed,  pose: [0.0, 0.0, -0.75, 0.3, -0.1, 0.25]}
      - {kind: sphere, pose: [0.1, -0.2, -0.7141428428542851, 0.1, 0.0, -0.2], device_turn: 3.141592653589793}

A posture may name the device's turn about its link axis, ``device_turn`` (rad:
0 the normal mounting, pi reversed, pi/2 a quarter turn; |turn| <= 2 pi): the
simulated device is turned to it while the driver walks that posture. A
posture without it takes the driver's ``device_turn`` parameter, so every plan
file written before turns existed walks as before.

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

from dataclasses import dataclass, replace
import json
import math
import os
from typing import Any

from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.device import (
    DEFAULT_LINK_LENGTH_M,
    DEFAULT_MOUNT,
    fixed_point,
    inclinometer_angles,
    MOUNTS,
)
from hexacal_identify.core.errors import UnreachablePoseError
from hexacal_identify.core.kinematics import inverse_kinematics
from hexacal_identify.core.measurements import FIXED, MeasurementLimits, POSTURE_KINDS, SPHERE
from hexacal_identify.core.postures import sample_poses, Workspace
from hexacal_msgs_py.files import atomic_write
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.parameters_file import read_yaml_document
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

_PLAN_KEYS = {'name', 'link_length'}  # required
_OPTIONAL_PLAN_KEYS = {
    'model',
    'mount',
}  # absent: the Hexa Slide, hanging (written only otherwise)
_POSTURE_KEYS = {'kind', 'pose'}
_OPTIONAL_POSTURE_KEYS = {'device_turn'}  # rad; absent: the driver's device_turn parameter
MAX_DEVICE_TURN_RAD = 2.0 * math.pi


class PlanError(ValueError):
    """A posture plan is invalid; the message names the file, the posture and the problem."""


@dataclass(frozen=True)
class PosturePlan:
    """An ordered list of postures; poses (N, 6) in m and rad, kinds (N,) 'sphere'/'fixed'.

    device_turns: per posture the device's turn about its link axis (rad) or None (the
    driver's device_turn parameter); () when no posture names one.
    """

    name: str
    link_length: float
    poses: np.ndarray
    kinds: tuple[str, ...]
    model: str = DEFAULT_MODEL  # the machine model the plan was made for
    mount: str = DEFAULT_MOUNT  # the device mount: hanging (platform below O) or standing
    device_turns: tuple[float | None, ...] = ()  # per posture, rad; None: the driver's parameter

    def __post_init__(self) -> None:
        poses = np.array(self.poses, dtype=float).reshape(-1, 6)
        poses.setflags(write=False)
        object.__setattr__(self, 'poses', poses)
        object.__setattr__(self, 'kinds', tuple(str(k) for k in self.kinds))
        turns = tuple(self.device_turns)
        if all(t is None for t in turns):
            turns = ()  # no posture names a turn: the same plan as one without turns
        object.__setattr__(self, 'device_turns', turns)
        problem = _plan_problem(self)
        if problem:
            raise PlanError(f'plan {self.name!r}: {problem}')

    def __len__(self) -> int:
        return len(self.poses)

    def device_turn(self, index: int, default: float = 0.0) -> float:
        """The device turn of posture `index` (rad): the plan's, else `default`."""
        if self.device_turns and self.device_turns[index] is not None:
            return float(self.device_turns[index])
        return float(default)

    def counts(self) -> dict[str, int]:
        """Number of postures of each kind."""
        return {kind: self.kinds.count(kind) for kind in POSTURE_KINDS}

    def describe(self) -> str:
        counts = self.counts()
        machine = '' if self.model == DEFAULT_MODEL else f', for a {self.model}'
        mount = '' if self.mount == DEFAULT_MOUNT else f', {self.mount} device'
        given = sum(t is not None for t in self.device_turns)
        turns = f', {given} with a device turn' if given else ''
        return (
            f"plan '{self.name}': {len(self)} postures ({counts[SPHERE]} sphere, "
            f'{counts[FIXED]} fixed), link length {self.link_length:g} m{machine}{mount}'
            f'{turns}'
        )


def _plan_problem(plan: PosturePlan) -> str | None:
    """What is wrong with a plan, or None (checks that need no machine model)."""
    if not isinstance(plan.name, str) or not plan.name.strip():
        return 'name must be a non-empty string'
    length = plan.link_length
    if (
        isinstance(length, bool)
        or not isinstance(length, (int, float, np.floating))
        or not math.isfinite(length)
        or length <= 0
    ):
        return f'link_length must be a positive number of m, got {length!r}'
    if len(plan.poses) == 0:
        return 'has no postures'
    if len(plan.kinds) != len(plan.poses):
        return f'{len(plan.poses)} poses but {len(plan.kinds)} kinds'
    if plan.model not in MODELS:
        return f'model must be one of {", ".join(MODELS)}, got {plan.model!r}'
    if plan.mount not in MOUNTS:
        return f'mount must be one of {", ".join(MOUNTS)}, got {plan.mount!r}'
    if plan.device_turns:
        if len(plan.device_turns) != len(plan.poses):
            return f'{len(plan.poses)} poses but {len(plan.device_turns)} device turns'
        for index, turn in enumerate(plan.device_turns):
            problem = _turn_problem(turn)
            if problem:
                return f'posture {index}: {problem}'
    limits = MeasurementLimits()
    for index, (pose, kind) in enumerate(zip(plan.poses, plan.kinds)):
        problem = _posture_problem(pose, kind, float(length), limits, plan.mount)
        if problem:
            return f'posture {index}: {problem}'
    return None


def _turn_problem(turn: object) -> str | None:
    """What is wrong with a posture's device_turn (None is fine: not given), or None."""
    if turn is None:
        return None
    if isinstance(turn, bool) or not isinstance(turn, (int, float, np.floating, np.integer)):
        return f'device_turn must be a number of rad, got {turn!r}'
    if not (math.isfinite(turn) and abs(turn) <= MAX_DEVICE_TURN_RAD):
        return f'device_turn must be a finite angle within +-2 pi rad, got {turn!r}'
    return None


def _posture_problem(
    pose: np.ndarray,
    kind: str,
    link_length: float,
    limits: MeasurementLimits,
    mount: str = DEFAULT_MOUNT,
) -> str | None:
    if kind not in POSTURE_KINDS:
        return f'kind must be one of {list(POSTURE_KINDS)}, got {kind!r}'
    if not np.all(np.isfinite(pose)):
        return f'pose must be finite, got {pose.tolist()}'
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
    """The workspace plans are drawn and checked in: the architecture's default, with this link
    length (and device mount; the Workspace's default, hanging, is left as it is)."""
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
    """'random' (sphere), 'fixed' or 'mixed' (3 sphere : 1 fixed) postures drawn with `seed`.

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
    name = os.fspath(path)

    def fail(message: str) -> PlanError:
        return PlanError(f'{name}: {message}')

    document = read_yaml_document(path, fail)
    if not isinstance(document, dict):
        raise fail("expected a mapping with keys 'plan' and 'postures'")
    unknown = sorted(set(map(str, document)) - {'plan', 'postures'})
    if unknown:
        raise fail(f"unknown top-level key(s) {unknown}; expected 'plan' and 'postures'")
    header = document.get('plan')
    if not isinstance(header, dict):
        raise fail("'plan' must be a mapping with 'name' and 'link_length'")
    unknown = sorted(set(map(str, header)) - _PLAN_KEYS - _OPTIONAL_PLAN_KEYS)
    if unknown:
        raise fail(
            f'unknown key(s) {unknown} in plan; expected {sorted(_PLAN_KEYS)} '
            f'(optional {sorted(_OPTIONAL_PLAN_KEYS)})'
        )
    for key in sorted(_PLAN_KEYS):
        if key not in header:
            raise fail(f'plan.{key} is missing')
    length = header['link_length']
    if isinstance(length, bool) or not isinstance(length, (int, float)):
        raise fail(f'plan.link_length must be a number of m, got {length!r}')
    entries = document.get('postures')
    if not isinstance(entries, list) or not entries:
        raise fail("'postures' must be a non-empty list of {kind, pose} entries")
    poses, kinds, turns = [], [], []
    for index, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise fail(f'posture {index}: expected a mapping with kind and pose, got {entry!r}')
        unknown = sorted(set(map(str, entry)) - _POSTURE_KEYS - _OPTIONAL_POSTURE_KEYS)
        missing = sorted(_POSTURE_KEYS - set(entry))
        if unknown or missing:
            raise fail(
                f'posture {index}: keys must be {sorted(_POSTURE_KEYS)}'
                + (f', unknown {unknown}' if unknown else '')
                + (f', missing {missing}' if missing else '')
                + f' (optional {sorted(_OPTIONAL_POSTURE_KEYS)})'
            )
        turn = entry.get('device_turn')
        problem = _turn_problem(turn) if 'device_turn' in entry else None
        if 'device_turn' in entry and turn is None:
            problem = 'device_turn must be a number of rad, got null'
        if problem:
            raise fail(f'posture {index}: {problem}')
        turns.append(None if turn is None else float(turn))
        pose = entry['pose']
        if (
            not isinstance(pose, list)
            or len(pose) != 6
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pose)
        ):
            raise fail(
                f'posture {index}: pose must be 6 numbers [x, y, z, theta, psi, phi] '
                f'(m, rad), got {pose!r}'
            )
        poses.append([float(v) for v in pose])
        kinds.append(entry['kind'])
    model = header.get('model', DEFAULT_MODEL)
    if not isinstance(model, str) or model not in MODELS:
        raise fail(f'plan.model must be one of {", ".join(MODELS)}, got {model!r}')
    mount = header.get('mount', DEFAULT_MOUNT)
    if not isinstance(mount, str) or mount not in MOUNTS:
        raise fail(f'plan.mount must be one of {", ".join(MOUNTS)}, got {mount!r}')
    try:
        return PosturePlan(
            header['name'],
            float(length),
            np.array(poses),
            tuple(kinds),
            model,
            mount,
            tuple(turns),
        )
    except PlanError as error:
        raise fail(str(error)) from None


def plan_document(plan: PosturePlan) -> dict[str, Any]:
    """The plan-file mapping of a plan (floats as Python floats)."""
    header: dict[str, Any] = {'name': plan.name, 'link_length': float(plan.link_length)}
    if plan.model != DEFAULT_MODEL:  # as in parameters files: absent = a Hexa Slide
        header['model'] = plan.model
    if plan.mount != DEFAULT_MOUNT:
        header['mount'] = plan.mount
    postures: list[dict[str, Any]] = []
    for index, (kind, pose) in enumerate(zip(plan.kinds, plan.poses)):
        entry: dict[str, Any] = {'kind': kind, 'pose': [float(v) for v in pose]}
        if plan.device_turns and plan.device_turns[index] is not None:
            entry['device_turn'] = float(plan.device_turns[index])
        postures.append(entry)
    return {'plan': header, 'postures': postures}


def save_plan(path: str | os.PathLike[str], plan: PosturePlan) -> None:
    """Write a plan file that load_plan reads back exactly (repr floats)."""
    lines = [
        'plan:',
        f'  name: {json.dumps(plan.name)}',
        f'  link_length: {float(plan.link_length)!r}',
    ]
    if plan.model != DEFAULT_MODEL:  # Hexa Slide plan files stay as they were
        lines.append(f'  model: {plan.model}')
    if plan.mount != DEFAULT_MOUNT:
        lines.append(f'  mount: {plan.mount}')
    lines.append('postures:')
    for index, (kind, pose) in enumerate(zip(plan.kinds, plan.poses)):
        values = ', '.join(repr(float(v)) for v in pose)
        turn = (
            f', device_turn: {float(plan.device_turns[index])!r}'
            if plan.device_turns and plan.device_turns[index] is not None
            else ''
        )
        lines.append(f'  - {{kind: {kind}, pose: [{values}]{turn}}}')
    atomic_write(path, '\n'.join(lines) + '\n')


# --------------------------------------------------------------------------- against a machine


def check_reachable(
    plan: PosturePlan, params: KinematicParameters, workspace: Workspace | None = None
) -> np.ndarray:
    """Actuator readings (N, 6) of every posture on `params`; PlanError if a posture is out of reach.

    Out of reach: a chain cannot close (Hexa Slide: a leg cannot reach its rail), or an
    actuator is outside the stroke of `workspace` (default: the architecture's default
    workspace, whose stroke is the machine's).
    """
    architecture = params.architecture
    if workspace is None:
        workspace = architecture.default_workspace()
    try:
        sliders = inverse_kinematics(params, plan.poses)
    except UnreachablePoseError as error:
        indices = [int(i) for i in error.indices[:10]]
        raise PlanError(
            f"plan '{plan.name}': posture(s) {indices} cannot be reached by this "
            f'machine ({architecture.unreachable_reason})'
        ) from error
    low, high = workspace.slider_stroke_m
    outside = np.flatnonzero(np.any((sliders < low) | (sliders > high), axis=1))
    if outside.size:
        actuator = architecture.layout.actuator_prefix
        raise PlanError(
            f"plan '{plan.name}': posture(s) {outside[:10].tolist()} need a {actuator} "
            f'outside the stroke [{low:g}, {high:g}] m'
        )
    return sliders


def resolve_plan(
    spec: str,
    params: KinematicParameters,
    count: int,
    seed: int,
    link_length: float = DEFAULT_LINK_LENGTH_M,
    mount: str = DEFAULT_MOUNT,
) -> PosturePlan:
    """A plan from the driver's `plan` parameter: a generated plan's name or a plan-file path.

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
