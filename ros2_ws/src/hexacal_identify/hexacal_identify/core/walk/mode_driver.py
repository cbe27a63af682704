"""
How the executor drives a plan's measuring mode (ROS-free).

The executor's ``measuring_mode`` parameter ('' = the plan's mode, and a plan without one walks
``compliant``: all six commanded) decides:

* ``passive_actuator``: the chain released at each posture, from the plan's
  ``released_actuator`` (joint names of the model) or, where the plan names none, chosen as the
  planner chooses (core/modes/released_actuator.py); core/walk/execution.py swaps it at rest and
  commands the five others.
* ``lvdt`` and ``compliant``: all six commanded (None per posture).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from hexacal_msgs_py.measuring_modes import measuring_mode, MeasuringMode
import numpy as np

from ..architectures import KinematicParameters
from ..machine.device import DEFAULT_MOUNT
from ..modes.released_actuator import choose_released_actuators


@dataclass(frozen=True)
class WalkMode:
    """The mode a walk drives, where it comes from, and the released chain per posture."""

    mode: MeasuringMode
    source: str  # 'measuring_mode' (the parameter), 'plan' or 'default'
    released: tuple[int | None, ...]  # per posture; None: all six commanded
    chosen: int  # postures whose released chain the executor chose (the plan named none)

    def describe(self, actuator_names: Sequence[str]) -> str:
        """Return one line for the log: the mode, its source and the releases."""
        text = f'measuring_mode {self.mode.value} ({self.source})'
        if self.mode != MeasuringMode.PASSIVE_ACTUATOR:
            return text + ': all six actuators commanded'
        names = sorted({actuator_names[i] for i in self.released if i is not None})
        text += f': one actuator released per posture ({", ".join(names)}), five commanded'
        if self.chosen:
            text += f'; {self.chosen} releases chosen here (the plan names none)'
        return text

    def all_six(self, source: str) -> WalkMode:
        """Return the compliant walk of the same postures (all six commanded), from `source`."""
        return WalkMode(MeasuringMode.COMPLIANT, source, (None,) * len(self.released), 0)


def walk_mode(
    parameter: str,
    plan_mode: str | None,
    released_names: Sequence[str | None] | None,
    nominal: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    stroke: tuple[float, float],
    mount: str = DEFAULT_MOUNT,
) -> WalkMode:
    """
    Return the walk's mode (module doc); ValueError naming what is wrong.

    ReleaseError (a ValueError) when a posture has no actuator that can be released.
    """
    if parameter:
        mode, source = measuring_mode(parameter), 'measuring_mode'
    elif plan_mode:
        mode, source = measuring_mode(plan_mode), 'plan'
    else:
        mode, source = MeasuringMode.COMPLIANT, 'default'
    count = len(poses)
    if mode != MeasuringMode.PASSIVE_ACTUATOR:
        return WalkMode(mode, source, (None,) * count, 0)
    names = list(nominal.layout.actuator_names)
    given = list(released_names or [None] * count)
    if len(given) != count:
        raise ValueError(f'the plan names {len(given)} released actuators for {count} postures')
    unknown = sorted({name for name in given if name is not None and name not in names})
    if unknown:
        raise ValueError(
            f'the plan releases {", ".join(unknown)}: not actuators of the model '
            f'({", ".join(names)})'
        )
    missing = [i for i, name in enumerate(given) if name is None]
    chosen: np.ndarray | None = None
    if missing:
        chosen = choose_released_actuators(
            nominal, np.asarray(poses, dtype=float), link_length, stroke, mount=mount
        ).released
    released = tuple(
        names.index(name) if name is not None else int(chosen[i])  # type: ignore[index]
        for i, name in enumerate(given)
    )
    return WalkMode(mode, source, released, len(missing))


__all__ = ['WalkMode', 'walk_mode']
