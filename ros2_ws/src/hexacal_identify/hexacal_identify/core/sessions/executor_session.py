"""
What the executor node decides besides the walk itself (ROS-free).

* `setup_walk`: the walk its parameters, nominal machine and plan describe:
  joints, stroke, settings, the plan checked before anything moves (refused:
  state REFUSED, nothing is ever commanded), the `PlanExecution`.
* `ExecutorStatus`: the fields, level and text of the executor's status
  (``hexacal/calibration_status``, status name 'hexacal executor'): the walk's
  progress, the plan, the refusal, what the start waits for, the calibration
  call, the device_turn requests; when it is due (at every change, and at
  least every ``STATUS_PERIOD_S`` for the ETA).
* `refine_step`: the intermediate calibrations of ``refine_targets``.
* `CalibrationCall`: ``calibrate_when_done``, the call of hexacal/calibrate
  once the plan is done.
* `parameter_problem`: the checks of the node's parameters beyond type and
  range (which their descriptors enforce); `load_plan`, `plan_mismatch`: a plan for
  another model or device mount than the nominal file's is refused.
* `inclinometer_line`: how fixed positions are judged, for the start's log.

What it asks of the drive and hears from it (release calls, the drive's mode):
core/walk/drive_calls.py.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import enum
import math
import re
from typing import Any, TYPE_CHECKING

from hexacal_msgs_py.inputs import DEFAULT_OFFSETS_RAD, DEFAULT_SIGNS, IMU_INCLINOMETER
from hexacal_msgs_py.inputs import InputMapping
from hexacal_msgs_py.measuring_modes import measuring_mode, MeasuringMode
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY, MODELS
from hexacal_msgs_py.names import INCLINOMETER_TOPIC
from hexacal_msgs_py.parameters_file import read_parameters_file

from ..architectures import KinematicParameters
from ..architectures.actuator_defaults import actuator_defaults
from ..machine.device import DEFAULT_MOUNT
from ..machine.measurements import FIXED, SPHERE
from ..planning.plan_check import check_stroke, plan_problems, plan_stroke, refusal_message
from ..walk.execution import Guard, PlanExecution
from ..walk.guard import GuardSettings, move_guard
from ..walk.messages import LogLevel, Messages
from ..walk.mode_driver import walk_mode, WalkMode
from ..walk.platform_paths import Command
from ..walk.settings import ExecutionSettings, ExecutionState
from ..walk_device.turns import DeviceTurnSetter, TURN_PARAMETER, TurnSetState
from ..walk_refine.refined_targets import refine_checkpoints, RefineCall, RefineState

if TYPE_CHECKING:
    from ..modes.link_load import LinkLoad
    from ..planning.planner import Plan

STATUS_PERIOD_S = 1.0  # progress (ETA) is republished at least this often
SERVICE_WAIT_S = 30.0  # calibrate_when_done: how long hexacal/calibrate may take to appear
_TIMES = ('eta_s', 'elapsed_s', 'paused_s')  # change every second: not a change of status
_NODE_NAME = re.compile(r'^/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$')


def joint_names(name: str, value: object, count: int) -> tuple[str, ...]:
    """Return `count` distinct non-empty joint names; ValueError naming parameter `name`."""
    if (
        not isinstance(value, (list, tuple))
        or len(value) != count
        or not all(isinstance(item, str) and item for item in value)
        or len(set(value)) != count
    ):
        raise ValueError(f'{name} must be {count} distinct joint names, got {value!r}')
    return tuple(value)


def node_names(value: object) -> tuple[str, ...]:
    """Return device_turn_nodes: distinct node names (relative or absolute); else ValueError."""
    if (
        not isinstance(value, (list, tuple))
        or not all(isinstance(item, str) and _NODE_NAME.match(item) for item in value)
        or len(set(value)) != len(value)
    ):
        raise ValueError(
            f'device_turn_nodes must be distinct node names (e.g. [collector, driver]), got '
            f'{list(value) if isinstance(value, (list, tuple)) else value!r}'
        )
    return tuple(value)


def parameter_problem(name: str, value: Any) -> str | None:
    """Return what is wrong with the executor's parameter `name` set to `value` (None: fine)."""
    if name in ('plan', 'nominal') and not value:
        return f"parameter '{name}' is required (-p {name}:=<path>)"
    if name == 'command_topic' and not value:
        return 'command_topic must name a topic'
    if isinstance(value, float) and not math.isfinite(value):
        return f'{name} must be finite, got {value}'
    try:
        if name == 'stroke_limits_m':
            try:
                check_stroke(list(value))
            except ValueError as error:
                return f'stroke_limits_m: {error}'
        elif name == 'actuator_joints':
            joint_names(name, list(value), 6)
        elif name == 'inclinometer_joints':
            joint_names(name, list(value), 2)
        elif name == 'device_turn_nodes':
            node_names(list(value))
        elif name == 'measuring_mode' and value:
            measuring_mode(value)
    except (TypeError, ValueError) as error:
        return str(error)
    return None


