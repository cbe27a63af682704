"""
What the ``kinematics`` node decides, without ROS: the calibrated model at work.

A `LiveSession` holds the parameters in use and the latest pose, and decides:
which calibration to take (`take_calibration`: a new one, the same again, one of
another model), which actuator readings to solve (`wants_reading`: at most one
per `min_period_ns` of their stamps), the pose of a reading (`solve`: from the
previous pose, else the workspace centre), whether a target pose becomes a
command or is refused and why (`command`, `RefusalReason`), which chain
compliances load the pose and the commands (`use_compliances`: the calibration's
compliance section with the weights of the physical description, `loaded_chains`),
when the markers are drawn again and how often a repeated problem is reported. Each decision
comes back as a `Report`: the status (level, `Outcome`, message, values) and
the log line the node publishes and logs. The node converts messages and
publishes; the texts, reasons and status values are all made here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
import math
from typing import Any, cast

from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.interface_names import SLIDERS_TOPIC
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.physical_file import (
    default_physical,
    PhysicalDescription,
    PhysicalFileError,
    read_physical_file,
)
import numpy as np

from ..architectures import KinematicParameters
from ..errors import ForwardKinematicsError, UnreachablePoseError
from ..fit.statics import MassModel, physical_source
from ..machine.device import MOUNTS
from ..machine.live import (
    actuator_targets,
    default_stroke,
    home_pose,
    LoadedChains,
    OutOfStrokeError,
    solve_pose,
)

MIN_MOVE_TIME_S = 0.1  # a command's time_from_start is never shorter
LOG_PERIOD_S = 5.0  # repeated problems (bad readings, failed solves) are reported this seldom
POSE_FIELDS = ('x', 'y', 'z', 'theta', 'psi', 'phi')


class KinematicsConfigurationError(ValueError):
    """Raise when the node's parameters do not describe a machine it can work with."""


class Level(StrEnum):
    """Diagnostic level of a status (the names diagnostic_status takes)."""

    OK = 'OK'
    WARN = 'WARN'
    ERROR = 'ERROR'


class Outcome(StrEnum):
    """The `outcome` value of a kinematics status."""

    WAITING = 'waiting'
    PARAMETERS = 'parameters'
    TRACKING = 'tracking'
    SENT = 'sent'
    REFUSED = 'refused'
    POSE_FAILED = 'pose-failed'
    INVALID_READING = 'invalid-reading'
    INVALID_PARAMETERS = 'invalid-parameters'
    MODEL_MISMATCH = 'model-mismatch'
    NOT_DEPLOYED = 'not-deployed'  # a parameters message that is not the deployed calibration


class RefusalReason(StrEnum):
    """Why a target pose was refused (the `reason` value of a `refused` status)."""

    WRONG_FRAME = 'wrong-frame'
    NO_PARAMETERS = 'no-parameters'
    INVALID_TARGET = 'invalid-target'
    OUTSIDE_STROKE = OutOfStrokeError.reason
    UNREACHABLE_POSE = UnreachablePoseError.reason
    NO_ACTUATOR_READINGS = 'no-actuator-readings'


@dataclass(frozen=True)
class Report:
    """A status to publish and the line to log (at the level's severity)."""

    level: Level
    outcome: Outcome
    message: str
    values: Mapping[str, object] = field(default_factory=dict)  # status values after the counters
    log: str = ''  # the log line when it is not the message
    log_level: Level | None = None  # the log's severity when it is not the status level

    @property
    def log_line(self) -> str:
        """Return the line to log."""
        return self.log or self.message


@dataclass(frozen=True)
class Command:
    """A compensated actuator command: joint names, targets (m) and the move time (s)."""

    names: tuple[str, ...]
    targets: np.ndarray
    move_s: float


