"""
Read and write posture plan files: the one owner of the format (ROS-free, no core imports).

The planner (``hexacal plan``, core.planning.Plan), the executor (through
``Plan.load``), the simulated driver (hexacal_driver.plan) and the CLI all read
and write plans here. A plan is a list of platform poses ``[x, y, z, theta,
psi, phi]`` (m, rad, the paper's eq. 1), each of one kind: ``sphere`` (the
platform on the link sphere of radius L) or ``fixed`` (the inclinometer reads
zero: position ``[0, 0, -L]``, ``[0, 0, +L]`` for a standing device). YAML, SI
units::

    # hexacal-plan: {"index": "O1", "model": "gough_stewart", ...}   <- optional
    plan:
      name: greedy-O1-25-3f2a9c1e
      link_length: 0.75
      model: gough_stewart   # optional: absent = hexa_slide (written only otherwise)
      mount: standing        # optional: absent = hanging (written only otherwise)
      measuring_mode: passive_actuator   # optional: absent = the reader's default
    postures:
      - {kind: sphere, pose: [x, y, z, theta, psi, phi], released_actuator: slider_3}
      - {kind: fixed, pose: [...], device_turn: 3.141592653589793}

``device_turn`` (rad, |turn| <= 2 pi) turns the device about its link axis for
that posture; a posture without one takes the reader's default (the driver's
``device_turn`` parameter, the normal mounting for the executor).

``measuring_mode`` (hexacal_msgs_py.measuring_modes: ``passive_actuator``,
``lvdt`` or ``compliant``) says how the machine is driven while the link is
attached; a plan without it takes the reader's default.  ``released_actuator``
(one of the plan model's actuator joint names, e.g. ``slider_3`` / ``leg_3``)
names the actuator released for that posture - the one not commanded, whose
encoder reads where the link put it; it is only meaningful with ``measuring_mode:
passive_actuator`` and a posture without one leaves the choice to the reader.
The actuator is named by its joint rather than its chain index because the
joint name is what every consumer uses (the commanded trajectory names the five
other joints, the release interface is per joint, the bag's JointStates name
it), it carries no 0/1-based ambiguity, and it is checked against the plan's
model (a Hexa Slide plan cannot release ``leg_2``).  Both keys are written only
when given, so a plan without them reads, and is written, byte for byte as a plan
of the keys above.

The planner's metadata rides in the ``# hexacal-plan:`` comment line (one JSON
object) so that plan files without it, and readers that know only the keys above,
read them unchanged: a strict YAML reader skips the line. ``read_plan_file`` checks
everything that needs no machine model; a subclass of `PlanFile` adds the checks that need
kinematics (`PlanFile.posture_problem`, the driver's PosturePlan).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import json
import math
import os
from pathlib import Path
from typing import Any, Callable, overload, TypeVar

from hexacal_msgs_py.files import atomic_write, load_yaml_text
from hexacal_msgs_py.measuring_modes import (
    MEASURING_MODE_KEY,
    MEASURING_MODES,
    MeasuringMode,
    RELEASED_ACTUATOR_KEY,
)
from hexacal_msgs_py.models import DEFAULT_MODEL, MAX_DEVICE_TURN, MODELS
import numpy as np
import yaml

PLAN_KEY = 'plan'
POSTURES_KEY = 'postures'
PLAN_MODEL_KEY = 'model'  # in the plan mapping: the machine model (absent = DEFAULT_MODEL)
PLAN_MOUNT_KEY = 'mount'  # in the plan mapping: the device mount (absent = DEFAULT_MOUNT)
DEVICE_TURN_KEY = 'device_turn'  # in a posture: rad; absent = the reader's default
# One comment line of JSON: strict YAML readers skip it, read_plan_file returns it as metadata.
METADATA_PREFIX = '# hexacal-plan: '

SPHERE = 'sphere'  # the platform anywhere on the link sphere
FIXED = 'fixed'  # the inclinometer reads zero: position [0, 0, -L] (hanging)
POSTURE_KINDS = (SPHERE, FIXED)
HANGING = 'hanging'  # the platform below the device's base joint
STANDING = 'standing'  # the platform above it (an upright machine)
MOUNTS = (HANGING, STANDING)
DEFAULT_MOUNT = HANGING

REQUIRED_PLAN_KEYS = frozenset({'name', 'link_length'})
OPTIONAL_PLAN_KEYS = frozenset({PLAN_MODEL_KEY, PLAN_MOUNT_KEY})
POSTURE_KEYS = frozenset({'kind', 'pose'})
OPTIONAL_POSTURE_KEYS = frozenset({DEVICE_TURN_KEY})
# The measuring-mode keys, optional too; listed apart in the refusals.
MODE_PLAN_KEYS = frozenset({MEASURING_MODE_KEY})
MODE_POSTURE_KEYS = frozenset({RELEASED_ACTUATOR_KEY})

PathLike = str | os.PathLike[str]


class PlanError(ValueError):
    """Refuse a posture plan; the message names the file, the posture and the problem."""


@dataclass(frozen=True)
class PlanFile:
    """
    Hold a plan file's contents: poses (N, 6) in m and rad, kinds (N,) 'sphere' / 'fixed'.

    device_turns: per posture the device's turn about its link axis (rad) or None (the
    reader's default); () when no posture names one. metadata: the planner's comment
    line (a JSON object) or None when the file has none (nothing is written then).
    """

    name: str
    link_length: float
    poses: np.ndarray
    kinds: tuple[str, ...]
    model: str = DEFAULT_MODEL  # the machine model the plan was made for
    mount: str = DEFAULT_MOUNT  # the device mount: hanging (platform below O) or standing
    device_turns: tuple[float | None, ...] = ()  # per posture, rad; None: the reader's default
    metadata: dict[str, Any] | None = field(default=None, compare=False)
    measuring_mode: str | None = None  # MeasuringMode value; None: the reader's default
    # Per posture the released actuator's joint name (passive_actuator mode) or None (the
    # reader chooses); () when no posture names one.
    released_actuators: tuple[str | None, ...] = ()

    def __post_init__(self) -> None:
        """Normalise the fields and refuse a plan with a problem (PlanError)."""
        poses = np.array(self.poses, dtype=float).reshape(-1, 6)
        poses.setflags(write=False)
        object.__setattr__(self, 'poses', poses)
        object.__setattr__(self, 'kinds', tuple(str(k) for k in self.kinds))
        turns = tuple(self.device_turns)
        if all(t is None for t in turns):
            turns = ()  # no posture names a turn: the same plan as one without turns
        object.__setattr__(self, 'device_turns', turns)
        released = tuple(self.released_actuators)
        if all(r is None for r in released):
            released = ()  # no posture names one: the same plan as one without
        object.__setattr__(self, 'released_actuators', released)
        problem = self.problem()
        if problem:
            raise PlanError(f'plan {self.name!r}: {problem}')

    def __len__(self) -> int:
        """Return the number of postures."""
        return len(self.poses)

    def device_turn(self, index: int, default: float = 0.0) -> float:
        """Return the device turn of posture `index` (rad): the plan's, else `default`."""
        turn = self.device_turns[index] if self.device_turns else None
        return float(default if turn is None else turn)

    def released_actuator(self, index: int) -> str | None:
        """Return the joint name of the actuator posture `index` releases, or None (not given)."""
        return self.released_actuators[index] if self.released_actuators else None

    def counts(self) -> dict[str, int]:
        """Return the number of postures of each kind."""
        return {kind: self.kinds.count(kind) for kind in POSTURE_KINDS}

    def describe(self) -> str:
        """Return one line naming the plan, its postures, machine, mount and turns."""
        counts = self.counts()
        machine = '' if self.model == DEFAULT_MODEL else f', for a {self.model}'
        mount = '' if self.mount == DEFAULT_MOUNT else f', {self.mount} device'
        given = sum(t is not None for t in self.device_turns)
        turns = f', {given} with a device turn' if given else ''
        mode = '' if self.measuring_mode is None else f', measuring mode {self.measuring_mode}'
        released = sum(r is not None for r in self.released_actuators)
        mode += f', {released} with a released actuator' if released else ''
        return (
            f"plan '{self.name}': {len(self)} postures ({counts[SPHERE]} sphere, "
            f'{counts[FIXED]} fixed), link length {self.link_length:g} m{machine}{mount}'
            f'{turns}{mode}'
        )

    def posture_problem(self, pose: np.ndarray, kind: str) -> str | None:
        """
        Return what is wrong with a finite pose of a known kind, or None.

        The format knows no machine: subclasses that do (the driver's) check where
        the device lets the platform stand.
        """
        return None

    def problem(self) -> str | None:
        """Return what is wrong with the plan, or None (posture_problem for each posture)."""
        if not isinstance(self.name, str) or not self.name.strip():
            return 'name must be a non-empty string'
        length = self.link_length
        if (
            isinstance(length, bool)
            or not isinstance(length, (int, float, np.floating))
            or not math.isfinite(length)
            or length <= 0
        ):
            return f'link_length must be a positive number of m, got {length!r}'
        if len(self.poses) == 0:
            return 'has no postures'
        if len(self.kinds) != len(self.poses):
            return f'{len(self.poses)} poses but {len(self.kinds)} kinds'
        if self.model not in MODELS:
            return f'model must be one of {", ".join(MODELS)}, got {self.model!r}'
        if self.mount not in MOUNTS:
            return f'mount must be one of {", ".join(MOUNTS)}, got {self.mount!r}'
        if self.device_turns:
            if len(self.device_turns) != len(self.poses):
                return f'{len(self.poses)} poses but {len(self.device_turns)} device turns'
            for index, turn in enumerate(self.device_turns):
                problem = turn_problem(turn)
                if problem:
                    return f'posture {index}: {problem}'
        problem = self._mode_problem()
        if problem:
            return problem
        for index, (pose, kind) in enumerate(zip(self.poses, self.kinds)):
            if kind not in POSTURE_KINDS:
                problem = f'kind must be one of {list(POSTURE_KINDS)}, got {kind!r}'
            elif not np.all(np.isfinite(pose)):
                problem = f'pose must be finite, got {pose.tolist()}'
            else:
                problem = self.posture_problem(pose, kind)
            if problem:
                return f'posture {index}: {problem}'
        return None

    def _mode_problem(self) -> str | None:
        """Return what is wrong with the measuring mode or a released actuator, or None."""
        mode = self.measuring_mode
        if mode is not None and (not isinstance(mode, str) or mode not in MEASURING_MODES):
            allowed = ', '.join(MEASURING_MODES)
            return f'{MEASURING_MODE_KEY} must be one of {allowed}, got {mode!r}'
        if not self.released_actuators:
            return None
        if len(self.released_actuators) != len(self.poses):
            return (
                f'{len(self.poses)} poses but {len(self.released_actuators)} released actuators'
            )
        names = MODELS[self.model].actuator_names
        for index, name in enumerate(self.released_actuators):
            if name is None:
                continue
            if mode != MeasuringMode.PASSIVE_ACTUATOR:
                given = 'names none' if mode is None else f'is {mode}'
                return (
                    f'posture {index}: {RELEASED_ACTUATOR_KEY} is only meaningful with '
                    f'{MEASURING_MODE_KEY} {MeasuringMode.PASSIVE_ACTUATOR.value} (the plan '
                    f'{given}), got {name!r}'
                )
            if not isinstance(name, str) or name not in names:
                return (
                    f'posture {index}: {RELEASED_ACTUATOR_KEY} must be one of the {self.model} '
                    f'actuators {", ".join(names)}, got {name!r}'
                )
        return None