def plan_mismatch(
    plan_path: str, plan_model: str, plan_mount: str, model: str, nominal_mount: str | None
) -> str | None:
    """
    Return why a plan cannot be walked on the nominal machine (None: it can).

    The plan must be for the nominal file's model, and for its device mount
    when the file names one (``nominal_mount`` None: it names none).
    """
    if plan_model != model:
        return (
            f'plan {plan_path} was made for a {plan_model} (plan.model; absent: hexa_slide) but '
            f'the nominal machine is a {model}'
        )
    if nominal_mount is not None and plan_mount != nominal_mount:
        return (
            f'plan {plan_path} is for a {plan_mount} device (plan.mount; absent: '
            f'{DEFAULT_MOUNT}) but the nominal file says {DEVICE_MOUNT_KEY}: {nominal_mount}'
        )
    return None


def load_plan(path: str, nominal_path: str, nominal_mount: str, model: str) -> Plan:
    """
    Return the plan at `path` if it can be walked on the nominal machine; else ValueError.

    A nominal file that names no device.mount (read as the default) takes any plan's mount.
    """
    from ..planning.planner import Plan

    try:
        plan = Plan.load(path)
    except (OSError, ValueError) as error:
        raise ValueError(f'plan: {error}') from error
    named = nominal_mount != DEFAULT_MOUNT or (
        plan.mount != nominal_mount
        and DEVICE_MOUNT_KEY in read_parameters_file(nominal_path).extras
    )
    problem = plan_mismatch(
        path, plan.model, plan.mount, model, nominal_mount if named else None
    )
    if problem:
        raise ValueError(problem)
    return plan


def inclinometer_line(mapping: InputMapping, settings: ExecutionSettings) -> str:
    """Return the log line on how fixed positions are judged (the inclinometer input)."""
    what = (
        'sensor_msgs/Imu orientation'
        if mapping.inclinometer_type == IMU_INCLINOMETER
        else f'JointState {", ".join(mapping.inclinometer_joints)}'
    )
    window = settings.inclinometer_settle_s
    text = f'fixed positions: inclinometer <- {mapping.input_topic(INCLINOMETER_TOPIC)} ({what})'
    corrections = (mapping.inclinometer_signs, mapping.inclinometer_offsets_rad)
    if corrections != (DEFAULT_SIGNS, DEFAULT_OFFSETS_RAD):
        text += (
            f', signs {list(mapping.inclinometer_signs)}, offsets '
            f'{list(mapping.inclinometer_offsets_rad)} rad'
        )
    return text + (
        f'; judged once settled over two {window:g} s windows'
        if window
        else f'; judged on the mean over settle_s ({settings.settle_s:g} s)'
    )


def start_waits(
    readings: bool,
    sliders_topic: str,
    controllers: int,
    command_topic: str,
    no_collector: bool,
    posture_topic: str,
) -> list[str]:
    """
    Return what the start waits for (empty: nothing).

    The plan starts once the machine is there: actuator readings, a controller on the command
    topic, (wait_for_posture: `no_collector` says none publishes postures) a collector; the
    node adds the nodes set to the mounting (core/walk_device/turns.py).
    """
    waiting = []
    if not readings:
        waiting.append(f'actuator readings on {sliders_topic}')
    if controllers == 0:
        waiting.append(f'a controller on {command_topic}')
    if no_collector:
        waiting.append(f'a collector on {posture_topic}')
    return waiting