def check_parameter(
    name: str, value: object, load: Callable[[str], object] | None = None
) -> str | None:
    """Return why a node parameter value is refused, or None (`load` tries a parameters file)."""
    if name == 'stroke_limits' and value is not None:
        limits = list(value)  # type: ignore[call-overload]
        if len(limits) != 2 or not all(math.isfinite(v) for v in limits) or limits[0] >= limits[1]:
            return f'stroke_limits must be [low, high] (m) with low < high, got {limits}'
    elif name == 'model' and value not in ('', *MODELS):
        return f"model must be '' or one of {', '.join(MODELS)}, got {value!r}"
    elif name == 'mount' and value not in ('', *MOUNTS):
        return f"mount must be '' or one of {', '.join(MOUNTS)}, got {value!r}"
    elif name in ('base_frame', 'command_topic') and not value:
        return f'{name} must not be empty'
    elif name == 'parameters' and value and load is not None:
        try:
            load(str(value))
        except KinematicsConfigurationError as error:
            return str(error)
    elif name == 'physical_file' and value:
        try:
            read_physical(str(value))
        except KinematicsConfigurationError as error:
            return str(error)
    elif isinstance(value, float) and not math.isfinite(value):
        return f'{name} must be finite, got {value}'
    return None


def read_physical(path: str) -> PhysicalDescription:
    """Return the physical description of a file; errors as configuration errors."""
    try:
        return read_physical_file(path)
    except PhysicalFileError as error:
        raise KinematicsConfigurationError(f'physical_file: {error}') from error


def loaded_chains(
    model: str, compliances: Mapping[str, float], physical_file: str = ''
) -> tuple[LoadedChains | None, str]:
    """
    Return the chains that load the machine of a calibration, and the status text saying so.

    ``compliances``: the calibration's compliance section (m/N; {}: rigid); the weights come from
    ``physical_file`` ('' = the model's shipped physical description). The link's compliance is
    the calibration's only (the link is off the machine in operation). A physical description
    of another model is a KinematicsConfigurationError.
    """
    physical = read_physical(physical_file) if physical_file else default_physical(model)
    if physical.model != model:
        raise KinematicsConfigurationError(
            f'physical_file {physical_file} describes a {physical.model}, the calibration is '
            f'of a {model}'
        )
    try:
        loaded = LoadedChains.from_file_values(compliances, MassModel.from_physical(physical))
    except ValueError as error:
        raise KinematicsConfigurationError(f'compliance: {error}') from error
    if loaded is None:
        return None, 'none (rigid)'
    if len(set(loaded.compliances)) == 1:
        values = f'chains {loaded.compliances[0]:.4g} m/N'
    else:
        values = 'chains ' + ', '.join(f'{c:.4g}' for c in loaded.compliances) + ' m/N'
    return loaded, f'{values}, loaded by the weights of {physical_source(physical_file, model)}'


def stroke(params: KinematicParameters, limits: Sequence[float] | None) -> tuple[float, float]:
    """Return the stroke limits commands must respect (m): `limits`, else the architecture's."""
    if limits is None:
        return default_stroke(params)
    return float(limits[0]), float(limits[1])


def pose_text(pose: np.ndarray) -> str:
    """Return a pose as '[x, y, z] m, [theta, psi, phi] rad'."""
    return (
        f'[{pose[0]:.6f}, {pose[1]:.6f}, {pose[2]:.6f}] m, '
        f'[{pose[3]:.6f}, {pose[4]:.6f}, {pose[5]:.6f}] rad'
    )


def pose_values(prefix: str, pose: np.ndarray | None) -> dict[str, float]:
    """Return the status values '<prefix>.x' .. '<prefix>.phi' of a pose ({} for None)."""
    if pose is None:
        return {}
    return {f'{prefix}.{k}': float(v) for k, v in zip(POSE_FIELDS, pose)}


