"""One calibration: from the inputs checked to the parameters file written."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import datetime, timezone
from typing import Protocol, TYPE_CHECKING

from hexacal_msgs_py.calibrate_answer import calibrate_answer, HEADER_SOURCE
from hexacal_msgs_py.errors import HexacalContractError, ParameterFileError
from hexacal_msgs_py.parameters_file import save_parameters
from hexacal_msgs_py.readings import PostureReading
from hexacal_msgs_py.store_format import FITTED_POSTURES_COMMENT, postures_digest

from .html_reports import ReportJob
from .node_settings import names, Settings
from .nominal import NominalFile
from .outcome import failure, Level, Outcome, Reason, ReportState
from .paths import output_path
from .prior import device_prior
from .received_postures import PostureStore
# calibration_steps and core.identification (the solver) are imported where they are used: at the
# first calibration, not when the node starts.
from ..core.errors import CalibrationError
from ..core.machine.measurements import Weights
from ..store.provenance import calibration_record

if TYPE_CHECKING:
    from ..core.architectures import KinematicParameters
    from ..core.fit.compliance import ComplianceModel
    from ..core.fit.statics import MassModel


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


def run_calibration(
    settings: Settings,
    nominal_file: NominalFile,
    store: PostureStore,
    log: Log,
    started: Callable[[int, str], None],
) -> Outcome:
    """
    Calibrate as `settings` say, from the live postures in `store` or a bag; return the outcome.

    `started(postures, source)` publishes the 'running' status once the inputs are checked.
    The output is written (atomically, with the device defects identified); the report is
    left to do (Outcome.report). Unexpected errors propagate: the session names them.
    """
    from ..calibration_steps.bag_postures import postures_from_bag
    from ..calibration_steps.calibration_run import (
        calibrate,
        device_prior_json,
        status_fields,
        weight_choice,
    )
    from ..calibration_steps.machine_files import compliance_file_extras, device_defects_extras
    from ..calibration_steps.posture_checks import check_model, ModelMismatchError
    from ..core.fit.identification import CONVERGED, ITERATION_LIMIT

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
        nominal, mount = nominal_file.load(nominal_path)
    except (ParameterFileError, ValueError) as error:
        return failure(Reason.INVALID_NOMINAL, f'nominal: {error}')
    if bag:
        try:
            loaded = postures_from_bag(bag)
        except Exception as error:  # noqa: BLE001 - BagError, CalibrationError, contract
            return failure(Reason.INVALID_BAG, f'bag {bag}: {error}', bag=bag)
        postures, source = loaded.postures, f'bag {bag} ({loaded.source})'
        not_used = {
            'postures_rejected_on_receipt': len(loaded.rejected),
            'invalid_messages': loaded.invalid_messages,
        }
        postures_models = {loaded.model} if loaded.model else set()
        measuring_mode = loaded.measuring_mode
        released_joints = [loaded.measuring.released_at(p.stamp_ns) for p in postures]
    else:
        postures, postures_models = store.since(0)
        source = 'live postures'
        not_used = {'postures_rejected_on_receipt': store.rejected}
        measuring_mode, released_joints = live_measuring_mode(postures), None
    verify_from = len(store)  # the postures after these verify it, never fit it
    for model in sorted(postures_models):
        try:
            check_model(
                model, nominal, 'the bag' if bag else 'the postures received', nominal_path
            )
        except ModelMismatchError as error:
            return failure(
                error.reason,
                str(error),
                postures_received=len(postures),
                source=source,
                model=nominal.model,
            )
    log.info(f'calibrating from {len(postures)} {source}, {cost} cost')
    started(len(postures), source)
    about = {'postures_received': len(postures), 'source': source, **not_used}
    noise = settings.noise()
    try:
        prior = device_prior(settings.device_prior, link_length)
    except ValueError as error:
        return failure(Reason.INVALID_DEVICE_PRIOR, str(error), **about)
    try:
        choice = weight_choice(
            postures,
            settings.weights,
            noise,
            settings.scatter_floor(),
            nominal.layout.actuator_unit,
        )
    except ValueError as error:  # scatter asked for but missing, a noise model asked for but unset
        return failure(Reason.INVALID_OPTIONS, str(error), **about)
    log.info(f'weights: {choice.note}')
    try:
        compliance, masses_source = compliance_setting(
            settings, nominal, measuring_mode, released_joints, bool(bag)
        )
    except ValueError as error:
        return failure(Reason.INVALID_OPTIONS, str(error), **about)
    if prior and choice.weights == Weights.NONE:
        return failure(
            Reason.DEVICE_PRIOR_WITHOUT_NOISE,
            f'a device prior ({prior.describe()}) is weighed against the data by the '
            'reading noise: set noise_slider_m and noise_angle_rad (> 0) or calibrate postures '
            'that carry their scatter, or set the prior std parameters (device.*_std) to 0',
            **about,
        )
    try:
        result = calibrate(
            nominal,
            postures,
            cost=cost,
            link_length=link_length,
            identify_device=names(settings.identify_device),
            noise=noise,
            robust_loss=settings.robust_loss or None,
            mount=mount,
            device_prior=prior,
            weights=settings.weights,
            scatter_floor=settings.scatter_floor(),
            compliance=compliance,
        )
    except CalibrationError as error:
        return failure(error.reason, str(error), **about)
    except ValueError as error:  # options the solver refuses (SolverOptions.validate)
        return failure(Reason.INVALID_OPTIONS, str(error), **about)
    values: dict[str, object] = {
        'postures_received': len(postures),
        'source': source,
        **status_fields(result, prior),
        **not_used,
    }
    if compliance is not None:  # whose weights loaded the compliances identified
        values['compliance_physical'] = masses_source
    summary = (
        f'{len(result.used_postures)} of {len(postures)} postures, {cost} cost, '
        f'{result.iterations} iterations, rank {result.rank}, rms residual '
        + ', '.join(f'{k} {v:.3g}' for k, v in result.rms_residual.items())
    )
    if result.reason not in (CONVERGED, ITERATION_LIMIT):
        return failure(
            result.reason, f'the identification did not converge ({summary})', **values
        )
    try:
        save_parameters(
            target,
            result.parameters.vector,
            model=result.parameters.model,
            header_comment=(
                f'hexacal calibration {_now()}'
                f'\n{HEADER_SOURCE}{source}: {summary}\nnominal: {nominal_path}; SI units'
                f'\n{FITTED_POSTURES_COMMENT}{postures_digest(postures)}'
            ),
            extras={**device_defects_extras(result), **compliance_file_extras(result)} or None,
        )
    except HexacalContractError as error:
        return Outcome(
            False,
            f'{Reason.OUTPUT_NOT_WRITTEN}: calibrated ({summary}) but {error}',
            Level.WARN,
            {**values, 'outcome': Reason.OUTPUT_NOT_WRITTEN},
            result.parameters,
            verify_from=verify_from,
            defects=result.device,
            link_length=link_length,
            mount=mount,
            source=source,
            compliance=dict(result.compliance),
        )
    values['output'] = str(target)
    if settings.deflection_check and result.reason == CONVERGED:
        values.update(
            deflection_values(settings, result, measuring_mode, released_joints, mount, log)
        )
    record = calibration_record(
        result,
        source='identify node',
        postures=postures,
        nominal_file=nominal_path,
        noise=noise,
        robust_loss=settings.robust_loss or None,
        link_length=link_length,
        mount=mount,
        device_prior=device_prior_json(prior),
        bag=bag or None,
    )
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
        calibrate_answer(result.reason, summary, target),  # the executor matches on it
        Level.OK if result.reason == CONVERGED else Level.WARN,
        values,
        result.parameters,
        report,
        verify_from=verify_from,
        defects=result.device,
        link_length=link_length,
        mount=mount,
        source=source,
        compliance=dict(result.compliance),
        record=record,
    )


def deflection_values(
    settings: Settings,
    result,
    measuring_mode: str | None,
    released_joints: Sequence[str] | None,
    mount: str,
    log: Log,
) -> dict[str, object]:
    """
    Return the rigid fit's deflection check as status values (``deflection_check.*``, SI).

    calibration_steps.calibration_run.deflection_check with physical_file's stiffnesses, as
    ``hexacal calibrate --physical`` runs it; logged in one line, a warning when the bias
    exceeds the calibration's statistical error.  A check that cannot run (a mass-only file,
    live postures that do not show their mode) is named in ``deflection_check.error``: the
    calibration stands.
    """
    from ..calibration_steps.calibration_run import deflection_check

    try:
        check = deflection_check(
            result, settings.physical_file, measuring_mode, released_joints,
            cost=settings.cost, link_length=settings.link_length, mount=mount,
            identify_device=names(settings.identify_device),
        )
    except ValueError as error:
        log.warning(f'no deflection check: {error}')
        return {'deflection_check.error': str(error)}
    # One call site per severity: rclpy refuses a severity change at the same line.
    if check.significant:
        log.warning(check.text())
    else:
        log.info(check.text())
    values: dict[str, object] = {}
    for key, value in check.to_json().items():
        if isinstance(value, dict):  # visible_rms: one per residual channel
            values.update({f'deflection_check.{key}.{k}': v for k, v in value.items()})
        else:
            values[f'deflection_check.{key}'] = value
    return values


def live_measuring_mode(postures: Sequence[PostureReading]) -> str | None:
    """
    Return the measuring mode live postures show, None when they do not say.

    A posture on hexacal/posture carries a measured link length (joint link_length) only in the
    lvdt mode (hexacal_msgs_py.measuring_modes), so postures that all carry one are the lvdt
    mode's. Neither the passive_actuator mode nor a posture's released actuator is on the
    message: the collector records them in its bag (bag.measuring), not on the topic.
    """
    if postures and all(p.link_length is not None for p in postures):
        return 'lvdt'
    return None


def compliance_setting(
    settings: Settings,
    nominal: KinematicParameters,
    measuring_mode: str | None,
    released_joints: Sequence[str] | None,
    from_bag: bool,
) -> tuple[ComplianceModel | None, str]:
    """
    Return (ComplianceModel or None, where the weights come from) of the compliance parameters.

    The same ComplianceModel ``hexacal calibrate --compliance`` builds
    (calibration_steps.calibration_run.compliance_for_postures); ValueError names what is
    missing or wrong.
    """
    from ..calibration_steps.calibration_run import (
        compliance_for_postures,
        drive_stiffness_of,
        parse_compliance_prior,
        released_friction_of,
    )

    prior = parse_compliance_prior(settings.compliance_prior)
    if settings.deflection_check and settings.compliance != 'none':
        raise ValueError(
            f'deflection_check judges a rigid fit, but compliance is {settings.compliance}: '
            'the compliances are identified (their values and standard deviations are on the '
            'status); set compliance to none, or deflection_check to false'
        )
    if settings.compliance == 'none':
        if prior:
            raise ValueError(
                'compliance_prior is set but compliance is none: set compliance to shared or '
                "per_chain, or compliance_prior to ''"
            )
        return None, ''
    if measuring_mode is None and not from_bag:
        raise ValueError(
            f'compliance {settings.compliance}: the live postures do not carry the measuring '
            'mode nor the released actuator of each posture (hexacal/posture has no such joint; '
            'only the lvdt postures show their mode, by their link_length), and the loads '
            'depend on them: calibrate from the bag the collector recorded (parameter bag), '
            'whose measuring record holds both, or set compliance to none'
        )
    if measuring_mode is None:
        raise ValueError(
            f'compliance {settings.compliance}: the bag does not record its measuring mode, and '
            'the loads depend on it (which chains and whether the link carry the weight)'
        )
    masses, source = mass_model(settings, nominal.model)
    model = compliance_for_postures(
        settings.compliance,
        masses,
        measuring_mode,
        released_joints,
        nominal.layout.actuator_names,
        prior,
        label='compliance',
        released_friction=released_friction_of(settings.physical_file, nominal.model),
        drive_stiffness=drive_stiffness_of(settings.physical_file, nominal.model),
    )
    return model, source


def mass_model(settings: Settings, model: str) -> tuple[MassModel, str]:
    """Return the weights that load the compliances, and where they come from (physical_file)."""
    from ..core.fit.statics import physical_weights

    return physical_weights(settings.physical_file, model)


# ------------------------------------------------------------------ verification
