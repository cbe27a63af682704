"""
The simulated machine the driver node runs, decided from its parameter values (ROS-free).

`SimulatedMachine` holds the true machine and device mount (`true_params` or the
model's default machine), the device (defects, turn), and either the plan walker
(plan mode) or the command follower (commanded mode), and the noisy sensors with their
models (sensor_models.py). The node only keeps time, converts messages and publishes.
"""

from __future__ import annotations

from typing import Any, Mapping, TYPE_CHECKING

from hexacal_driver.drives import DriveFollower, DriveSettings
from hexacal_driver.plan import machine_workspace, PlanError, PosturePlan, resolve_plan
from hexacal_driver.sensor_models import (
    EFFECTS_STREAM,
    SensorEffect,
    SensorOutput,
    SensorSettings,
    SensorStreams,
)
from hexacal_driver.simulation import (
    check_trajectory,
    ConstraintError,
    device_true_poses,
    PlanWalker,
    SensorReadings,
    SensorSimulator,
    TrajectoryPoint,
    WalkSample,
)
from hexacal_identify.calibration_steps.machine_files import load_machine_and_mount
from hexacal_identify.core.architectures import architecture, KinematicParameters
from hexacal_identify.core.errors import UnreachablePoseError
from hexacal_identify.core.machine.device import (
    DEFAULT_MOUNT,
    DeviceDefects,
    DeviceMountError,
    fixed_point,
)
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
import numpy as np

if TYPE_CHECKING:
    from hexacal_msgs_py.physical_file import PhysicalDescription

NOISE_STREAM = 0x5E45  # noise draws from their own stream: the same seed gives the same plan
LINK_STREAM = 0x11D7  # the LVDT's noise: its own stream, so the other streams draw as before


class DriverConfigurationError(Exception):
    """The node's parameters do not describe a machine and plan it can simulate."""


def true_machine(path: str, model: str) -> tuple[KinematicParameters, str]:
    """Return the true machine and the device mount (the file's device.mount, else hanging)."""
    if not path:
        return architecture(model or DEFAULT_MODEL).default_parameters(), DEFAULT_MOUNT
    try:
        params, mount = load_machine_and_mount(path)
    except (ParameterFileError, DeviceMountError, ValueError) as error:
        raise DriverConfigurationError(f'true_params: {error}') from error
    if model and model != params.model:
        raise DriverConfigurationError(
            f'model {model!r} contradicts true_params {path}, a {params.model} parameters '
            f"file: leave model '' or name the file's model"
        )
    return params, mount


