"""
What the executor asks of the drive and hears from it (ROS-free).

* `trajectory`: the joints and points of a command as the controller gets them (the released
  chain is not commanded: it is left out of the trajectory).
* `ReleaseCalls`: a `ReleaseRequest` of the walk carried out through the drive's SetBool
  services, one call at a time (lock the chain released now, then release the posture's), each
  given ``release_wait_s`` to appear and to answer; the outcome (the chain released now, what
  went wrong) is what `PlanExecution.on_release` hears.
* `DriveMode`: the drive's measuring mode and release services confirm a plan's
  ``passive_actuator`` mode; on a drive without them the plan walks all six commanded (compliant)
  with a warning saying what to change, on either side.  The drive's status also says which
  chain it has released and whether it faulted.
* `lvdt_extension`: the LVDT link's extension (m) from its length reading.

The node (nodes/executor.py) only turns these into messages and service calls.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol, TYPE_CHECKING

from hexacal_msgs_py.names import LINK_LENGTH_JOINT, RELEASE_SERVICE_PREFIX

from .messages import LogLevel, Messages
from .platform_paths import Command
from ..planning.measuring_plan import walking_notice

if TYPE_CHECKING:
    from .execution import PlanExecution, ReleaseRequest
    from .mode_driver import WalkMode

# A plan made for passive_actuator (not the parameter) on a drive without release services
# walks all six commanded (compliant, with a warning) once this has passed.
RELEASE_DISCOVERY_S = 3.0


def trajectory(
    command: Command, joints: Sequence[str], released: int | None
) -> tuple[list[str], list[tuple[list[float], float]]]:
    """Return the joint names and (positions, time from start) points the controller gets."""
    names = [name for i, name in enumerate(joints) if i != released]
    points = [
        ([float(p) for i, p in enumerate(point) if i != released], float(seconds))
        for point, seconds in zip(command.points, command.times)
    ]
    return names, points


def command_text(command: Command, total: int) -> str:
    """Return the debug line on a command: purpose, posture, points, target (mm), duration."""
    what = f'posture {command.posture + 1} of {total}' if command.posture >= 0 else 'hold'
    return (
        f'{command.purpose} ({what}): {len(command.points)} points to '
        f'[{", ".join(f"{p * 1e3:.3f}" for p in command.positions)}] mm in '
        f'{command.duration_s:.2f} s'
    )


def lvdt_extension(
    names: Sequence[str], positions: Sequence[float], link_length: float
) -> float | None:
    """Return the LVDT link's extension (m) from its JointState fields; None: no length."""
    names = list(names)
    if LINK_LENGTH_JOINT not in names or len(positions) != len(names):
        return None
    return float(positions[names.index(LINK_LENGTH_JOINT)]) - float(link_length)


class ReleaseClient(Protocol):
    """One chain's release service (std_srvs/SetBool: True releases, False locks)."""

    srv_name: str

    def service_is_ready(self) -> bool:
        """Return whether the service is there."""

    def call(self, release: bool) -> Any:
        """Call it without blocking; return a future (done(), result() with success, message)."""


@dataclass
class _Calls:
    steps: list[tuple[int, bool]]  # (chain, release?) still to call
    released: int | None  # the chain released now, as the drive has answered so far
    since: float  # when the current step began waiting (s)
    future: Any = field(default=None)


