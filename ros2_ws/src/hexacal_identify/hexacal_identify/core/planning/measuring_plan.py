"""
What a plan adds for its measuring mode: released actuators, LVDT extensions.

* ``passive_actuator``: each posture's released actuator (``released_actuator.py``), written
  into the plan by joint name, with the conditioning it gives and the worst it avoids; given
  the weights, the link's predicted load at each posture and along the move into it
  (``link_load.py``; the move's start bears the posture's release: the executor swaps the
  releases at rest before it moves): the release is chosen for the passive system's
  conditioning along the moves (a jam faults the drives), and the postures whose move loads
  the link beyond its limit are named (the planner leaves them out and chooses again).
* ``lvdt``: every posture's predicted link extension on the nominal machine (zero to rounding
  for postures planned on the sphere: the check that the plan is the link's) and its gain, the
  extension per unit actuator error (``lvdt.extension_gains``), from which the model error the
  stroke tolerates follows: stroke / gain.
* ``compliant``: nothing new.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from hexacal_msgs_py.measuring_modes import (
    DEFAULT_LVDT_STROKE_M,
    measuring_mode,
    MeasuringMode,
)
import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT
from ..machine.kinematics import inverse_kinematics
from ..modes.link_load import LinkLoad, move_link_forces, released_link_forces
from ..modes.lvdt import extension_gains, lvdt_extensions
from ..modes.released_actuator import choose_released_actuators, ReleaseChoice


@dataclass(frozen=True)
class LvdtCheck:
    """Hold a plan's predicted extensions (K,) m, gains (K,) m/m and the stroke (+- m)."""

    extensions: np.ndarray
    gains: np.ndarray
    stroke_m: float

    @property
    def inside(self) -> bool:
        """Return True when every predicted extension is inside the stroke."""
        return bool(np.all(np.abs(self.extensions) <= self.stroke_m))

    @property
    def tolerated_error_m(self) -> float:
        """Return the actuator-equivalent model error (m) the stroke absorbs at the worst pose."""
        return float(self.stroke_m / np.max(self.gains))


@dataclass(frozen=True)
class MeasuringCheck:
    """A plan's measuring mode and what it adds (module doc); None where the mode has nothing."""

    mode: MeasuringMode
    release: ReleaseChoice | None = None
    lvdt: LvdtCheck | None = None
    # passive_actuator with the weights given: the link's predicted |tension| at each posture
    # with its chosen release and the largest along the move into it (K, walking order), N,
    # and the limit they are compared with.
    link_forces: np.ndarray | None = None
    link_force_limit_n: float | None = None
    link_move_forces: np.ndarray | None = None

    @property
    def overloaded(self) -> np.ndarray:
        """Return the postures (walking order) whose move loads the link beyond the limit."""
        forces = self.link_forces if self.link_move_forces is None else self.link_move_forces
        if forces is None or self.link_force_limit_n is None:
            return np.zeros(0, int)
        return np.flatnonzero(forces > self.link_force_limit_n)

    def to_json(self, actuator_names: tuple[str, ...]) -> dict:
        """Return the check as JSON-safe builtins (SI units)."""
        out: dict = {'measuring_mode': self.mode.value}
        if self.release is not None:
            chosen, worst = self.release.chosen_conditions, self.release.worst_conditions
            out.update(
                released_actuators=list(self.release.names(actuator_names)),
                released_condition=chosen.tolist(),
                released_condition_max=float(np.max(chosen)),
                worst_condition_max=float(np.max(worst)),
                released_travel_max_m=float(np.max(self.release.released_travel)),
                moves_via_centre=int(np.sum(self.release.via_centre)),
            )
            if self.release.move_conditions is not None and self.release.jams is not None:
                out.update(
                    rehearsed_machines=self.release.machines,
                    released_move_condition_max=float(np.max(self.release.move_conditions)),
                    moves_jamming=int(np.sum(self.release.jams > 0)),
                )
        if self.link_forces is not None:
            out.update(
                link_force_n=self.link_forces.tolist(),
                link_force_max_n=float(np.max(self.link_forces)),
                link_force_limit_n=self.link_force_limit_n,
                link_overloaded_postures=self.overloaded.tolist(),
            )
        if self.link_move_forces is not None:
            out.update(
                link_move_force_n=self.link_move_forces.tolist(),
                link_move_force_max_n=float(np.max(self.link_move_forces)),
            )
        if self.lvdt is not None:
            out.update(
                lvdt_stroke_m=self.lvdt.stroke_m,
                lvdt_extension_m=self.lvdt.extensions.tolist(),
                lvdt_extension_max_m=float(np.max(np.abs(self.lvdt.extensions))),
                lvdt_gain_max=float(np.max(self.lvdt.gains)),
                lvdt_tolerated_error_m=self.lvdt.tolerated_error_m,
                lvdt_inside=self.lvdt.inside,
            )
        return out