class SimulatedMachine:
    """Decide the true machine, the device, the plan (or commanded mode) and the sensors."""

    def __init__(
        self,
        value: Mapping[str, Any],
        truth: tuple[KinematicParameters, str] | None = None,
    ) -> None:
        """
        Build from the node's parameter values (name -> value); DriverConfigurationError.

        `truth`: the true machine and device mount in memory instead of `true_params`
        (recording.simulate_recording).
        """
        self.true_params, self.mount = truth or true_machine(value['true_params'], value['model'])
        self.model: str = self.true_params.model
        self.link_length = float(value['link_length'])
        self.defects = DeviceDefects.parse(value['device_defects'])  # checked when declared
        self.true_link_length = self.link_length + self.defects.dL  # the sphere the platform is on
        if not self.true_link_length > 0:
            raise DriverConfigurationError(
                f'device_defects dL {self.defects.dL:g} m leaves no link of link_length '
                f'{self.link_length:g} m'
            )
        self.device_turn = float(value['device_turn'])
        self.plan: PosturePlan | None = None
        self.walker: PlanWalker | None = None
        self.follower: DriveFollower | None = None
        self.drive_settings = DriveSettings.from_values(value)
        self.stroke: tuple[float, float] | None = None
        self.physics = value.get('physics', 'kinematic')
        self.physical = self._physical(value) if self.physics == 'mujoco' else None
        if value['command_topic']:
            self.follower = self._start_follower(value['max_actuator_speed_m_s'])
        else:
            if self.physics == 'mujoco':
                raise DriverConfigurationError(
                    'physics mujoco simulates the commanded mode only: set command_topic (the '
                    'plan walker moves the kinematic machine)'
                )
            try:
                self.plan = resolve_plan(
                    value['plan'],
                    self.true_params,
                    value['postures'],
                    value['seed'],
                    value['link_length'],
                    self.mount,
                )
            except PlanError as error:
                raise DriverConfigurationError(str(error)) from error
            self.walker = self.plan_walker(value['settle_s'], value['dwell_s'], value['loop'])
        self.sensors = SensorSimulator(
            NoiseModel(value['slider_noise_m'], value['angle_noise_rad']),
            np.random.default_rng([value['seed'], NOISE_STREAM]),
            self.mount,
            self.defects,
        )
        self._link_rng = np.random.default_rng([value['seed'], LINK_STREAM])
        # The sensor models (sensor_effects), drawing from a random stream of their own.
        self.streams = SensorStreams(
            self.sensors,
            SensorSettings.from_values(value),
            np.random.default_rng([value['seed'], EFFECTS_STREAM]),
            1.0 / float(value['rate_hz']),
        )

    def require_follower(self) -> DriveFollower:
        """Return the command follower (commanded mode); RuntimeError in plan mode."""
        if self.follower is None:
            raise RuntimeError('the driver walks a plan: it has no drives to command')
        return self.follower

    def require_plan(self) -> PosturePlan:
        """Return the plan (plan mode); RuntimeError in commanded mode."""
        if self.plan is None:
            raise RuntimeError('the driver is commanded: it walks no plan')
        return self.plan

    def require_walker(self) -> PlanWalker:
        """Return the plan walker (plan mode); RuntimeError in commanded mode."""
        if self.walker is None:
            raise RuntimeError('the driver is commanded: it walks no plan')
        return self.walker

    def read_link(self, sliders_stamp_ns: int | None) -> tuple[float, int | None]:
        """
        Return the LVDT's reading (m) and its stamp (None: dropped), lvdt commanded mode.

        The link length on the nominal scale (link_length + extension) plus uniform noise of the
        actuators' half-width (slider_noise_m); with sensor_effects `quantisation` rounded to
        actuator_resolution_m. The LVDT is read with the actuators (their stamp, their drop).
        """
        value = self.require_follower().link_reading_m
        value += float(self._link_rng.uniform(-1.0, 1.0)) * self.sensors.noise.actuator_m
        settings = self.streams.settings
        resolution = settings.actuator_resolution_m
        if SensorEffect.QUANTISATION in settings.effects and resolution > 0.0:
            value = round(value / resolution) * resolution
        return value, sliders_stamp_ns

    def plan_walker(self, settle_s: float, dwell_s: float, loop: bool) -> PlanWalker:
        """
        Return the walker over the plan's postures as the true device lets the platform stand.

        simulation.device_true_poses: on the sphere L + dL, fixed ones where the turned
        device reads zero.
        """
        plan = self.require_plan()
        poses = device_true_poses(
            plan.poses,
            plan.kinds,
            self.link_length,
            self.defects,
            self.mount,
            self.posture_turns(),
        )
        try:
            return PlanWalker(self.true_params, poses, settle_s, dwell_s, loop)
        except UnreachablePoseError as error:
            raise DriverConfigurationError(
                f"plan '{plan.name}' with the device's true link length "
                f'{self.true_link_length!r} m (device_defects): {error}'
            ) from error

    def posture_turns(self) -> np.ndarray:
        """Return the device turn of every plan posture (rad): the plan's, else the parameter."""
        plan = self.require_plan()
        return np.array([plan.device_turn(i, self.device_turn) for i in range(len(plan))])

    def posture_turn(self, index: int) -> float:
        """Return the device turn at plan posture `index` (plan mode), else the parameter."""
        if self.plan is None:
            return self.device_turn
        return self.plan.device_turn(index, self.device_turn)

    def read(self, sample: WalkSample) -> tuple[SensorReadings, float]:
        """Return the noisy readings of `sample` (no sensor effects) and the device turn."""
        turn = self.posture_turn(sample.posture_index)
        return self.sensors.read(sample, turn), turn

    def read_streams(self, sample: WalkSample, stamp_ns: int) -> tuple[SensorOutput, float]:
        """Return the three streams' output for `sample` at `stamp_ns` and the device turn."""
        turn = self.posture_turn(sample.posture_index)
        return self.streams.read(sample, turn, stamp_ns), turn

    def set_noise(self, actuator_m: float | None, angle_rad: float | None) -> bool:
        """Change the noise half-widths given (None: unchanged); return whether it changed."""
        noise = self.sensors.noise
        changed = NoiseModel(
            noise.actuator_m if actuator_m is None else actuator_m,
            noise.angle_rad if angle_rad is None else angle_rad,
        )
        if changed == noise:
            return False
        self.sensors.noise = changed
        return True

    def set_device_turn(self, turn: float) -> float | None:
        """
        Turn the device (rad); return the previous turn, or None if it did not change.

        Fixed postures stand where the turned device reads zero: with a defective device
        the walker is rebuilt (same timing; the walk goes on from where it is).
        """
        if float(turn) == self.device_turn:
            return None
        previous, self.device_turn = self.device_turn, float(turn)
        if self.walker is not None and self.defects != DeviceDefects():
            walker = self.walker
            self.walker = self.plan_walker(walker.settle_s, walker.dwell_s, walker.loop)
        return previous

    def check_command(
        self,
        joint_names: list[str],
        points: list[tuple[list[float], float]],
        start_ns: int,
        now_ns: int,
    ) -> tuple[list[TrajectoryPoint] | None, str | None]:
        """
        Return a command's checked points and what is wrong with it (None: follow it).

        points: (positions m, time_from_start s); start_ns: header.stamp (0: on arrival).
        """
        follower = self.require_follower()
        if follower.fault is not None:
            return None, (
                f'the drives are in fault ({follower.fault.text}): reset them first '
                '(the driver reset service)'
            )
        released = follower.released_joint
        if released and released in joint_names:
            return None, (
                f'it names {released}, which is released (passive_actuator): command the five '
                f'others {list(follower.commanded_names())} only'
            )
        checked, problem = check_trajectory(
            joint_names,
            points,
            follower.commanded_names(),
            follower.actuator_stroke_m,  # the stroke (_start_follower)
            self.true_params.layout.actuator_unit,
        )
        if problem is not None and self.drive_settings.mode == 'passive_actuator' and not released:
            problem += (
                ' (no joint is released: release one first, or command all six, which the '
                'rigid link over-constrains)'
            )
        if (
            problem is None
            and start_ns
            and start_ns + int(checked[-1].time_from_start_s * 1e9) < now_ns
        ):
            problem = 'it ends in the past (header.stamp + time_from_start)'
        if problem is None and released:
            checked = self._with_released(checked)
        return checked, problem

    def _with_released(self, points: list[TrajectoryPoint]) -> list[TrajectoryPoint]:
        """Return five-joint points with the released joint's column (its position) inserted."""
        follower = self.require_follower()
        index = follower.released
        if index is None:  # nothing released: the points have the six columns
            return points
        position = float(follower.actuators[index])
        return [
            TrajectoryPoint(np.insert(point.positions, index, position), point.time_from_start_s)
            for point in points
        ]

    def _physical(self, value: Mapping[str, Any]) -> PhysicalDescription:
        """Return the physical description (the file's, else the model's shipped one)."""
        from hexacal_msgs_py.physical_file import (
            default_physical,
            PhysicalFileError,
            read_physical_file,
        )

        path = value.get('physical', '')
        try:
            physical = read_physical_file(path) if path else default_physical(self.model)
        except PhysicalFileError as error:
            raise DriverConfigurationError(f'physical: {error}') from error
        if physical.model != self.model:
            raise DriverConfigurationError(
                f'physical {path} describes a {physical.model}, the true machine is a '
                f'{self.model}'
            )
        return physical

    def _start_follower(self, max_speed_m_s: float) -> DriveFollower:
        """Commanded mode: the machine stands at the fixed-position point with zero angles."""
        workspace = machine_workspace(self.true_params, self.link_length, self.mount)
        self.stroke = (
            float(workspace.actuator_stroke_m[0]),
            float(workspace.actuator_stroke_m[1]),
        )
        # The link holds the platform on the true sphere (link_length + dL).
        home = np.concatenate([fixed_point(self.true_link_length, self.mount), np.zeros(3)])
        options: dict[str, Any] = {
            'settings': self.drive_settings,
            'joint_names': MODELS[self.model].actuator_names,
            'nominal_link_m': self.link_length,
            'stroke_m': self.stroke,
        }
        follower: DriveFollower
        try:
            if self.physical is not None:  # physics mujoco
                # mujoco is imported only when it simulates the machine.
                from hexacal_driver.physics_follower import PhysicsFollower

                follower = PhysicsFollower(
                    self.true_params, home, max_speed_m_s, self.true_link_length, self.mount,
                    physical=self.physical, defects=self.defects, device_turn=self.device_turn,
                    **options,
                )
            else:
                follower = DriveFollower(
                    self.true_params, home, max_speed_m_s, self.true_link_length, self.mount,
                    **options,
                )
        except (UnreachablePoseError, ConstraintError) as error:
            raise DriverConfigurationError(
                f'commanded mode: the machine cannot stand at the fixed-position point {home[:3]} '
                f'with zero angles: {error}'
            ) from error
        low, high = self.stroke
        unit = self.true_params.layout.actuator_unit  # m, or rad for cranks
        if np.any((follower.actuators < low) | (follower.actuators > high)):
            raise DriverConfigurationError(
                f'commanded mode: at the fixed-position point the actuators '
                f'{np.round(follower.actuators, 4).tolist()} {unit} are outside the stroke '
                f'[{low:g}, {high:g}] {unit}'
            )
        return follower