class ReleaseCalls:
    """The service calls carrying out the walk's release requests, one call at a time."""

    def __init__(self, clients: Sequence[ReleaseClient], joints: Sequence[str], wait_s: float):
        """Call `clients` (one per chain, `joints` their names); wait `wait_s` for each step."""
        self.clients = list(clients)
        self.joints = list(joints)
        self.wait_s = float(wait_s)
        self._calls: _Calls | None = None
        self.messages: Messages = []  # for the node to log

    @property
    def active(self) -> bool:
        """Return whether a request is being carried out."""
        return self._calls is not None

    def step(
        self, now: float, request: ReleaseRequest | None, clock: Callable[[], float]
    ) -> tuple[int | None, str] | None:
        """
        Advance the calls of `request`; return (released now, problem) once over, else None.

        problem '' when the drive did both; `clock` is the time now (a step may follow
        seconds of work in the same tick: its wait is timed from then, not from `now`).
        """
        calls = self._calls
        if calls is None:
            assert request is not None
            steps = [(request.lock, False)] if request.lock is not None else []
            steps += [(request.release, True)] if request.release is not None else []
            calls = self._calls = _Calls(steps, request.lock, clock())
        if not calls.steps:
            return self._over('')
        chain, release = calls.steps[0]
        client = self.clients[chain]
        what = f'{"release" if release else "lock"} {self.joints[chain]}'
        if calls.future is None:
            if client.service_is_ready():
                calls.future = client.call(release)
                calls.since = clock()
            elif now - calls.since > self.wait_s:
                return self._over(
                    f'cannot {what}: no service {client.srv_name} (waited {self.wait_s:g} s)'
                )
            return None
        if not calls.future.done():
            if now - calls.since > self.wait_s:
                return self._over(
                    f'cannot {what}: {client.srv_name} did not answer within {self.wait_s:g} s'
                )
            return None
        try:
            answer = calls.future.result()
        except Exception as error:  # noqa: B902 - the status must say what happened
            return self._over(f'cannot {what}: {type(error).__name__}: {error}')
        if not answer.success:
            return self._over(f'the drive refused to {what}: {answer.message}')
        self.messages.append((LogLevel.INFO, f'{what}: {answer.message}'))
        calls.released = chain if release else None
        calls.steps.pop(0)
        calls.future, calls.since = None, now
        return self._over('') if not calls.steps else None

    def _over(self, problem: str) -> tuple[int | None, str]:
        calls, self._calls = self._calls, None
        assert calls is not None
        return calls.released, problem


class DriveMode:
    """What the drive's status says: its measuring mode, its released joint, a fault."""

    def __init__(self, discovery_s: float = RELEASE_DISCOVERY_S):
        """Confirm a passive_actuator plan within `discovery_s` of the start, else fall back."""
        self.discovery_s = float(discovery_s)
        self.mode: str | None = None  # the driver's status says its measuring_mode
        self._since: float | None = None  # when the start began to wait for the services
        self.messages: Messages = []  # for the node to log

    def hear(
        self,
        values: dict[str, str],
        execution: PlanExecution,
        joints: Sequence[str],
        now: float,
    ) -> list[Command] | None:
        """Hear the driver's status `values`; return the commands a fault asks (None: none)."""
        self.mode = values.get('measuring_mode', self.mode)
        joint = values.get('released_joint')
        if joint is not None:  # e.g. left released by an earlier plan: lock it first
            names = list(joints)
            execution.on_drive_released(names.index(joint) if joint in names else None)
        if values.get('state') == 'fault':
            return execution.on_drive_fault(now, values.get('fault', ''))
        return None

    def confirm(
        self, mode: WalkMode, execution: PlanExecution, now: float, services_ready: bool
    ) -> tuple[WalkMode, list[str]]:
        """
        Return the mode to walk and what the start waits for to drive the plan's mode.

        Only a plan's passive_actuator mode (not the parameter) is confirmed: on a drive that
        offers no release service (its status names another mode, or none appears within
        `discovery_s`) the plan walks all six commanded, unguarded, with a warning.
        """
        if mode.mode.value != 'passive_actuator' or mode.source != 'plan':
            return mode, []
        if self.mode == 'passive_actuator' or services_ready:
            return replace(mode, source='plan, confirmed'), []
        if self._since is None:
            self._since = now
        if self.mode is None and now - self._since < self.discovery_s:
            return mode, [
                f'the release services {RELEASE_SERVICE_PREFIX}<joint> (a passive_actuator plan)'
            ]
        why = (
            f"the drive's measuring_mode is {self.mode}"
            if self.mode is not None
            else f'no release service {RELEASE_SERVICE_PREFIX}<joint> within '
            f'{self.discovery_s:g} s'
        )
        # Say what to do, on either side: the drive's mode or the plan's.
        self.messages.append((
            LogLevel.WARN,
            f'{why}: {walking_notice(mode.mode.value)}. To walk it as planned, run the drives '
            'in measuring_mode passive_actuator with a release service per joint (the launch '
            'argument measuring_mode:=passive_actuator, bringup --measuring-mode '
            'passive_actuator for the simulated driver); else plan for these drives: hexacal '
            f'plan --measuring-mode {self.mode or "compliant"}',
        ))
        mode = mode.all_six('the plan is passive_actuator, the drive is not')
        execution.released = list(mode.released)
        execution.guard = None  # all six commanded: the passive_actuator guard does not apply
        return mode, []


__all__ = [
    'command_text',
    'DriveMode',
    'lvdt_extension',
    'RELEASE_DISCOVERY_S',
    'ReleaseCalls',
    'ReleaseClient',
    'trajectory',
]