class LiveSession:
    """The parameters in use, the latest pose and the counters of one kinematics node."""

    def __init__(
        self,
        params: KinematicParameters | None,
        parameters_source: str,
        home: np.ndarray,
        min_period_ns: int,
    ) -> None:
        self.params = params
        self.parameters_source = parameters_source
        self.parameters_updates = 0
        self.home = home
        self.min_period_ns = min_period_ns  # readings closer (by their stamps) are skipped
        self.pose: np.ndarray | None = None  # latest solved pose, its readings and stamp
        self.readings: np.ndarray | None = None
        self.pose_stamp: Any = None  # the reading's stamp, as the node keeps it
        self.poses_published = 0
        self.pose_failures = 0
        self.invalid_readings = 0
        self.commands_sent = 0
        self.commands_refused = 0
        self._last_solved_ns: int | None = None
        self._drawn: tuple | None = None  # the (stamp, parameters, frame) last drawn
        self._tracking = False
        self._last_report_s: dict[str, float] = {}
        # Which deployed calibration is in use: the status keys active_calibration,
        # active_since, active_reason ('' = none; the node sets them from the store).
        self.deployment: Mapping[str, object] = {}
        # The calibration's chain compliances and the weights (None: a rigid machine).
        self.loaded: LoadedChains | None = None
        self.physical_file = ''  # the weights' physical description ('': the model's default)
        self.compliances: Mapping[str, float] = {}  # the calibration's compliance section
        self.compliance_text = 'none (rigid)'  # the status value `compliance`

    @classmethod
    def start(
        cls,
        params: KinematicParameters | None,
        parameters_source: str,
        link_length: float,
        mount: str,
        min_period_ns: int,
        physical_file: str = '',
        compliances: Mapping[str, float] | None = None,
    ) -> LiveSession:
        """
        Return a session whose first solve starts at the workspace centre of `mount`.

        `compliances`: the compliance section of the calibration `params` come from (None or {}:
        rigid), loaded by the weights of `physical_file` ('' = the model's default).
        """
        session = cls(params, parameters_source, home_pose(link_length, mount), min_period_ns)
        session.physical_file = physical_file
        if params is not None:
            session.use_compliances(compliances or {})
        return session

    def use_compliances(self, compliances: Mapping[str, float]) -> None:
        """Load the chains by the compliances of the calibration in use (module doc)."""
        assert self.params is not None
        self.loaded, self.compliance_text = loaded_chains(
            self.params.model, compliances, self.physical_file
        )
        self.compliances = dict(compliances)

    # ------------------------------------------------------------------ status

    def status_values(self, report: Report) -> dict[str, object]:
        """Return the values of a report's status: the outcome, the counters, its own values."""
        return {
            'outcome': report.outcome,
            'model': self.params.model if self.params is not None else '',
            'parameters_source': self.parameters_source,
            'parameters_updates': self.parameters_updates,
            'poses_published': self.poses_published,
            'commands_sent': self.commands_sent,
            'commands_refused': self.commands_refused,
            'compliance': self.compliance_text,
            **self.deployment,
            **report.values,
        }

    def start_report(self, following: str, command_topic: str, store: str = '') -> Report:
        """
        Return the report at start: the parameters in use, or waiting for a calibration.

        `following`: the topic whose every calibration is taken ('' = only deployed ones);
        `store`: the calibration store whose deploys are followed.
        """
        deploys = f'deploys of the calibration store {store}' if store else ''
        if self.params is None and not following:
            return Report(
                Level.WARN,
                Outcome.WAITING,
                'waiting for a deployed calibration',
                log=f'waiting for a calibration deployed in {store}; commands on {command_topic}',
                log_level=Level.OK,
            )
        if self.params is None:
            return Report(
                Level.WARN,
                Outcome.WAITING,
                'waiting for calibrated parameters on hexacal/parameters',
                log=f'waiting for calibrated parameters on {following}; '
                f'commands on {command_topic}',
                log_level=Level.OK,  # waiting is normal at start: logged as information
            )
        text = f'{self.params.model} parameters from {self.parameters_source}'
        if self.loaded is not None:
            text = f'{text}; compliances {self.compliance_text}'
        if following:
            calibrations = f'following calibrations on {following}'
        else:
            calibrations = 'calibrations on hexacal/parameters ignored unless deployed'
        if deploys:
            calibrations = f'{calibrations}; following {deploys}'
        log = f'{text}; {calibrations}; commands on {command_topic}'
        return Report(Level.OK, Outcome.PARAMETERS, text, log=log)

    def throttled(self, key: str, now_s: float, report: Report) -> Report | None:
        """Return `report` unless one of `key` was returned less than LOG_PERIOD_S ago."""
        if now_s - self._last_report_s.get(key, -math.inf) < LOG_PERIOD_S:
            return None
        self._last_report_s[key] = now_s
        return report

    def summary(self) -> str:
        """Return the counts the node logs at shutdown."""
        return (
            f'{self.poses_published} platform poses published ({self.pose_failures} readings '
            f'without a pose, {self.invalid_readings} invalid), {self.commands_sent} commands '
            f'sent, {self.commands_refused} refused, {self.parameters_updates} calibrations taken'
        )

    # ------------------------------------------------------------------ calibrations

    def invalid_calibration(self, topic: str, error: Exception) -> Report:
        """Return the report of a parameters message that is no calibration."""
        return Report(
            Level.ERROR,
            Outcome.INVALID_PARAMETERS,
            f'invalid parameters message: {error}',
            log=f'ignoring a message on {topic}: {error}',
        )

    def not_deployed(self, topic: str, store: str) -> Report:
        """Return the report of a calibration message that is not the deployed calibration."""
        return Report(
            Level.WARN,
            Outcome.NOT_DEPLOYED,
            f'a calibration on {topic} is not the one deployed in {store}; keeping the '
            'parameters in use (deploy it, or set follow_calibrations to follow any)',
        )

    def take_calibration(
        self,
        params: KinematicParameters,
        topic: str,
        source: str,
        compliances: Mapping[str, float] | None = None,
    ) -> Report | None:
        """
        Take a calibration heard on `topic` (resolved: `source`); None when it is the same.

        One of another model than the parameters in use is refused (model-mismatch).
        `compliances`: its file's compliance section; None: not known (a parameters message
        carries only the geometry): the same parameters keep their compliances, others are
        rigid. Compliances that cannot load the machine are refused (invalid-parameters).
        """
        previous = self.params
        if previous is not None and params.model != previous.model:
            text = (
                f'a {params.model} calibration on {topic} does not fit this {previous.model} '
                f'machine ({self.parameters_source}); keeping its parameters'
            )
            return Report(Level.ERROR, Outcome.MODEL_MISMATCH, text)
        same = previous is not None and np.array_equal(params.vector, previous.vector)
        if same and (compliances is None or dict(compliances) == self.compliances):
            return None  # the same calibration again (e.g. republished at identify's start)
        try:
            loaded = loaded_chains(params.model, compliances or {}, self.physical_file)
        except KinematicsConfigurationError as error:
            return self.invalid_calibration(topic, error)
        was_loaded = self.loaded is not None
        self.loaded, self.compliance_text = loaded
        self.compliances = dict(compliances or {})
        self.params = params
        self.parameters_source = source
        self.parameters_updates += 1
        self._drawn = None
        if previous is None:
            text = f'calibrated {params.model} parameters received on {source}'
            if self.loaded is not None:
                text = f'{text}; compliances {self.compliance_text}'
            return Report(Level.OK, Outcome.PARAMETERS, text, {'largest_change_m': ''})
        change = float(np.abs(params.vector - previous.vector).max())
        text = (
            f'new calibration on {source}: {params.model} parameters updated '
            f'(largest change {change * 1e3:.4f} mm)'
        )
        if was_loaded or self.loaded is not None:
            text = f'{text}; compliances {self.compliance_text}'
        return Report(Level.OK, Outcome.PARAMETERS, text, {'largest_change_m': change})

    # ------------------------------------------------------------------ pose

    def wants_reading(self, stamp_ns: int) -> bool:
        """Return whether to solve a reading of this stamp (parameters known, rate kept)."""
        if self.params is None:
            return False
        last = self._last_solved_ns
        return last is None or not 0 <= stamp_ns - last < self.min_period_ns

    def invalid_reading(self, error: Exception, now_s: float) -> Report | None:
        """Count an actuator reading that is not one of the model's; its throttled report."""
        self.invalid_readings += 1
        assert self.params is not None
        text = (
            f'invalid actuator reading on {SLIDERS_TOPIC} ({self.params.model} '
            f'joints {", ".join(self.params.layout.actuator_names)}): {error}'
        )
        values = {'count': self.invalid_readings}
        report = Report(Level.WARN, Outcome.INVALID_READING, text, values)
        return self.throttled('invalid', now_s, report)

    def solve(
        self, stamp_ns: int, readings: np.ndarray, stamp: object, now_s: float
    ) -> tuple[np.ndarray | None, Report | None]:
        """Return the pose of `readings` (None: no pose) and the report to make, if any."""
        assert self.params is not None
        self._last_solved_ns = stamp_ns
        pose = None
        problems = []
        guesses = (self.pose, self.home) if self.pose is not None else (self.home,)
        for guess in cast(tuple[Sequence[float], ...], guesses):
            try:
                # live.py takes sequences; the arrays are read as such (np.asarray).
                pose = solve_pose(
                    self.params, cast(Sequence[float], readings), guess, self.loaded
                )
                break
            except ForwardKinematicsError as error:
                problems.append(str(error))
        if pose is None:
            self.pose_failures += 1
            self.pose = None
            self._tracking = False
            text = f'no platform pose for the readings {readings.tolist()}: {problems[-1]}'
            report = Report(Level.WARN, Outcome.POSE_FAILED, text, {'count': self.pose_failures})
            return None, self.throttled('pose', now_s, report)
        self.pose, self.readings, self.pose_stamp = pose, readings, stamp
        return pose, None

    def published(self, pose: np.ndarray, topic: str) -> Report | None:
        """Count a published pose; the report when tracking (re)starts with it."""
        self.poses_published += 1
        if self._tracking:
            return None
        self._tracking = True
        text = (
            f'tracking the platform: pose [{pose[0] * 1e3:.3f}, {pose[1] * 1e3:.3f}, '
            f'{pose[2] * 1e3:.3f}] mm, [{math.degrees(pose[3]):.3f}, '
            f'{math.degrees(pose[4]):.3f}, {math.degrees(pose[5]):.3f}] deg on {topic}'
        )
        return Report(Level.OK, Outcome.TRACKING, text)

    def drawing(self, stamp_key: tuple, frame: str) -> Mapping[str, np.ndarray] | None:
        """Return the machine's drawing at the latest pose, or None when it is drawn already."""
        if self.pose is None or self.params is None:
            return None
        key = (*stamp_key, id(self.params), frame)
        if key == self._drawn:
            return None
        self._drawn = key
        return self.params.architecture.drawing(self.params, self.pose, self.readings)

    # ------------------------------------------------------------------ commands

    def command(
        self,
        frame: str,
        base_frame: str,
        target: Callable[[], Sequence[float]],
        limits: Sequence[float] | None,
        speed: float,
    ) -> tuple[Command | None, Report]:
        """Return the command of a target pose (`target()` reads it) or None, and its report."""
        if frame not in ('', base_frame):
            return None, self._refuse(
                RefusalReason.WRONG_FRAME,
                f'target pose in frame {frame!r}; commands are poses in '
                f'{base_frame!r} (base_frame)',
            )
        if self.params is None:
            return None, self._refuse(RefusalReason.NO_PARAMETERS, 'no calibrated parameters yet')
        try:
            pose = np.array(target())
        except InvalidReadingError as error:
            text = f'target is not a pose: {error}'
            return None, self._refuse(RefusalReason.INVALID_TARGET, text)
        try:
            limit = stroke(self.params, limits)
            targets = actuator_targets(
                self.params, cast(Sequence[float], pose), limit, self.loaded
            )
        except OutOfStrokeError as error:
            reason = RefusalReason(error.reason)
            return None, self._refuse(reason, f'target {pose_text(pose)} {error}', pose)
        except UnreachablePoseError:
            return None, self._refuse(
                RefusalReason.UNREACHABLE_POSE,
                f'target {pose_text(pose)} is unreachable: '
                f'{self.params.architecture.unreachable_reason}',
                pose,
            )
        if self.readings is None:
            return None, self._refuse(
                RefusalReason.NO_ACTUATOR_READINGS,
                f'no actuator reading on {SLIDERS_TOPIC} yet: the '
                'move time needs the current position',
                pose,
            )
        travel = float(np.abs(targets - self.readings).max())
        move_s = max(MIN_MOVE_TIME_S, travel / speed)
        names = tuple(self.params.layout.actuator_names)
        self.commands_sent += 1
        text = (
            f'command {self.commands_sent}: target {pose_text(pose)} -> '
            f'{", ".join(f"{n} {t:.6f}" for n, t in zip(names, targets))} m in {move_s:.2f} s'
        )
        values = {
            'commands_sent': self.commands_sent,
            'move_time_s': move_s,
            **pose_values('target', pose),
            **{f'target.{n}': float(t) for n, t in zip(names, targets)},
        }
        return Command(names, targets, move_s), Report(Level.OK, Outcome.SENT, text, values)

    def _refuse(
        self, reason: RefusalReason, text: str, pose: np.ndarray | None = None
    ) -> Report:
        self.commands_refused += 1
        values = {
            'reason': reason,
            'commands_refused': self.commands_refused,
            **pose_values('target', pose),
        }
        text = f'refused: {reason}: {text}; nothing sent'
        return Report(Level.WARN, Outcome.REFUSED, text, values)
