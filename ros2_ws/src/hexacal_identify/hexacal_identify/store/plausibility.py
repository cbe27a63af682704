"""
How far a calibration is from the active one: the largest parameter change and pose change.

The pose change is what a deploy does to the machine: at the actuator readings that put the
platform at poses of the architecture's default workspace with the active parameters, forward
kinematics with the new parameters gives other poses; the largest position difference (m) and
rotation difference (rad) over those poses.  numpy and the core are imported when a check runs.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Any

# Poses drawn from the default workspace (seeded: the same check gives the same figures).
POSE_SAMPLES = 64
POSE_SEED = 20
# A calibration of the same machine moves lengths by tens of um (bags/README.md); a wrong file,
# another machine or a nominal set moves them by millimetres.
DEFAULT_MAX_PARAMETER_CHANGE_M = 1e-3
DEFAULT_MAX_POSE_CHANGE_M = 0.5e-3
# The platform's orientation at the same readings: a recalibration turns it by ~0.1 mrad.
DEFAULT_MAX_ROTATION_CHANGE_RAD = 2e-3


@dataclass(frozen=True)
class Change:
    """The figures of one comparison (SI units); None when they cannot be computed."""

    previous_id: str
    same_model: bool
    parameter_change_m: float | None = None
    parameter_name: str | None = None
    pose_change_m: float | None = None
    rotation_change_rad: float | None = None
    poses: int = 0
    fk_failures: int = 0

    def to_json(self) -> dict[str, Any]:
        return {
            'previous_id': self.previous_id,
            'same_model': self.same_model,
            'parameter_change_m': _finite(self.parameter_change_m),
            'parameter_name': self.parameter_name,
            'pose_change_m': _finite(self.pose_change_m),
            'rotation_change_rad': _finite(self.rotation_change_rad),
            'poses': self.poses,
            'fk_failures': self.fk_failures,
        }


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def compare(previous_id: str, previous_file: Path, new_file: Path) -> Change:
    """Return the change from the parameters of `previous_file` to those of `new_file`."""
    from hexacal_msgs_py.parameters_file import read_parameters_file
    import numpy as np

    from ..core.architectures import architecture, parameters_for
    from ..core.errors import CalibrationError
    from ..core.machine.kinematics import forward_kinematics, inverse_kinematics
    from ..core.machine.postures import sample_poses

    old, new = read_parameters_file(previous_file), read_parameters_file(new_file)
    if old.model != new.model:
        return Change(previous_id, same_model=False)
    layout = old.layout
    lengths = np.array([unit == 'm' for unit in layout.parameter_units])
    difference = np.abs(new.vector - old.vector) * lengths
    largest = int(np.argmax(difference))
    arch = architecture(old.model)
    old_params, new_params = (
        parameters_for(old.model, old.vector),
        parameters_for(new.model, new.vector),
    )
    poses = sample_poses(
        old_params,
        POSE_SAMPLES,
        np.random.default_rng(POSE_SEED),
        'sphere',
        arch.default_workspace(),
    )
    try:
        actuators = inverse_kinematics(old_params, poses)
        moved = forward_kinematics(new_params, actuators, poses)
    except CalibrationError:  # the new machine cannot reach the old one's readings at all
        return Change(
            previous_id,
            True,
            float(difference[largest]),
            layout.parameter_names[largest],
            math.inf,
            math.inf,
            POSE_SAMPLES,
            POSE_SAMPLES,
        )
    ok = moved.converged
    failures = int(np.count_nonzero(~ok))
    if not np.any(ok):
        pose_change, rotation_change = math.inf, math.inf
    else:
        delta = moved.poses[ok] - poses[ok]
        pose_change = float(np.max(np.linalg.norm(delta[:, :3], axis=1)))
        rotation_change = float(np.max(np.abs(_wrapped(delta[:, 3:]))))
        if failures:  # a reading the new parameters cannot reach is a jump of its own
            pose_change, rotation_change = math.inf, math.inf
    return Change(
        previous_id,
        True,
        float(difference[largest]),
        layout.parameter_names[largest],
        pose_change,
        rotation_change,
        len(poses),
        failures,
    )


def _wrapped(angles):
    import numpy as np

    return (angles + np.pi) % (2 * np.pi) - np.pi