@dataclass(frozen=True)
class WalkSetup:
    """The walk the executor's parameters describe on the nominal machine."""

    actuator_joints: tuple[str, ...]  # in chain order, as the controller names them
    inclinometer_joints: tuple[str, ...]  # alpha, beta
    stroke: tuple[float, float]  # m
    stroke_source: str  # where the stroke comes from (for the log)
    settings: ExecutionSettings
    device_turn_nodes: tuple[str, ...]
    problems: dict[int, str]  # posture index -> why it cannot be commanded (refused)
    refusal: str  # '' unless refused
    execution: PlanExecution
    mode: WalkMode
    guard: GuardSettings
    weights: str = ''  # where the link's weights come from (walk_link_load), when weighed

    def start_lines(self, plan: Plan, model: str, command_topic: str) -> list[str]:
        """Return what the node logs at the start: the plan, the commands, the turns."""
        kinds, stroke = [str(kind) for kind in plan.kinds], self.stroke
        units = MODELS[model].actuator_quantities  # m and m/s, or rad and rad/s for cranks
        counts = {kind: kinds.count(kind) for kind in (SPHERE, FIXED)}
        lines = [
            f"plan '{plan.name}': {len(plan.poses)} postures ({counts[SPHERE]} sphere, "
            f'{counts[FIXED]} fixed) for a {model}; commands on {command_topic} (joints '
            f'{", ".join(self.actuator_joints)}), at most '
            f'{self.settings.max_actuator_speed_m_s:g} {units.speed_unit}, stroke '
            f'[{stroke[0]:g}, {stroke[1]:g}] {units.unit} ({self.stroke_source})'
        ]
        turns = sorted({float(turn) for turn in plan.turns})
        if any(turns):
            degrees = [round(math.degrees(t), 3) for t in turns]
            lines.append(
                f'turning procedure: device turns {degrees} deg; '
                + (
                    f'device_turn set on {", ".join(self.device_turn_nodes)} at each remount'
                    if self.device_turn_nodes
                    else 'device_turn_nodes is empty: no node is told the turn'
                )
            )
        if self.mode.source != 'default':  # a plan without a mode walks as it always did
            lines.append(self.mode.describe(self.actuator_joints))
        load = self.execution.link_load
        if load is not None:
            lines.append(
                'releases chosen again at the machine keep the measuring link within the '
                f"plan's {load.max_force_n:g} N (weights: {self.weights})"
            )
        return lines

    def start_messages(
        self, plan: Plan, model: str, command_topic: str, mapping: InputMapping
    ) -> Messages:
        """Return what the node logs at the start: `start_lines`, the inclinometer, a refusal."""
        messages: Messages = [
            (LogLevel.INFO, line) for line in self.start_lines(plan, model, command_topic)
        ]
        if FIXED in self.execution.kinds:
            messages.append((LogLevel.INFO, inclinometer_line(mapping, self.settings)))
        if self.problems:
            messages.append((LogLevel.ERROR, self.refusal))
        return messages

    def status(
        self, plan: str, model: str, calibration: CalibrationCall, turns: DeviceTurnSetter
    ) -> ExecutorStatus:
        """Return the executor's status of this walk."""
        status = ExecutorStatus(
            self.execution, plan, model, sorted(self.problems), calibration, turns
        )
        status.measuring_mode = self.mode.mode.value
        status.joint_names = self.actuator_joints
        return status


# The executor's parameters that are actuator quantities (core.architectures.actuator_defaults)
# and their slider-sized defaults (ExecutionSettings', GuardSettings'): the nominal model's
# defaults follow from them.
ACTUATOR_PARAMETERS = {
    'max_actuator_speed_m_s': 'speed',
    'position_tolerance_m': 'length',
    'still_tolerance_m': 'length',
    'servo_stiffness_n_per_m': 'stiffness',
    'max_force_n': 'force',
    'released_margin_m': 'length',
}
ACTUATOR_DEFAULTS = {
    name: getattr(
        GuardSettings() if name in GuardSettings.__dataclass_fields__ else ExecutionSettings(),
        name,
    )
    for name in ACTUATOR_PARAMETERS
}


def model_defaults(
    metadata: dict, nominal: KinematicParameters
) -> tuple[dict[str, Any], str]:
    """
    Return the defaults of the model's parameters and where the stroke comes from.

    The model's parameters: the stroke, the joint names and the actuator quantities
    (ACTUATOR_PARAMETERS, in the nominal model's actuator unit).
    """
    stroke, source = plan_stroke(metadata, nominal)
    return {
        'stroke_limits_m': list(stroke),
        'actuator_joints': list(nominal.layout.actuator_names),
        **actuator_defaults(nominal.model, ACTUATOR_DEFAULTS, ACTUATOR_PARAMETERS),
    }, source


