"""
The calibrated model at work.

The pose of live actuator readings, actuator targets of a commanded pose.

What the ``kinematics`` node and ``hexacal ik`` / ``hexacal fk`` share (ROS-free):

* ``home_pose``: where a solve starts when nothing better is known - the
  workspace centre, the device's fixed point (``[0, 0, -L]`` hanging,
  ``[0, 0, +L]`` standing) with the platform level and phi = 0;
* ``solve_pose``: forward kinematics of one set of readings.  Newton from the
  guess first (the previous pose, while tracking a moving machine); when it
  does not converge near the guess, a continuation: the readings are moved
  from those of the guess to the target in steps, each solved from the last,
  so the solution found is the assembly mode connected to the guess (the
  working mode when the guess is the home pose) and never another branch;
* ``actuator_targets``: inverse kinematics of a commanded pose, refused when a
  leg cannot reach it (``UnreachablePoseError``) or a reading would leave the
  stroke (``OutOfStrokeError``, naming the actuators).

A calibration with axial compliances (core/fit/compliance.py) is used with ``LoadedChains``:
in operation the measuring link is off and the six chains carry the weights (core/fit/statics.py,
the lvdt statics without a link), so an encoder reads the joint coordinate plus
``c_c q_c(X)``.  ``solve_pose`` then solves the pose of the readings minus that shift (a few
fixed-point steps: the shift depends on the pose only through the loads) and
``actuator_targets`` commands the encoders where the loaded joints reach the pose.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from .device import DEFAULT_LINK_LENGTH_M, DEFAULT_MOUNT, fixed_point
from .kinematics import forward_kinematics, inverse_kinematics
from ..architectures import KinematicParameters
from ..errors import ForwardKinematicsError, UnreachablePoseError
from ..fit.statics import MassModel, static_loads

MIN_CONTINUATION_STEP = 1.0 / 512  # of the way from the guess's readings to the target's
LOADED_STEPS = 4  # fixed-point steps of a loaded pose: the shift's pose dependence is ~1e-5


@dataclass(frozen=True)
class LoadedChains:
    """The chains' axial compliances (m/N) and the weights that load them in operation."""

    compliances: tuple[float, ...]  # six, chain order
    masses: MassModel

    def __post_init__(self) -> None:
        values = np.asarray(self.compliances, dtype=float)
        if values.shape != (6,) or not np.all(np.isfinite(values)):
            raise ValueError(
                f'six finite chain compliances (m/N) expected, got {self.compliances}'
            )
        object.__setattr__(self, 'compliances', tuple(float(v) for v in values))
        # In operation the measuring link is off the machine.
        object.__setattr__(self, 'masses', replace(self.masses, link_mass=0.0))

    @classmethod
    def from_file_values(
        cls, values: Mapping[str, float], masses: MassModel
    ) -> 'LoadedChains | None':
        """Return the chains of a parameters file's compliance section (None: rigid, none)."""
        if 'chains' in values:
            chains = [values['chains']] * 6
        else:
            chains = [values.get(f'chain_{c}', 0.0) for c in range(1, 7)]
        if not any(chains):
            return None
        return cls(tuple(chains), masses)

    def shifts(self, params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
        """Return encoder minus joint coordinate (N, 6), m, at ``poses``."""
        loads = static_loads(params, poses, self.masses, 'lvdt')
        return loads.reading_loads * np.asarray(self.compliances)


class OutOfStrokeError(UnreachablePoseError):
    """A commanded pose needs an actuator reading outside the stroke limits."""

    reason = 'outside-stroke'


def home_pose(
    link_length: float = DEFAULT_LINK_LENGTH_M, mount: str = DEFAULT_MOUNT
) -> np.ndarray:
    """
    Return the workspace centre [x, y, z, theta, psi, phi].

    The device's fixed point, platform level, phi 0.
    """
    return np.concatenate([fixed_point(link_length, mount), np.zeros(3)])


def default_stroke(params: KinematicParameters) -> tuple[float, float]:
    """Return the architecture's actuator stroke of its default workspace (m, or rad: its unit)."""
    low, high = params.architecture.default_workspace().actuator_stroke_m
    return float(low), float(high)


def actuator_targets(
    params: KinematicParameters,
    pose: Sequence[float],
    stroke: tuple[float, float] | None = None,
    loaded: LoadedChains | None = None,
) -> np.ndarray:
    """
    Return the six actuator readings that put the platform at ``pose``.

    The six actuator readings (SI: the layout's actuator_unit, m or rad) that put the platform
    at ``pose``, inside ``stroke`` (None: the architecture's default). UnreachablePoseError /
    OutOfStrokeError say why a pose is refused. With ``loaded`` the encoders' readings at which
    the loaded chains reach it (module doc).
    """
    poses = np.asarray(pose, dtype=float).reshape(1, 6)
    targets = inverse_kinematics(params, poses)[0]
    if loaded is not None:
        targets = targets + loaded.shifts(params, poses)[0]
    low, high = default_stroke(params) if stroke is None else stroke
    outside = np.flatnonzero((targets < low) | (targets > high))
    if outside.size:
        names, unit = params.layout.actuator_names, params.layout.actuator_unit
        detail = ', '.join(f'{names[i]} {targets[i]:.6f} {unit}' for i in outside)
        raise OutOfStrokeError(
            f'outside the stroke [{low:g}, {high:g}] {unit}: {detail}', outside.tolist()
        )
    return targets


def solve_pose(
    params: KinematicParameters,
    actuators: Sequence[float] | np.ndarray,
    guess: Sequence[float] | np.ndarray,
    loaded: LoadedChains | None = None,
) -> np.ndarray:
    """
    Return the pose (6,) of the readings ``actuators`` (6,).

    The pose (6,) of the readings ``actuators`` (6,), on the branch of ``guess`` (see the module
    doc); with ``loaded``, of the joint coordinates under the weights (module doc).

    ForwardKinematicsError when neither Newton from the guess nor the continuation converges.
    """
    pose = _solve_rigid_pose(params, actuators, guess)
    if loaded is None:
        return pose
    readings = np.asarray(actuators, dtype=float).reshape(6)
    for _ in range(LOADED_STEPS):
        joints = readings - loaded.shifts(params, pose[None])[0]
        pose = _solve_rigid_pose(params, joints, pose)
    return pose


def _solve_rigid_pose(
    params: KinematicParameters,
    actuators: Sequence[float] | np.ndarray,
    guess: Sequence[float] | np.ndarray,
) -> np.ndarray:
    """Return the pose of joint coordinates ``actuators`` (solve_pose without loads)."""
    target = np.asarray(actuators, dtype=float).reshape(6)
    start = np.asarray(guess, dtype=float).reshape(6)
    result = forward_kinematics(params, target[None], start[None])
    if result.converged[0]:
        return result.poses[0]
    direct = result.failures.get(0, 'no convergence')
    if not np.all(np.isfinite(target)):
        raise ForwardKinematicsError(f'non-finite actuator readings {target.tolist()}', [0])
    try:
        start_readings = inverse_kinematics(params, start[None])[0]
    except UnreachablePoseError as error:
        raise ForwardKinematicsError(
            f'{direct}; the guess itself is unreachable ({error})', [0]
        ) from None
    pose, done, step = start, 0.0, 1.0
    while done < 1.0:
        step = min(step, 1.0 - done)
        readings = start_readings + (done + step) * (target - start_readings)
        result = forward_kinematics(params, readings[None], pose[None])
        if result.converged[0]:
            pose, done, step = result.poses[0], done + step, 2.0 * step
            continue
        step /= 2.0
        if step < MIN_CONTINUATION_STEP:
            raise ForwardKinematicsError(
                f"no pose on the guess's branch: Newton from the guess: {direct}; "
                f"the continuation from the guess's readings stopped {100.0 * done:.1f}% "
                f'of the way ({result.failures.get(0, "")})',
                [0],
            )
    return pose
