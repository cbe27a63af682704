"""
Simulation math of the driver (ROS-free): walk a posture plan in time, read the sensors.

The driver node only keeps time and publishes; everything here is plain numpy
on the core's model, so it is unit-tested without ROS.

Timeline of one lap over N postures, each `settle_s + dwell_s` long: posture i
starts with `settle_s` of motion from posture i-1 (posture 0 of the first lap
is where the machine starts, so it is already there and stands still), then
stands still for `dwell_s`. Motion follows a quintic (minimum-jerk) time law,
so sliders start and stop smoothly; the platform moves along the great circle
of the link sphere, as the measuring link forces it to, with the Euler angles
interpolated linearly. Slider positions are the true machine's inverse
kinematics of the platform pose. Any architecture (core.architectures): the
"sliders" are its six actuator readings (Hexa Slide: slider positions along the
rails; Gough-Stewart: leg extensions).

The device may be defective and turned about its link axis (core/machine/device.py:
`DeviceDefects`, ``device_turn`` rad, 0 normal mounting, pi reversed, pi/2 a
quarter turn): the inclinometer reads through the core's defect model
(`inclinometer_readings`) in the turned device's frame and the rotary sensor
reads wrap(phi - turn + phi0). Its link is L + dL long, so the platform stands
on that true sphere (`device_true_poses`): sphere postures radially on it,
fixed postures where the defective, turned inclinometer reads zero.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from hexacal_identify.core.architectures import KinematicParameters
from hexacal_identify.core.errors import UnreachablePoseError
from hexacal_identify.core.machine.device import (
    DEFAULT_MOUNT,
    device_position,
    DeviceDefects,
    inclinometer_readings,
)
from hexacal_identify.core.machine.kinematics import inverse_kinematics, wrap_angle
from hexacal_identify.core.machine.measurements import FIXED, NoiseModel
# The compliant servos' pose on the link sphere: one model, the core's (re-exported here).
from hexacal_identify.core.modes.compliant import (  # noqa: F401
    ConstraintError,
    device_constrained_pose,
    STRAIN_RETRY_M,
)
# The executor's interpolation; without a link length: the great circle of the true sphere.
from hexacal_identify.core.walk.platform_paths import interpolate_pose, smooth_step
import numpy as np

SETTLING = 'settling'  # moving to the posture (or, at the start, standing at it)
DWELLING = 'dwelling'  # standing still at the posture: what the collector measures
DONE = 'done'  # the plan is finished: standing still at its last posture


@dataclass(frozen=True)
class WalkSample:
    """Where the machine is at one instant of the plan."""

    pose: np.ndarray  # [x y z theta psi phi], m and rad
    # (6,) actuator readings lambda of the true machine (slider positions), m
    actuators: np.ndarray
    posture_index: int  # the posture being approached or held
    phase: str  # SETTLING, DWELLING or DONE
    lap: int  # 0 for the first pass over the plan; counts up when looping


class PlanWalker:
    """Time since the plan started -> pose and slider positions of the true machine."""

    def __init__(
        self,
        params: KinematicParameters,
        poses: np.ndarray,
        settle_s: float,
        dwell_s: float,
        loop: bool = False,
    ):
        poses = np.atleast_2d(np.asarray(poses, dtype=float))
        if poses.ndim != 2 or poses.shape[1] != 6 or len(poses) == 0:
            raise ValueError(f'poses must be (N >= 1, 6), got {poses.shape}')
        if not (settle_s > 0 and dwell_s > 0):
            raise ValueError(f'settle_s and dwell_s must be > 0, got {settle_s}, {dwell_s}')
        self.params = params
        self.poses = poses
        self.settle_s = float(settle_s)
        self.dwell_s = float(dwell_s)
        self.loop = bool(loop)
        # Raises UnreachablePoseError for an unreachable plan posture: check plans first.
        self.posture_actuators = inverse_kinematics(params, poses)

    @property
    def posture_period_s(self) -> float:
        return self.settle_s + self.dwell_s

    @property
    def lap_duration_s(self) -> float:
        """Time to walk the plan once."""
        return len(self.poses) * self.posture_period_s

    def sample(self, t: float) -> WalkSample:
        """Return the machine at t s after the plan started (t < 0 counts as 0)."""
        t = max(float(t), 0.0)
        n = len(self.poses)
        lap, in_lap = divmod(t, self.lap_duration_s)
        lap = int(lap)
        if lap >= 1 and not self.loop:
            last = n - 1
            return WalkSample(
                self.poses[last].copy(), self.posture_actuators[last].copy(), last, DONE, 0
            )
        index = min(int(in_lap // self.posture_period_s), n - 1)
        into = in_lap - index * self.posture_period_s
        if into >= self.settle_s:
            return WalkSample(
                self.poses[index].copy(),
                self.posture_actuators[index].copy(),
                index,
                DWELLING,
                lap,
            )
        if index == 0 and lap == 0:  # the machine starts at the first posture
            return WalkSample(
                self.poses[0].copy(), self.posture_actuators[0].copy(), 0, SETTLING, 0
            )
        previous = (index - 1) % n
        s = float(smooth_step(into / self.settle_s))
        pose = interpolate_pose(self.poses[previous], self.poses[index], s)
        try:
            actuators = inverse_kinematics(self.params, pose[None])[0]
        except UnreachablePoseError:
            # The straight path leaves the workspace: move the sliders directly instead.
            # Readings in motion are never measured, so consistency there does not matter.
            start, end = self.posture_actuators[previous], self.posture_actuators[index]
            actuators = start + s * (end - start)
        return WalkSample(pose, actuators, index, SETTLING, lap)


@dataclass(frozen=True)
class SensorReadings:
    """One reading of every sensor: sliders (m), inclinometer alpha/beta and rotary phi (rad)."""

    actuators_m: np.ndarray
    alpha_rad: float
    beta_rad: float
    phi_rad: float


IDEAL_DEVICE = DeviceDefects()


def exact_readings(
    pose: np.ndarray,
    actuators: np.ndarray,
    mount: str = DEFAULT_MOUNT,
    defects: DeviceDefects = IDEAL_DEVICE,
    device_turn: float = 0.0,
) -> SensorReadings:
    """
    Return what noise-free sensors read.

    The sliders, the inclinometer's alpha/beta through the core's defect model
    (core.device.inclinometer_readings, for the device mount and `device_turn` rad about the link
    axis), and the rotary phi - turn + phi0 wrapped to [-pi, pi) (phi as it is for an ideal device
    in its normal mounting).
    """
    pose = np.asarray(pose, dtype=float)
    turn = float(device_turn)
    alpha, beta = inclinometer_readings(
        pose[None, :3], defects, mount, None if turn == 0.0 else turn
    )
    phi = float(pose[5])
    if turn != 0.0 or defects.phi0 != 0.0:
        phi = float(wrap_angle(phi - turn + defects.phi0))
    return SensorReadings(np.array(actuators, dtype=float), float(alpha[0]), float(beta[0]), phi)


def device_true_poses(
    poses: np.ndarray,
    kinds,
    link_length: float,
    defects: DeviceDefects = IDEAL_DEVICE,
    mount: str = DEFAULT_MOUNT,
    device_turns: np.ndarray | float | None = None,
) -> np.ndarray:
    """
    Return where the platform stands for plan `poses` with the true device attached.

    Where the platform stands for plan `poses` (planned on the nominal sphere of radius
    `link_length`) with the true device attached: sphere postures moved radially onto the true
    sphere of radius L + dL, fixed postures (kind 'fixed') where the defective inclinometer, turned
    by the posture's `device_turns` (rad), reads zero (core.device.device_position). Orientations
    are kept. An ideal device changes nothing (the poses are returned as given).
    """
    poses = np.array(poses, dtype=float).reshape(-1, 6)
    if defects == IDEAL_DEVICE:
        return poses
    n = len(poses)
    turns = (
        np.zeros(n)
        if device_turns is None
        else np.broadcast_to(np.asarray(device_turns, dtype=float), (n,))
    )
    true_length = float(link_length) + defects.dL
    radius = np.linalg.norm(poses[:, :3], axis=1)
    fixed = np.array([str(kind) == FIXED for kind in kinds])
    zero = device_position(np.zeros(n), np.zeros(n), float(link_length), defects, mount, turns)
    sphere_positions = poses[:, :3] * (true_length / radius)[:, None]
    poses[:, :3] = np.where(fixed[:, None], zero.position, sphere_positions)
    return poses


class SensorSimulator:
    """
    Add fresh uniform noise to every reading of a device with `defects`.

    Adds fresh uniform noise (NoiseModel half-widths) to every reading of a device with `defects`;
    read() takes the device's turn about its link axis (rad).
    """

    def __init__(
        self,
        noise: NoiseModel,
        rng: np.random.Generator,
        mount: str = DEFAULT_MOUNT,
        defects: DeviceDefects = IDEAL_DEVICE,
    ):
        self.noise = noise
        self.rng = rng
        self.mount = mount
        self.defects = defects

    def read(self, sample: WalkSample, device_turn: float = 0.0) -> SensorReadings:
        return self.add_noise(
            exact_readings(sample.pose, sample.actuators, self.mount, self.defects, device_turn)
        )

    def add_noise(self, exact: SensorReadings) -> SensorReadings:
        """Return `exact` plus fresh noise (six actuator draws, then three angle draws)."""
        actuator_noise = self.rng.uniform(-1.0, 1.0, 6) * self.noise.actuator_m
        angle_noise = self.rng.uniform(-1.0, 1.0, 3) * self.noise.angle_rad
        return SensorReadings(
            exact.actuators_m + actuator_noise,
            exact.alpha_rad + angle_noise[0],
            exact.beta_rad + angle_noise[1],
            exact.phi_rad + angle_noise[2],
        )


# --------------------------------------------------------------------------- commanded mode

MOVING = 'moving'  # commanded mode: a trajectory is being followed
STILL = 'still'  # commanded mode: the setpoints stand still


@dataclass(frozen=True)
class TrajectoryPoint:
    """One point of a commanded trajectory: actuator positions (model order, m), time (s)."""

    positions: np.ndarray
    time_from_start_s: float


def check_trajectory(
    joint_names: list[str],
    points: list[tuple[list[float], float]],
    expected_names: tuple[str, ...],
    stroke_m: tuple[float, float],
    unit: str = 'm',
) -> tuple[list[TrajectoryPoint], str | None]:
    """
    Return a JointTrajectory's joints and points in the machine's order, or the reason.

    A JointTrajectory's joints and points in the machine's order, or the reason it is rejected.

    Like ros2_control's joint_trajectory_controller (without partial joint goals): the joint
    names must be exactly the machine's actuators (any order, each once), every point needs one
    finite position per joint, times from start must strictly increase and not be negative, and
    an empty trajectory is rejected. Unlike the controller, a position outside the actuator
    stroke rejects the whole command (a simulated hard limit) instead of being clamped.
    ``stroke_m`` and the positions are in the actuators' ``unit``: m, or rad for cranks.
    """
    names = list(joint_names)
    if not names:
        return [], 'no joint names'
    if len(set(names)) != len(names):
        return [], f'joint names repeat: {names}'
    if set(names) != set(expected_names):
        unknown = sorted(set(names) - set(expected_names))
        missing = sorted(set(expected_names) - set(names))
        return [], (
            f"joint names {names} are not this machine's actuators "
            f'{list(expected_names)}'
            + (f': unknown {unknown}' if unknown else '')
            + (f', missing {missing}' if missing else '')
        )
    if not points:
        return [], 'empty trajectory (no points)'
    order = [names.index(name) for name in expected_names]
    low, high = stroke_m
    checked: list[TrajectoryPoint] = []
    previous = -math.inf
    for index, (positions, time_s) in enumerate(points):
        if len(positions) != len(names):
            return [], f'point {index} has {len(positions)} positions for {len(names)} joints'
        values = np.array([float(positions[i]) for i in order])
        if not np.all(np.isfinite(values)):
            return [], f'point {index} has non-finite positions {values.tolist()}'
        if not math.isfinite(time_s) or time_s < 0.0:
            return [], f'point {index} time_from_start {time_s!r} s is negative or not finite'
        if time_s <= previous:
            return [], (
                f'time_from_start of point {index} ({time_s:g} s) is not after that of '
                f'point {index - 1} ({previous:g} s)'
            )
        outside = [
            f'{expected_names[i]} {values[i]:.6g} {unit}'
            for i in range(len(values))
            if not low <= values[i] <= high
        ]
        if outside:
            return [], (
                f'point {index} is outside the actuator stroke [{low:g}, {high:g}] {unit}: '
                + ', '.join(outside)
            )
        previous = time_s
        checked.append(TrajectoryPoint(values, float(time_s)))
    return checked, None


class CommandFollower:
    """
    A trajectory controller with mock hardware, on the true machine with the device attached.

    Each accepted trajectory replaces the one being followed and starts from the current
    setpoints (as joint_trajectory_controller does on its topic interface). The setpoints move
    linearly from point to point, all actuators together, each segment taking its
    time_from_start difference or longer if the fastest actuator would exceed
    `max_speed_m_s`. The machine's pose is where the device link lets it be
    (`device_constrained_pose`); `sample` gives it with the true actuator readings.
    """

    def __init__(
        self,
        params: KinematicParameters,
        start_pose: np.ndarray,
        max_speed_m_s: float,
        link_length: float,
        mount: str = DEFAULT_MOUNT,
    ):
        if not (max_speed_m_s > 0 and math.isfinite(max_speed_m_s)):
            raise ValueError(f'max_speed_m_s must be > 0, got {max_speed_m_s}')
        self.params = params
        self.max_speed_m_s = float(max_speed_m_s)
        self.link_length = float(link_length)
        self.mount = mount
        self.pose = np.array(start_pose, dtype=float)
        self.setpoints = inverse_kinematics(params, self.pose[None])[0]
        self.actuators = self.setpoints.copy()
        self.pose, self.actuators = device_constrained_pose(
            params, self.setpoints, self.pose, self.link_length, mount
        )
        # Segments (start time s, end time s, start setpoints, end setpoints) of the trajectory.
        self._segments: list[tuple[float, float, np.ndarray, np.ndarray]] = []
        self._solved_for = self.setpoints.copy()
        self.commands = 0
        self.strain_m = float(np.max(np.abs(self.actuators - self.setpoints)))

    @property
    def end_time_s(self) -> float:
        """When the trajectory being followed ends (-inf if none)."""
        return self._segments[-1][1] if self._segments else -math.inf

    def setpoints_at(self, now_s: float) -> np.ndarray:
        for start_s, end_s, begin, end in self._segments:
            if now_s < start_s:
                return begin.copy()
            if now_s < end_s:
                s = (now_s - start_s) / (end_s - start_s)
                return begin + s * (end - begin)
        return self._segments[-1][3].copy() if self._segments else self.setpoints.copy()

    def command(
        self, now_s: float, points: list[TrajectoryPoint], start_s: float | None = None
    ) -> float:
        """
        Follow `points` (checked, model order) from now; return when the last one is reached.

        Follow `points` (checked, model order) from now (or from start_s if later); returns the
        time the last point is reached, s.
        """
        current = self.setpoints_at(now_s)
        self.setpoints = current
        begin_s = max(now_s, start_s) if start_s is not None else now_s
        segments = []
        previous_positions, previous_time, t = current, 0.0, begin_s
        for point in points:
            largest = float(np.max(np.abs(point.positions - previous_positions)))
            duration = max(point.time_from_start_s - previous_time, largest / self.max_speed_m_s)
            segments.append((t, t + duration, previous_positions, point.positions.copy()))
            previous_positions, previous_time, t = (
                point.positions,
                point.time_from_start_s,
                t + duration,
            )
        self._segments = segments
        self.commands += 1
        return t

    def sample(self, now_s: float) -> WalkSample:
        """Return the machine at now_s (node clock, s): pose, true readings, MOVING or STILL."""
        self.setpoints = self.setpoints_at(now_s)
        if not np.array_equal(self.setpoints, self._solved_for):
            try:
                self.pose, self.actuators = device_constrained_pose(
                    self.params, self.setpoints, self.pose, self.link_length, self.mount
                )
            except (ConstraintError, UnreachablePoseError):
                pass  # stays where it was (a setpoint path the link does not allow)
            self._solved_for = self.setpoints.copy()
            self.strain_m = float(np.max(np.abs(self.actuators - self.setpoints)))
        phase = MOVING if now_s < self.end_time_s else STILL
        return WalkSample(self.pose.copy(), self.actuators.copy(), 0, phase, 0)