def setup_walk(
    values: Mapping[str, Any],
    nominal: KinematicParameters,
    plan: Plan,
    stroke_source: str,
    default_stroke: list[float],
) -> WalkSetup:
    """
    Return the walk of `plan` the parameter `values` describe.

    ValueError naming the parameter if they describe none; a plan with
    postures that cannot be commanded is refused (state REFUSED).
    """
    actuator_joints = joint_names('actuator_joints', list(values['actuator_joints']), 6)
    inclinometer_joints = joint_names(
        'inclinometer_joints', list(values['inclinometer_joints']), 2
    )
    if list(values['stroke_limits_m']) != list(default_stroke):
        stroke_source = 'stroke_limits_m'
    try:
        stroke = check_stroke(list(values['stroke_limits_m']))
    except ValueError as error:
        raise ValueError(f'stroke_limits_m: {error}') from error
    settings = ExecutionSettings(  # a setting not given keeps its default
        **{name: values[name] for name in ExecutionSettings.__dataclass_fields__ if name in values}
    )
    turn_nodes = node_names(list(values['device_turn_nodes']))
    poses, link_length, mount = plan.poses, plan.link_length, plan.mount
    targets, problems = plan_problems(
        nominal, poses, plan.kinds, stroke, link_length, mount, settings.path_step_m
    )
    try:
        mode = walk_mode(
            str(values.get('measuring_mode', '')),
            plan.measuring_mode,
            plan.released_actuators,
            nominal,
            poses,
            link_length,
            stroke,
            mount,
        )
    except ValueError as error:
        raise ValueError(f'measuring_mode: {error}') from error
    guard_settings = GuardSettings(  # a setting not given keeps its default
        **{name: values[name] for name in GuardSettings.__dataclass_fields__ if name in values}
    )
    # A plan without a mode walks as it always did: no prediction in the default compliant mode.
    guard = (
        move_guard(nominal, mode.mode, link_length, stroke, guard_settings, mount)
        if mode.source != 'default'
        else None
    )
    link_load, weights = walk_link_load(
        str(values.get('physical_file', '')), plan.metadata, nominal.model, mode.mode
    )
    execution = PlanExecution(
        nominal,
        poses,
        plan.kinds,
        targets,
        settings,
        stroke,
        link_length,
        mount,
        start_paused=bool(values['start_paused']),
        device_turns=plan.turns,
        mounted_turn=float(values['mounted_turn']),
        released=mode.released,
        guard=guard,
        refine_at=refine_checkpoints(
            bool(values.get('refine_targets', False)), nominal.layout.n_parameters, len(poses)
        ),
        link_load=link_load,
    )
    refusal = refusal_message(problems, len(targets)) if problems else ''
    if problems:  # nothing is ever commanded
        execution.state = ExecutionState.REFUSED
        execution.refusal = refusal
    return WalkSetup(
        actuator_joints,
        inclinometer_joints,
        stroke,
        stroke_source,
        settings,
        turn_nodes,
        problems,
        refusal,
        execution,
        mode,
        guard_settings,
        weights,
    )


def walk_link_load(
    physical_file: str, metadata: Mapping[str, Any] | None, model: str, mode: MeasuringMode
) -> tuple[LinkLoad | None, str]:
    """
    Return the link's load the executor's own release choices keep within, and its weights' file.

    A passive_actuator plan made with the link's load names its limit (``link_force_limit_n``);
    the weights are `physical_file`'s ('' : the model's shipped physical description).  (None,
    '') for any other plan.  ValueError naming physical_file when it cannot be read.
    """
    limit = (metadata or {}).get('link_force_limit_n')
    if mode != MeasuringMode.PASSIVE_ACTUATOR or limit is None:
        return None, ''
    from ..fit.statics import physical_weights
    from ..modes.link_load import LinkLoad

    try:
        masses, source = physical_weights(physical_file, model)
        return LinkLoad(masses, float(limit)), source
    except (ValueError, TypeError) as error:  # PhysicalFileError is a ValueError
        raise ValueError(f'physical_file: {error}') from error


def refined_guard(setup: WalkSetup, model: KinematicParameters) -> Guard | None:
    """Return the walk's guard predicting on the intermediate `model` (None: no guard)."""
    execution = setup.execution
    if execution.guard is None:
        return None
    return move_guard(
        model,
        setup.mode.mode,
        execution.link_length,
        execution.stroke,
        setup.guard,
        execution.mount,
    )


