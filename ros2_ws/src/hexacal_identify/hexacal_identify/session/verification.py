"""One verification of the latest calibration, on the postures received after it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence, TYPE_CHECKING

from hexacal_msgs_py import store_format as fmt
from hexacal_msgs_py.errors import ParameterFileError

from .html_reports import VerificationTask
from .node_settings import Settings
from .nominal import NominalFile
from .outcome import failure, Level, Outcome, Reason, ReportState
from .received_postures import PostureStore
from ..core.architectures import KinematicParameters
from ..core.errors import CalibrationError
from ..core.machine.device import DeviceDefects
from ..store import postures_digest

if TYPE_CHECKING:
    import numpy as np
    from hexacal_msgs_py.readings import PostureReading

    from ..core.fit.compliance import ComplianceModel


@dataclass
class LatestCalibration:
    """The calibration hexacal/verify verifies: the latest that produced parameters."""

    number: int  # its calibration number (0: the saved output republished at start-up)
    parameters: KinematicParameters
    defects: DeviceDefects  # device defects identified with it
    source: str  # what it was fitted on, for the messages
    verify_from: int  # live postures received before it took its postures: the later verify it
    link_length: float | None  # the device it assumed (None: the parameters at verify time)
    mount: str | None
    outcome: Outcome | None  # its result (its report job); None when republished from the file
    store_id: str | None = None  # its calibration store entry (None: not kept in the store)
    compliance: dict[str, float] = field(default_factory=dict)  # identified, m/N; {}: rigid


def run_verification(
    settings: Settings,
    number: int,
    latest: LatestCalibration | None,
    nominal_file: NominalFile,
    store: PostureStore,
    calibrate_service: str,
) -> tuple[Outcome, VerificationTask | None]:
    """
    Verify verification `number` of `latest` on the postures in `store` after it.

    Return the outcome, and the report to write (None: no report). Unexpected errors
    propagate: the session names them.
    """
    from ..calibration_steps.posture_checks import check_model, measurements_from_postures
    from ..core.machine.device import DeviceModel
    from ..core.assessment.verification import PASS, verify

    if latest is None:
        return failure(
            Reason.NO_CALIBRATION,
            'no calibration to verify yet: calibrate first '
            f'({calibrate_service}), then measure fresh postures '
            'and call verify again',
        ), None
    postures, postures_models = store.since(latest.verify_from)
    about = {
        'calibration': latest.source,
        'calibration_number': latest.number,
        'postures_before_calibration': latest.verify_from,
    }
    if not postures:
        return failure(
            Reason.NO_POSTURES,
            f'no postures received since the calibration it verifies '
            f'({latest.source}, calibration {latest.number}): measure fresh postures '
            '(a verification plan) and call verify again',
            postures=0,
            **about,
        ), None
    nominal_path = settings.nominal
    if not nominal_path:
        return failure(
            Reason.MISSING_PARAMETER,
            "parameter 'nominal' is not set: verification compares "
            'the nominal and the calibrated parameters (-p nominal:=<path>)',
            **about,
        ), None
    try:
        nominal, mount = nominal_file.load(nominal_path)
    except (ParameterFileError, ValueError) as error:
        return failure(Reason.INVALID_NOMINAL, f'nominal: {error}', **about), None
    link_length = latest.link_length or settings.link_length
    mount = latest.mount or mount
    try:
        names = nominal.layout.actuator_names
        compliance = calibrated_compliance(settings, latest, names, postures)
    except ValueError as error:
        return failure(Reason.INVALID_OPTIONS, str(error), postures=len(postures), **about), None
    try:
        for model in sorted(postures_models):
            check_model(
                model, nominal, 'the postures received since the calibration', nominal_path
            )
        result = verify(
            nominal,
            latest.parameters,
            measurements_from_postures(postures, nominal_link_length=link_length),
            device=DeviceModel(link_length=link_length, mount=mount),
            threshold_m=settings.verify_threshold_m or None,
            noise=settings.noise(),
            postures_model=next(iter(postures_models)) if len(postures_models) == 1 else None,
            calibrated_defects=latest.defects,
            calibrated_compliance=compliance,
        )
    except (CalibrationError, ValueError) as error:
        reason = getattr(error, 'reason', Reason.INVALID_INPUT)
        return failure(reason, str(error), postures=len(postures), **about), None
    values: dict[str, object] = {
        'outcome': Reason.VERIFIED,
        **result.status_values(),
        **about,
    }
    if compliance is not None:
        values['compliance_mode'] = compliance[0].mode
    before, after = result.nominal.figures(), result.calibrated.figures()
    message = (
        f'{result.verdict_reason()}; position rms nominal '
        f'{before["position_rms_m"] * 1e6:.2f} um, calibrated '
        f'{after["position_rms_m"] * 1e6:.2f} um ({result.improvement:.1f}x), rotary rms '
        f'nominal {before["rotary_rms_rad"] * 1e6:.2f} urad, calibrated '
        f'{after["rotary_rms_rad"] * 1e6:.2f} urad; {result.postures} postures since '
        f'calibration {latest.number}'
    )
    passed = result.verdict == PASS
    job = latest.outcome.report if latest.outcome is not None else None
    writing = job is not None or bool(settings.report_dir)
    values['report_state'] = ReportState.WRITING if writing else ReportState.DISABLED
    outcome = Outcome(passed, message, Level.OK if passed else Level.WARN, values)
    outcome.figures = {  # as `hexacal verify --json` gives them, for the calibration store
        **result.to_json(),
        'source': f'{len(postures)} live postures',
        'calibration': latest.source,
        'nominal_file': nominal_path,
        fmt.VERIFICATION_POSTURES_DIGEST: postures_digest(postures),  # other than the fit's
    }
    if not writing:
        return outcome, None
    payload = {
        **result.to_json(per_posture=True),
        'source': f'{len(postures)} live postures',
        'calibration': latest.source,
        'nominal_file': nominal_path,
    }
    task = VerificationTask(
        number,
        latest.number,
        job,
        settings.report_dir,
        settings.output_dir,
        payload,
        outcome,
    )
    return outcome, task


def calibrated_compliance(
    settings: Settings,
    latest: LatestCalibration,
    actuator_names: Sequence[str],
    postures: Sequence[PostureReading],
) -> tuple[ComplianceModel, np.ndarray] | None:
    """
    Return the calibration's compliances loaded for the live postures (None: a rigid one).

    The loads depend on the measuring mode, which live postures show only in lvdt (their
    measured link length); a ValueError names the offline way otherwise, as calibrate does.
    """
    if not latest.compliance:
        return None
    from .calibration import live_measuring_mode, mass_model
    from ..calibration_steps.calibration_run import drive_stiffness_of, identified_compliance

    mode = live_measuring_mode(postures)
    if mode is None:
        raise ValueError(
            f'the calibration ({latest.source}) carries compliances, and the live postures do '
            "not show their measuring mode nor each posture's released actuator (only lvdt "
            'postures do), on which the loads depend: verify the bag the collector recorded '
            '(hexacal verify BAG --calibrated FILE)'
        )
    masses, _ = mass_model(settings, latest.parameters.model)
    return identified_compliance(
        latest.compliance, masses, mode, None, actuator_names, 'verify',
        drive_stiffness_of(settings.physical_file, latest.parameters.model),
    )
