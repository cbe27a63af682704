"""
The HTML reports written after the answer: one at a time, the latest calibration's.

A newer calibration replaces a report still waiting to start; a verification's report is that
calibration's page again with a verification section (or, for a calibration republished at
start-up, a verification page alone under `<report_dir>/verification/`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import threading

from hexacal_msgs_py.readings import PostureReading

from .outcome import Outcome
from .paths import output_path
from ..core.machine.device import DevicePrior
from ..report.page import write_report, write_verification_report


@dataclass
class ReportJob:
    """What the background report of one calibration needs (parameters read when it ran)."""

    report_dir: str
    output_dir: str
    result: object  # IdentificationResult
    postures: list[PostureReading]
    source: str
    link_length: float
    mount: str = 'hanging'
    device_prior: DevicePrior | None = None  # shown beside the identified device parameters
    # Its calibration store entry and the active calibration (calibration_id, active_*).
    store: dict[str, object] = field(default_factory=dict)


@dataclass
class VerificationTask:
    """The report of one verification: the calibration's page with a verification section."""

    number: int  # the verification number: its follow-up is published while it is the latest
    calibration_number: int
    job: ReportJob | None  # the calibration's report job; None: a verification page alone
    report_dir: str
    output_dir: str
    payload: dict  # VerificationResult.to_json(per_posture=True) + source
    outcome: Outcome  # the verification status to follow up


class ReportQueue:
    """The reports waiting: the latest calibration's and the latest verification's."""

    def __init__(self) -> None:
        """Start with nothing waiting."""
        self._lock = threading.Lock()
        self._calibration: tuple[int, Outcome] | None = None
        self._verification: VerificationTask | None = None

    def put_calibration(self, number: int, outcome: Outcome) -> int | None:
        """Queue calibration `number`'s report; return the number of the one it replaced."""
        with self._lock:
            replaced, self._calibration = self._calibration, (number, outcome)
        return None if replaced is None else replaced[0]

    def put_verification(self, task: VerificationTask) -> None:
        """Queue a verification's report, replacing one waiting."""
        with self._lock:
            self._verification = task

    def take(self) -> tuple[tuple[int, Outcome] | None, VerificationTask | None]:
        """Return what waits (and empty the queue): (calibration number, outcome), verification."""
        with self._lock:
            taken = self._calibration, self._verification
            self._calibration = self._verification = None
        return taken


def write_page(job: ReportJob | None, verification: VerificationTask | None) -> Path:
    """Write the calibration's page (with the verification's section), or the verification's."""
    from ..calibration_steps.posture_checks import measurements_from_postures

    if job is None:  # a calibration republished at start-up: no result to show
        if verification is None:
            raise ValueError('no report to write: neither a calibration nor a verification')
        directory = output_path(verification.report_dir, verification.output_dir) / 'verification'
        return write_verification_report(
            verification.payload,
            directory,
            title=f'hexacal verification ({verification.payload["calibration"]})',
        )
    directory = output_path(job.report_dir, job.output_dir)
    mount = {} if job.mount == 'hanging' else {'mount': job.mount}
    return write_report(
        job.result,
        directory,
        title=f'hexacal calibration ({job.source})',
        measurements=measurements_from_postures(
            job.postures, nominal_link_length=job.link_length
        ),
        link_length=job.link_length,
        extras={'source': job.source, **job.store},
        device_prior=job.device_prior,
        verification=None if verification is None else verification.payload,
        **mount,
    )
