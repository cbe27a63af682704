"""
The calibration session of the identify node: postures, calibrations, verifications, reports.

Everything the node decides, without ROS: the node converts messages, reads its parameters
into a Settings, runs these methods on its threads and publishes through a StatusSink.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
import threading
from typing import Protocol

from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError, ParameterFileError
from hexacal_msgs_py.models import DEFAULT_MODEL, model_for_actuator_names, MODELS
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_NAME,
    VERIFICATION_STATUS_NAME,
)
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
from hexacal_msgs_py.readings import PostureReading

from .nominal import NominalFile
from .outcome import failure, Level, Outcome, Reason, ReportState
from .paths import interrupted_writes, output_path
from .postures import PostureStore, Receipt
from .prior import device_prior
from .reports import ReportJob, ReportQueue, VerificationTask, write_page
from .settings import names, Settings
# pipeline and core.identification (the solver) are imported where they are used: at the first
# posture or calibration, not when the node starts.
from ..core.architectures import KinematicParameters
from ..core.device import DeviceDefects
from ..core.errors import CalibrationError


class StatusSink(Protocol):
    """Where the session publishes (the node's publishers)."""

    def status(self, name: str, level: Level, message: str, values: dict[str, object]) -> None:
        """Publish a status named `name` (calibration or verification)."""

    def parameters(self, vector: Sequence[float], model: str) -> None:
        """Publish a calibrated vector of `model`'s layout."""


class Log(Protocol):
    """The node's logger (rclpy's, or logging.Logger in tests)."""

    def info(self, message: str) -> object:
        """Log an information."""

    def warning(self, message: str) -> object:
        """Log a warning."""

    def error(self, message: str) -> object:
        """Log an error."""


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec='seconds')


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