def turn_problem(turn: object) -> str | None:
    """Return what is wrong with a posture's device_turn (None is fine: not given), or None."""
    if turn is None:
        return None
    if isinstance(turn, bool) or not isinstance(turn, (int, float, np.floating, np.integer)):
        return f'device_turn must be a number of rad, got {turn!r}'
    value = float(turn)
    if not (math.isfinite(value) and abs(value) <= MAX_DEVICE_TURN):
        return f'device_turn must be a finite angle within +-2 pi rad, got {turn!r}'
    return None


# --------------------------------------------------------------------------- reading

PlanType = TypeVar('PlanType', bound=PlanFile)


@overload
def read_plan_file(path: PathLike) -> PlanFile:
    ...


@overload
def read_plan_file(path: PathLike, plan_type: type[PlanType]) -> PlanType:
    ...


def read_plan_file(path: PathLike, plan_type: type[PlanFile] = PlanFile) -> PlanFile:
    """Read and check a plan file into a `plan_type`; PlanError names the file and the problem."""
    name = os.fspath(path)

    def fail(message: str) -> PlanError:
        return PlanError(f'{name}: {message}')

    text = _read_text(path, fail)
    try:
        document = load_yaml_text(text)
    except yaml.YAMLError as error:
        raise fail(f'not readable as a plan file: invalid YAML: {error}') from error
    except RecursionError:  # PyYAML composes recursively: '[[[[...' thousands deep
        raise fail('not readable as a plan file: invalid YAML: nested too deeply') from None
    header, entries = _plan_sections(document, fail)
    poses, kinds, turns, released = [], [], [], []
    for index, entry in enumerate(entries):
        pose, kind, turn = _posture(index, entry, fail)
        poses.append(pose)
        kinds.append(kind)
        turns.append(turn)
        released.append(_released_actuator(index, entry, fail))
    model = header.get(PLAN_MODEL_KEY, DEFAULT_MODEL)
    if not isinstance(model, str) or model not in MODELS:
        raise fail(f'plan.model must be one of {", ".join(MODELS)}, got {model!r}')
    mount = header.get(PLAN_MOUNT_KEY, DEFAULT_MOUNT)
    if not isinstance(mount, str) or mount not in MOUNTS:
        raise fail(f'plan.mount must be one of {", ".join(MOUNTS)}, got {mount!r}')
    mode = header.get(MEASURING_MODE_KEY)
    if MEASURING_MODE_KEY in header and (not isinstance(mode, str) or mode not in MEASURING_MODES):
        raise fail(
            f'plan.{MEASURING_MODE_KEY} must be one of {", ".join(MEASURING_MODES)} (absent: '
            f"the reader's default), got {mode!r}"
        )
    metadata = _metadata(text, fail)
    try:
        return plan_type(
            header['name'],
            float(header['link_length']),
            np.array(poses),
            tuple(kinds),
            model,
            mount,
            tuple(turns),
            metadata,
            measuring_mode=mode,
            released_actuators=tuple(released),
        )
    except PlanError as error:
        raise fail(str(error)) from None