def check_measuring_mode(
    nominal: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke_m: tuple[float, float],
    mode: str,
    lvdt_stroke_m: float = DEFAULT_LVDT_STROKE_M,
    mount: str = DEFAULT_MOUNT,
    groups: np.ndarray | None = None,
    link_load: LinkLoad | None = None,
    progress: Callable[[str], None] | None = None,
) -> MeasuringCheck:
    """
    Return what plan `poses` (K, 6, plan order) need in measuring mode `mode` (module doc).

    `groups` (K,): the order within each group is free (passive_actuator may choose it:
    ``release.order``); `link_load`: passive_actuator, the weights and the link's limit: the
    link's predicted load at each posture with its release and along the move into it
    (modes/link_load.py: ``move_link_forces``); `progress` hears of each posture rehearsed.

    ReleaseError (passive_actuator) when a posture has no actuator that can be released.
    """
    chosen = measuring_mode(mode)
    if chosen == MeasuringMode.PASSIVE_ACTUATOR:
        release = choose_released_actuators(
            nominal, poses, link_length, stroke_m, mount=mount, groups=groups,
            link_load=link_load, progress=progress,
        )
        if link_load is None:
            return MeasuringCheck(chosen, release=release)
        walked = poses if release.order is None else poses[release.order]
        forces = released_link_forces(nominal, walked, link_load.masses)
        return MeasuringCheck(
            chosen,
            release=release,
            link_forces=forces[np.arange(len(walked)), release.released],
            link_force_limit_n=link_load.max_force_n,
            link_move_forces=move_link_forces(
                nominal, walked, release.released, link_load.masses, link_length, stroke_m,
                mount,
            ),
        )
    if chosen == MeasuringMode.LVDT:
        if not (np.isfinite(lvdt_stroke_m) and lvdt_stroke_m > 0):
            raise ValueError(
                f'the LVDT stroke must be a positive length in m, got {lvdt_stroke_m}'
            )
        commanded = inverse_kinematics(nominal, poses)
        extensions = lvdt_extensions(nominal, commanded, poses, link_length)
        check = LvdtCheck(extensions, extension_gains(nominal, poses), float(lvdt_stroke_m))
        return MeasuringCheck(chosen, lvdt=check)
    return MeasuringCheck(chosen)


__all__ = ['LvdtCheck', 'MeasuringCheck', 'check_measuring_mode']


def walking_notice(mode: str | None) -> str | None:
    """
    Return what the executor must tell the operator before walking a plan of `mode`, or None.

    For an executor that commands all six actuators whatever the plan says (its drive cannot
    release one): a plan made for a released actuator or an LVDT link is then walked
    over-constrained. The operator hears it before anything moves.
    """
    if mode is None or measuring_mode(mode) is MeasuringMode.COMPLIANT:
        return None
    return (
        f"the plan is made for measuring_mode '{measuring_mode(mode).value}', but this executor "
        'commands all six actuators (the compliant mode): no actuator is released and no LVDT '
        'length is read. Walk it only on a machine whose drives are torque-limited while the '
        'measuring link is attached'
    )