class CalibrationSession:
    """
    Posture store, calibrations and verifications on request, and their reports.

    Thread-safe: postures arrive on one thread while a calibration or verification runs on
    another (the node runs one at a time) and reports are written on a third. Statuses are
    published under one lock, so a 'collecting' status never lands between a calibration's
    'running' status and its result, and a report's follow-up never over a newer result.
    """

    def __init__(
        self,
        sink: StatusSink,
        log: Log,
        schedule_report: Callable[[], object],
        calibrate_service: str = CALIBRATE_SERVICE,
    ) -> None:
        """Publish through `sink`; `schedule_report()` runs write_reports() later, elsewhere."""
        self._sink = sink
        self._log = log
        self._schedule_report = schedule_report
        self._calibrate_service = calibrate_service  # as resolved, for the messages
        self.postures = PostureStore()
        self.nominal = NominalFile()
        self.reports = ReportQueue()
        # Orders 'collecting' statuses (posture thread) against the calibration's statuses;
        # guards the numbers, the latest calibration and the flags below.
        self._status_lock = threading.Lock()
        self._calibrating = False
        self._last_outcome = 'none'
        self._calibration_number = 0
        self._verification_number = 0
        self._latest: LatestCalibration | None = None

    @property
    def latest(self) -> LatestCalibration | None:
        """Return the calibration hexacal/verify would verify (None: none yet)."""
        with self._status_lock:
            return self._latest

    # ------------------------------------------------------------------ postures

    def receive_posture(
        self,
        joint_names: Sequence[str],
        convert: Callable[[str], PostureReading],
        nominal_path: str,
    ) -> Receipt:
        """
        Store a posture, or count why it is rejected; publish the collecting status.

        The nominal file's model names the joints; without a loadable one the joints decide.
        `convert(model)` reads the message as that model's posture (InvalidReadingError).
        """
        from .. import pipeline

        expected = self.nominal.model(nominal_path)
        carried = model_for_actuator_names(joint_names)
        model = expected or (carried.name if carried is not None else DEFAULT_MODEL)
        posture = None
        if (
            expected is not None
            and carried is not None
            and carried.name != expected
            and not set(MODELS[expected].actuator_names).issubset(joint_names)
        ):
            joints = carried.actuator_names
            problem = (
                pipeline.MODEL_MISMATCH,
                f'posture carries the actuator joints of a {carried.name} '
                f'({joints[0]}..{joints[-1]}) but '
                f"the nominal model is a {expected}'s ({nominal_path})",
            )
        else:
            try:
                posture = convert(model)
                problem = pipeline.posture_problem(posture, model=model)
            except InvalidReadingError as error:
                problem = (Reason.INVALID_READING, str(error))
        if problem is not None:
            receipt = self.postures.reject(*problem)
        else:
            receipt = self.postures.add(posture, model)
        with self._status_lock:
            if not self._calibrating:  # a running calibration's status stays until its result
                count = receipt.count
                values: dict[str, object] = {
                    'outcome': Reason.COLLECTING,
                    'postures_received': count,
                    'last_calibration': self._last_outcome,
                }
                if self._latest is not None:  # the postures hexacal/verify would use
                    values['verification_postures'] = max(count - self._latest.verify_from, 0)
                values.update(self.postures.rejection_values())
                level = Level.OK if receipt.stored else Level.WARN
                self._sink.status(
                    CALIBRATION_STATUS_NAME, level, self.postures.summary(count), values
                )
        return receipt

    # ------------------------------------------------------------------ calibration

    def calibrate(self, settings: Settings) -> Outcome:
        """Calibrate, publish the result and queue its report; never raise."""
        with self._status_lock:
            self._calibration_number += 1
            number = self._calibration_number
        try:
            outcome = self._run_calibration(settings)
        except Exception as error:  # noqa: BLE001 - the node must survive and say what happened
            self._log.error(f'calibration failed unexpectedly: {error!r}')
            outcome = failure(Reason.INTERNAL_ERROR, f'{type(error).__name__}: {error}')
        with self._status_lock:
            if outcome.parameters is not None:
                self._sink.parameters(outcome.parameters.vector, outcome.parameters.model)
            self._sink.status(
                CALIBRATION_STATUS_NAME, outcome.level, outcome.message, outcome.values
            )
            self._calibrating = False
            self._last_outcome = str(outcome.values.get('outcome', outcome.level))
            if outcome.parameters is not None:  # published: the calibration verify verifies
                self._latest = LatestCalibration(
                    number,
                    outcome.parameters,
                    outcome.defects,
                    outcome.source,
                    outcome.verify_from,
                    outcome.link_length,
                    outcome.mount,
                    outcome,
                )
        if outcome.report is not None:
            replaced = self.reports.put_calibration(number, outcome)
            if replaced is not None:
                self._log.info(
                    f'the report of calibration {replaced} is replaced by '
                    f'that of calibration {number}'
                )
            self._schedule_report()
        return outcome

    def _run_calibration(self, settings: Settings) -> Outcome:
        from .. import pipeline
        from ..core.identification import CONVERGED, ITERATION_LIMIT

        nominal_path, cost, bag = settings.nominal, settings.cost, settings.bag
        link_length = settings.link_length
        target = output_path(settings.output, settings.output_dir)
        if not nominal_path:
            return failure(
                Reason.MISSING_PARAMETER,
                "parameter 'nominal' is not set: give the "
                'nominal parameters YAML to start from (-p nominal:=<path>)',
            )
        try:
            nominal, mount = self.nominal.load(nominal_path)
        except (ParameterFileError, ValueError) as error:
            return failure(Reason.INVALID_NOMINAL, f'nominal: {error}')
        if bag:
            try:
                loaded = pipeline.postures_from_bag(bag)
            except Exception as error:  # noqa: BLE001 - BagError, CalibrationError, contract
                return failure(Reason.INVALID_BAG, f'bag {bag}: {error}', bag=bag)
            postures, source = loaded.postures, f'bag {bag} ({loaded.source})'
            not_used = {
                'postures_rejected_on_receipt': len(loaded.rejected),
                'invalid_messages': loaded.invalid_messages,
            }
            postures_models = {loaded.model} if loaded.model else set()
        else:
            postures, postures_models = self.postures.since(0)
            source = 'live postures'
            not_used = {'postures_rejected_on_receipt': self.postures.rejected}
        verify_from = len(self.postures)  # the postures after these verify it, never fit it
        for model in sorted(postures_models):
            try:
                pipeline.check_model(
                    model, nominal, 'the bag' if bag else 'the postures received', nominal_path
                )
            except pipeline.ModelMismatchError as error:
                return failure(
                    error.reason,
                    str(error),
                    postures_received=len(postures),
                    source=source,
                    model=nominal.model,
                )
        self._log.info(f'calibrating from {len(postures)} {source}, {cost} cost')
        with self._status_lock:
            self._calibrating = True
            self._sink.status(
                CALIBRATION_STATUS_NAME,
                Level.OK,
                f'calibrating from {len(postures)} postures',
                {'outcome': Reason.RUNNING, 'postures_received': len(postures), 'source': source},
            )
        about = {'postures_received': len(postures), 'source': source, **not_used}
        noise = settings.noise()
        try:
            prior = device_prior(settings.device_prior, link_length)
        except ValueError as error:
            return failure(Reason.INVALID_DEVICE_PRIOR, str(error), **about)
        if prior and noise is None:
            return failure(
                Reason.DEVICE_PRIOR_WITHOUT_NOISE,
                f'a device prior ({prior.describe()}) is weighed against the data by the '
                'reading noise: set noise_slider_m and noise_angle_rad (> 0), or the prior std '
                'parameters (device.*_std) to 0',
                **about,
            )
        try:
            result = pipeline.calibrate(
                nominal,
                postures,
                cost=cost,
                link_length=link_length,
                identify_device=names(settings.identify_device),
                noise=noise,
                robust_loss=settings.robust_loss or None,
                mount=mount,
                device_prior=prior,
            )
        except CalibrationError as error:
            return failure(error.reason, str(error), **about)
        except ValueError as error:  # options the solver refuses (SolverOptions.validate)
            return failure(Reason.INVALID_OPTIONS, str(error), **about)
        values: dict[str, object] = {
            'postures_received': len(postures),
            'source': source,
            **pipeline.status_fields(result, prior),
            **not_used,
        }
        summary = (
            f'{len(result.used_postures)} of {len(postures)} postures, {cost} cost, '
            f'{result.iterations} iterations, rank {result.rank}, rms residual '
            + ', '.join(f'{k} {v:.3g}' for k, v in result.rms_residual.items())
        )
        if result.reason not in (CONVERGED, ITERATION_LIMIT):
            return failure(
                result.reason, f'the identification did not converge ({summary})', **values
            )
        calibration = {
            'verify_from': verify_from,
            'defects': result.device,
            'link_length': link_length,
            'mount': mount,
            'source': source,
        }
        try:
            save_parameters(
                target,
                result.parameters.vector,
                model=result.parameters.model,
                header_comment=(
                    f'hexacal calibration {_now()}'
                    f'\nfrom {source}: {summary}\nnominal: {nominal_path}; SI units'
                ),
                extras=pipeline.device_defects_extras(result) or None,
            )
        except HexacalContractError as error:
            return Outcome(
                False,
                f'{Reason.OUTPUT_NOT_WRITTEN}: calibrated ({summary}) but {error}',
                Level.WARN,
                {**values, 'outcome': Reason.OUTPUT_NOT_WRITTEN},
                result.parameters,
                **calibration,
            )
        values['output'] = str(target)
        # The report (figures, pose-error map, result payload) is written after the answer.
        report = None
        if settings.report_dir:
            report = ReportJob(
                settings.report_dir,
                settings.output_dir,
                result,
                postures,
                source,
                link_length,
                mount,
                prior,
            )
            values['report_state'] = ReportState.WRITING
        else:
            values['report_state'] = ReportState.DISABLED
        return Outcome(
            True,
            f'{result.reason}: {summary}; wrote {target}',
            Level.OK if result.reason == CONVERGED else Level.WARN,
            values,
            result.parameters,
            report,
            **calibration,
        )

    # ------------------------------------------------------------------ verification

    def verify(self, settings: Settings) -> Outcome:
        """Verify the latest calibration on the postures after it; publish; queue its report."""
        with self._status_lock:
            self._verification_number += 1
            number = self._verification_number
            latest = self._latest
        task = None
        try:
            outcome, task = self._run_verification(settings, number, latest)
        except Exception as error:  # noqa: BLE001 - the node must survive and say what happened
            self._log.error(f'verification failed unexpectedly: {error!r}')
            outcome = failure(Reason.INTERNAL_ERROR, f'{type(error).__name__}: {error}')
        with self._status_lock:
            self._sink.status(
                VERIFICATION_STATUS_NAME, outcome.level, outcome.message, outcome.values
            )
        if task is not None:
            self.reports.put_verification(task)
            self._schedule_report()
        return outcome

    def _run_verification(
        self, settings: Settings, number: int, latest: LatestCalibration | None
    ) -> tuple[Outcome, VerificationTask | None]:
        from .. import pipeline
        from ..core.device import DeviceModel
        from ..core.verification import PASS, verify

        if latest is None:
            return failure(
                Reason.NO_CALIBRATION,
                'no calibration to verify yet: calibrate first '
                f'({self._calibrate_service}), then measure fresh postures '
                'and call verify again',
            ), None
        postures, postures_models = self.postures.since(latest.verify_from)
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
            nominal, mount = self.nominal.load(nominal_path)
        except (ParameterFileError, ValueError) as error:
            return failure(Reason.INVALID_NOMINAL, f'nominal: {error}', **about), None
        link_length = latest.link_length or settings.link_length
        mount = latest.mount or mount
        try:
            for model in sorted(postures_models):
                pipeline.check_model(
                    model, nominal, 'the postures received since the calibration', nominal_path
                )
            result = verify(
                nominal,
                latest.parameters,
                pipeline.measurements_from_postures(postures),
                device=DeviceModel(link_length=link_length, mount=mount),
                threshold_m=settings.verify_threshold_m or None,
                noise=settings.noise(),
                postures_model=next(iter(postures_models)) if len(postures_models) == 1 else None,
                calibrated_defects=latest.defects,
            )
        except (CalibrationError, ValueError) as error:
            reason = getattr(error, 'reason', Reason.INVALID_INPUT)
            return failure(reason, str(error), postures=len(postures), **about), None
        values: dict[str, object] = {
            'outcome': Reason.VERIFIED,
            **result.status_values(),
            **about,
        }
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

    # ------------------------------------------------------------------ reports

    def write_reports(self) -> None:
        """
        Write what waits, then publish the follow-up statuses (on the report thread).

        The latest calibration's report and/or the latest verification's, as one page when the
        verification is of that calibration. A failed report is logged and said in the
        follow-up: the parameters, the file and the outcome stay as they are.
        """
        pending, verification = self.reports.take()
        if pending is None and verification is None:
            return  # a newer task replaced it, and an earlier task wrote that one
        if (
            pending is not None
            and verification is not None
            and verification.calibration_number != pending[0]
        ):
            # A verification of an older calibration: the newer calibration's page replaces it.
            self._follow_up_verification(
                verification,
                ReportState.SUPERSEDED,
                f'report superseded by calibration {pending[0]}',
                {},
            )
            verification = None
        if pending is not None:
            number, job = pending[0], pending[1].report
        else:
            number, job = verification.calibration_number, verification.job
        try:
            path = write_page(job, verification)
        except Exception as error:  # noqa: BLE001 - the parameters are written; a report is extra
            self._log.warning(f'calibration report not written: {error}')
            state, text = ReportState.FAILED, f'report failed: {error}'
            extra: dict[str, object] = {'report_error': f'{type(error).__name__}: {error}'}
        else:
            what = 'calibration' if job is not None else 'verification'
            self._log.info(f'{what} report written: {path}')
            state, text, extra = ReportState.READY, f'report ready: {path}', {'report': str(path)}
        if pending is not None:
            outcome = pending[1]
            with self._status_lock:
                if number == self._calibration_number:  # else a newer calibration's stands
                    try:
                        self._sink.status(
                            CALIBRATION_STATUS_NAME,
                            outcome.level,
                            f'{outcome.message}; {text}',
                            {**outcome.values, 'report_state': state, **extra},
                        )
                    except Exception as error:  # noqa: BLE001 - shutting down: no context
                        self._log.warning(f'report status not published: {error}')
        if verification is not None:
            self._follow_up_verification(verification, state, text, extra)

    def _follow_up_verification(
        self, task: VerificationTask, state: ReportState, text: str, extra: dict[str, object]
    ) -> None:
        with self._status_lock:
            if task.number != self._verification_number:
                return  # a newer verification's status stands
            try:
                self._sink.status(
                    VERIFICATION_STATUS_NAME,
                    task.outcome.level,
                    f'{task.outcome.message}; {text}',
                    {**task.outcome.values, 'report_state': state, **extra},
                )
            except Exception as error:  # noqa: BLE001 - shutting down: the context may be gone
                self._log.warning(f'verification report status not published: {error}')

    # ------------------------------------------------------------------ start-up

    def republish_saved(self, settings: Settings) -> None:
        """
        Republish an existing output file; it becomes the calibration verify verifies.

        Temporary files of a write that a crash interrupted are removed first (the output
        itself is only ever replaced whole). The file's device defects are the device it was
        calibrated with, so it is verified through that device.
        """
        try:
            target = output_path(settings.output, settings.output_dir)
        except ValueError:
            return
        for leftover in interrupted_writes(target):
            try:
                leftover.unlink()
                self._log.warning(f'removed {leftover}, an interrupted write')
            except OSError as error:
                self._log.warning(f'cannot remove {leftover}: {error}')
        if not target.exists():
            return
        try:
            saved = read_parameters_file(target)
        except ParameterFileError as error:
            self._log.error(f'not republishing the saved calibration: {error}')
            return
        self._sink.parameters(saved.vector, saved.model)
        self._log.info(f'republished the saved calibration {target}')
        from ..core.architectures import parameters_for
        from ..pipeline import device_defects_from_extras

        try:
            parameters = parameters_for(saved.model, saved.vector)
            defects, _ = device_defects_from_extras(saved.extras, target)  # the device it had
        except ValueError as error:
            self._log.warning(f'the saved calibration cannot be verified: {error}')
            return
        with self._status_lock:  # verify verifies it on the postures received from now on
            self._latest = LatestCalibration(
                0, parameters, defects, f'saved calibration {target}', 0, None, None, None
            )
