"""
The calibration session of the identify node: postures, calibrations, verifications, reports.

Everything the node decides, without ROS: the node converts messages, reads its parameters
into a Settings, runs these methods on its threads and publishes through a StatusSink.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
import threading
from typing import Protocol

from hexacal_msgs_py.errors import InvalidReadingError, ParameterFileError
from hexacal_msgs_py.models import DEFAULT_MODEL, model_for_actuator_names, MODELS
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_NAME,
    DEPLOY_SERVICE,
    DEPLOYMENT_STATUS_NAME,
    VERIFICATION_STATUS_NAME,
)
from hexacal_msgs_py.parameters_file import read_parameters_file
from hexacal_msgs_py.readings import PostureReading
import numpy as np

from .calibration import Log, run_calibration
from .deployment import ACTIVE_KEYS
from .history import History
from .html_reports import ReportQueue, VerificationTask, write_page
from .node_settings import Settings
from .nominal import NominalFile
from .outcome import failure, Level, Outcome, Reason, ReportState
from .paths import interrupted_writes, output_path
from .received_postures import PostureStore, Receipt
from .verification import LatestCalibration, run_verification
from ..store import StoreError


class StatusSink(Protocol):
    """Where the session publishes (the node's publishers)."""

    def status(self, name: str, level: Level, message: str, values: dict[str, object]) -> None:
        """Publish a status named `name` (calibration or verification)."""

    def parameters(self, vector: Sequence[float] | np.ndarray, model: str) -> None:
        """Publish a calibrated vector of `model`'s layout."""


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
        self.history = History()  # the calibration store: every calibration kept, deploys

    def use_log(self, log: Log) -> None:
        """Log through `log` from now on (the node's shutdown keeps its lines for later)."""
        self._log = log

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
        from ..calibration_steps.posture_checks import MODEL_MISMATCH, posture_problem

        expected = self.nominal.model(nominal_path)
        carried = model_for_actuator_names(joint_names)
        model = expected or (carried.name if carried is not None else DEFAULT_MODEL)
        posture: PostureReading | None = None
        problem: tuple[str, str] | None
        if (
            expected is not None
            and carried is not None
            and carried.name != expected
            and not set(MODELS[expected].actuator_names).issubset(joint_names)
        ):
            joints = carried.actuator_names
            problem = (
                MODEL_MISMATCH,
                f'posture carries the actuator joints of a {carried.name} '
                f'({joints[0]}..{joints[-1]}) but '
                f"the nominal model is a {expected}'s ({nominal_path})",
            )
        else:
            try:
                posture = convert(model)
                problem = posture_problem(posture, model=model)
            except InvalidReadingError as error:
                problem = (Reason.INVALID_READING, str(error))
        if problem is not None:
            receipt = self.postures.reject(*problem)
        else:
            assert posture is not None  # converted, no problem found
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
        """
        Calibrate, publish the result and queue its report; never raise.

        From the live postures, or the bag `settings.bag` names. On success the parameters are
        written atomically to the output (with the device defects identified,
        `device.defects.<name>`), published, then the status; the report follows
        (`report_state: writing`). A refused or failed calibration publishes an ERROR status
        naming the reason and no parameters; the postures received are kept either way.
        """
        with self._status_lock:
            self._calibration_number += 1
            number = self._calibration_number
        try:
            outcome = run_calibration(
                settings, self.nominal, self.postures, self._log, self._started
            )
        except Exception as error:  # noqa: BLE001 - the node must survive and say what happened
            self._log.error(f'calibration failed unexpectedly: {error!r}')
            outcome = failure(Reason.INTERNAL_ERROR, f'{type(error).__name__}: {error}')
        try:
            store_id = self._keep(settings, outcome)
        except Exception as error:  # noqa: BLE001 - the calibration is written: say, go on
            self._log.error(f'calibration not kept in the store: {error!r}')
            outcome.values['store_error'] = f'{type(error).__name__}: {error}'
            store_id = None
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
                    store_id,
                    outcome.compliance,
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

    def _keep(self, settings: Settings, outcome: Outcome) -> str | None:
        """Add a written calibration to the store; its status values say which entry."""
        if outcome.record is None or outcome.parameters is None:
            return None
        model = outcome.parameters.model
        entry, values = self.history.add(
            settings.calibration_store, model, Path(str(outcome.values['output'])), outcome.record
        )
        if entry is None:
            self._log.warning(f'calibration not kept in the store: {values["store_error"]}')
        outcome.values.update(values)
        outcome.values.update(self.history.active_values(settings.calibration_store, model))
        if outcome.report is not None:  # the report says which entry, and what is active
            keys = ('calibration_id', 'calibration_store', *ACTIVE_KEYS)
            outcome.report.store = {k: outcome.values[k] for k in keys if k in outcome.values}
        return entry.id if entry is not None else None

    def _started(self, postures: int, source: str) -> None:
        with self._status_lock:
            self._calibrating = True  # the collecting statuses wait for the result
            self._sink.status(
                CALIBRATION_STATUS_NAME,
                Level.OK,
                f'calibrating from {postures} postures',
                {'outcome': Reason.RUNNING, 'postures_received': postures, 'source': source},
            )

    # ------------------------------------------------------------------ verification

    def verify(self, settings: Settings) -> Outcome:
        """
        Verify the latest calibration on the postures after it; publish; queue its report.

        The latest calibration that produced parameters (or the output republished at start-up)
        is verified on the postures that arrived after it took its postures, never one the fit
        used: the device's measurement against forward kinematics at the measured actuator
        readings, for the nominal and the calibrated parameters
        (core/assessment/verification.py). The status (VERIFICATION_STATUS_NAME, outcome
        `verified`) carries the `hexacal verify` JSON keys flattened; success when the verdict
        is pass. Threshold: `verify_threshold_m`, or
        (0) 3x the residual the reading noise alone gives when it is set, else 50 um. Refused
        as `no-calibration` or `no-postures`. The calibration's report is then written again
        with a verification section. The postures stay: the next calibration fits on all.
        """
        with self._status_lock:
            self._verification_number += 1
            number = self._verification_number
            latest = self._latest
        task = None
        try:
            outcome, task = run_verification(
                settings, number, latest, self.nominal, self.postures, self._calibrate_service
            )
        except Exception as error:  # noqa: BLE001 - the node must survive and say what happened
            self._log.error(f'verification failed unexpectedly: {error!r}')
            outcome = failure(Reason.INTERNAL_ERROR, f'{type(error).__name__}: {error}')
        if outcome.figures is not None and latest is not None and latest.store_id is not None:
            model = latest.parameters.model
            outcome.values.update(
                self.history.attach(
                    settings.calibration_store, model, latest.store_id, outcome.figures
                )
            )
            outcome.values.update(self.history.active_values(settings.calibration_store, model))
        with self._status_lock:
            self._sink.status(
                VERIFICATION_STATUS_NAME, outcome.level, outcome.message, outcome.values
            )
        if task is not None:
            self.reports.put_verification(task)
            self._schedule_report()
        return outcome

    # ------------------------------------------------------------------ deployment

    def _model(self, settings: Settings) -> str:
        latest = self.latest
        if latest is not None:
            return latest.parameters.model
        return self.nominal.model(settings.nominal) or DEFAULT_MODEL

    def deploy(self, settings: Settings, force: bool = False) -> Outcome:
        """
        Deploy the latest calibration (kept in the store); publish; never raise.

        The store refuses one without a verification verdict pass, or a surprising jump from
        the active calibration, unless `force` (recorded as forced). The now-active calibration
        is published on hexacal/parameters (what a kinematics node following the store takes).
        """
        latest = self.latest
        store_id = latest.store_id if latest is not None else None
        model = self._model(settings)
        return self._deployed(
            settings,
            model,
            self.history.deploy(
                settings.calibration_store, model, store_id, force, DEPLOY_SERVICE
            ),
        )

    def rollback(self, settings: Settings) -> Outcome:
        """Return to the previously active calibration of the store; publish; never raise."""
        model = self._model(settings)
        return self._deployed(
            settings, model, self.history.rollback(settings.calibration_store, model)
        )

    def announce_active(self, settings: Settings) -> None:
        """Publish which calibration of the store is active (at start-up)."""
        model = self._model(settings)
        message, values = self.history.active_status(settings.calibration_store, model)
        with self._status_lock:
            self._sink.status(DEPLOYMENT_STATUS_NAME, Level.OK, message, values)

    def _deployed(self, settings: Settings, model: str, outcome: Outcome) -> Outcome:
        active = None
        if outcome.success:
            try:
                active = self.history.active_parameters(settings.calibration_store, model)
            except (ParameterFileError, OSError, StoreError) as error:
                self._log.warning(f'the active calibration is not published: {error}')
        with self._status_lock:
            if active is not None:
                self._sink.parameters(active.vector, active.model)
            self._sink.status(
                DEPLOYMENT_STATUS_NAME, outcome.level, outcome.message, outcome.values
            )
        return outcome

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
        elif verification is not None:
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
        from hexacal_msgs_py.parameters_file import compliances_from_extras

        from ..core.architectures import parameters_for
        from ..calibration_steps.machine_files import device_defects_from_extras

        try:
            parameters = parameters_for(saved.model, saved.vector)
            defects, _ = device_defects_from_extras(saved.extras, target)  # the device it had
            compliance = compliances_from_extras(saved.extras)
        except ValueError as error:
            self._log.warning(f'the saved calibration cannot be verified: {error}')
            return
        entry = self.history.find(settings.calibration_store, saved.model, target)
        with self._status_lock:  # verify verifies it on the postures received from now on
            self._latest = LatestCalibration(
                0,
                parameters,
                defects,
                f'saved calibration {target}',
                0,
                None,
                None,
                None,
                entry.id if entry is not None else None,
                compliance,
            )
