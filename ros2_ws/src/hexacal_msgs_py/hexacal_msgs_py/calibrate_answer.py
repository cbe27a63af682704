"""
The answer of ``hexacal/calibrate`` (std_srvs/Trigger) that a client can rely on (ROS-free).

A successful calibration answers ``success`` true and the message
``<outcome>: <summary>; wrote <file>``: the identification's outcome (``converged``,
``iteration-limit``), a one-line summary of the fit (postures, cost, iterations, rank, rms
residual) and the absolute path of the parameters file it wrote.  The same summary is a line
of that file's header comment (``# from <source>: <summary>``), and the vector in the file is
the one published on ``hexacal/parameters`` for that request, bit for bit (the file is written
with repr floats).  The answer is the only thing a Trigger carries back to the one who called,
so it is what ties a client to its own calibration: the parameters topic is shared by every
client and latched (transient local), so a vector heard there may be another client's.
"""

from __future__ import annotations

from dataclasses import dataclass
import os

WROTE = '; wrote '  # between the summary and the written file's path
HEADER_SOURCE = 'from '  # the header line that carries the summary: '# from <source>: <summary>'


def calibrate_answer(outcome: str, summary: str, written: str | os.PathLike[str]) -> str:
    """Return the message of a successful ``hexacal/calibrate`` answer (module doc)."""
    return f'{outcome}: {summary}{WROTE}{os.fspath(written)}'


@dataclass(frozen=True)
class CalibrateAnswer:
    """What a successful answer's message names: the outcome, the fit's summary, the file."""

    outcome: str
    summary: str
    written: str


def parse_calibrate_answer(message: str) -> CalibrateAnswer | None:
    """Return what `message` names, None when it is not a successful answer's (module doc)."""
    head, wrote, written = message.partition(WROTE)
    outcome, colon, summary = head.partition(': ')
    if not (wrote and colon and outcome and summary and written.strip()):
        return None
    return CalibrateAnswer(outcome, summary, written.strip())


def header_names_summary(text: str, summary: str) -> bool:
    """Return whether a parameters file's text carries `summary` in its header comment."""
    for line in text.splitlines():
        if not line.startswith('#'):
            return False  # the header is over
        comment = line[1:].strip()
        if comment.startswith(HEADER_SOURCE) and comment.endswith(f': {summary}'):
            return True
    return False


__all__ = [
    'calibrate_answer',
    'CalibrateAnswer',
    'header_names_summary',
    'HEADER_SOURCE',
    'parse_calibrate_answer',
    'WROTE',
]