def _read_text(path: PathLike, fail: Callable[[str], PlanError]) -> str:
    """Return the file's text; a missing or undecodable file is a named PlanError."""
    try:
        return Path(path).read_text(encoding='utf-8')
    except OSError as error:
        reason = error.strerror or error
        raise fail(f'not readable as a plan file: cannot read: {reason}') from error
    except UnicodeDecodeError as error:
        raise fail(f'not readable as a plan file: not UTF-8 text: {error}') from error


def _plan_sections(
    document: object, fail: Callable[[str], PlanError]
) -> tuple[dict[Any, Any], list[Any]]:
    """Return the checked ``plan`` mapping and ``postures`` list of a document."""
    if not isinstance(document, dict):
        raise fail("not a plan file: expected a mapping with keys 'plan' and 'postures'")
    unknown = sorted(set(map(str, document)) - {PLAN_KEY, POSTURES_KEY})
    if unknown:
        raise fail(f"unknown top-level key(s) {unknown}; expected 'plan' and 'postures'")
    header = document.get(PLAN_KEY)
    if not isinstance(header, dict):
        raise fail("not a plan file: 'plan' must be a mapping with 'name' and 'link_length'")
    known = REQUIRED_PLAN_KEYS | OPTIONAL_PLAN_KEYS | MODE_PLAN_KEYS
    unknown = sorted(set(map(str, header)) - known)
    if unknown:
        raise fail(
            f'unknown key(s) {unknown} in plan; expected {sorted(REQUIRED_PLAN_KEYS)} '
            f'(optional {sorted(OPTIONAL_PLAN_KEYS)}), measuring mode {sorted(MODE_PLAN_KEYS)}'
        )
    for key in sorted(REQUIRED_PLAN_KEYS):
        if key not in header:
            raise fail(f'plan.{key} is missing')
    length = header['link_length']
    if isinstance(length, bool) or not isinstance(length, (int, float)):
        raise fail(f'plan.link_length must be a number of m, got {length!r}')
    entries = document.get(POSTURES_KEY)
    if not isinstance(entries, list) or not entries:
        raise fail("'postures' must be a non-empty list of {kind, pose} entries")
    return header, entries


