"""Node `driver`: a simulated machine (Hexa Slide or Gough-Stewart) with the measuring device attached.

The true machine is `true_params` (a parameters YAML of either model, which
names its model), or the default machine of `model` (Hexa Slide: Table 1;
Gough-Stewart: the default hexapod of core.architectures); the device hangs
below the base (``device.mount`` of true_params: ``standing`` for an upright
machine, core/device.py). Walks a posture plan
on it and publishes, at `rate_hz`, the actuator readings (`hexacal/sliders`:
joints slider_1..6 on a Hexa Slide, leg_1..6 on a Gough-Stewart platform), the
inclinometer angles
(`hexacal/inclinometer`) and the rotary angle (`hexacal/encoder`), each with
fresh uniform noise, stamped with the node clock (SENSOR_QOS, SI units).

The machine starts standing at the plan's first posture. With
`wait_for_subscriber` (default) it holds there until a subscriber is matched on
all three streams, so a collector started a little later still sees every
posture. When the plan is done it stands at the last posture (still
publishing), or walks the plan again with `loop`.

Commanded mode (`command_topic` set, e.g. /joint_trajectory_controller/joint_trajectory):
the machine takes the real machine's interface instead of walking a plan. Like
ros2_control's joint_trajectory_controller with mock hardware, it follows
`trajectory_msgs/JointTrajectory` commands on that topic (COMMAND_QOS): the
model's actuator joints (any order), each new trajectory replacing the one
followed, the setpoints moving linearly through its points at the slower of
their time_from_start and `max_actuator_speed_m_s`. A command with other joint
names, an empty, malformed or late one, or one with a position outside the
stroke (the true machine's workspace) is rejected with a log line and ignored.
It starts standing at the fixed-position point with zero angles and keeps
publishing the three sensor streams (with noise as configured) for where the
machine stands: the measuring link holds the platform on its sphere, so the pose
is the one on the sphere whose true actuator positions are nearest the
setpoints (simulation.device_constrained_pose), the actuator readings those
positions and the device readings those of the pose (a strain beyond 10 mm, the
sign of commands that leave the sphere, is logged as a warning). `plan`, `postures`,
`settle_s`, `dwell_s`, `loop` and `wait_for_subscriber` do not apply.

The measuring device (core/device.py): `device_defects` ('' an ideal device;
e.g. 'dL=5e-4,alpha0=2e-4,beta0=-1e-4,gamma=1e-4,phi0=3e-4', SI units) are the
simulated device's errors, and `device_turn` (rad, settable at run time) how
far it is turned about its link axis from its normal mounting (0 normal, pi
reversed, pi/2 a quarter turn). The inclinometer and rotary readings go through
the core's defect model for that turn (the rotary reads wrap(phi - turn +
phi0)), and the inclinometer message carries the joint `device_turn` whenever
the turn is non-zero. `link_length` stays the nominal L; the true link is L +
dL, so the platform stands on that sphere: plan postures (planned on the
nominal sphere) move radially onto it, fixed postures to where the defective,
turned inclinometer reads zero, and the commanded mode's link holds the
platform on it. A plan file's posture may name its own `device_turn` (plan.py):
the device is turned to it while that posture is walked; the others take the
parameter.

The math lives in `simulation.py` and `plan.py`; this node keeps time and publishes.
"""

from __future__ import annotations

import math
import sys
import time

