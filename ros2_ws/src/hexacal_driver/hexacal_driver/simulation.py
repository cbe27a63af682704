"""Simulation math of the driver (ROS-free): walk a posture plan in time, read the sensors.

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
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from hexacal_identify.core.device import DEFAULT_MOUNT, inclinometer_angles
from hexacal_identify.core.errors import UnreachablePoseError
from hexacal_identify.core.kinematics import inverse_kinematics
from hexacal_identify.core.measurements import NoiseModel
from hexacal_identify.core.architectures import KinematicParameters

SETTLING = 'settling'  # moving to the posture (or, at the start, standing at it)
DWELLING = 'dwelling'  # standing still at the posture: what the collector measures
DONE = 'done'  # the plan is finished: standing still at its last posture

_SAME_RADIUS_M = 1e-9


def smooth_step(s: float) -> float:
    """Quintic time law on [0, 1]: zero velocity and acceleration at both ends."""
    s = min(max(float(s), 0.0), 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def interpolate_pose(start: np.ndarray, end: np.ndarray, s: float) -> np.ndarray:
    """Pose at fraction s in [0, 1] of the way from start to end.

    Positions at the same distance from O move along the great circle (the
    link sphere); otherwise linearly. Euler angles move linearly.
    """
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    p0, p1 = start[:3], end[:3]
    r0, r1 = float(np.linalg.norm(p0)), float(np.linalg.norm(p1))
    angle = 0.0
    if r0 > 0 and abs(r0 - r1) <= _SAME_RADIUS_M:
        angle = math.acos(min(max(float(np.dot(p0, p1)) / (r0 * r1), -1.0), 1.0))
    if angle > 1e-12 and math.pi - angle > 1e-6:  # slerp; antipodes are never in a workspace
        sin_angle = math.sin(angle)
        position = (math.sin((1 - s) * angle) * p0 + math.sin(s * angle) * p1) / sin_angle
    else:
        position = p0 + s * (p1 - p0)
    return np.concatenate([position, start[3:] + s * (end[3:] - start[3:])])


@dataclass(frozen=True)
class WalkSample:
    """Where the machine is at one instant of the plan."""

    pose: np.ndarray  # [x y z theta psi phi], m and rad
    sliders: np.ndarray  # (6,) actuator readings lambda of the true machine (slider positions), m
    posture_index: int  # the posture being approached or held
    phase: str  # SETTLING, DWELLING or DONE
    lap: int  # 0 for the first pass over the plan; counts up when looping


class PlanWalker:
    """Time since the plan started -> pose and slider positions of the true machine."""

    def __init__(self, params: KinematicParameters, poses: np.ndarray, settle_s: float,
                 dwell_s: float, loop: bool = False):
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
        self.posture_sliders = inverse_kinematics(params, poses)

    @property
    def posture_period_s(self) -> float:
        return self.settle_s + self.dwell_s

    @property
    def lap_duration_s(self) -> float:
        """Time to walk the plan once."""
        return len(self.poses) * self.posture_period_s

    def sample(self, t: float) -> WalkSample:
        """The machine at t s after the plan started (t < 0 counts as 0)."""
        t = max(float(t), 0.0)
        n = len(self.poses)
        lap, in_lap = divmod(t, self.lap_duration_s)
        lap = int(lap)
        if lap >= 1 and not self.loop:
            last = n - 1
            return WalkSample(self.poses[last].copy(), self.posture_sliders[last].copy(), last,
                              DONE, 0)
        index = min(int(in_lap // self.posture_period_s), n - 1)
        into = in_lap - index * self.posture_period_s
        if into >= self.settle_s:
            return WalkSample(self.poses[index].copy(), self.posture_sliders[index].copy(), index,
                              DWELLING, lap)
        if index == 0 and lap == 0:  # the machine starts at the first posture
            return WalkSample(self.poses[0].copy(), self.posture_sliders[0].copy(), 0, SETTLING, 0)
        previous = (index - 1) % n
        s = smooth_step(into / self.settle_s)
        pose = interpolate_pose(self.poses[previous], self.poses[index], s)
        try:
            sliders = inverse_kinematics(self.params, pose[None])[0]
        except UnreachablePoseError:
            # The straight path leaves the workspace: move the sliders directly instead.
            # Readings in motion are never measured, so consistency there does not matter.
            start, end = self.posture_sliders[previous], self.posture_sliders[index]
            sliders = start + s * (end - start)
        return WalkSample(pose, sliders, index, SETTLING, lap)


@dataclass(frozen=True)
class SensorReadings:
    """One reading of every sensor: sliders (m), inclinometer alpha/beta and rotary phi (rad)."""

    sliders_m: np.ndarray
    alpha_rad: float
    beta_rad: float
    phi_rad: float


def exact_readings(pose: np.ndarray, sliders: np.ndarray,
                   mount: str = DEFAULT_MOUNT) -> SensorReadings:
    """What noise-free sensors read: the sliders, eq. 4 inverted for alpha/beta (for the device
    mount, core/device.py), and phi."""
    pose = np.asarray(pose, dtype=float)
    alpha, beta = inclinometer_angles(pose[None, :3], mount)
    return SensorReadings(np.array(sliders, dtype=float), float(alpha[0]), float(beta[0]),
                          float(pose[5]))


class SensorSimulator:
    """Adds fresh uniform noise (NoiseModel half-widths) to every reading."""

    def __init__(self, noise: NoiseModel, rng: np.random.Generator, mount: str = DEFAULT_MOUNT):
        self.noise = noise
        self.rng = rng
        self.mount = mount

    def read(self, sample: WalkSample) -> SensorReadings:
        exact = exact_readings(sample.pose, sample.sliders, self.mount)
        slider_noise = self.rng.uniform(-1.0, 1.0, 6) * self.noise.slider_m
        angle_noise = self.rng.uniform(-1.0, 1.0, 3) * self.noise.angle_rad
        return SensorReadings(exact.sliders_m + slider_noise, exact.alpha_rad + angle_noise[0],
                              exact.beta_rad + angle_noise[1], exact.phi_rad + angle_noise[2])
