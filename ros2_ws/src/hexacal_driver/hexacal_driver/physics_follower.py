"""
The driver's commanded mode on the MuJoCo machine (``physics: mujoco``), ROS-free.

`PhysicsFollower` is a DriveFollower (same trajectories, release/lock, reset, status, guards)
whose standing is not solved from the kinematics but simulated: the setpoints of the
trajectory drive the MuJoCo machine's servos (physics_machine.PhysicsMachine, built from the
true parameters, the physical description and the device mount) and every sample advances it
to the node's clock.  The pose is the platform's, the actuators the encoders' (motor side of
the chains' springs), the link's length its own; the sensors read them as on the kinematic
machine (sensor_models.py, with every sensor effect on top).

Time: the trajectory is followed on the simulation's clock, the node's clock less the time
the simulation fell behind it.  Each sample advances the machine at most MAX_STEP_S, the
setpoints moving linearly along the trajectory within it; where the simulation is slower than
real time, the machine moves slower in wall time and exactly as commanded in its own.

Faults are the physics': a commanded actuator farther than the following-error limit (the
physical description's ``drives.following_error_limit``) from its setpoint, a released one
past its end of stroke, or an unstable simulation (PhysicsError).  The drives then hold where
they stand, as the kinematic follower does.
"""

from __future__ import annotations

import math

from hexacal_driver.drives import DriveFault, DriveFollower, DriveSettings
from hexacal_driver.physics_machine import PhysicsError, PhysicsMachine
from hexacal_driver.simulation import MOVING, STILL, WalkSample
from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.machine.device import DEFAULT_MOUNT, DeviceDefects
from hexacal_msgs_py.measuring_modes import MeasuringMode
from hexacal_msgs_py.physical_file import PhysicalDescription
import numpy as np

MAX_SETTLE_S = 2.0  # after a motion, STILL at rest or at the latest this long after its end
# One sample advances the simulation at most this far: a machine that cannot keep up with the
# node's clock runs slower than it (its clock falls behind), it never jumps.
MAX_STEP_S = 0.02


