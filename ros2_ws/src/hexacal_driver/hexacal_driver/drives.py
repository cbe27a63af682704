"""
The simulated machine's drives in commanded mode, per measuring mode, with a guard (ROS-free).

`DriveFollower` is the CommandFollower (a trajectory controller with mock hardware) whose
drives behave as the measuring mode (hexacal_msgs_py.measuring_modes) says, on the TRUE machine
with the true link (link_length + dL):

* ``compliant`` (the default): six equally compliant servos; the
  platform stands on the link sphere where the elastic energy is least
  (simulation.device_constrained_pose). Each actuator carries the force
  ``servo_stiffness_n_per_m * (position - setpoint)`` (N, positive when the link pushes it
  past its setpoint). The drive faults when a force would exceed ``max_force_n``, or the
  tension or compression those forces put on the rigid link (core.modes.compliant.link_tension)
  would exceed ``max_link_force_n`` (both by default the 500 N a measuring link of the
  documented kind bears, hexacal_msgs_py.measuring_modes.LINK_FORCE_LIMIT_N).
* ``passive_actuator``: stiff drives. With one joint released (`release`) the five commanded
  actuators stand exactly at their setpoints and the released one is where the link puts it
  (core.passive_actuator.solve_passive from the previous pose); it faults at its stroke's end.
  With no joint released the six stiff drives fight the rigid link: the actuators stand where
  the least-squares pose on the sphere puts them, off their setpoints by the following error,
  and the drive faults when that would exceed ``max_following_error_m``.
* ``lvdt``: stiff drives, six commanded, all at their setpoints; the telescopic link extends to
  ``|P|`` (forward kinematics of the setpoints, core.lvdt.lvdt_extensions). Beyond
  ``+-lvdt_stroke_m`` about the true link's rest length it stands at its end stop (a rigid
  link of that length): the drives build up following error and fault as above.

The guard checks every new standing BEFORE it is taken: a motion that would cross a limit
faults, stops (the trajectory is dropped) and holds the last standing inside the limits, as a
real drive does. Nothing moves and trajectories are refused until `reset`, which re-enables the
drives where they stand (setpoints := the true positions, so no following error is left).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
import math
from typing import Any, Mapping

from hexacal_driver.simulation import (
    CommandFollower,
    ConstraintError,
    device_constrained_pose,
    MOVING,
    STILL,
    TrajectoryPoint,
    WalkSample,
)
from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.errors import ForwardKinematicsError, UnreachablePoseError
from hexacal_identify.core.machine.device import DEFAULT_MOUNT
from hexacal_identify.core.machine.kinematics import forward_kinematics
from hexacal_identify.core.modes.compliant import thrust_link_tension
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_msgs_py.measuring_modes import (
    COMPLIANT_SERVO_STIFFNESS_N_PER_M,
    LINK_FORCE_LIMIT_N,
    measuring_mode,
    MeasuringMode,
)
import numpy as np

# The largest change of the setpoints the machine is solved across at once (m; rad for a crank).
# A tick brings 1 / rate_hz of motion (1 mm at 0.1 m/s and 100 Hz), but a late wake-up on a
# loaded computer can bring 50 mm at once, across which the passive system's Newton solve may
# land on another branch. A real machine moves continuously whatever the node's timing: the
# solve follows it in steps of at most this much.
CONTINUATION_STEP = 5e-3
MAX_CONTINUATION_STEPS = 1000


class DriveState(StrEnum):
    """The drives' state, as the status says it."""

    OK = 'ok'
    FAULT = 'fault'


@dataclass(frozen=True)
class DriveSettings:
    """The measuring mode and the drives' limits (the node's parameters of the same names)."""

    mode: MeasuringMode = MeasuringMode.COMPLIANT
    max_following_error_m: float = 5e-4
    servo_stiffness_n_per_m: float = COMPLIANT_SERVO_STIFFNESS_N_PER_M
    max_force_n: float = LINK_FORCE_LIMIT_N
    lvdt_stroke_m: float = 0.005
    max_link_force_n: float = LINK_FORCE_LIMIT_N

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> DriveSettings:
        """Return the settings from the node's parameter values (name -> value)."""
        return cls(
            measuring_mode(values['measuring_mode']),
            float(values['max_following_error_m']),
            float(values['servo_stiffness_n_per_m']),
            float(values['max_force_n']),
            float(values['lvdt_stroke_m']),
            float(values.get('max_link_force_n', LINK_FORCE_LIMIT_N)),
        )


