"""
The MuJoCo-simulated machine (ROS-free): physics the identification did not write.

Built by hexacal_identify.physics.mjcf (the export's writer) from the TRUE parameters, a
physical description (hexacal_msgs_py.physical_file) and the device mount, assembled at a
pose.  What it adds to the kinematic driver's machine: masses under gravity, position servos
of finite stiffness (kp, kd per actuator) with a following-error limit (a drive fault, as
drives.py reports them), axial springs between each encoder and its chain's joint centres and
in the measuring link, friction on a released actuator.

Readings are what the instruments see:

* actuators: the encoder, i.e. the actuated joint (motor side of the chain's spring), a slide
  or a hinge as the architecture's mechanism says.  Actuator values (setpoints, encoders,
  following errors and their limit) are in the model's actuator unit: m, or rad for a motor
  turning a crank (the ``_m`` names are kept for both);
* inclinometer: an accelerometer on the link (its site frame is the device frame at zero
  reading, turned by ``device_turn``); at rest it reads the specific force -g, whose direction
  in that frame gives eq. 4's (alpha, beta) for the device's universal joint order (beta about
  the base-side axis -Y, alpha about the link-side axis -X).  With gravity off it reads the
  site's orientation instead (an ideal tilt sensor).  The device's defects apply through the
  core's defect model (core.device.inclinometer_readings) as in the kinematic driver;
* rotary sensor: phi, the platform's rotation about its own z (eq. 2), with the turn and phi0
  as the kinematic driver applies them;
* LVDT (lvdt mode): the link's length, L + the link slide.

Stability: MuJoCo's automatic reset on a bad acceleration is disabled; its warnings
(bad acceleration, singular inertia, constraint or solver trouble) raise PhysicsError,
never a silent reset.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
import time
from typing import Any

from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.machine.device import (
    DEFAULT_MOUNT,
    device_position,
    DeviceDefects,
    inclinometer_readings,
)
from hexacal_identify.core.machine.kinematics import wrap_angle
from hexacal_identify.core.walk.platform_paths import smooth_step
from hexacal_identify.physics.mjcf import (
    DEFAULT_TIMESTEP_S,
    INCLINOMETER_SENSOR,
    INCLINOMETER_SITE,
    LINK_CONNECT,
    machine_mjcf,
    MachineMjcf,
    PLATFORM_NAME,
)
from hexacal_msgs_py.measuring_modes import measuring_mode, MeasuringMode
from hexacal_msgs_py.physical_file import PhysicalDescription
import numpy as np

REST_SPEED = 1e-7  # m/s and rad/s: every joint slower than this is at rest ...
REST_HOLD_S = 0.02  # ... for this long (a vibration passes through zero speed at its turns)
CONTROL_PERIOD_S = 1e-3  # setpoints of a move are updated this often
_CLOCK_ROUNDING_S = 1e-9  # simulated times this close are the same (sums of timesteps)
NOSLIP_ITERATIONS = 20  # hard Coulomb friction on a released actuator (MuJoCo's is soft without)


class PhysicsError(RuntimeError):
    """The simulation became unstable (MuJoCo's warning named); it is never reset silently."""


@dataclass(frozen=True)
class PhysicsReadings:
    """One reading of every sensor: actuators (m; rad), alpha, beta, phi (rad), the link (m)."""

    actuators_m: np.ndarray
    alpha_rad: float
    beta_rad: float
    phi_rad: float
    link_length_m: float


@dataclass(frozen=True)
class PhysicsFault:
    """A drive fault: the joint (0-based chain), its following error and the limit (m; rad)."""

    chain: int
    following_error_m: float
    limit_m: float
    time_s: float


@dataclass
class _Move:
    start: np.ndarray
    end: np.ndarray
    start_s: float
    duration_s: float
    linear: bool = False


@dataclass
class _Released:
    chain: int
    gains: tuple[float, float, float, float]  # kp and the bias terms (constant, position, speed)
    start_s: float = 0.0  # when the release began: the drive's force ramps down from there
    ramping: bool = False
    held_force: float = 0.0  # the drive's force when the release began (N, or N m)


def pose_from_frame(position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Return [x y z theta psi phi] of a frame, R = R_Y(theta) R_X(psi) R_z(phi) (eq. 2)."""
    psi = math.asin(max(-1.0, min(1.0, -rotation[1, 2])))
    theta = math.atan2(rotation[0, 2], rotation[2, 2])
    phi = math.atan2(rotation[1, 0], rotation[1, 1])
    return np.array([*position, theta, psi, phi])


class PhysicsMachine:
    """A MuJoCo machine: command, release/lock, advance, read, check (module doc)."""

    def __init__(
        self,
        params: KinematicParameters,
        physical: PhysicalDescription,
        pose: np.ndarray,
        *,
        link_length: float | None = None,
        mount: str = DEFAULT_MOUNT,
        defects: DeviceDefects = DeviceDefects(),
        device_turn: float = 0.0,
        mode: str = MeasuringMode.PASSIVE_ACTUATOR,
        lvdt_stiffness: float = 0.0,
        timestep: float = DEFAULT_TIMESTEP_S,
        stiff: bool = True,
    ):
        import mujoco

        self._mj = mujoco
        self.params = params
        self.physical = physical
        self.mount = mount
        self.defects = defects
        self.device_turn = float(device_turn)
        self.mode = measuring_mode(mode)
        self.mjcf: MachineMjcf = machine_mjcf(
            params,
            physical,
            pose,
            link_length=link_length,
            mount=mount,
            device_turn=self.device_turn,
            measuring_mode=self.mode,
            lvdt_stiffness=lvdt_stiffness,
            timestep=timestep,
            stiff=stiff,
        )
        self.model = mujoco.MjModel.from_xml_string(self.mjcf.xml)
        # Never reset silently on a bad acceleration: the warning is raised as an error.
        self.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        self.data = mujoco.MjData(self.model)
        names = self.mjcf.names
        self._actuated_qpos = np.array(
            [self.model.jnt_qposadr[self.model.joint(j).id] for j in names.actuated_joints]
        )
        self._actuated_dof = np.array(
            [self.model.jnt_dofadr[self.model.joint(j).id] for j in names.actuated_joints]
        )
        self._platform = self.model.body(PLATFORM_NAME).id
        self._site = self.model.site(INCLINOMETER_SITE).id
        sensor = self.model.sensor(INCLINOMETER_SENSOR)
        self._accelerometer = slice(sensor.adr[0], sensor.adr[0] + 3)
        self._link_qpos = (
            None
            if names.link_spring_joint is None
            else self.model.jnt_qposadr[self.model.joint(names.link_spring_joint).id]
        )
        self._connects = [self.model.equality(name).id for name in names.equalities]
        self._link_connect = (
            self.model.equality(LINK_CONNECT).id if LINK_CONNECT in names.equalities else None
        )
        self.data.ctrl[:] = self.data.qpos[self._actuated_qpos]
        self._move: _Move | None = None
        self._rest_speed = REST_SPEED
        self._rest_since: float | None = None
        self._released: _Released | None = None
        self.faults: list[PhysicsFault] = []
        self.wall_s = 0.0  # wall time spent stepping (for the speed against real time)
        self.cpu_s = 0.0  # this process's CPU time spent stepping (one core, however busy)
        self._mj.mj_forward(self.model, self.data)

    # -- commands -----------------------------------------------------------------------------

    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def setpoints(self) -> np.ndarray:
        return np.array(self.data.ctrl)

    @property
    def released(self) -> int | None:
        """Return the released chain (0-based), None when all six are powered."""
        return None if self._released is None else self._released.chain

    def command(
        self, setpoints: np.ndarray, duration_s: float = 0.0, linear: bool = False
    ) -> None:
        """
        Move the setpoints to ``setpoints`` (the actuator unit: m, rad) over ``duration_s``.

        A quintic time law (at rest at both ends), or ``linear`` (a piece of a trajectory the
        caller interpolates).
        """
        end = np.asarray(setpoints, dtype=float).reshape(-1)
        if end.shape != (self.model.nu,) or not np.all(np.isfinite(end)):
            unit = self.params.layout.actuator_unit
            raise ValueError(
                f'setpoints must be {self.model.nu} finite values in {unit}, got {end}'
            )
        if duration_s <= 0.0 or np.array_equal(end, self.data.ctrl):
            # Setpoints that stay where they are are no move: the follower re-commands them
            # every tick, and a move each tick would keep the machine from ever being at rest.
            self._move = None
            self.data.ctrl[:] = end
        else:
            self._move = _Move(
                np.array(self.data.ctrl), end, self.time_s, float(duration_s), linear
            )

    def release(self, chain: int) -> None:
        """
        Unpower actuator ``chain`` (0-based): it moves freely with the released friction.

        The drive's force goes to zero over the description's ``drives.release_ramp_s``: the
        servo loop is opened and the force it held then is applied, scaled down on the quintic
        law, as a drive disabled with a torque ramp does.  Cut at once, the force the link then
        takes is a step, and the machine overshoots to about 1.5x the link's static load (Hexa
        Slide, shipped description).  The gains scaled down instead (before session 8) overshot
        by up to 26 % of the load's change at a swap: the softened servo let the slider move
        while it still held most of its force.
        """
        if self._released is not None:
            if self._released.chain == chain:
                return
            raise ValueError(
                f'actuator {self._released.chain + 1} is released: lock it before releasing '
                'another'
            )
        if not 0 <= chain < self.model.nu:
            raise ValueError(f'chain must be 0..{self.model.nu - 1}, got {chain}')
        model = self.model
        gains = (
            float(model.actuator_gainprm[chain, 0]),
            float(model.actuator_biasprm[chain, 0]),
            float(model.actuator_biasprm[chain, 1]),
            float(model.actuator_biasprm[chain, 2]),
        )
        ramping = self.physical.release_ramp_s > 0.0
        held = float(self.data.actuator_force[chain]) if ramping else 0.0
        model.actuator_gainprm[chain, 0] = 0.0
        model.actuator_biasprm[chain, 0] = held  # the servo open: a constant force, ramped down
        model.actuator_biasprm[chain, 1:3] = 0.0
        dof = self._actuated_dof[chain]
        model.dof_frictionloss[dof] = self.physical.released_coulomb
        model.dof_damping[dof] = self.physical.released_viscous
        if self.physical.released_coulomb > 0.0:
            model.opt.noslip_iterations = NOSLIP_ITERATIONS
        self._released = _Released(
            chain, gains, start_s=self.time_s, ramping=ramping, held_force=held
        )

    def lock(self) -> None:
        """Power the released actuator again, holding it where it stands."""
        if self._released is None:
            return
        chain, (kp, bias_0, bias_p, bias_d) = self._released.chain, self._released.gains
        model = self.model
        model.actuator_gainprm[chain, 0] = kp
        model.actuator_biasprm[chain, 0] = bias_0
        model.actuator_biasprm[chain, 1] = bias_p
        model.actuator_biasprm[chain, 2] = bias_d
        dof = self._actuated_dof[chain]
        model.dof_frictionloss[dof] = 0.0
        model.dof_damping[dof] = 0.0
        model.opt.noslip_iterations = 0
        self.data.ctrl[chain] = self.data.qpos[self._actuated_qpos[chain]]
        if self._move is not None:
            self._move.end[chain] = self.data.ctrl[chain]
            self._move.start[chain] = self.data.ctrl[chain]
        self._released = None

    # -- time -----------------------------------------------------------------------------------

    def advance(self, seconds: float) -> None:
        """Simulate ``seconds`` (setpoints of a move updated every CONTROL_PERIOD_S)."""
        mj, model, data = self._mj, self.model, self.data
        steps_per_control = max(1, round(CONTROL_PERIOD_S / model.opt.timestep))
        n_step_s = steps_per_control * model.opt.timestep  # setpoints at the end of each chunk
        remaining = max(0, round(seconds / model.opt.timestep))
        started, cpu_started = time.perf_counter(), time.process_time()
        try:
            while remaining > 0:
                if self._move is not None:
                    move = self._move
                    fraction = (self.time_s + n_step_s - move.start_s) / move.duration_s
                    s = min(fraction, 1.0) if move.linear else smooth_step(fraction)
                    target = move.start + s * (move.end - move.start)
                    if self._released is not None:
                        target[self._released.chain] = data.ctrl[self._released.chain]
                    data.ctrl[:] = target
                    if s >= 1.0:
                        self._move = None
                if self._releasing:
                    self._ramp_release()
                n = min(steps_per_control, remaining)
                mj.mj_step(model, data, nstep=n)
                remaining -= n
                self._check_stability()
                self._check_following_error()
                self._track_rest()
        finally:
            self.wall_s += time.perf_counter() - started
            self.cpu_s += time.process_time() - cpu_started

    @property
    def _releasing(self) -> bool:
        """Return True while the released drive is still letting go (release's ramp)."""
        return self._released is not None and self._released.ramping

    def release_left_s(self) -> float:
        """Return how long the released drive still takes to let go (s; 0: it has)."""
        released = self._released
        if released is None or not released.ramping:
            return 0.0
        left = released.start_s + self.physical.release_ramp_s - self.time_s
        return left if left > _CLOCK_ROUNDING_S else 0.0

    def _ramp_release(self) -> None:
        """Scale the released drive's force down along its ramp (release's doc)."""
        released = self._released
        if released is None:
            return
        fraction = (self.time_s - released.start_s) / self.physical.release_ramp_s
        scale = 1.0 - float(smooth_step(fraction))
        released.ramping = self.release_left_s() > 0.0
        held = released.held_force * scale if released.ramping else 0.0
        self.model.actuator_biasprm[released.chain, 0] = held

    def settle(self, max_seconds: float, speed: float = REST_SPEED) -> bool:
        """Advance until at rest (True) or ``max_seconds`` passed (False); rest below ``speed``."""
        self._rest_speed, self._rest_since = float(speed), None
        end = self.time_s + max_seconds
        try:
            while self.time_s < end - 0.5 * self.model.opt.timestep:
                self.advance(min(0.01, end - self.time_s))
                if self.at_rest():
                    return True
            return self.at_rest()
        finally:
            self._rest_speed = REST_SPEED

    def at_rest(self) -> bool:
        """
        Return True when the machine is at rest.

        No move under way, no release still ramping down, and no joint faster than the rest
        speed (REST_SPEED, or settle's) for REST_HOLD_S of simulated time.
        """
        return (
            self._move is None
            and not self._releasing
            and self._rest_since is not None
            and self.time_s - self._rest_since >= REST_HOLD_S - 1e-9
        )

    def _track_rest(self) -> None:
        still = (
            self._move is None and not self._releasing
            and float(np.max(np.abs(self.data.qvel))) < self._rest_speed
        )
        if not still:
            self._rest_since = None
        elif self._rest_since is None:
            self._rest_since = self.time_s

    def _check_stability(self) -> None:
        warnings = self._mj.mjtWarning
        data = self.data
        for kind in (
            warnings.mjWARN_BADQACC,
            warnings.mjWARN_BADQPOS,
            warnings.mjWARN_BADQVEL,
            warnings.mjWARN_BADCTRL,
            warnings.mjWARN_INERTIA,
        ):
            if data.warning[int(kind)].number > 0:
                raise PhysicsError(
                    f'MuJoCo warns {kind.name} at t = {self.time_s:.4f} s: the simulation is '
                    'unstable (a smaller timestep, softer springs or lower gains)'
                )
        if not np.all(np.isfinite(data.qpos)):
            raise PhysicsError(f'non-finite joint positions at t = {self.time_s:.4f} s')

    def _check_following_error(self) -> None:
        errors = self.following_errors()
        limit = self.physical.following_error_limit
        for chain in np.flatnonzero(np.abs(errors) > limit):
            if not any(f.chain == chain for f in self.faults):
                self.faults.append(
                    PhysicsFault(int(chain), float(errors[chain]), limit, self.time_s)
                )

    # -- readings -------------------------------------------------------------------------------

    def following_errors(self) -> np.ndarray:
        """Return setpoint - encoder per actuator (m; rad); 0 for a released one."""
        errors = self.data.ctrl - self.data.qpos[self._actuated_qpos]
        if self._released is not None:
            errors[self._released.chain] = 0.0
        return np.array(errors)

    def encoders(self) -> np.ndarray:
        """Return the actuator readings (m; rad): the actuated joints, motor side of springs."""
        return np.array(self.data.qpos[self._actuated_qpos])

    def pose(self) -> np.ndarray:
        """Return the platform's true pose [x y z theta psi phi] (m, rad)."""
        return pose_from_frame(
            np.array(self.data.xpos[self._platform]),
            np.array(self.data.xmat[self._platform]).reshape(3, 3),
        )

    def link_length(self) -> float:
        """Return the link's length (m): its rest length plus the spring or LVDT travel."""
        extension = 0.0 if self._link_qpos is None else float(self.data.qpos[self._link_qpos])
        return self.mjcf.link_length + extension

    @property
    def has_link(self) -> bool:
        """Whether the machine carries the measuring link (link_force needs it)."""
        return self._link_connect is not None

    def link_force(self) -> float:
        """
        Return the measuring link's axial force at its platform joint (N, tension positive).

        The connect constraint's force on the platform projected on the link's direction: the
        link's spring (or LVDT spring) and the axial share of its weight; in passive_actuator
        mode the load it bears for the released actuator.
        """
        if self._link_connect is None:
            raise ValueError('the machine has no measuring link')
        mj, model, data = self._mj, self.model, self.data
        mj.mj_forward(model, data)
        rows = np.flatnonzero(
            (data.efc_type == int(mj.mjtConstraint.mjCNSTR_EQUALITY))
            & (data.efc_id == self._link_connect)
        )
        if len(rows) != 3:
            raise PhysicsError(f'the link joint has {len(rows)} constraint rows, not 3')
        # A connect's rows are the world-frame components of (link end - platform point); its
        # force pulls the link's end toward the platform when positive along the link.
        direction = self.pose()[:3] / np.linalg.norm(self.pose()[:3])
        return float(np.asarray(data.efc_force[rows]) @ direction)

    def ideal_inclinometer(self) -> tuple[float, float]:
        """Return (alpha, beta) of the device frame from the accelerometer (module doc)."""
        if float(np.linalg.norm(self.model.opt.gravity)) > 0.0:
            self._mj.mj_forward(self.model, self.data)  # the sensors of the current state
            up = np.array(self.data.sensordata[self._accelerometer])
            # The specific force points against gravity; in the device frame tilted from it.
            gravity = np.array(self.model.opt.gravity)
            if gravity[0] != 0.0 or gravity[1] != 0.0:
                raise ValueError('the inclinometer is defined for gravity along -Z of the base')
        else:
            frame = np.array(self.data.site_xmat[self._site]).reshape(3, 3)
            up = frame.T @ np.array([0.0, 0.0, 1.0])
        return math.atan2(-up[1], up[2]), math.atan2(up[0], math.hypot(up[1], up[2]))

    def readings(self) -> PhysicsReadings:
        """Return what the instruments read now (module doc), the device's defects applied."""
        alpha, beta = self.ideal_inclinometer()
        turn = self.device_turn
        # Eq. 4 in the device frame, back in the base frame, read through the defect model.
        position = device_position(
            np.array([alpha]), np.array([beta]), 1.0, DeviceDefects(), self.mount,
            None if turn == 0.0 else np.array([turn]),
        ).position
        alpha_read, beta_read = inclinometer_readings(
            position, self.defects, self.mount, None if turn == 0.0 else turn
        )
        phi = float(self.pose()[5])
        if turn != 0.0 or self.defects.phi0 != 0.0:
            phi = float(wrap_angle(phi - turn + self.defects.phi0))
        return PhysicsReadings(
            self.encoders(), float(alpha_read[0]), float(beta_read[0]), phi, self.link_length()
        )

    def joint_gaps(self) -> np.ndarray:
        """Return the open gap (m) of each connect constraint: chains, then the link."""
        model, data = self.model, self.data
        gaps = []
        for eq in self._connects:
            b1, b2 = model.eq_obj1id[eq], model.eq_obj2id[eq]
            a1, a2 = model.eq_data[eq, 0:3], model.eq_data[eq, 3:6]
            p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ a1
            p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ a2
            gaps.append(float(np.linalg.norm(p1 - p2)))
        return np.array(gaps)

    def status(self) -> dict[str, Any]:
        """Return what the simulation reached: time, rest, joint gaps, faults, speed (SI)."""
        gaps = self.joint_gaps()
        return {
            'physics': 'mujoco',
            'time_s': self.time_s,
            'at_rest': self.at_rest(),
            'max_joint_speed': float(np.max(np.abs(self.data.qvel))),
            'joint_gaps_m': gaps.tolist(),
            'max_joint_gap_m': float(gaps.max()),
            'released_chain': self.released,
            'following_errors_m': self.following_errors().tolist(),
            'faults': [
                {'chain': f.chain, 'following_error_m': f.following_error_m, 'limit_m': f.limit_m,
                 'time_s': f.time_s}
                for f in self.faults
            ],
            'real_time_factor': self.real_time_factor(),
            'cpu_real_time_factor': self.real_time_factor(cpu=True),
        }

    def real_time_factor(self, cpu: bool = False) -> float:
        """Return simulated seconds per wall (``cpu``: CPU) second spent stepping; NaN at first."""
        spent = self.cpu_s if cpu else self.wall_s
        return self.time_s / spent if spent > 0 else math.nan