def _posture(
    index: int, entry: object, fail: Callable[[str], PlanError]
) -> tuple[list[float], Any, float | None]:
    """Return (pose, kind, device turn or None) of one posture entry, checked."""
    if not isinstance(entry, dict):
        raise fail(f'posture {index}: expected a mapping with kind and pose, got {entry!r}')
    unknown = sorted(
        set(map(str, entry)) - POSTURE_KEYS - OPTIONAL_POSTURE_KEYS - MODE_POSTURE_KEYS
    )
    missing = sorted(POSTURE_KEYS - set(entry))
    if unknown or missing:
        raise fail(
            f'posture {index}: keys must be {sorted(POSTURE_KEYS)}'
            + (f', unknown {unknown}' if unknown else '')
            + (f', missing {missing}' if missing else '')
            + f' (optional {sorted(OPTIONAL_POSTURE_KEYS)}), measuring mode '
            + f'{sorted(MODE_POSTURE_KEYS)}'
        )
    turn = entry.get(DEVICE_TURN_KEY)
    if DEVICE_TURN_KEY in entry:
        problem = turn_problem(turn)
        if turn is None:
            problem = 'device_turn must be a number of rad, got null'
        if problem:
            raise fail(f'posture {index}: {problem}')
    pose = entry['pose']
    if (
        not isinstance(pose, list)
        or len(pose) != 6
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pose)
    ):
        raise fail(
            f'posture {index}: pose must be 6 numbers [x, y, z, theta, psi, phi] '
            f'(m, rad), got {pose!r}'
        )
    return [float(v) for v in pose], entry['kind'], None if turn is None else float(turn)