@dataclass(frozen=True)
class DriveFault:
    """Why the drives stopped: the quantity, the joint, its value and the limit (SI)."""

    text: str
    joint: str = ''
    value: float = math.nan
    limit: float = math.nan


@dataclass(frozen=True)
class Standing:
    """A candidate standing of the machine: pose, true actuators, link length |P| (m)."""

    pose: np.ndarray
    actuators: np.ndarray
    link_m: float
    end_stop: bool = False  # lvdt: the link is at its end stop


class DriveFollower(CommandFollower):
    """CommandFollower whose drives follow the measuring mode and fault at their limits."""

    def __init__(
        self,
        params: KinematicParameters,
        start_pose: np.ndarray,
        max_speed_m_s: float,
        link_length: float,
        mount: str = DEFAULT_MOUNT,
        *,
        settings: DriveSettings = DriveSettings(),
        joint_names: tuple[str, ...] = (),
        nominal_link_m: float | None = None,
        stroke_m: tuple[float, float] = (-math.inf, math.inf),
    ) -> None:
        """
        Stand at `start_pose` (the true link `link_length` long) with all six joints locked.

        `joint_names`: the actuators' joint names (model order) for messages; `nominal_link_m`:
        the link's nominal length (the LVDT reads on that scale; default `link_length`);
        `stroke_m`: the actuators' stroke (low, high), m: a released actuator faults outside it.
        """
        super().__init__(params, start_pose, max_speed_m_s, link_length, mount)
        self.settings = settings
        self.joint_names = tuple(joint_names) or tuple(f'actuator_{i + 1}' for i in range(6))
        self.nominal_link_m = float(link_length if nominal_link_m is None else nominal_link_m)
        self.actuator_stroke_m = stroke_m
        self.released: int | None = None
        self.fault: DriveFault | None = None
        self._sampled_s: float | None = None  # the last sample's time (continuation)
        self.link_m = float(np.linalg.norm(self.pose[:3]))
        self.end_stop = False
        self.peaks = {'following_error_m': 0.0, 'force_n': 0.0, 'link_extension_m': 0.0,
                      'actuator_deviation_m': 0.0, 'link_force_n': 0.0}
        self.rest_deviation_m = 0.0
        # Per motion (so a report can split before/after refinement): the rests reached after a
        # commanded motion, the peaks of the motion under way and of the last one that ended.
        self.rests = 0
        self.move_peaks = {'force_n': 0.0, 'link_extension_m': 0.0, 'link_force_n': 0.0}
        self.last_move_peaks = dict(self.move_peaks)
        # What the link's peak of the motion came after, with the joint: ('move', '') for a
        # trajectory, ('release' | 'lock', joint); a swap of the releases is a lock, a release.
        self._last_event = ('move', '')
        self.move_link_peak_after = ('', '')
        self.last_move_link_peak_after = ('', '')
        self.last_refusal = ''  # why the last trajectory was refused ('' none yet)
        self._tension_key: tuple[bytes, bytes] | None = None  # the last link tension computed
        self._tension_n = 0.0
        self._update_measures()

    # ------------------------------------------------------------------ what the drives show

    @property
    def mode(self) -> MeasuringMode:
        """Return the measuring mode."""
        return self.settings.mode

    @property
    def state(self) -> DriveState:
        """Return ok or fault."""
        return DriveState.OK if self.fault is None else DriveState.FAULT

    @property
    def released_joint(self) -> str:
        """Return the released joint's name ('' none)."""
        return '' if self.released is None else self.joint_names[self.released]

    def commanded_mask(self) -> np.ndarray:
        """Return which actuators are commanded (6,) bool: all but the released one."""
        mask = np.ones(6, bool)
        if self.released is not None:
            mask[self.released] = False
        return mask

    def commanded_names(self) -> tuple[str, ...]:
        """Return the joints a trajectory must name: all but the released one."""
        return tuple(n for n, c in zip(self.joint_names, self.commanded_mask()) if c)

    def deviations(self) -> np.ndarray:
        """Return true position - setpoint of each actuator (6,), m; 0 for the released one."""
        return np.where(self.commanded_mask(), self.actuators - self.setpoints, 0.0)

    def forces(self) -> np.ndarray | None:
        """Return each actuator's force (6,), N (compliant: stiffness x deviation), else None."""
        if self.mode != MeasuringMode.COMPLIANT:
            return None
        return self.settings.servo_stiffness_n_per_m * (self.actuators - self.setpoints)

    def link_force(self) -> float | None:
        """Return the measuring link's tension (N, compression negative): compliant, else None."""
        forces = self.forces()  # the servos' (a physics machine's own gains)
        if forces is None:
            return None
        return self._tension(self.pose, -forces)

    def _tension(self, pose: np.ndarray, thrust: np.ndarray) -> float:
        """Return the link's tension for these thrusts at `pose`: the guard's, reused by status."""
        key = (pose.tobytes(), thrust.tobytes())
        if key != self._tension_key:
            self._tension_key = key
            self._tension_n = float(thrust_link_tension(self.params, pose, thrust)[0])
        return self._tension_n

    @property
    def link_extension_m(self) -> float:
        """Return the link's extension from its rest length (m): lvdt, else 0."""
        return self.link_m - self.link_length if self.mode == MeasuringMode.LVDT else 0.0

    @property
    def link_reading_m(self) -> float:
        """Return what a noise-free LVDT reads (m): nominal length + extension."""
        return self.nominal_link_m + self.link_extension_m

    def status_values(self) -> dict[str, object]:
        """Return the status keys (docs/nodes.md, driver) with their values, SI."""
        fault = self.fault or DriveFault('')
        forces = self.forces()
        lvdt = self.mode == MeasuringMode.LVDT
        return {
            'measuring_mode': self.mode.value,
            'released_joint': self.released_joint,
            'state': self.state.value,
            'fault': fault.text,
            'fault_joint': fault.joint,
            'fault_value': '' if math.isnan(fault.value) else fault.value,
            'fault_limit': '' if math.isnan(fault.limit) else fault.limit,
            'following_error_m': self.following_error_m,
            'max_following_error_m': self.peaks['following_error_m'],
            'link_extension_m': self.link_extension_m if lvdt else '',
            'max_link_extension_m': self.peaks['link_extension_m'] if lvdt else '',
            'force_n': float(np.max(np.abs(forces))) if forces is not None else '',
            'max_force_n': self.peaks['force_n'] if forces is not None else '',
            'link_force_n': self.link_force_n if forces is not None else '',
            'max_link_force_n': self.peaks['link_force_n'] if forces is not None else '',
            'actuator_deviation_m': self.rest_deviation_m,
            'max_actuator_deviation_m': self.peaks['actuator_deviation_m'],
            'refused_command': self.last_refusal,
            'rests': self.rests,
            'move_max_force_n': self.last_move_peaks['force_n'] if forces is not None else '',
            'move_max_link_extension_m': self.last_move_peaks['link_extension_m'] if lvdt else '',
            'move_max_link_force_n': (
                self.last_move_peaks['link_force_n'] if forces is not None else ''
            ),
            'move_max_link_force_after': (
                self.last_move_link_peak_after[0] if forces is not None else ''
            ),
        }

    def rest_reached(self) -> None:
        """
        Close the commanded motion that just ended at rest: count the rest, keep its peaks.

        The node calls it once per rest (and then publishes the status), so a monitor hears
        every rest's deviation and the largest force / extension of the motion that led there.
        """
        self.rests += 1
        self.last_move_peaks = dict(self.move_peaks)
        self.last_move_link_peak_after = self.move_link_peak_after
        # This standing is counted in the motion that ended here; the next one starts anew.
        self.move_peaks = {'force_n': 0.0, 'link_extension_m': 0.0, 'link_force_n': 0.0}
        self.move_link_peak_after = ('', '')

    # ------------------------------------------------------------------ release, lock, reset

    def command(
        self, now_s: float, points: list[TrajectoryPoint], start_s: float | None = None
    ) -> float:
        """Follow `points` (CommandFollower.command); the link's next peak comes after a move."""
        self._last_event = ('move', '')
        return super().command(now_s, points, start_s)

    def release(self, joint: str, release: bool, now_s: float) -> tuple[bool, str]:
        """Release (True) or lock (False) `joint`; return (done, what happened or why not)."""
        if self.mode != MeasuringMode.PASSIVE_ACTUATOR:
            return False, f'measuring_mode is {self.mode.value}: no joint can be released'
        if joint not in self.joint_names:
            return False, f'unknown joint {joint!r} (joints {", ".join(self.joint_names)})'
        if self.fault is not None:
            return False, f'the drives are in fault ({self.fault.text}): reset first'
        if now_s < self.end_time_s:
            return False, 'refused while moving: release and lock only at rest'
        index = self.joint_names.index(joint)
        if release:
            if self.released == index:
                return True, f'{joint} is already released'
            if self.released is not None:
                return False, (
                    f'{self.released_joint} is released: lock it first (one joint at a time)'
                )
            self.released = index
            self._segments = []  # at rest: the setpoints are self.setpoints from now on
            self._last_event = ('release', joint)
            self._update_measures()
            return True, f'{joint} released: it follows the link, its encoder reads'
        if self.released != index:
            return True, f'{joint} is already locked'
        # Locked where it stands: its setpoint becomes its position, no jump.
        self.setpoints[index] = self.actuators[index]
        self._solved_for = self.setpoints.copy()
        self._segments = []
        self.released = None
        self._last_event = ('lock', joint)
        self._update_measures()
        unit = self.params.layout.actuator_unit  # m, or rad for a crank
        return True, f'{joint} locked at {self.actuators[index]:.6f} {unit}'

    def reset(self) -> tuple[bool, str]:
        """Clear a fault: re-enable the drives where they stand; return (done, message)."""
        if self.fault is None:
            return True, 'no fault to reset'
        text = self.fault.text
        self.fault = None
        mask = self.commanded_mask()
        self.setpoints[mask] = self.actuators[mask]
        self._solved_for = self.setpoints.copy()
        self._segments = []
        self._update_measures()
        return True, f'fault reset ({text}): the drives hold where they stand'

    # ------------------------------------------------------------------ motion

    def sample(self, now_s: float) -> WalkSample:
        """Return the machine at now_s (s): moved as the mode says, unless the guard faults."""
        for time_s in self._continuation(now_s):
            setpoints = self.setpoints_at(time_s)
            if self.fault is None and not np.array_equal(setpoints, self._solved_for):
                self._move(setpoints)
        self._sampled_s = now_s
        phase = MOVING if now_s < self.end_time_s else STILL
        if phase == STILL:
            self._at_rest()
        return WalkSample(self.pose.copy(), self.actuators.copy(), 0, phase, 0)

    def _continuation(self, now_s: float) -> np.ndarray:
        """Return the times (s) up to now_s to solve the machine at: one unless a tick is late."""
        last_s = self._sampled_s
        change = float(np.max(np.abs(self.setpoints_at(now_s) - self._solved_for)))
        steps = min(MAX_CONTINUATION_STEPS, math.ceil(change / CONTINUATION_STEP))
        if self.fault is not None or last_s is None or now_s <= last_s or steps <= 1:
            return np.array([now_s])
        return np.linspace(last_s, now_s, steps + 1)[1:]

    def _move(self, setpoints: np.ndarray) -> None:
        """Take the standing for `setpoints`, or fault and hold if it crosses a limit."""
        try:
            standing = self._solve(setpoints)
        except (ConstraintError, UnreachablePoseError, ForwardKinematicsError) as error:
            if self.mode != MeasuringMode.COMPLIANT:
                self._trip(self._jam(error))
                return
            # Compliant servos: all six commanded, the platform stays where it was.
            standing = Standing(self.pose, self.actuators, self.link_m)
        fault = self._check(standing, setpoints)
        if fault is not None:
            self._trip(fault)
            return
        self.setpoints = setpoints
        self._solved_for = setpoints.copy()
        self.pose, self.actuators = standing.pose, standing.actuators
        self.link_m, self.end_stop = standing.link_m, standing.end_stop
        self._update_measures()

    def _jam(self, error: Exception) -> DriveFault:
        """Return the fault of setpoints no standing of the true machine fits (it jams)."""
        if self.released is not None:
            return DriveFault(
                f'the five commanded actuators and the link jam (released {self.released_joint}: '
                f'a singularity of the passive system on the way, no pose near the previous '
                f'one): {error}',
                self.released_joint,
            )
        return DriveFault(f'no pose of the true machine fits the setpoints: {error}')

    def _solve(self, setpoints: np.ndarray) -> Standing:
        """Return where the true machine stands with these setpoints in this mode."""
        if self.released is not None:
            solved = solve_passive(
                self.params, setpoints[None], self.released, self.pose[None],
                self.link_length, self.mount,
            )
            solved.raise_if_failed()
            return Standing(solved.poses[0], solved.actuators[0], self.link_length)
        if self.mode == MeasuringMode.LVDT:
            # core.lvdt.lvdt_extensions: forward kinematics of the six setpoints -> |P| - L.
            free = forward_kinematics(self.params, setpoints[None], self.pose[None])
            free.raise_if_failed()
            pose = free.poses[0]
            extension = float(np.linalg.norm(pose[:3])) - self.link_length
            stroke = self.settings.lvdt_stroke_m
            if abs(extension) <= stroke:  # stiff drives: the six stand at their setpoints
                return Standing(pose, setpoints.copy(), self.link_length + extension)
            # At its end stop the link is rigid, stroke longer or shorter than at rest.
            length = self.link_length + math.copysign(stroke, extension)
            pose, actuators = device_constrained_pose(
                self.params, setpoints, self.pose, length, self.mount
            )
            return Standing(pose, actuators, length, end_stop=True)
        pose, actuators = device_constrained_pose(
            self.params, setpoints, self.pose, self.link_length, self.mount
        )
        return Standing(pose, actuators, self.link_length)

    def _check(self, standing: Standing, setpoints: np.ndarray) -> DriveFault | None:
        """Return the fault this standing would cause (a limit crossed), else None."""
        if self.mode == MeasuringMode.COMPLIANT:
            return self.compliant_fault(setpoints, standing.actuators, standing.pose)
        mask = self.commanded_mask()
        deviation = np.where(mask, np.abs(standing.actuators - setpoints), 0.0)
        worst = int(np.argmax(deviation))
        limit = self.settings.max_following_error_m
        if deviation[worst] > limit:
            why = ('the link at its end stop' if standing.end_stop
                   else 'six stiff drives against the rigid link: over-constrained')
            return DriveFault(
                f'following error of {self.joint_names[worst]} {deviation[worst]:.3g} m '
                f'beyond the limit {limit:g} m ({why})',
                self.joint_names[worst], float(deviation[worst]), limit,
            )
        if self.released is not None:
            position = float(standing.actuators[self.released])
            low, high = self.actuator_stroke_m
            if not low <= position <= high:
                joint = self.joint_names[self.released]
                bound = low if position < low else high
                return DriveFault(
                    f'released {joint} at {position:.6g} m would pass its end of stroke '
                    f'{bound:g} m', joint, position, bound,
                )
        return None

    def compliant_fault(
        self, setpoints: np.ndarray, actuators: np.ndarray, pose: np.ndarray | None = None
    ) -> DriveFault | None:
        """
        Return the compliant drives' fault for a standing, else None.

        A servo's force beyond max_force_n, or (with the standing's `pose`) the link's tension
        or compression beyond max_link_force_n.
        """
        stiffness = self.settings.servo_stiffness_n_per_m
        forces = np.abs(stiffness * (actuators - setpoints))
        worst = int(np.argmax(forces))
        limit = self.settings.max_force_n
        if forces[worst] > limit:
            return DriveFault(
                f'force on {self.joint_names[worst]} {forces[worst]:.4g} N beyond the limit '
                f'{limit:g} N (compliant servos against the link)',
                self.joint_names[worst], float(forces[worst]), limit,
            )
        if pose is None:
            return None
        tension = self._tension(np.asarray(pose, dtype=float), stiffness * (setpoints - actuators))
        limit = self.settings.max_link_force_n
        if abs(tension) <= limit:
            return None
        return DriveFault(
            f'measuring link {"tension" if tension > 0 else "compression"} {abs(tension):.4g} N '
            f'beyond the limit {limit:g} N (compliant servos against the link)',
            'link', abs(tension), limit,
        )

    def _trip(self, fault: DriveFault) -> None:
        """Fault: drop the trajectory, hold the last standing (setpoints where they were)."""
        self.fault = fault
        self._segments = []
        self._solved_for = self.setpoints.copy()

    def _update_measures(self) -> None:
        """Recompute the following error, force and extension of the standing; keep peaks."""
        self.following_error_m = float(np.max(np.abs(self.deviations())))
        # Of the commanded actuators only: a released one has no setpoint to be strained from.
        self.strain_m = self.following_error_m
        peaks = self.peaks
        peaks['following_error_m'] = max(peaks['following_error_m'], self.following_error_m)
        forces = self.forces()
        if forces is not None:
            peaks['force_n'] = max(peaks['force_n'], float(np.max(np.abs(forces))))
        link = self.link_force()
        self.link_force_n = 0.0 if link is None else link
        peaks['link_force_n'] = max(peaks['link_force_n'], abs(self.link_force_n))
        peaks['link_extension_m'] = max(peaks['link_extension_m'], abs(self.link_extension_m))
        move = self.move_peaks
        if forces is not None:
            move['force_n'] = max(move['force_n'], float(np.max(np.abs(forces))))
        move['link_extension_m'] = max(move['link_extension_m'], abs(self.link_extension_m))
        if abs(self.link_force_n) > move['link_force_n']:
            move['link_force_n'] = abs(self.link_force_n)
            self.move_link_peak_after = self._last_event

    def _at_rest(self) -> None:
        """Record the commanded actuators' true deviation from their setpoints at rest."""
        self.rest_deviation_m = self.following_error_m
        peaks = self.peaks
        peaks['actuator_deviation_m'] = max(peaks['actuator_deviation_m'], self.rest_deviation_m)