def input_mapping(
    values: Mapping[str, Any], setup: WalkSetup, topics: Sequence[str]
) -> InputMapping:
    """
    Return how the inputs are read, as the collector reads them (InputMappingError if not).

    `topics`: the resolved sliders and inclinometer topics (the executor reads no encoder).
    """
    return InputMapping(
        actuator_joints=setup.actuator_joints,
        inclinometer_joints=setup.inclinometer_joints,
        inclinometer_type=values['inclinometer_type'],
        inclinometer_signs=values['inclinometer_signs'],
        inclinometer_offsets_rad=values['inclinometer_offsets_rad'],
        topics=(topics[0], topics[1], ''),
    )


def refine_step(
    refine: RefineCall, setup: WalkSetup, now: float, service_ready: bool
) -> tuple[bool, list[Command] | None]:
    """
    Advance the intermediate calibration the walk asks (``refine_request``).

    Return whether to call hexacal/calibrate now, and once it is answered (or has timed out)
    the walk's commands re-targeted on the intermediate model (None until then).
    """
    execution = setup.execution
    call = False
    if refine.state != RefineState.WAITING:
        postures = execution.refine_request
        assert postures is not None
        call = refine.start(now, postures, service_ready)
    refine.poll(now)
    if refine.state != RefineState.DONE:
        return call, None
    refine.state = RefineState.IDLE
    model = refine.model
    guard = refined_guard(setup, model) if model is not None else None
    return call, execution.on_refined(now, model, refine.message, guard)


class CalibrationState(enum.StrEnum):
    """calibrate_when_done's call (status field ``calibration``: the values)."""

    DISABLED = 'disabled'
    PENDING = 'pending'  # until the plan is done and the service is there
    RUNNING = 'running'
    SUCCESS = 'success'
    FAILED = 'failed'


class CalibrationCall:
    """The call of hexacal/calibrate once the plan is done (calibrate_when_done)."""

    def __init__(self, enabled: bool, service: str):
        self.enabled = bool(enabled)
        self.service = service
        self.state = CalibrationState.PENDING if enabled else CalibrationState.DISABLED
        self.message = ''  # the service's answer, or why it was not called
        self.requested_at: float | None = None
        self.messages: Messages = []  # for the node to log

    @property
    def answered(self) -> bool:
        """Return whether nothing more will happen (disabled, answered or failed)."""
        return self.state not in (CalibrationState.PENDING, CalibrationState.RUNNING)

    def due(self, now: float, service_ready: bool) -> bool:
        """Return whether to call the service now (the plan is done); fail if it never appears."""
        if self.state != CalibrationState.PENDING:
            return False
        if self.requested_at is None:
            self.requested_at = now
            self.messages.append((LogLevel.INFO, f'plan done: calling {self.service}'))
        if not service_ready:
            if now - self.requested_at > SERVICE_WAIT_S:
                self.state = CalibrationState.FAILED
                self.message = f'{self.service} did not appear within {SERVICE_WAIT_S:g} s'
                self.messages.append((LogLevel.ERROR, f'calibration not run: {self.message}'))
            return False
        self.state = CalibrationState.RUNNING
        return True

    def answer(self, success: bool, message: str) -> None:
        """Record what the service answered: success and message, or False and the error."""
        self.state = CalibrationState.SUCCESS if success else CalibrationState.FAILED
        self.message = message
        if success:
            self.messages.append((LogLevel.INFO, f'calibration: {message}'))
        else:
            self.messages.append((LogLevel.ERROR, f'calibration failed: {message}'))