from hexacal_driver.plan import GENERATED_PLANS, load_plan, PlanError, PosturePlan, resolve_plan
from hexacal_driver.simulation import (
    check_trajectory,
    CommandFollower,
    ConstraintError,
    device_true_poses,
    DONE,
    DWELLING,
    MOVING,
    PlanWalker,
    SensorSimulator,
)
from hexacal_identify.core.architectures import architecture, KinematicParameters, parameters_for
from hexacal_identify.core.device import (
    check_mount,
    DEFAULT_MOUNT,
    DeviceDefects,
    DeviceMountError,
    fixed_point,
)
from hexacal_identify.core.errors import UnreachablePoseError
from hexacal_identify.core.measurements import NoiseModel
from hexacal_identify.nodes.parameters import parameter_descriptor
from hexacal_identify.nodes.parameters import ParameterSpec as _Spec
from hexacal_identify.nodes.runtime import run_node
from hexacal_msgs_py.conversions import (
    encoder_reading_to_joint_state,
    inclinometer_reading_to_joint_state,
    slider_reading_to_joint_state,
)
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.models import DEFAULT_MODEL, HEXA_SLIDE, MODELS
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY as MOUNT_PARAMETER
from hexacal_msgs_py.names import (
    ENCODER_TOPIC,
    INCLINOMETER_TOPIC,
    MAX_DEVICE_TURN,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.parameters_file import load_parameters, read_parameters_file
from hexacal_msgs_py.qos import COMMAND_QOS, SENSOR_QOS
from hexacal_msgs_py.readings import EncoderReading, InclinometerReading, SliderReading
import numpy as np
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterValueException, InvalidTopicNameException
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

NODE_NAME = 'driver'
# The timer wakes at most this often and publishes rate_hz / MAX_WAKE_HZ samples per wake-up,
# each stamped with its own sampling time (1 / rate_hz apart, the last one now): an executor
# wake-up costs more than the publishing, so 1 kHz costs 200 wake-ups per second, not 1000.
MAX_WAKE_HZ = 200.0
NS_PER_S = 1_000_000_000
# Commanded mode: a strain of the measuring link beyond this is logged (at most every period).
STRAIN_WARNING_M = 0.01
STRAIN_WARNING_PERIOD_S = 5.0
# Parameters that may change while the node runs; all others shape the plan and are read-only.
RUNTIME_PARAMETERS = ('slider_noise_m', 'angle_noise_rad', 'device_turn')


MODEL_CHOICES = ('', *MODELS)

PARAMETERS: dict[str, _Spec] = {
    'true_params': _Spec(
        '',
        'parameters YAML (SI) of the simulated true machine, of any model '
        "(its 'model' key; 'device.mount: standing' for an upright device, "
        'default hanging); empty: the default machine of `model` (Hexa Slide: '
        'Table 1 of the paper)',
    ),
    'model': _Spec(
        '',
        "machine model: 'hexa_slide' or 'gough_stewart'; '' = the model of "
        'true_params, else hexa_slide. Without true_params the default machine of '
        'the model is simulated; with it, the two must agree',
        constraints="'', " + ', '.join(repr(name) for name in MODELS),
    ),
    'link_length': _Spec(
        0.75, 'measuring link length L between the U-joint centres (m)', 0.1, 5.0
    ),
    'slider_noise_m': _Spec(1e-5, 'half-width of the uniform slider noise (m)', 0.0, 0.01),
    'angle_noise_rad': _Spec(
        1e-5, 'half-width of the uniform inclinometer and rotary noise (rad)', 0.0, 0.1
    ),
    'seed': _Spec(0, 'seed of the random plan and of the noise', 0, 2**31 - 1),
    'rate_hz': _Spec(100.0, 'publishing rate of every sensor stream (Hz)', 1.0, 1000.0),
    'settle_s': _Spec(1.0, 'time to move from one posture to the next (s)', 0.05, 600.0),
    'dwell_s': _Spec(1.5, 'time standing still at each posture (s)', 0.1, 3600.0),
    'plan': _Spec(
        'random',
        'posture plan: random (sphere postures), fixed (fixed-position '
        'postures), mixed (3 sphere : 1 fixed) or the path of a plan YAML',
        constraints="'random', 'fixed', 'mixed' or an existing plan file",
    ),
    'postures': _Spec(50, 'number of postures of a random, fixed or mixed plan', 1, 100000),
    'loop': _Spec(False, 'walk the plan again when done (else stand at the last posture)'),
    'wait_for_subscriber': _Spec(
        True, 'hold the first posture until the three sensor streams have a matched subscriber'
    ),
    'command_topic': _Spec(
        '',
        "'' (default): walk the plan; else follow trajectory_msgs/"
        'JointTrajectory commands on this topic (e.g. /joint_trajectory_'
        'controller/joint_trajectory) like a trajectory controller with mock '
        'hardware, instead of walking a plan',
    ),
    'device_defects': _Spec(
        '',
        "the simulated device's errors, 'NAME=VALUE,...' with NAME one "
        'of dL (link length offset, m: the true link is link_length + dL), '
        'alpha0, beta0 (inclinometer zero offsets, rad), gamma (skew of the '
        "inclinometer axes, rad), phi0 (rotary zero offset, rad); '' = an "
        'ideal device',
        constraints="'' or NAME=VALUE pairs (core.device.DeviceDefects.parse)",
    ),
    'device_turn': _Spec(
        0.0,
        "the device's rotation about its link axis from its normal "
        'mounting (rad; 0 normal, pi reversed, pi/2 a quarter turn), for the '
        'postures whose plan entry names none; settable at run time',
        -MAX_DEVICE_TURN,
        MAX_DEVICE_TURN,
    ),
    'max_actuator_speed_m_s': _Spec(
        0.1,
        'commanded mode: the fastest an actuator moves (m/s); '
        "slower when a point's time_from_start asks for it",
        1e-6,
        10.0,
    ),
}


class DriverConfigurationError(Exception):
    """The node's parameters do not describe a machine and plan it can simulate."""


def _parameter_problem(parameter: Parameter) -> str | None:
    """Checks beyond type and range (which the descriptors enforce)."""
    value = parameter.value
    if parameter.name == 'plan':
        if value in GENERATED_PLANS:
            return None
        if not value:
            return f"plan must be one of {list(GENERATED_PLANS)} or a plan file path, got ''"
        try:
            load_plan(value)
        except PlanError as error:
            return (
                f'plan {value!r} is neither one of {list(GENERATED_PLANS)} nor a valid '
                f'plan file: {error}'
            )
    elif parameter.name == 'true_params' and value:
        try:
            load_parameters(value)
        except ParameterFileError as error:
            return f'true_params: {error}'
    elif parameter.name == 'device_defects':
        try:
            DeviceDefects.parse(value)
        except ValueError as error:
            return f'device_defects {value!r}: {error}'
    elif parameter.name == 'device_turn' and not (
        math.isfinite(value) and abs(value) <= MAX_DEVICE_TURN
    ):
        return f'device_turn must be a finite angle within +-2 pi rad, got {value!r}'
    elif parameter.name == 'model' and value not in MODEL_CHOICES:
        return f"model must be '' or one of {', '.join(MODELS)}, got {value!r}"
    elif parameter.name in (
        'link_length',
        'rate_hz',
        'settle_s',
        'dwell_s',
        'slider_noise_m',
        'angle_noise_rad',
        'max_actuator_speed_m_s',
    ) and not math.isfinite(value):
        return f'{parameter.name} must be finite, got {value}'
    return None


class DriverNode(Node):
    """Simulated machine + device: plan walker, noisy sensors, three SENSOR_QOS publishers."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        # Registered before declaring, so command-line overrides are validated too.
        self.add_on_set_parameters_callback(self._validate_parameters)
        for name, spec in PARAMETERS.items():
            self.declare_parameter(
                name,
                spec.default,
                parameter_descriptor(name, spec, read_only=name not in RUNTIME_PARAMETERS),
            )
        self.add_post_set_parameters_callback(self._apply_parameters)
        value = {name: self.get_parameter(name).value for name in PARAMETERS}

        self.true_params, self.mount = self._load_true_params(value['true_params'], value['model'])
        self.model = self.true_params.model
        self.command_topic = value['command_topic']
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
        self.follower: CommandFollower | None = None
        if self.command_topic:
            self.follower = self._start_follower(value['max_actuator_speed_m_s'])
            plan_name = f'commanded on {self.command_topic}'
        else:
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
            self.walker = self._plan_walker(value['settle_s'], value['dwell_s'], value['loop'])
            plan_name = self.plan.name
        self.declare_parameter(
            'plan_name',
            plan_name,
            ParameterDescriptor(
                description='name of the plan being walked (set by the node)', read_only=True
            ),
            ignore_override=True,
        )
        # Noise draws from their own stream: the same seed gives the same plan whatever the noise.
        self.sensors = SensorSimulator(
            NoiseModel(value['slider_noise_m'], value['angle_noise_rad']),
            np.random.default_rng([value['seed'], 0x5E45]),
            self.mount,
            self.defects,
        )
        self.rate_hz = float(value['rate_hz'])
        self.wait_for_subscriber = bool(value['wait_for_subscriber'])

        self._sliders_pub = self.create_publisher(JointState, SLIDERS_TOPIC, SENSOR_QOS)
        self._inclinometer_pub = self.create_publisher(JointState, INCLINOMETER_TOPIC, SENSOR_QOS)
        self._encoder_pub = self.create_publisher(JointState, ENCODER_TOPIC, SENSOR_QOS)
        self._ticks = 0  # plan time is ticks / rate_hz: every posture gets its samples under load
        self.published = 0  # messages published on each of the three streams (load accounting)
        self.published_before_plan = 0  # ... of which while holding for a subscriber
        self.plan_start_stamp_ns: int | None = None  # stamp of the first message of the plan
        self._started = False
        self._started_monotonic = 0.0
        self._last_reported: tuple[int, int, str] | None = None
        self._last_phase = ''
        self._per_wake = max(1, math.ceil(self.rate_hz / MAX_WAKE_HZ - 1e-9))
        self._period_ns = int(round(NS_PER_S / self.rate_hz))
        self._last_stamp_ns = -1
        # Preallocated messages: each tick sets the stamps and positions only.
        self._messages = {
            'sliders': slider_reading_to_joint_state(
                SliderReading(0, (0.0,) * 6), model=self.model
            ),
            'inclinometer': inclinometer_reading_to_joint_state(InclinometerReading(0, 0.0, 0.0)),
            'encoder': encoder_reading_to_joint_state(EncoderReading(0, 0.0)),
        }
        # The inclinometer message of a turned device: the device_turn joint too.
        self._turned_inclinometer = inclinometer_reading_to_joint_state(
            InclinometerReading(0, 0.0, 0.0, math.pi)
        )
        self.commands_accepted = 0
        self.commands_rejected = 0
        if self.follower is not None:
            try:
                self.create_subscription(
                    JointTrajectory, self.command_topic, self._on_command, COMMAND_QOS
                )
            except InvalidTopicNameException as error:
                raise DriverConfigurationError(f'command_topic: {error}') from error
        self._timer = self.create_timer(self._per_wake / self.rate_hz, self._wake)

        if value['true_params']:
            source = value['true_params']
        elif self.model == HEXA_SLIDE:
            source = 'Table 1'
        else:
            source = f'the default {MODELS[self.model].title}'
        if self.model != HEXA_SLIDE:
            source += f' ({self.model}, joints {", ".join(MODELS[self.model].actuator_names)})'
        if self.mount != DEFAULT_MOUNT:
            source += f', {self.mount} device'
        if self.defects != DeviceDefects():
            source += f'; device defects {self.defects.describe()}'
        if self.device_turn != 0.0:
            source += f'; device turned {self.device_turn:.6g} rad about its link'
        if self.follower is not None:
            low, high = self.stroke
            topic = self.resolve_topic_name(self.command_topic)
            self.get_logger().info(
                f'following JointTrajectory commands on {topic} (joints '
                f'{", ".join(MODELS[self.model].actuator_names)}, at most '
                f'{self.follower.max_speed_m_s:g} m/s, stroke [{low:g}, {high:g}] m); true machine: '
                f'{source}; {self.rate_hz:g} Hz, noise +-{self.sensors.noise.slider_m:g} m / '
                f'+-{self.sensors.noise.angle_rad:g} rad; standing at the fixed-position point'
            )
            return
        self.get_logger().info(
            f'{self.plan.describe()}; true machine: {source}; {self.rate_hz:g} Hz, settle '
            f'{self.walker.settle_s:g} s, dwell {self.walker.dwell_s:g} s (one pass '
            f'{self.walker.lap_duration_s:.1f} s), noise +-{self.sensors.noise.slider_m:g} m / '
            f'+-{self.sensors.noise.angle_rad:g} rad{", looping" if self.walker.loop else ""}'
        )
        if self.wait_for_subscriber:
            self.get_logger().info(
                f'holding the first posture until {self._sliders_pub.topic_name} has a subscriber'
            )

    # ------------------------------------------------------------------ parameters

    def _load_true_params(self, path: str, model: str) -> tuple[KinematicParameters, str]:
        """The true machine and the device mount (the file's device.mount, else hanging)."""
        if not path:
            return architecture(model or DEFAULT_MODEL).default_parameters(), DEFAULT_MOUNT
        try:
            loaded = read_parameters_file(path)
            params = parameters_for(loaded.model, loaded.vector)
            mount = check_mount(loaded.extras.get(MOUNT_PARAMETER, DEFAULT_MOUNT))
        except (ParameterFileError, DeviceMountError, ValueError) as error:
            raise DriverConfigurationError(f'true_params: {error}') from error
        if model and model != loaded.model:
            raise DriverConfigurationError(
                f'model {model!r} contradicts true_params {path}, a {loaded.model} parameters '
                f"file: leave model '' or name the file's model"
            )
        return params, mount

    def _plan_walker(self, settle_s: float, dwell_s: float, loop: bool) -> PlanWalker:
        """The walker over the plan's postures as the true device lets the platform stand
        (simulation.device_true_poses: on the sphere L + dL, fixed ones where the turned device
        reads zero)."""
        turns = self._posture_turns()
        poses = device_true_poses(
            self.plan.poses, self.plan.kinds, self.link_length, self.defects, self.mount, turns
        )
        try:
            return PlanWalker(self.true_params, poses, settle_s, dwell_s, loop)
        except UnreachablePoseError as error:
            raise DriverConfigurationError(
                f"plan '{self.plan.name}' with the device's true link length "
                f'{self.true_link_length!r} m (device_defects): {error}'
            ) from error

    def _posture_turns(self) -> np.ndarray:
        """The device turn of every plan posture (rad): the plan's, else the parameter."""
        return np.array(
            [self.plan.device_turn(i, self.device_turn) for i in range(len(self.plan))]
        )

    def _sample_turn(self, sample) -> float:
        """The device turn while `sample` is measured: the posture's (plan mode), else the parameter."""
        if self.plan is None:
            return self.device_turn
        return self.plan.device_turn(sample.posture_index, self.device_turn)

    def _start_follower(self, max_speed: float) -> CommandFollower:
        """Commanded mode: the machine stands at the fixed-position point with zero angles."""
        from hexacal_driver.plan import machine_workspace

        self.stroke = tuple(
            float(v)
            for v in machine_workspace(
                self.true_params, self.link_length, self.mount
            ).slider_stroke_m
        )
        # The link holds the platform on the true sphere (link_length + dL).
        home = np.concatenate([fixed_point(self.true_link_length, self.mount), np.zeros(3)])
        try:
            follower = CommandFollower(
                self.true_params, home, max_speed, self.true_link_length, self.mount
            )
        except (UnreachablePoseError, ConstraintError) as error:
            raise DriverConfigurationError(
                f'commanded mode: the machine cannot stand at the fixed-position point {home[:3]} '
                f'with zero angles: {error}'
            ) from error
        low, high = self.stroke
        if np.any((follower.sliders < low) | (follower.sliders > high)):
            raise DriverConfigurationError(
                f'commanded mode: at the fixed-position point the actuators '
                f'{np.round(follower.sliders, 4).tolist()} m are outside the stroke [{low:g}, '
                f'{high:g}] m'
            )
        return follower

    def _on_command(self, message: JointTrajectory) -> None:
        """A JointTrajectory command: follow it, or reject it with the reason."""
        points = [
            (
                list(point.positions),
                point.time_from_start.sec + point.time_from_start.nanosec * 1e-9,
            )
            for point in message.points
        ]
        checked, problem = check_trajectory(
            list(message.joint_names), points, MODELS[self.model].actuator_names, self.stroke
        )
        now_ns = self.get_clock().now().nanoseconds
        start_ns = message.header.stamp.sec * NS_PER_S + message.header.stamp.nanosec
        if (
            problem is None
            and start_ns
            and start_ns + int(checked[-1].time_from_start_s * 1e9) < now_ns
        ):
            problem = 'it ends in the past (header.stamp + time_from_start)'
        if problem is not None:
            self.commands_rejected += 1
            self.get_logger().warning(f'rejected a JointTrajectory command: {problem}')
            return
        self.commands_accepted += 1
        end_s = self.follower.command(
            now_ns / NS_PER_S, checked, start_ns / NS_PER_S if start_ns else None
        )
        target = checked[-1].positions
        self.get_logger().info(
            f'command {self.commands_accepted}: to [{", ".join(f"{v * 1e3:.3f}" for v in target)}] '
            f'mm in {end_s - now_ns / NS_PER_S:.2f} s'
        )

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            problem = _parameter_problem(parameter)
            if problem:
                return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        if not hasattr(self, 'sensors'):
            return  # still declaring
        noise = self.sensors.noise
        for parameter in parameters:
            if parameter.name == 'slider_noise_m':
                noise = NoiseModel(parameter.value, noise.angle_rad)
            elif parameter.name == 'angle_noise_rad':
                noise = NoiseModel(noise.slider_m, parameter.value)
        if noise != self.sensors.noise:
            self.sensors.noise = noise
            self.get_logger().info(f'noise now +-{noise.slider_m:g} m / +-{noise.angle_rad:g} rad')
        for parameter in parameters:
            if parameter.name == 'device_turn' and float(parameter.value) != self.device_turn:
                previous, self.device_turn = self.device_turn, float(parameter.value)
                if self.walker is not None and self.defects != DeviceDefects():
                    # Fixed postures stand where the turned device reads zero: re-place them
                    # (same timing; the walk goes on from where it is).
                    walker = self.walker
                    self.walker = self._plan_walker(walker.settle_s, walker.dwell_s, walker.loop)
                self.get_logger().info(
                    f'device_turn {previous:.6g} -> {self.device_turn:.6g} rad: the device is '
                    'turned about its link axis'
                    + (
                        ' (for the postures whose plan names no turn)'
                        if self.plan is not None and self.plan.device_turns
                        else ''
                    )
                )

    # ------------------------------------------------------------------ publishing

    def _wake(self) -> None:
        """Publish the samples of one timer period, stamped 1 / rate_hz apart up to now."""
        now = self.get_clock().now().nanoseconds
        for remaining in range(self._per_wake - 1, -1, -1):
            # Strictly increasing and never ahead of the clock, even after a late wake-up.
            stamp = max(now - remaining * self._period_ns, self._last_stamp_ns + 1)
            self._last_stamp_ns = stamp
            self._tick(stamp)

    def _tick(self, stamp: int) -> None:
        if self.follower is not None:
            if not self._started:
                self._started = True
                self.published_before_plan = self.published
            sample = self.follower.sample(stamp / NS_PER_S)
            self._publish(sample, stamp)
            self._report_motion(sample.phase)
            return
        if not self._started:
            # Matched (DDS), not just on the graph, on all three: no plan sample goes to nobody.
            if (
                self.wait_for_subscriber
                and min(
                    publisher.get_subscription_count()
                    for publisher in (self._sliders_pub, self._inclinometer_pub, self._encoder_pub)
                )
                == 0
            ):
                self._publish(self.walker.sample(0.0), stamp)
                return
            self._started = True
            self._started_monotonic = time.monotonic()
            self.published_before_plan = self.published
            self.get_logger().info(f"starting plan '{self.plan.name}'")
        sample = self.walker.sample(self._ticks / self.rate_hz)
        self._ticks += 1
        self._publish(sample, stamp)
        self._report(sample.posture_index, sample.lap, sample.phase)

    def _publish(self, sample, stamp: int) -> None:
        turn = self._sample_turn(sample)
        readings = self.sensors.read(sample, turn)
        # One stamp for the three: the sensors are sampled together.
        if self._started and self.plan_start_stamp_ns is None:
            self.plan_start_stamp_ns = stamp
        seconds, nanoseconds = divmod(stamp, NS_PER_S)
        messages = self._messages
        for message in messages.values():
            message.header.stamp.sec = seconds
            message.header.stamp.nanosec = nanoseconds
        messages['sliders'].position = readings.sliders_m.tolist()
        if turn == 0.0:  # the normal mounting: the message as it always was
            inclinometer = messages['inclinometer']
            inclinometer.position = [readings.alpha_rad, readings.beta_rad]
        else:
            inclinometer = self._turned_inclinometer
            inclinometer.header.stamp.sec = seconds
            inclinometer.header.stamp.nanosec = nanoseconds
            inclinometer.position = [readings.alpha_rad, readings.beta_rad, turn]
        messages['encoder'].position = [readings.phi_rad]
        self._sliders_pub.publish(messages['sliders'])
        self._inclinometer_pub.publish(inclinometer)
        self._encoder_pub.publish(messages['encoder'])
        self.published += (
            1  # complete ticks: Ctrl-C may cut the last one after some of its publishes
        )

    def _report_motion(self, phase: str) -> None:
        """Commanded mode: one line when a commanded motion ends (with the link's strain); a
        warning while the link strains the machine beyond STRAIN_WARNING_M."""
        strain = self.follower.strain_m
        if strain > STRAIN_WARNING_M:
            self.get_logger().warning(
                f'the measuring link strains the machine: actuators {strain * 1e3:.1f} mm from '
                'their setpoints (commanded positions off the link sphere: move along it)',
                throttle_duration_sec=STRAIN_WARNING_PERIOD_S,
            )
        if phase == self._last_phase:
            return
        self._last_phase = phase
        if phase != MOVING and self.commands_accepted:
            strain = self.follower.strain_m
            self.get_logger().info(
                f'standing at the commanded position (actuators {strain * 1e6:.0f} um from the '
                'setpoints: the strain of the measuring link)'
                if strain > 1e-6
                else 'standing at the commanded position'
            )

    def _report(self, index: int, lap: int, phase: str) -> None:
        state = (index, lap, phase)
        if phase not in (DWELLING, DONE) or state == self._last_reported:
            return
        self._last_reported = state
        elapsed = time.monotonic() - self._started_monotonic
        if phase == DONE:
            self.get_logger().info(
                f"end of plan '{self.plan.name}': {len(self.plan)} postures in {elapsed:.1f} s; "
                'standing at the last posture'
            )
            return
        pose = self.plan.poses[index]
        lap_text = f' (lap {lap + 1})' if self.walker.loop else ''
        self.get_logger().info(
            f'posture {index + 1}/{len(self.plan)}{lap_text} ({self.plan.kinds[index]}): '
            f'position [{pose[0] * 1e3:.1f}, {pose[1] * 1e3:.1f}, {pose[2] * 1e3:.1f}] mm, '
            f'angles [{math.degrees(pose[3]):.1f}, {math.degrees(pose[4]):.1f}, '
            f'{math.degrees(pose[5]):.1f}] deg'
            + (
                f', device turned {turn:.6g} rad'
                if (turn := self.plan.device_turn(index, self.device_turn)) != 0.0
                else ''
            )
        )
        if self.walker.loop and index == len(self.plan) - 1:
            self.get_logger().info(f"end of plan '{self.plan.name}' lap {lap + 1}: looping")


SHUTDOWN_LINGER_S = 0.3


def _finish(node: DriverNode) -> list[str]:
    # Best-effort samples of the last ticks may still sit in Fast DDS's writer queues: give its
    # send threads a moment before the publishers are destroyed, so a stop loses nothing in flight.
    time.sleep(SHUTDOWN_LINGER_S)
    lines = [
        f'published {node.published} messages on each sensor stream, '
        f'{node.published - node.published_before_plan} of them since the plan '
        f'started (first stamp {node.plan_start_stamp_ns} ns)'
    ]
    if node.follower is not None:
        lines.append(
            f'commands: {node.commands_accepted} followed, {node.commands_rejected} rejected'
        )
    return lines


def main(args: list[str] | None = None) -> int:
    return run_node(
        NODE_NAME,
        DriverNode,
        args=args,
        finish=_finish,
        startup_errors=(DriverConfigurationError, InvalidParameterValueException),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