def _released_actuator(
    index: int, entry: dict[Any, Any], fail: Callable[[str], PlanError]
) -> str | None:
    """Return a posture's released actuator (a joint name) or None; the rest: PlanFile."""
    if RELEASED_ACTUATOR_KEY not in entry:
        return None
    name = entry[RELEASED_ACTUATOR_KEY]
    if not isinstance(name, str):
        raise fail(
            f'posture {index}: {RELEASED_ACTUATOR_KEY} must be an actuator joint name, '
            f'got {name!r}'
        )
    return name


def _metadata(text: str, fail: Callable[[str], PlanError]) -> dict[str, Any] | None:
    """Return the planner's metadata comment (the last one) as a dict, or None if absent."""
    metadata = None
    start = len(METADATA_PREFIX)
    for line in text.splitlines():
        if line.startswith(METADATA_PREFIX):
            try:
                metadata = dict(json.loads(line[start:]))
            except (ValueError, TypeError):
                raise fail(
                    f"its '{METADATA_PREFIX.strip()}' comment is not a JSON object"
                ) from None
    return metadata


# --------------------------------------------------------------------------- writing


def plan_document(plan: PlanFile) -> dict[str, Any]:
    """Return the plan-file mapping of a plan (floats as Python floats; no metadata)."""
    header: dict[str, Any] = {'name': plan.name, 'link_length': float(plan.link_length)}
    if plan.model != DEFAULT_MODEL:  # as in parameters files: absent = a Hexa Slide
        header[PLAN_MODEL_KEY] = plan.model
    if plan.mount != DEFAULT_MOUNT:
        header[PLAN_MOUNT_KEY] = plan.mount
    if plan.measuring_mode is not None:
        header[MEASURING_MODE_KEY] = str(plan.measuring_mode)
    postures: list[dict[str, Any]] = []
    for index, (kind, pose) in enumerate(zip(plan.kinds, plan.poses)):
        entry: dict[str, Any] = {'kind': kind, 'pose': [float(v) for v in pose]}
        turn = plan.device_turns[index] if plan.device_turns else None
        if turn is not None:
            entry[DEVICE_TURN_KEY] = float(turn)
        released = plan.released_actuator(index)
        if released is not None:
            entry[RELEASED_ACTUATOR_KEY] = released
        postures.append(entry)
    return {PLAN_KEY: header, POSTURES_KEY: postures}


def plan_file_text(plan: PlanFile) -> str:
    """Return the text of a plan file that read_plan_file reads back exactly (repr floats)."""
    lines = []
    if plan.metadata is not None:
        lines.append(METADATA_PREFIX + json.dumps(json_safe(plan.metadata), sort_keys=True))
    lines += [
        f'{PLAN_KEY}:',
        f'  name: {json.dumps(plan.name)}',
        f'  link_length: {float(plan.link_length)!r}',
    ]
    if plan.model != DEFAULT_MODEL:  # Hexa Slide plan files stay as they were
        lines.append(f'  {PLAN_MODEL_KEY}: {plan.model}')
    if plan.mount != DEFAULT_MOUNT:  # no mount = hanging
        lines.append(f'  {PLAN_MOUNT_KEY}: {plan.mount}')
    if plan.measuring_mode is not None:  # written only when given: earlier files stay as they were
        lines.append(f'  {MEASURING_MODE_KEY}: {plan.measuring_mode}')
    lines.append(f'{POSTURES_KEY}:')
    for index, (kind, pose) in enumerate(zip(plan.kinds, plan.poses)):
        values = ', '.join(repr(float(v)) for v in pose)
        turn = plan.device_turns[index] if plan.device_turns else None
        turned = '' if turn is None else f', {DEVICE_TURN_KEY}: {float(turn)!r}'
        released = plan.released_actuator(index)
        if released is not None:
            turned += f', {RELEASED_ACTUATOR_KEY}: {released}'
        lines.append(f'  - {{kind: {kind}, pose: [{values}]{turned}}}')
    return '\n'.join(lines) + '\n'


def write_plan_file(path: PathLike, plan: PlanFile) -> Path:
    """Write a plan file atomically (temporary file, fsync, rename); return its path."""
    return atomic_write(Path(path), plan_file_text(plan))


def json_safe(value: Any) -> Any:
    """Return metadata as JSON-safe builtins (numpy scalars and arrays as Python ones)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