class PhysicsFollower(DriveFollower):
    """A DriveFollower whose machine is simulated by MuJoCo (module doc)."""

    def __init__(
        self,
        params: KinematicParameters,
        start_pose: np.ndarray,
        max_speed_m_s: float,
        link_length: float,
        mount: str = DEFAULT_MOUNT,
        *,
        physical: PhysicalDescription,
        defects: DeviceDefects = DeviceDefects(),
        device_turn: float = 0.0,
        settings: DriveSettings = DriveSettings(),
        joint_names: tuple[str, ...] = (),
        nominal_link_m: float | None = None,
        stroke_m: tuple[float, float] = (-math.inf, math.inf),
    ) -> None:
        """Stand at ``start_pose`` like a DriveFollower, the MuJoCo machine assembled there."""
        super().__init__(
            params, start_pose, max_speed_m_s, link_length, mount, settings=settings,
            joint_names=joint_names, nominal_link_m=nominal_link_m, stroke_m=stroke_m,
        )
        self.physical = physical
        self.machine = PhysicsMachine(
            params, physical, self.pose, link_length=link_length, mount=mount,
            defects=defects, device_turn=device_turn, mode=settings.mode,
        )
        self._lag_s = 0.0  # how far the simulation's clock is behind the node's (s)
        self._simulated_s: float | None = None  # the node-clock time the machine has reached
        self._motion_end_s = -math.inf

    def _clock(self, now_s: float) -> float:
        """Return the simulation's clock at the node's ``now_s``."""
        return now_s - self._lag_s

    def command(self, now_s: float, points, start_s: float | None = None) -> float:
        """
        Follow ``points`` on the simulation's clock; return the end on the node's.

        A drive still letting a released chain go (the description's ``release_ramp_s``)
        starts the trajectory once it has: moved meanwhile, the five would pull against a
        drive that still holds.
        """
        begin = None if start_s is None else self._clock(start_s)
        left_s = self.machine.release_left_s()
        if left_s > 0.0:
            reached = self._clock(now_s) if self._simulated_s is None else self._simulated_s
            released_s = reached + left_s
            begin = released_s if begin is None else max(begin, released_s)
        end_s = super().command(self._clock(now_s), points, begin)
        return end_s + self._lag_s

    def forces(self) -> np.ndarray | None:
        """Return each actuator's servo force (6,), N (compliant), kp x deviation."""
        if self.mode != MeasuringMode.COMPLIANT:
            return None
        return np.array(self.physical.drive_kp) * (self.actuators - self.setpoints)

    def link_force(self) -> float | None:
        """
        Return the link's axial force the simulation measures (N, tension positive), any mode.

        Not only the compliant mode's: in passive_actuator the link bears the load of the
        released actuator, which no encoder and no kinematic model shows.
        """
        machine = getattr(self, 'machine', None)  # None while DriveFollower.__init__ runs
        return machine.link_force() if machine is not None and machine.has_link else None

    def release(self, joint: str, release: bool, now_s: float) -> tuple[bool, str]:
        """Release or lock ``joint`` (DriveFollower's checks), then on the MuJoCo machine."""
        done, message = super().release(joint, release, self._clock(now_s))
        if done:
            if self.released is not None:
                self.machine.release(self.released)
            else:
                self.machine.lock()
                self.setpoints[:] = self.machine.setpoints
                self._solved_for = self.setpoints.copy()
        return done, message

    def reset(self) -> tuple[bool, str]:
        """Clear a fault: the drives hold where the machine stands."""
        done, message = super().reset()
        if done:
            self.machine.faults.clear()
            setpoints = self.machine.setpoints
            mask = self.commanded_mask()
            setpoints[mask] = self.machine.encoders()[mask]
            self.machine.command(setpoints)
            self.setpoints = setpoints
            self._solved_for = setpoints.copy()
        return done, message

    def sample(self, now_s: float) -> WalkSample:
        """Advance the MuJoCo machine to ``now_s`` with the trajectory's setpoints; read it."""
        if self._simulated_s is None:
            self._simulated_s = self._clock(now_s)
        step_s = self._clock(now_s) - self._simulated_s
        if step_s > MAX_STEP_S:  # slower than the node's clock: fall behind, never jump
            self._lag_s += step_s - MAX_STEP_S
            step_s = MAX_STEP_S
        now_s = self._simulated_s + max(step_s, 0.0)  # on the simulation's clock from here
        if self.fault is None:
            setpoints = self.setpoints_at(now_s)
            self.machine.command(
                self._with_released_setpoint(setpoints), max(step_s, 0.0), linear=True
            )
            self.setpoints = setpoints
            self._solved_for = setpoints.copy()
        self._simulated_s = now_s
        if step_s > 0.0:
            try:
                self.machine.advance(step_s)
            except PhysicsError as error:
                self._trip(DriveFault(f'the simulation became unstable: {error}'))
        self.pose = self.machine.pose()
        self.actuators = self.machine.encoders()
        self.link_m = self.machine.link_length()
        self._fault_from_machine()
        self._update_measures()
        if now_s < self.end_time_s:
            self._motion_end_s = self.end_time_s
            phase = MOVING
        elif self.machine.at_rest() or now_s >= self._motion_end_s + MAX_SETTLE_S:
            phase = STILL
        else:
            phase = MOVING
        if phase == STILL:
            self._at_rest()
        return WalkSample(self.pose.copy(), self.actuators.copy(), 0, phase, 0)

    def _with_released_setpoint(self, setpoints: np.ndarray) -> np.ndarray:
        """Return the servo controls: the released actuator's is left where the drive has it."""
        controls = np.array(setpoints, dtype=float)
        if self.released is not None:
            # Where it was released: a drive ramping its force down lets go of that standing
            # (moved along, it would drop the force at once).
            controls[self.released] = self.machine.setpoints[self.released]
        return controls

    def _fault_from_machine(self) -> None:
        if self.fault is not None:
            return
        if self.machine.faults:
            fault = self.machine.faults[0]
            joint = self.joint_names[fault.chain]
            unit = self.machine.params.layout.actuator_unit  # m, or rad for a crank
            self._trip(DriveFault(
                f'following error of {joint} {abs(fault.following_error_m):.3g} {unit} beyond '
                f'the limit {fault.limit_m:g} {unit} (drives.following_error_limit of the '
                'physical description)',
                joint, abs(fault.following_error_m), fault.limit_m,
            ))
            self.machine.command(self.machine.encoders())  # hold where it stands
            return
        if self.released is not None:
            position = float(self.actuators[self.released])
            low, high = self.actuator_stroke_m
            if not low <= position <= high:
                joint = self.joint_names[self.released]
                bound = low if position < low else high
                self._trip(DriveFault(
                    f'released {joint} at {position:.6g} m passed its end of stroke {bound:g} m',
                    joint, position, bound,
                ))

    def status_values(self) -> dict[str, object]:
        """Return DriveFollower's status plus the simulation's (physics, rest, joint gaps)."""
        values = super().status_values()
        status = self.machine.status()
        values.update(
            physics='mujoco',
            physics_at_rest=status['at_rest'],
            physics_time_s=status['time_s'],
            max_joint_gap_m=status['max_joint_gap_m'],
            real_time_factor=status['cpu_real_time_factor'],
        )
        if self.machine.has_link:  # the simulated link's force, in every measuring mode
            values.update(
                link_force_n=self.link_force_n, max_link_force_n=self.peaks['link_force_n'],
                move_max_link_force_n=self.last_move_peaks['link_force_n'],
                move_max_link_force_after=self.last_move_link_peak_after[0],
            )
        return values
