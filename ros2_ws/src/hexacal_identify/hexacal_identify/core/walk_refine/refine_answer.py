"""
Which calibration is the executor's own (ROS-free).

The executor asks ``hexacal/calibrate`` for an intermediate calibration and must compute its
targets (and rebuild its guard) with THAT result only.  ``hexacal/parameters`` is no answer to
anyone: every client's calibration is published there, and the topic is latched (transient
local), so a restarted identify node republishes an older result to everyone.  The
calibrate answer is the only thing that comes back to the caller alone, and a successful one
names the parameters file it wrote and the fit's summary, which the file's header carries too
(hexacal_msgs_py.calibrate_answer).  So:

1. `read_own_result`: at the answer, the file it names is read; it is this request's result
   when its header carries the answer's summary (a later calibration - another client's - that
   overwrote the file has its own summary) and it did not change while it was read.
2. `choose_parameters`: that vector is the model, whether or not the identify node's
   publication of it has been heard yet (the vectors heard on the topic that differ from it -
   another client's, a stale latched one - are ignored and counted).  When the file cannot
   be read (the identify node on another host, an answer without a file), the published
   vectors heard since the request decide: exactly one distinct vector is taken; several
   distinct ones are ambiguous and leave the targets (the safe side: a wrong model would move
   the machine and the guard's predictions with it); none yet: wait (at most
   ``refine_timeout_s``, core/walk_refine/refined_targets.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hexacal_msgs_py.calibrate_answer import header_names_summary, parse_calibrate_answer
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.parameters_file import read_parameters_file
import numpy as np


@dataclass(frozen=True)
class OwnResult:
    """
    The parameters the answer's file holds, when that file is this request's result.

    ``vector`` None: ``problem`` says why the file could not be used; ``written`` is the path
    the answer names ('' when it names none).
    """

    vector: np.ndarray | None
    written: str = ''
    problem: str = ''


def read_own_result(message: str) -> OwnResult:
    """Return the result of the calibration a successful answer's `message` names (module doc)."""
    answer = parse_calibrate_answer(message)
    if answer is None:
        return OwnResult(None, '', 'the answer names no parameters file')
    path = Path(answer.written)
    try:
        before = path.read_text(encoding='utf-8')
        vector = read_parameters_file(path).vector
        after = path.read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError, ParameterFileError) as error:
        return OwnResult(None, answer.written, f'cannot read {answer.written}: {error}')
    if before != after:
        return OwnResult(None, answer.written, f'{answer.written} changed while it was read')
    if not header_names_summary(before, answer.summary):
        return OwnResult(
            None,
            answer.written,
            f"{answer.written} holds another calibration (its header lacks the answer's summary)",
        )
    return OwnResult(vector, answer.written)


@dataclass(frozen=True)
class RefineChoice:
    """
    The parameters to take (None: none), whether to wait for more, and where they came from.

    ``note`` says so in words for the log; ``ignored`` counts the distinct vectors heard on the
    parameters topic that are not this request's.
    """

    vector: np.ndarray | None
    waiting: bool
    note: str
    ignored: int = 0


def _distinct(vectors: Sequence[np.ndarray]) -> list[np.ndarray]:
    unique: list[np.ndarray] = []
    for vector in vectors:
        if not any(_same(vector, seen) for seen in unique):
            unique.append(vector)
    return unique


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b))


def choose_parameters(own: OwnResult, heard: Sequence[np.ndarray]) -> RefineChoice:
    """Return which parameters are this request's: `own` from the answer, else `heard` (doc)."""
    distinct = _distinct([np.asarray(vector, dtype=float) for vector in heard])
    if own.vector is not None:
        matched = any(_same(own.vector, vector) for vector in distinct)
        others = len(distinct) - int(matched)
        published = 'the published parameters match' if matched else 'not heard published yet'
        ignored = f'; {others} other parameter set(s) heard since the request ignored'
        return RefineChoice(
            own.vector,
            False,
            f"parameters of the answer's file {own.written} ({published})"
            + (ignored if others else ''),
            others,
        )
    if not distinct:
        return RefineChoice(None, True, f'{own.problem}; waiting for the published parameters')
    if len(distinct) == 1:
        return RefineChoice(
            distinct[0], False, f'{own.problem}: the one parameter set published since the request'
        )
    return RefineChoice(
        None,
        False,
        f'{own.problem}, and {len(distinct)} different parameter sets were published since the '
        "request: which is this request's cannot be told; the targets stay",
        len(distinct),
    )


__all__ = ['choose_parameters', 'OwnResult', 'read_own_result', 'RefineChoice']
