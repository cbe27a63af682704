"""What one calibration or verification request did: the answer and the status to publish."""

from __future__ import annotations

from dataclasses import dataclass, field
import enum
from typing import TYPE_CHECKING

from ..core.architectures import KinematicParameters
from ..core.machine.device import DeviceDefects

if TYPE_CHECKING:  # reports imports this module
    from .html_reports import ReportJob


class Level(enum.StrEnum):
    """Severity of a status (diagnostic_msgs' level names)."""

    OK = 'OK'
    WARN = 'WARN'
    ERROR = 'ERROR'


class Reason(enum.StrEnum):
    """
    The status key `outcome` that the session names itself.

    The core's reasons (CalibrationError.reason, the identification's result.reason such as
    `converged`) pass through as the strings they are.
    """

    COLLECTING = 'collecting'
    RUNNING = 'running'
    VERIFIED = 'verified'
    MISSING_PARAMETER = 'missing-parameter'
    INVALID_NOMINAL = 'invalid-nominal'
    INVALID_BAG = 'invalid-bag'
    INVALID_DEVICE_PRIOR = 'invalid-device-prior'
    DEVICE_PRIOR_WITHOUT_NOISE = 'device-prior-without-noise'
    INVALID_OPTIONS = 'invalid-options'
    INVALID_INPUT = 'invalid-input'
    INVALID_READING = 'invalid-reading'
    OUTPUT_NOT_WRITTEN = 'output-not-written'
    INTERNAL_ERROR = 'internal-error'
    NO_CALIBRATION = 'no-calibration'
    NO_POSTURES = 'no-postures'


class ReportState(enum.StrEnum):
    """The status key `report_state`: where the HTML report of a result is."""

    WRITING = 'writing'  # queued on the report worker; a follow-up status says how it ended
    READY = 'ready'
    FAILED = 'failed'
    DISABLED = 'disabled'  # report_dir is ''
    SUPERSEDED = 'superseded'  # a newer calibration's page replaced this verification's


@dataclass
class Outcome:
    """What one calibration request did: the service response and the status to publish."""

    success: bool
    message: str
    level: Level
    values: dict[str, object]
    parameters: KinematicParameters | None = None
    report: ReportJob | None = None  # written after the answer (report_state 'writing')
    # A calibration's: live postures received before it took its postures (the later ones verify
    # it), the device defects it identified (none: the ideal device), the device it assumed.
    verify_from: int = 0
    defects: DeviceDefects = DeviceDefects()
    link_length: float | None = None
    mount: str | None = None
    source: str = ''
    # A calibration's identified axial compliances (m/N; empty: rigid), which verify applies.
    compliance: dict[str, float] = field(default_factory=dict)
    # A calibration's provenance record for the store; a verification's `hexacal verify --json`
    # figures, attached to the calibration's store entry.
    record: dict[str, object] | None = None
    figures: dict[str, object] | None = None


def failure(reason: str, message: str, **values: object) -> Outcome:
    """Return a refused or failed request: ERROR, the reason first in the message and values."""
    return Outcome(False, f'{reason}: {message}', Level.ERROR, {'outcome': reason, **values})