class ExecutorStatus:
    """The executor's status: fields, level, text, and when to publish them."""

    def __init__(
        self,
        execution: PlanExecution,
        plan: str,
        model: str,
        refused_postures: list[int],
        calibration: CalibrationCall,
        turns: DeviceTurnSetter,
    ):
        self.execution = execution
        self.plan = plan
        self.model = model
        self.refused_postures = list(refused_postures)  # 0-based
        self.calibration = calibration
        self.turns = turns
        self.commands_sent = 0
        self.invalid_readings = 0
        self.waiting_for: tuple[str, ...] = ()  # what the start waits for
        self._last_key: tuple | None = None
        self._last_s = 0.0
        # Set by the node: the mode walked and the controller's joint names.
        self.measuring_mode = ''
        self.joint_names: tuple[str, ...] = ()

    def values(self, now: float) -> dict[str, object]:
        """Return the status fields (KeyValues) at `now` (s)."""
        execution = self.execution
        values: dict[str, object] = dict(execution.progress(now))
        values['plan'] = self.plan
        values['model'] = self.model
        values['commands_sent'] = self.commands_sent
        if execution.state == ExecutionState.REFUSED:
            values['refused_postures'] = ', '.join(str(i + 1) for i in self.refused_postures)
            values['reason'] = execution.refusal
        if execution.state == ExecutionState.WAITING and self.waiting_for:
            values['waiting_for'] = '; '.join(self.waiting_for)
        if self.calibration.enabled:
            values['calibration'] = self.calibration.state
            if self.calibration.message:
                values['calibration_message'] = self.calibration.message
        values['targets_model'] = execution.targets_model
        if execution.refine_message:
            values['targets_refinement'] = execution.refine_message
        if execution.waiting_for_turn:
            values['notice'] = execution.turn_notice
        elif execution.notice:
            values['notice'] = execution.notice
        if self.measuring_mode:
            values['measuring_mode'] = self.measuring_mode
        if self.measuring_mode == 'passive_actuator':
            released = execution.released_now
            values['released_joint'] = '' if released is None else self.joint_names[released]
        if self.turns.state is not None:
            values['device_turn_set'] = self.turns.state
            if self.turns.message:
                values['device_turn_set_message'] = self.turns.message
        if self.invalid_readings:
            values['invalid_readings'] = self.invalid_readings
        return values

    def wait_for(self, waiting: Sequence[str]) -> bool:
        """Record what the start waits for; return whether that changed (log and publish it)."""
        if tuple(waiting) == self.waiting_for:
            return False
        self.waiting_for = tuple(waiting)
        return True

    def due(self, now: float, values: dict[str, object], force: bool = False) -> bool:
        """Return whether to publish `values` now: forced, changed, or STATUS_PERIOD_S passed."""
        key = tuple((k, v) for k, v in values.items() if k not in _TIMES)
        if not force and key == self._last_key and now - self._last_s < STATUS_PERIOD_S:
            return False
        self._last_key, self._last_s = key, now
        return True

    def level(self, values: dict[str, object]) -> str:
        """Return the diagnostic level: ERROR (refused, calibration failed), WARN or OK."""
        state = self.execution.state
        if state == ExecutionState.REFUSED or self.calibration.state == CalibrationState.FAILED:
            return 'ERROR'
        if (
            state == ExecutionState.ABORTED
            or values.get('skipped')
            or self.turns.state == TurnSetState.FAILED
            or (state == ExecutionState.PAUSED and self.execution.notice)
        ):
            return 'WARN'
        return 'OK'

    def text(self, values: dict[str, object]) -> str:
        """Return the status message: one line on where the walk stands."""
        execution = self.execution
        state = execution.state
        if state == ExecutionState.REFUSED:
            return execution.refusal
        if state == ExecutionState.WAITING:
            return 'waiting for ' + ', '.join(self.waiting_for) if self.waiting_for else 'starting'
        text = (
            f'{state}: posture {values["posture"]} of {values["postures"]}, '
            f'{values["measured"]} measured, {values["skipped"]} skipped'
        )
        if 'eta_s' in values and state in (ExecutionState.RUNNING, ExecutionState.PAUSED):
            text += f', ETA {values["eta_s"]:.0f} s'
        if execution.notice and state == ExecutionState.PAUSED:
            text += f'; {execution.notice}'
        if execution.waiting_for_turn:
            text += f'; {execution.turn_notice}'
            if self.turns.state == TurnSetState.PENDING:
                text += f' (setting {TURN_PARAMETER} on {self.turns.names})'
        if self.calibration.enabled and state == ExecutionState.DONE:
            text += f'; calibration {self.calibration.state}'
            if self.calibration.message:
                text += f': {self.calibration.message}'
        return text

    def finished(self) -> bool:
        """Return whether the node has nothing left to do (shutdown_when_done)."""
        state = self.execution.state
        if state in (ExecutionState.ABORTED, ExecutionState.REFUSED):
            return True
        return state == ExecutionState.DONE and self.calibration.answered
