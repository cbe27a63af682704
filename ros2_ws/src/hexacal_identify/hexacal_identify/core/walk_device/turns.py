"""
Turning the device about its link axis during a plan, and telling the nodes (ROS-free).

A turning procedure (``Plan.turns``, per posture, rad; core/machine/device.py "Turning
the device about its link axis") has the operator remount the device between
postures; `PlanExecution` pauses before a posture in another mounting.  The
nodes that stamp or simulate the turn (collector, driver) carry it in their
``device_turn`` parameter, which the executor sets (`DeviceTurnSetter`):

* before the first move, to the mounting at the start (``mounted_turn``), so
  no node keeps the turn an earlier plan left it at (the start waits for it);
* on the operator's resume after a turn; the posture begins once every node
  has answered, failed, or ``TURN_SET_TIMEOUT_S`` has passed.  A node that
  refuses or does not answer is reported (state FAILED) and the plan goes on.

The requests go through a `TurnClient` (the node wraps rclpy's
AsyncParameterClient); nothing here blocks or waits.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
import enum
import math
from typing import Any, Protocol

import numpy as np

from ..walk.messages import LogLevel, Messages

TURN_TOLERANCE_RAD = 1e-9  # mountings closer than this (modulo 2 pi) are the same
TURN_PARAMETER = 'device_turn'  # the parameter (rad) of the collector and the driver
TURN_SET_TIMEOUT_S = 10.0  # how long a node's set_parameters may take (discovery too)


def same_turn(a: float, b: float) -> bool:
    """Return whether two device turns (rad) are the same mounting (modulo 2 pi)."""
    difference = math.remainder(float(a) - float(b), 2.0 * math.pi)
    return abs(difference) <= TURN_TOLERANCE_RAD


def check_turns(turns: object, total: int) -> np.ndarray:
    """
    Return the plan's per-posture device turns as (total,) floats (None: all 0).

    ValueError if not one finite angle per posture.
    """
    if turns is None:
        return np.zeros(total)
    values = np.asarray(turns, dtype=float).reshape(-1)
    if values.shape != (total,) or not np.all(np.isfinite(values)):
        raise ValueError(
            f'device turns: one finite angle (rad) per posture ({total}), got {turns!r}'
        )
    return values


def turn_text(turn: float) -> str:
    """Return a turn as the operator reads it: '180 deg (3.14159 rad)'."""
    return f'{math.degrees(turn):.4g} deg ({turn:.6g} rad)'


class TurnSetState(enum.StrEnum):
    """Where setting device_turn on the nodes stands (status ``device_turn_set``)."""

    PENDING = 'pending'
    DONE = 'done'
    FAILED = 'failed'


class AnswerFuture(Protocol):
    """A pending answer (rclpy's Future); its result has ``results`` (SetParametersResult)."""

    def done(self) -> bool: ...

    def result(self) -> Any: ...

    def cancel(self) -> Any: ...


class TurnClient(Protocol):
    """One node's device_turn parameter, as the executor node reaches it."""

    def ready(self) -> bool: ...  # its parameter services are there

    def request(self, turn: float) -> AnswerFuture: ...  # set device_turn


@dataclass
class TurnSetting:
    """One round of requests: every node's device_turn set to `turn` (rad)."""

    turn: float
    started_s: float
    at_start: bool = False  # the mounting at the start, not a resume
    futures: dict[str, AnswerFuture] = field(default_factory=dict)
    problems: dict[str, str] = field(default_factory=dict)  # node -> why it is not set
    done: list[str] = field(default_factory=list)  # nodes that set it

    def settled(self, name: str) -> bool:
        """Return whether `name` has answered or failed."""
        return name in self.problems or name in self.done

    def step(self, now: float, clients: Mapping[str, TurnClient]) -> bool:
        """Send the requests whose services are there, collect answers; True once all settled."""
        late = now - self.started_s > TURN_SET_TIMEOUT_S
        for name, client in clients.items():
            if self.settled(name):
                continue
            future = self.futures.get(name)
            if future is None:
                if client.ready():
                    self.futures[name] = client.request(self.turn)
                elif late:
                    self.problems[name] = (
                        f'its parameter services did not appear within {TURN_SET_TIMEOUT_S:g} s'
                    )
                continue
            if not future.done():
                if late:
                    future.cancel()
                    self.problems[name] = f'no answer within {TURN_SET_TIMEOUT_S:g} s'
                continue
            try:
                results = future.result().results
            except Exception as error:  # noqa: B902 - the status must say what happened
                self.problems[name] = f'{type(error).__name__}: {error}'
                continue
            if len(results) == 1 and results[0].successful:
                self.done.append(name)
            else:
                self.problems[name] = 'refused: ' + (results[0].reason if results else 'no result')
        return len(self.done) + len(self.problems) >= len(clients)


class DeviceTurnSetter:
    """The executor's device_turn requests to `device_turn_nodes` and what became of them."""

    def __init__(self, clients: Mapping[str, TurnClient]):
        self.clients = dict(clients)
        self.setting: TurnSetting | None = None  # the round in flight
        self.state: TurnSetState | None = None  # of the last round (None: none yet)
        self.message = ''  # what the last round did (status device_turn_set_message)
        self.start_done = not self.clients  # the nodes carry the mounting at the start
        self.messages: Messages = []  # for the node to log

    @property
    def names(self) -> str:
        """Return the nodes, as a log line lists them."""
        return ', '.join(self.clients)

    def begin(self, turn: float, now: float, why: str, at_start: bool = False) -> None:
        """Start a round setting device_turn to `turn` (rad) on every node."""
        self.setting = TurnSetting(float(turn), now, at_start)
        self.state, self.message = TurnSetState.PENDING, ''
        self._say(LogLevel.INFO, f'{why}: setting {TURN_PARAMETER} {turn:.6g} rad on {self.names}')

    def cancel(self) -> bool:
        """Drop the round in flight (a pause cancels the resume); whether there was one."""
        if self.setting is None:
            return False
        self.setting, self.state, self.message = None, None, ''
        self._say(LogLevel.INFO, 'pause: the resume after the device turn is cancelled')
        return True

    def resume(self, turn: float, now: float, index: int, total: int) -> str:
        """Begin the round of the operator's resume after a turn; the service's answer."""
        if self.setting is not None:
            return f'already resuming: waiting for {self.names} to set {TURN_PARAMETER}'
        self.begin(turn, now, 'resume after the device turn')
        return (
            f'setting {TURN_PARAMETER} {turn:.6g} rad on {self.names}; posture '
            f'{index + 1} of {total} begins once they answer'
        )

    def start_waiting(self, mounted_turn: float, now: float) -> str | None:
        """Return what the first move waits for (begin that round if needed; None: nothing)."""
        if self.start_done:
            return None
        if self.setting is None:
            self.begin(mounted_turn, now, 'the mounting at the start', at_start=True)
            self.step(now)
        if self.start_done:
            return None
        return (
            f'{self.names} to set {TURN_PARAMETER} {mounted_turn:.6g} rad '
            '(the mounting at the start)'
        )

    def step(self, now: float) -> TurnSetting | None:
        """Advance the round in flight; the round once every node has settled, else None."""
        setting = self.setting
        if setting is None or not setting.step(now, self.clients):
            return None
        self.setting = None
        self.start_done = self.start_done or setting.at_start
        turn = f'{TURN_PARAMETER} {setting.turn:.6g} rad'
        if setting.problems:
            self.state = TurnSetState.FAILED
            self.message = '; '.join(f'{name}: {why}' for name, why in setting.problems.items())
            self._say(
                LogLevel.ERROR, f'{turn} not set on every node ({self.message}); the plan goes on'
            )
        else:
            self.state = TurnSetState.DONE
            # In device_turn_nodes' order, not the answers': the same line however they race.
            self.message = f'{turn} set on {self.names}'
            self._say(LogLevel.INFO, self.message)
        return setting

    def _say(self, level: LogLevel, text: str) -> None:
        self.messages.append((level, text))
