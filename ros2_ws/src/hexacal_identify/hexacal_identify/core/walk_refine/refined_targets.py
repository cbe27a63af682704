"""
The executor's targets refined from a first calibration, ROS-free.

The schedule is core/walk_refine/refinement.py's (one owner): the first checkpoint is the posture
count that allows a calibration of full rank, then geometrically more.  When the postures measured
so far reach a checkpoint, the walk (core/walk/execution.py) stops at rest between postures and
asks for a calibration; `RefineCall` follows the identify node's answer and the parameters it
publishes, bounded by ``refine_timeout_s``; the remaining targets then come from the intermediate
model (`refined_targets`).  A calibration that fails, is refused or does not come in time leaves
the current targets.  Only this request's result is taken (core/walk_refine/refine_answer.py):
the parameters file the answer names, read at the answer, else the one parameter set published
since the request; another client's calibration or a stale latched message is ignored.
"""

from __future__ import annotations

import enum

import numpy as np

from .refine_answer import choose_parameters, OwnResult, read_own_result
from .refinement import full_rank_postures, refinement_checkpoints
from ..architectures import KinematicParameters
from ..machine.kinematics import inverse_kinematics
from ..walk.messages import LogLevel, Messages

NOMINAL_TARGETS = 'nominal'


def targets_model_label(postures: int | None) -> str:
    """Return the status value ``targets_model``: nominal, or the calibration's posture count."""
    return NOMINAL_TARGETS if postures is None else f'calibration after {postures} postures'


def refine_checkpoints(enabled: bool, n_parameters: int, total: int) -> tuple[int, ...]:
    """Return the measured-posture counts at which the executor re-calibrates (ascending)."""
    if not enabled:
        return ()
    return refinement_checkpoints(total, full_rank_postures(n_parameters))


def refined_targets(model: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    """Return the setpoints (N, 6) of `poses` (N, 6) under the intermediate `model`."""
    return inverse_kinematics(model, np.atleast_2d(np.asarray(poses, dtype=float)))


class RefineState(enum.StrEnum):
    """Where an intermediate calibration stands."""

    IDLE = 'idle'
    WAITING = 'waiting'  # the service's answer and the parameters it publishes
    DONE = 'done'  # model set (None: the current targets stay; ``message`` says why)


class RefineCall:
    """
    One intermediate calibration through the identify node: answer, then published parameters.

    The node calls `start` when it sent the request (or found no service), `answer` with the
    service's reply, `parameters` with each parameter vector it hears, and `poll` every tick;
    when ``state`` is DONE, ``model`` is the intermediate model (None: keep the targets), the
    request's own result only (module doc); ``ignored`` counts the parameter sets heard that
    were not.
    """

    def __init__(self, nominal: KinematicParameters, timeout_s: float):
        self.nominal = nominal
        self.timeout_s = float(timeout_s)
        self.state = RefineState.IDLE
        self.model: KinematicParameters | None = None
        self.message = ''
        self.messages: Messages = []
        self._since = 0.0
        self._answered = False
        self._own = OwnResult(None)  # the answer's file, read at the answer
        self._heard: list[np.ndarray] = []  # every vector published since the request
        self._no_service_said = False
        self.postures = 0
        self.ignored = 0

    def start(self, now: float, postures: int, service_ready: bool) -> bool:
        """Begin a calibration of `postures`; return whether to send the request now."""
        self.model, self.message, self._answered = None, '', False
        self._own, self._heard, self.ignored = OwnResult(None), [], 0
        self._since, self.postures = now, postures
        if not service_ready:
            self._done(None, 'no calibration service: the targets stay', once=True)
            return False
        self.state = RefineState.WAITING
        self.messages.append(
            (LogLevel.INFO, f'{postures} postures measured: intermediate calibration requested')
        )
        return True

    def answer(self, success: bool, message: str) -> None:
        """Hear the service's reply (False and the error when the call failed)."""
        if self.state != RefineState.WAITING:
            return
        if not success:
            self._done(None, f'intermediate calibration failed: {message}; the targets stay')
            return
        self._answered = True
        self._own = read_own_result(message)  # at once: a later calibration may overwrite it

    def parameters(self, vector: np.ndarray) -> None:
        """Hear a parameter vector published after the request (whoever's it is)."""
        if self.state == RefineState.WAITING:
            self._heard.append(np.asarray(vector, dtype=float))

    def poll(self, now: float) -> None:
        """Conclude when this request's parameters are known, or on the timeout."""
        if self.state != RefineState.WAITING:
            return
        choice = choose_parameters(self._own, self._heard) if self._answered else None
        if choice is not None and not choice.waiting:
            self.ignored = choice.ignored
            if choice.vector is None:
                self._done(None, f'intermediate calibration: {choice.note}')
                return
            source = 'published' if self._own.vector is None else "answer's file"
            try:
                model = type(self.nominal)(choice.vector)
            except ValueError as error:
                self._done(None, f'the {source} parameters do not fit: {error}')
                return
            self.messages.append((LogLevel.INFO, f'intermediate calibration: {choice.note}'))
            self._done(model, f'targets from the {targets_model_label(self.postures)}')
        elif now - self._since > self.timeout_s:
            missing = 'the parameters' if self._answered else 'the answer'
            why = f' ({self._own.problem})' if self._answered and self._own.problem else ''
            self._done(
                None,
                f'intermediate calibration: {missing} did not come within '
                f'{self.timeout_s:g} s{why}; the targets stay',
            )

    def _done(self, model: KinematicParameters | None, message: str, once: bool = False) -> None:
        self.state, self.model, self.message = RefineState.DONE, model, message
        if once and self._no_service_said:
            return
        self._no_service_said = self._no_service_said or once
        self.messages.append((LogLevel.INFO if model is not None else LogLevel.WARN, message))


__all__ = [
    'NOMINAL_TARGETS',
    'RefineCall',
    'RefineState',
    'refine_checkpoints',
    'refined_targets',
    'targets_model_label',
]
