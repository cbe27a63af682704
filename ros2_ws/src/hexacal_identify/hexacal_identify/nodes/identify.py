"""Node `identify`: keep every posture received and calibrate on request.

The machine model is the one the `nominal` parameters file names (``model:``;
none = Hexa Slide), and so is the device mount (``device.mount``: hanging, the
default, or standing for an upright machine): postures carry its actuator joints (slider_1..6 on a Hexa
Slide, leg_1..6 on a Gough-Stewart platform), the result has its parameters
(54 or 42, published with that model's layout and saved with its ``model``
key). A posture with another model's joints is rejected on receipt
(`rejected.model-mismatch`); without a readable nominal file the joints decide,
and a calibration whose postures are of another model than the nominal file (or
bag) is refused as `model-mismatch`.

Subscribes `hexacal/posture` (POSTURE_QOS). Service `hexacal/calibrate`
(std_srvs/Trigger) runs `pipeline.calibrate` on a worker thread, from the live
postures or, with the `bag` parameter, from a recorded bag; the executor
(multi-threaded, reentrant service group) keeps receiving postures and
answers a second call at once with 'busy: a calibration is running'.

On success the parameters are written atomically to `output` (under
`output_dir`) and published on `hexacal/parameters` (transient local: late
subscribers get them), with the outcome on `hexacal/calibration_status`, and
the service answers. Only then is the HTML report (`report_dir`) written, on a
background worker of its own, so the answer waits for the solve and the
parameters file alone: the result status says `report_state: writing`, and a
follow-up status with the same values says `report_state: ready` with the
page's path in `report`, or `report_state: failed` with `report_error` (logged;
the parameters, the file and the outcome stay as they are). One report is
written at a time, that of the latest calibration: a newer calibration replaces
a report still waiting to start, and the follow-up of an older calibration is
not published over a newer one's status. On shutdown the report under way (and
the one waiting, the latest) are finished, so the report is whole. A
refused or failed calibration publishes an ERROR status naming the reason and
no parameters; the postures received are kept either way. Between
calibrations the status reports the postures received so far ('collecting',
`postures_received`). A posture that is not valid (NaN/inf, missing joints) or
reads beyond a sensor's range (pipeline.posture_problem) is never stored: it is
logged and counted in the status (`postures_rejected`, `rejected.<reason>`,
`last_rejection`), and the postures already received are kept. At start-up an
existing `output` file is republished, and temporary files of a write that a
crash interrupted are removed (the output itself is only ever replaced whole).
The output carries the device defects identified with the calibration
(`device.defects.<name>`, SI; none when only the machine was identified), so a
republished calibration is verified through the device it was calibrated with.

Prior knowledge of the device (core.device.DevicePrior): `device.link_length` (m, a caliper's measured
length; 0 = not measured) with `device.link_length_std` (m; > 0 makes a prior on dL =
device.link_length - link_length, `link_length` being the length the device model assumes), and
`device.<defect>` / `device.<defect>_std` (rad) for alpha0, beta0, gamma, phi0. A std > 0 makes a
prior: that parameter is identified, and the prior is weighed against the data by the reading noise,
so it needs `noise_slider_m` and `noise_angle_rad` (else the calibration fails as
`device-prior-without-noise`). The result status carries each prior (`prior.device.<name>`,
`prior_std.device.<name>`) beside the posterior (`device.<name>`, `std.device.<name>`), and the report
shows them side by side. A negative or non-finite std, and a link std without the measured length, are
refused when set.

Verification without ground truth (core/verification.py): service
`hexacal/verify` (std_srvs/Trigger) verifies the latest calibration - the latest
one that produced parameters, or at start-up the republished `output` file - on
the postures received after it: those that arrived after the calibration took its
postures (a second, verification plan walked on the machine), never one the fit
used. It compares the device's measurement with forward kinematics at the
measured actuator readings for the nominal (`nominal`) and the calibrated
parameters, publishes the figures on `hexacal/calibration_status` under the name
'hexacal verification' (outcome `verified`, the JSON keys of `hexacal verify`
flattened: `nominal.position_rms_m`, ..., `improvement`, `threshold_m`,
`verdict`), and answers success when the verdict is pass ('pass: ...' / 'fail:
...'). The threshold is `verify_threshold_m` (0: 3x the residual the reading
noise alone gives when `noise_slider_m` and `noise_angle_rad` are set, else 50
um). It refuses, with an ERROR status naming the reason and no figures, when no
calibration exists yet (`no-calibration`) or no posture arrived since
(`no-postures`). The report of that calibration is then written again with a
verification section, in the background like the calibration's: the
verification status says `report_state: writing`, its follow-up `ready` (with
`report`) or `failed`; the calibration's own status keeps its report_state
semantics. A calibration republished at start-up has no report here: its
verification page goes to `<report_dir>/verification/`. Postures stay in the
store either way: the next calibration fits on every posture received (the
verification postures included), and is verified on the postures after it.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime, timezone
import glob
import math
import os
from pathlib import Path
import sys
import threading

from diagnostic_msgs.msg import DiagnosticArray
from hexacal_msgs_py.conversions import (
    actuator_model,
    diagnostic_status,
    joint_state_to_posture_reading,
    parameters_to_multiarray,
)
from hexacal_msgs_py.errors import HexacalContractError, InvalidReadingError, ParameterFileError
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.names import (
    CALIBRATE_SERVICE,
    CALIBRATION_STATUS_TOPIC,
    PARAMETERS_TOPIC,
    POSTURE_TOPIC,
    VERIFICATION_STATUS_NAME,
    VERIFY_SERVICE,
)
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
from hexacal_msgs_py.qos import PARAMETERS_QOS, POSTURE_QOS, STATUS_QOS
from hexacal_msgs_py.readings import PostureReading
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterValueException
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

# pipeline and core.identification (the solver, scipy.linalg) are imported where they are used: at the first
# posture or calibration, not at start-up.
from ..core.architectures import KinematicParameters
from ..core.device import DEVICE_PARAMETER_NAMES, DeviceDefects, DevicePrior
from ..core.errors import CalibrationError
from ..core.measurements import NoiseModel
from ..core.residuals import COSTS
from ..report.page import write_report, write_verification_report
from .runtime import run_node

NODE_NAME = 'identify'
BUSY_MESSAGE = 'busy: a calibration is running'
BUSY_VERIFYING_MESSAGE = 'busy: a verification is running'
STATUS_NAME = 'hexacal calibration'
DEFAULT_OUTPUT = 'hexacal_calibration.yaml'
INVALID_LOG_PERIOD_S = 5.0
PROGRESS_LOG_PERIOD_S = 5.0
# The report task lets the answer go out first: rendering holds the GIL in long stretches, and the
# executor thread that sends the response would wait for it (a few ms per switch).
REPORT_START_DELAY_S = 0.05


# Prior knowledge of the device (parameters device.*): the measured link length, and a value per defect,
# each with its std; a std > 0 makes a prior (DevicePrior), 0 = none.
LINK_LENGTH_PRIOR = 'device.link_length'
ANGLE_PRIORS = ('alpha0', 'beta0', 'gamma', 'phi0')
PRIOR_VALUE_PARAMETERS = (LINK_LENGTH_PRIOR, *(f'device.{name}' for name in ANGLE_PRIORS))
PRIOR_STD_PARAMETERS = tuple(f'{name}_std' for name in PRIOR_VALUE_PARAMETERS)
MISSING_NOISE_FOR_PRIOR = 'device-prior-without-noise'


def _names(text: str) -> tuple[str, ...]:
    return tuple(name.strip() for name in text.split(',') if name.strip())


def output_path(output: str, output_dir: str) -> Path:
    """The file `output` names, which must lie under `output_dir` (ValueError otherwise)."""
    if not output:
        raise ValueError('output must name a file')
    directory = Path(output_dir or os.getcwd()).expanduser().resolve()
    target = (directory / Path(output).expanduser()).resolve()
    if target == directory or not target.is_relative_to(directory):
        raise ValueError(
            f'output {output!r} is outside output_dir {str(directory)!r}: '
            'the node writes only under output_dir'
        )
    return target


@dataclass
class Outcome:
    """What one calibration request did: the service response and the status to publish."""

    success: bool
    message: str
    level: str  # 'OK', 'WARN' or 'ERROR'
    values: dict[str, object]
    parameters: KinematicParameters | None = None
    report: ReportJob | None = None  # written after the answer (report_state 'writing')
    # A calibration's: live postures received before it took its postures (the later ones verify it),
    # the device defects it identified (none: the ideal device), the device it assumed.
    verify_from: int = 0
    defects: DeviceDefects = DeviceDefects()
    link_length: float | None = None
    mount: str | None = None
    source: str = ''


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


def _failure(reason: str, message: str, **values: object) -> Outcome:
    return Outcome(False, f'{reason}: {message}', 'ERROR', {'outcome': reason, **values})


@dataclass
class LatestCalibration:
    """The calibration hexacal/verify verifies: the latest that produced parameters."""

    number: int  # its calibration number (0: the saved output republished at start-up)
    parameters: KinematicParameters
    defects: DeviceDefects  # device defects identified with it
    source: str  # what it was fitted on, for the messages
    verify_from: (
        int  # live postures received before it took its postures: the later ones verify it
    )
    link_length: float | None  # the device it assumed (None: the node's parameters at verify time)
    mount: str | None
    outcome: Outcome | None  # its result (its report job); None when republished from the file


@dataclass
class VerificationTask:
    """The report of one verification: the calibration's page again with a verification section."""

    number: (
        int  # the verification number: its follow-up status is published while it is the latest
    )
    calibration_number: int
    job: ReportJob | None  # the calibration's report job; None: a verification page alone
    report_dir: str
    output_dir: str
    payload: dict  # VerificationResult.to_json(per_posture=True) + source
    outcome: Outcome  # the verification status to follow up


class IdentifyNode(Node):
    """Posture store + calibration service + transient-local result."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.declare_parameter(
            'output_dir',
            os.getcwd(),
            ParameterDescriptor(
                description='directory the node writes under (default: its working directory)'
            ),
        )
        self.declare_parameter(
            'output',
            DEFAULT_OUTPUT,
            ParameterDescriptor(
                description='parameters YAML written after a calibration; relative to output_dir, '
                'and never outside it'
            ),
        )
        self.declare_parameter(
            'nominal',
            '',
            ParameterDescriptor(
                description='parameters YAML of the nominal model to start from (required to '
                "calibrate); its 'model' key (none: hexa_slide) is the machine model, which names "
                'the posture joints'
            ),
        )
        self.declare_parameter(
            'cost',
            'absolute',
            ParameterDescriptor(
                description='cost function of the identification',
                additional_constraints=('one of ' + ', '.join(COSTS)),
            ),
        )
        self.declare_parameter(
            'bag',
            '',
            ParameterDescriptor(
                description="bag to calibrate from; '' = the postures received live"
            ),
        )
        self.declare_parameter(
            'link_length',
            0.75,
            ParameterDescriptor(
                description='measuring link length L (m)',
                floating_point_range=[FloatingPointRange(from_value=0.1, to_value=5.0, step=0.0)],
            ),
        )
        self.declare_parameter(
            'identify_device',
            '',
            ParameterDescriptor(
                description="device defects to identify jointly, comma-separated (e.g. 'dL,alpha0,gamma'); "
                "'' = none",
                additional_constraints='names from ' + ', '.join(DEVICE_PARAMETER_NAMES),
            ),
        )
        self.declare_parameter(
            'noise_slider_m',
            0.0,
            ParameterDescriptor(
                description='known slider noise half-width (m); with noise_angle_rad > 0 the residuals are '
                'weighted by the reading noise; 0 = unweighted',
                floating_point_range=[FloatingPointRange(from_value=0.0, to_value=0.01, step=0.0)],
            ),
        )
        self.declare_parameter(
            'noise_angle_rad',
            0.0,
            ParameterDescriptor(
                description='known angle noise half-width (rad), see noise_slider_m',
                floating_point_range=[FloatingPointRange(from_value=0.0, to_value=0.01, step=0.0)],
            ),
        )
        self.declare_parameter(
            'robust_loss',
            '',
            ParameterDescriptor(description="'' (least squares), 'huber' or 'soft_l1'"),
        )
        # Declared value before std: a std given at start-up is checked against its value (declared first).
        self.declare_parameter(
            LINK_LENGTH_PRIOR,
            0.0,
            ParameterDescriptor(
                description='measured length of the device link (m), e.g. by a caliper; with '
                'device.link_length_std > 0 it is a prior on dL = device.link_length - link_length (link_length '
                'is the length the device model assumes); 0.0 = not measured'
            ),
        )
        self.declare_parameter(
            f'{LINK_LENGTH_PRIOR}_std',
            0.0,
            ParameterDescriptor(
                description='standard deviation of device.link_length (m); > 0 makes the prior (needs '
                'device.link_length > 0 and noise_slider_m, noise_angle_rad); 0.0 = no prior'
            ),
        )
        for name in ANGLE_PRIORS:
            self.declare_parameter(
                f'device.{name}',
                0.0,
                ParameterDescriptor(
                    description=f'prior value of the device defect {name} (rad), used when device.{name}_std > 0'
                ),
            )
            self.declare_parameter(
                f'device.{name}_std',
                0.0,
                ParameterDescriptor(
                    description=f'standard deviation of the prior on {name} (rad); > 0 makes it a prior (the '
                    'defect is identified; needs noise_slider_m and noise_angle_rad); 0.0 = no prior'
                ),
            )
        self.declare_parameter(
            'verify_threshold_m',
            0.0,
            ParameterDescriptor(
                description='hexacal/verify passes when the calibrated position rms is at most this (m); 0 = '
                '3x the rms the reading noise alone gives when noise_slider_m and noise_angle_rad are set, '
                'else 50 um',
                floating_point_range=[FloatingPointRange(from_value=0.0, to_value=0.1, step=0.0)],
            ),
        )
        self.declare_parameter(
            'report_dir',
            'report',
            ParameterDescriptor(
                description='HTML calibration report written after each calibration, relative to output_dir; '
                "'' = none"
            ),
        )

        self._postures: list[PostureReading] = []
        self._posture_models: list[str] = []  # the model of each stored posture's joints
        self._postures_lock = threading.Lock()
        self.invalid_postures = 0  # rejected postures, all reasons
        self.rejected_postures: dict[str, int] = {}
        self._last_rejection = ''
        self._busy = threading.Lock()
        # Orders 'collecting' statuses (posture thread) against the calibration's statuses.
        self._status_lock = threading.Lock()
        self._calibrating = False
        self._last_outcome = 'none'
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix='calibration')
        # The report of the latest calibration, written after the answer on a worker of its own;
        # _calibration_number (under _status_lock) tells whether its follow-up status is still current.
        self._report_worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix='report')
        self._report_lock = threading.Lock()
        self._pending_report: tuple[int, Outcome] | None = None
        self._pending_verification_report: VerificationTask | None = None
        self._calibration_number = 0
        self._busy_message = BUSY_MESSAGE  # what a call answers while _busy is held
        # The calibration hexacal/verify verifies (under _status_lock), and the verifications so far.
        self._latest: LatestCalibration | None = None
        self._verification_number = 0
        # (file identity, (parameters, device mount)) of the nominal file
        self._nominal_cache: tuple[tuple, tuple[KinematicParameters, str]] | None = None
        self._model_cache: tuple[tuple, str | None] | None = None  # (file identity, model name)

        self._parameters_pub = self.create_publisher(
            Float64MultiArray, PARAMETERS_TOPIC, PARAMETERS_QOS
        )
        self._status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self.create_subscription(
            JointState,
            POSTURE_TOPIC,
            self._on_posture,
            POSTURE_QOS,
            callback_group=MutuallyExclusiveCallbackGroup(),
        )
        self.create_service(
            Trigger, CALIBRATE_SERVICE, self._on_calibrate, callback_group=ReentrantCallbackGroup()
        )
        self.create_service(
            Trigger, VERIFY_SERVICE, self._on_verify, callback_group=ReentrantCallbackGroup()
        )
        self._republish_saved()
        self.get_logger().info(
            f'collecting postures on {self.resolve_topic_name(POSTURE_TOPIC)}; calibrate with '
            f'{self.resolve_topic_name(CALIBRATE_SERVICE)}, verify with '
            f'{self.resolve_topic_name(VERIFY_SERVICE)}'
        )

    # ------------------------------------------------------------------ parameters

    def _validate_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        def current(name: str, fallback: str) -> str:
            new = [p.value for p in parameters if p.name == name]
            if new:
                return new[0]
            return self.get_parameter(name).value if self.has_parameter(name) else fallback

        for parameter in parameters:
            if parameter.name == 'identify_device':
                unknown = sorted(set(_names(parameter.value)) - set(DEVICE_PARAMETER_NAMES))
                if unknown:
                    return SetParametersResult(
                        successful=False,
                        reason=(
                            f'identify_device: unknown {unknown}; choose from {", ".join(DEVICE_PARAMETER_NAMES)}'
                        ),
                    )
            if (
                parameter.name == 'robust_loss' and parameter.value != ''
            ):  # '' (the default): no import
                from ..core.identification import ROBUST_LOSSES

                if parameter.value not in ROBUST_LOSSES:
                    return SetParametersResult(
                        successful=False,
                        reason=(
                            f"robust_loss must be '', {', '.join(ROBUST_LOSSES)}; got {parameter.value!r}"
                        ),
                    )
            if parameter.name == 'report_dir' and parameter.value:  # '' = no report
                try:
                    output_path(parameter.value, current('output_dir', ''))
                except ValueError as error:
                    return SetParametersResult(successful=False, reason=f'report_dir: {error}')
            if parameter.name == 'cost' and parameter.value not in COSTS:
                return SetParametersResult(
                    successful=False,
                    reason=(f'cost must be one of {", ".join(COSTS)}, got {parameter.value!r}'),
                )
            if parameter.name == 'link_length' and not math.isfinite(parameter.value):
                return SetParametersResult(successful=False, reason='link_length must be finite')
            if parameter.name in PRIOR_VALUE_PARAMETERS and not math.isfinite(parameter.value):
                return SetParametersResult(
                    successful=False,
                    reason=(
                        f'{parameter.name} must be finite (SI units: m for the link, rad for angles), '
                        f'got {parameter.value!r}'
                    ),
                )
            if parameter.name in PRIOR_STD_PARAMETERS and not (
                math.isfinite(parameter.value) and parameter.value >= 0
            ):
                return SetParametersResult(
                    successful=False,
                    reason=(
                        f'{parameter.name} must be a finite standard deviation >= 0 (0 = no prior), '
                        f'got {parameter.value!r}'
                    ),
                )
            if parameter.name == LINK_LENGTH_PRIOR and parameter.value < 0:
                return SetParametersResult(
                    successful=False,
                    reason=(
                        f'{LINK_LENGTH_PRIOR} is a length in m (0 = not measured), got {parameter.value!r}'
                    ),
                )
            if (
                parameter.name in (LINK_LENGTH_PRIOR, f'{LINK_LENGTH_PRIOR}_std')
                and current(f'{LINK_LENGTH_PRIOR}_std', 0.0) > 0
                and current(LINK_LENGTH_PRIOR, 0.0) <= 0
            ):
                return SetParametersResult(
                    successful=False,
                    reason=(
                        f'{LINK_LENGTH_PRIOR}_std > 0 makes a prior on the link length, but {LINK_LENGTH_PRIOR} '
                        'is not set: give the measured length in m (-p device.link_length:=0.7503), or set '
                        f'{LINK_LENGTH_PRIOR}_std to 0'
                    ),
                )
            if parameter.name in ('output', 'output_dir'):
                try:
                    output_path(current('output', DEFAULT_OUTPUT), current('output_dir', ''))
                except ValueError as error:
                    return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def _device_prior(self, link_length: float) -> DevicePrior:
        """The prior the device.* parameters give (empty: none). The link's is on dL = device.link_length -
        link_length (the length the device model assumes); ValueError when it is incomplete."""
        entries = []
        std = self.get_parameter(f'{LINK_LENGTH_PRIOR}_std').value
        if std > 0:
            measured = self.get_parameter(LINK_LENGTH_PRIOR).value
            if measured <= 0:
                raise ValueError(
                    f'{LINK_LENGTH_PRIOR}_std = {std:g} m but {LINK_LENGTH_PRIOR} is not set: give '
                    'the measured link length in m'
                )
            entries.append(('dL', measured - link_length, std))
        for name in ANGLE_PRIORS:
            std = self.get_parameter(f'device.{name}_std').value
            if std > 0:
                entries.append((name, self.get_parameter(f'device.{name}').value, std))
        return DevicePrior(tuple(entries))

    def _output_path(self) -> Path:
        return output_path(
            self.get_parameter('output').value, self.get_parameter('output_dir').value
        )

    # ------------------------------------------------------------------ postures

    def _on_posture(self, message: JointState) -> None:
        from .. import pipeline

        expected = self._nominal_model()
        carried = actuator_model(message.name)
        model = expected or (carried.name if carried is not None else DEFAULT_MODEL)
        if (
            expected is not None
            and carried is not None
            and carried.name != expected
            and not set(MODELS[expected].actuator_names).issubset(message.name)
        ):
            names = carried.actuator_names
            problem = (
                pipeline.MODEL_MISMATCH,
                (
                    f'posture carries the actuator joints of a {carried.name} ({names[0]}..{names[-1]}) but '
                    f"the nominal model is a {expected}'s ({self.get_parameter('nominal').value})"
                ),
            )
        else:
            try:
                posture = joint_state_to_posture_reading(message, model)
                problem = pipeline.posture_problem(posture, model=model)
            except InvalidReadingError as error:
                problem = ('invalid-reading', str(error))
        if problem is not None:
            reason, detail = problem
            self.invalid_postures += 1
            self.rejected_postures[reason] = self.rejected_postures.get(reason, 0) + 1
            self._last_rejection = f'{reason}: {detail}'
            self.get_logger().warning(
                f'ignored an invalid posture ({self.invalid_postures} so far): {reason}: {detail}',
                throttle_duration_sec=INVALID_LOG_PERIOD_S,
            )
            level = 'WARN'
            with self._postures_lock:
                count = len(self._postures)
        else:
            level = 'OK'
            with self._postures_lock:
                self._postures.append(posture)
                self._posture_models.append(model)
                count = len(self._postures)
        with self._status_lock:
            if not self._calibrating:  # a running calibration's status stays until its result
                values: dict[str, object] = {
                    'outcome': 'collecting',
                    'postures_received': count,
                    'last_calibration': self._last_outcome,
                }
                if self._latest is not None:  # the postures hexacal/verify would use
                    values['verification_postures'] = max(count - self._latest.verify_from, 0)
                if self.invalid_postures:
                    values.update(
                        {
                            'postures_rejected': self.invalid_postures,
                            **{
                                f'rejected.{reason}': n
                                for reason, n in sorted(self.rejected_postures.items())
                            },
                            'last_rejection': self._last_rejection,
                        }
                    )
                text = f'{count} postures received'
                if self.invalid_postures:
                    text += f', {self.invalid_postures} rejected (last: {self._last_rejection})'
                self._status_pub.publish(self._status_message(level, text, values))
        if problem is not None:
            return
        self.get_logger().info(
            f'{count} postures received', throttle_duration_sec=PROGRESS_LOG_PERIOD_S
        )

    def posture_count(self) -> int:
        with self._postures_lock:
            return len(self._postures)

    # ------------------------------------------------------------------ calibration

    def _on_calibrate(
        self, request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        if not self._busy.acquire(blocking=False):
            response.success, response.message = False, self._busy_message
            return response
        try:
            # The solve runs on the worker; this executor thread only waits for it.
            outcome = self._worker.submit(self._calibrate).result()
            response.success, response.message = outcome.success, outcome.message
        except Exception as error:  # noqa: BLE001 - a caller must always get an answer
            response.success = False
            response.message = f'internal-error: {type(error).__name__}: {error}'
        finally:
            self._busy.release()
        return response

    def _calibrate(self) -> Outcome:
        with self._status_lock:
            self._calibration_number += 1
            number = self._calibration_number
        try:
            outcome = self._run_calibration()
        except Exception as error:  # noqa: BLE001 - the node must survive and say what happened
            self.get_logger().error(f'calibration failed unexpectedly: {error!r}')
            outcome = _failure('internal-error', f'{type(error).__name__}: {error}')
        with self._status_lock:
            self._publish_result(outcome)
            self._calibrating = False
            self._last_outcome = str(outcome.values.get('outcome', outcome.level))
            if (
                outcome.parameters is not None
            ):  # published: the calibration hexacal/verify verifies
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
            self._queue_report(number, outcome)
        # One call site per severity: rclpy refuses a severity change at the same line.
        if outcome.success:
            self.get_logger().info(outcome.message)
        else:
            self.get_logger().error(outcome.message)
        return outcome

    def _run_calibration(self) -> Outcome:
        from .. import pipeline
        from ..core.identification import CONVERGED, ITERATION_LIMIT

        nominal_path = self.get_parameter('nominal').value
        cost = self.get_parameter('cost').value
        bag = self.get_parameter('bag').value
        link_length = self.get_parameter('link_length').value
        target = self._output_path()
        if not nominal_path:
            return _failure(
                'missing-parameter',
                "parameter 'nominal' is not set: give the "
                'nominal parameters YAML to start from (-p nominal:=<path>)',
            )
        try:
            nominal, mount = self._load_nominal(nominal_path)
        except (ParameterFileError, ValueError) as error:
            return _failure('invalid-nominal', f'nominal: {error}')
        if bag:
            try:
                loaded = pipeline.postures_from_bag(bag)
            except Exception as error:  # noqa: BLE001 - BagError, CalibrationError, contract errors
                return _failure('invalid-bag', f'bag {bag}: {error}', bag=bag)
            postures, source = loaded.postures, f'bag {bag} ({loaded.source})'
            not_used = {
                'postures_rejected_on_receipt': len(loaded.rejected),
                'invalid_messages': loaded.invalid_messages,
            }
            postures_models = {loaded.model} if loaded.model else set()
        else:
            with self._postures_lock:
                postures = list(self._postures)
                postures_models = set(self._posture_models)
            source = 'live postures'
            not_used = {'postures_rejected_on_receipt': self.invalid_postures}
        with (
            self._postures_lock
        ):  # the postures after these were never in this fit: they verify it
            verify_from = len(self._postures)
        for model in sorted(postures_models):
            try:
                pipeline.check_model(
                    model, nominal, 'the bag' if bag else 'the postures received', nominal_path
                )
            except pipeline.ModelMismatchError as error:
                return _failure(
                    error.reason,
                    str(error),
                    postures_received=len(postures),
                    source=source,
                    model=nominal.model,
                )
        self.get_logger().info(f'calibrating from {len(postures)} {source}, {cost} cost')
        with self._status_lock:
            self._calibrating = True
            self._status_pub.publish(
                self._status_message(
                    'OK',
                    f'calibrating from {len(postures)} postures',
                    {'outcome': 'running', 'postures_received': len(postures), 'source': source},
                )
            )
        slider_noise = self.get_parameter('noise_slider_m').value
        angle_noise = self.get_parameter('noise_angle_rad').value
        noise = (
            NoiseModel(slider_noise, angle_noise) if slider_noise > 0 and angle_noise > 0 else None
        )
        try:
            device_prior = self._device_prior(link_length)
        except ValueError as error:
            return _failure(
                'invalid-device-prior',
                str(error),
                postures_received=len(postures),
                source=source,
                **not_used,
            )
        if device_prior and noise is None:
            return _failure(
                MISSING_NOISE_FOR_PRIOR,
                (
                    f'a device prior ({device_prior.describe()}) is weighed against the data by the reading noise: '
                    'set noise_slider_m and noise_angle_rad (> 0), or the prior std parameters (device.*_std) to 0'
                ),
                postures_received=len(postures),
                source=source,
                **not_used,
            )
        try:
            result = pipeline.calibrate(
                nominal,
                postures,
                cost=cost,
                link_length=link_length,
                identify_device=_names(self.get_parameter('identify_device').value),
                noise=noise,
                robust_loss=self.get_parameter('robust_loss').value or None,
                mount=mount,
                device_prior=device_prior,
            )
        except CalibrationError as error:
            return _failure(
                error.reason,
                str(error),
                postures_received=len(postures),
                source=source,
                **not_used,
            )
        except (
            ValueError
        ) as error:  # options the solver refuses (SolverOptions.validate): named, not a crash
            return _failure(
                'invalid-options',
                str(error),
                postures_received=len(postures),
                source=source,
                **not_used,
            )
        values: dict[str, object] = {
            'postures_received': len(postures),
            'source': source,
            **pipeline.status_fields(result, device_prior),
            **not_used,
        }
        summary = (
            f'{len(result.used_postures)} of {len(postures)} postures, {cost} cost, '
            f'{result.iterations} iterations, rank {result.rank}, rms residual '
            + ', '.join(f'{k} {v:.3g}' for k, v in result.rms_residual.items())
        )
        if result.reason not in (CONVERGED, ITERATION_LIMIT):
            return _failure(
                result.reason, f'the identification did not converge ({summary})', **values
            )
        try:
            save_parameters(
                target,
                result.parameters.vector,
                model=result.parameters.model,
                header_comment=(
                    f'hexacal calibration {datetime.now(timezone.utc).isoformat(timespec="seconds")}'
                    f'\nfrom {source}: {summary}\nnominal: {nominal_path}; SI units'
                ),
                extras=pipeline.device_defects_extras(result) or None,
            )
        except HexacalContractError as error:
            return Outcome(
                False,
                f'output-not-written: calibrated ({summary}) but {error}',
                'WARN',
                {**values, 'outcome': 'output-not-written'},
                result.parameters,
                verify_from=verify_from,
                defects=result.device,
                link_length=link_length,
                mount=mount,
                source=source,
            )
        values['output'] = str(target)
        # The report (figures, pose-error map, result payload) is written after the answer.
        report_dir = self.get_parameter('report_dir').value
        report = None
        if report_dir:
            report = ReportJob(
                report_dir,
                self.get_parameter('output_dir').value,
                result,
                postures,
                source,
                link_length,
                mount,
                device_prior,
            )
            values['report_state'] = 'writing'
        else:
            values['report_state'] = 'disabled'
        level = 'OK' if result.reason == CONVERGED else 'WARN'
        return Outcome(
            True,
            f'{result.reason}: {summary}; wrote {target}',
            level,
            values,
            result.parameters,
            report,
            verify_from=verify_from,
            defects=result.device,
            link_length=link_length,
            mount=mount,
            source=source,
        )

    # ------------------------------------------------------------------ verification

    def _on_verify(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if not self._busy.acquire(blocking=False):
            response.success, response.message = False, self._busy_message
            return response
        self._busy_message = BUSY_VERIFYING_MESSAGE
        try:
            outcome = self._worker.submit(self._verify).result()  # serialised with calibrations
            response.success, response.message = outcome.success, outcome.message
        except Exception as error:  # noqa: BLE001 - a caller must always get an answer
            response.success = False
            response.message = f'internal-error: {type(error).__name__}: {error}'
        finally:
            self._busy_message = BUSY_MESSAGE
            self._busy.release()
        return response

    def _verify(self) -> Outcome:
        with self._status_lock:
            self._verification_number += 1
            number = self._verification_number
            latest = self._latest
        task = None
        try:
            outcome, task = self._run_verification(number, latest)
        except Exception as error:  # noqa: BLE001 - the node must survive and say what happened
            self.get_logger().error(f'verification failed unexpectedly: {error!r}')
            outcome = _failure('internal-error', f'{type(error).__name__}: {error}')
        with self._status_lock:
            self._status_pub.publish(
                self._verification_status(outcome.level, outcome.message, outcome.values)
            )
        if task is not None:
            with self._report_lock:
                self._pending_verification_report = task
            self._report_worker.submit(self._write_pending_report)
        if outcome.level == 'OK':
            self.get_logger().info(f'verification: {outcome.message}')
        else:
            self.get_logger().warning(f'verification: {outcome.message}')
        return outcome

    def _run_verification(
        self, number: int, latest: LatestCalibration | None
    ) -> tuple[Outcome, VerificationTask | None]:
        from .. import pipeline
        from ..core.device import DeviceModel
        from ..core.verification import PASS, verify

        if latest is None:
            return _failure(
                'no-calibration',
                'no calibration to verify yet: calibrate first '
                f'({self.resolve_service_name(CALIBRATE_SERVICE)}), then measure fresh postures '
                'and call verify again',
            ), None
        with self._postures_lock:
            postures = list(self._postures[latest.verify_from :])
            postures_models = set(self._posture_models[latest.verify_from :])
        about = {
            'calibration': latest.source,
            'calibration_number': latest.number,
            'postures_before_calibration': latest.verify_from,
        }
        if not postures:
            return _failure(
                'no-postures',
                f'no postures received since the calibration it verifies '
                f'({latest.source}, calibration {latest.number}): measure fresh postures '
                '(a verification plan) and call verify again',
                postures=0,
                **about,
            ), None
        nominal_path = self.get_parameter('nominal').value
        if not nominal_path:
            return _failure(
                'missing-parameter',
                "parameter 'nominal' is not set: verification compares "
                'the nominal and the calibrated parameters (-p nominal:=<path>)',
                **about,
            ), None
        try:
            nominal, mount = self._load_nominal(nominal_path)
        except (ParameterFileError, ValueError) as error:
            return _failure('invalid-nominal', f'nominal: {error}', **about), None
        link_length = latest.link_length or self.get_parameter('link_length').value
        mount = latest.mount or mount
        slider_noise = self.get_parameter('noise_slider_m').value
        angle_noise = self.get_parameter('noise_angle_rad').value
        noise = (
            NoiseModel(slider_noise, angle_noise) if slider_noise > 0 and angle_noise > 0 else None
        )
        threshold = self.get_parameter('verify_threshold_m').value or None
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
                threshold_m=threshold,
                noise=noise,
                postures_model=next(iter(postures_models)) if len(postures_models) == 1 else None,
                calibrated_defects=latest.defects,
            )
        except (CalibrationError, ValueError) as error:
            return _failure(
                getattr(error, 'reason', 'invalid-input'),
                str(error),
                postures=len(postures),
                **about,
            ), None
        values: dict[str, object] = {'outcome': 'verified', **result.status_values(), **about}
        before, after = result.nominal.figures(), result.calibrated.figures()
        message = (
            f'{result.verdict_reason()}; position rms nominal {before["position_rms_m"] * 1e6:.2f} um, '
            f'calibrated {after["position_rms_m"] * 1e6:.2f} um ({result.improvement:.1f}x), rotary rms '
            f'nominal {before["rotary_rms_rad"] * 1e6:.2f} urad, calibrated '
            f'{after["rotary_rms_rad"] * 1e6:.2f} urad; {result.postures} postures since calibration '
            f'{latest.number}'
        )
        passed = result.verdict == PASS
        task = None
        report_dir = self.get_parameter('report_dir').value
        job = latest.outcome.report if latest.outcome is not None else None
        if job is not None or report_dir:
            values['report_state'] = 'writing'
        else:
            values['report_state'] = 'disabled'
        outcome = Outcome(passed, message, 'OK' if passed else 'WARN', values)
        if values['report_state'] == 'writing':
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
                report_dir,
                self.get_parameter('output_dir').value,
                payload,
                outcome,
            )
        return outcome, task

    def _verification_status(
        self, level: str, message: str, values: dict[str, object]
    ) -> DiagnosticArray:
        return diagnostic_status(
            level,
            VERIFICATION_STATUS_NAME,
            message,
            values,
            hardware_id=self.get_fully_qualified_name(),
            stamp=self.get_clock().now().nanoseconds,
        )

    def _load_nominal(self, path: str) -> tuple[KinematicParameters, str]:
        """The nominal model and the device mount; the YAML (~4 ms to parse) is read again only
        when the file changed."""
        from ..pipeline import load_machine_and_mount

        key = _file_identity(path)  # None: read_parameters_file names the problem
        cached = self._nominal_cache
        if key is not None and cached is not None and cached[0] == key:
            return cached[1]
        loaded = load_machine_and_mount(path)  # immutable: safe to share
        if key is not None:
            self._nominal_cache = (key, loaded)
            self._model_cache = (key, loaded[0].model)
        return loaded

    def _nominal_model(self) -> str | None:
        """The model the nominal file names; None without a (readable) nominal file. Cached per file."""
        path = self.get_parameter('nominal').value
        if not path:
            return None
        key = _file_identity(path)
        if key is None:
            return None
        cached = self._model_cache
        if cached is not None and cached[0] == key:
            return cached[1]
        try:
            model: str | None = read_parameters_file(path).model
        except (HexacalContractError, ValueError):
            model = None  # the calibration names the problem ('invalid-nominal')
        self._model_cache = (key, model)
        return model

    # ------------------------------------------------------------------ report

    def _queue_report(self, number: int, outcome: Outcome) -> None:
        """Write this calibration's report after the answer, replacing one not yet started."""
        with self._report_lock:
            replaced, self._pending_report = self._pending_report, (number, outcome)
        if replaced is not None:
            self.get_logger().info(
                f'the report of calibration {replaced[0]} is replaced by '
                f'that of calibration {number}'
            )
        self._report_worker.submit(self._write_pending_report)

    def _write_pending_report(self) -> None:
        """Write what waits: the latest calibration's report and/or the latest verification's, as one page
        when the verification is of that calibration; then publish their follow-up statuses."""
        threading.Event().wait(REPORT_START_DELAY_S)  # a sleep (the import lines are left alone)
        with self._report_lock:
            pending, self._pending_report = self._pending_report, None
            verification, self._pending_verification_report = (
                self._pending_verification_report,
                None,
            )
        if pending is None and verification is None:
            return  # a newer task replaced it, and an earlier task wrote that one
        if (
            pending is not None
            and verification is not None
            and verification.calibration_number != pending[0]
        ):
            # A verification of an older calibration: the newer calibration's page replaces it.
            self._follow_up_verification(
                verification, 'superseded', f'report superseded by calibration {pending[0]}', {}
            )
            verification = None
        if pending is not None:
            number, job = pending[0], pending[1].report
        else:
            number, job = verification.calibration_number, verification.job
        try:
            path = self._write_page(job, verification)
        except Exception as error:  # noqa: BLE001 - the parameters are written; the report is extra
            self.get_logger().warning(f'calibration report not written: {error}')
            state, text = 'failed', f'report failed: {error}'
            extra = {'report_error': f'{type(error).__name__}: {error}'}
        else:
            what = 'calibration' if job is not None else 'verification'
            self.get_logger().info(f'{what} report written: {path}')
            state, text, extra = 'ready', f'report ready: {path}', {'report': str(path)}
        if pending is not None:
            outcome = pending[1]
            with self._status_lock:
                if number == self._calibration_number:  # else a newer calibration's status stands
                    try:
                        self._status_pub.publish(
                            self._status_message(
                                outcome.level,
                                f'{outcome.message}; {text}',
                                {**outcome.values, 'report_state': state, **extra},
                            )
                        )
                    except Exception as error:  # noqa: BLE001 - shutting down: the context may be gone
                        self.get_logger().warning(f'report status not published: {error}')
        if verification is not None:
            self._follow_up_verification(verification, state, text, extra)

    def _write_page(self, job: ReportJob | None, verification: VerificationTask | None) -> Path:
        """The calibration's page (with the verification's section), or the verification's page alone."""
        from .. import pipeline

        if (
            job is None
        ):  # a calibration republished at start-up: no result to show, its verification alone
            directory = (
                output_path(verification.report_dir, verification.output_dir) / 'verification'
            )
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
            measurements=pipeline.measurements_from_postures(job.postures),
            link_length=job.link_length,
            extras={'source': job.source},
            device_prior=job.device_prior,
            verification=None if verification is None else verification.payload,
            **mount,
        )

    def _follow_up_verification(
        self, task: VerificationTask, state: str, text: str, extra: dict[str, object]
    ) -> None:
        with self._status_lock:
            if task.number != self._verification_number:
                return  # a newer verification's status stands
            try:
                self._status_pub.publish(
                    self._verification_status(
                        task.outcome.level,
                        f'{task.outcome.message}; {text}',
                        {**task.outcome.values, 'report_state': state, **extra},
                    )
                )
            except Exception as error:  # noqa: BLE001 - shutting down: the context may be gone
                self.get_logger().warning(f'verification report status not published: {error}')

    def _status_message(
        self, level: str, message: str, values: dict[str, object]
    ) -> DiagnosticArray:
        return diagnostic_status(
            level,
            STATUS_NAME,
            message,
            values,
            hardware_id=self.get_fully_qualified_name(),
            stamp=self.get_clock().now().nanoseconds,
        )

    def _publish_result(self, outcome: Outcome) -> None:
        if outcome.parameters is not None:
            self._parameters_pub.publish(
                parameters_to_multiarray(outcome.parameters.vector, outcome.parameters.model)
            )
        self._status_pub.publish(
            self._status_message(outcome.level, outcome.message, outcome.values)
        )

    def _republish_saved(self) -> None:
        try:
            target = self._output_path()
        except ValueError:
            return
        # save_parameters writes '.<name>.<random>.tmp' beside the target, then renames it:
        # a leftover one is a write that a crash interrupted, never a calibration.
        for leftover in target.parent.glob(f'.{glob.escape(target.name)}.*.tmp'):
            try:
                leftover.unlink()
                self.get_logger().warning(f'removed {leftover}, an interrupted write')
            except OSError as error:
                self.get_logger().warning(f'cannot remove {leftover}: {error}')
        if not target.exists():
            return
        try:
            saved = read_parameters_file(target)
        except ParameterFileError as error:
            self.get_logger().error(f'not republishing the saved calibration: {error}')
            return
        self._parameters_pub.publish(parameters_to_multiarray(saved.vector, saved.model))
        self.get_logger().info(f'republished the saved calibration {target}')
        try:
            from ..core.architectures import parameters_for
            from ..pipeline import device_defects_from_extras

            parameters = parameters_for(saved.model, saved.vector)
            defects, _ = device_defects_from_extras(
                saved.extras, target
            )  # the device it was calibrated with
        except ValueError as error:
            self.get_logger().warning(f'the saved calibration cannot be verified: {error}')
            return
        with self._status_lock:  # hexacal/verify verifies it on the postures received from now on
            self._latest = LatestCalibration(
                0, parameters, defects, f'saved calibration {target}', 0, None, None, None
            )

    def shutdown(self) -> None:
        self._worker.shutdown(wait=True, cancel_futures=True)
        # After the calibration worker: a calibration that finished during shutdown queues its report.
        # The report under way and the latest one waiting are written whole (atomic_write).
        self._report_worker.shutdown(wait=True)


def _file_identity(path: str) -> tuple | None:
    """What changes when a file is replaced or edited (None: it cannot be stat'ed)."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return (
        os.path.abspath(path),
        info.st_dev,
        info.st_ino,
        info.st_size,
        info.st_mtime_ns,
        info.st_ctime_ns,
    )


def _finish(node: IdentifyNode) -> list[str]:
    node.shutdown()  # a calibration under way finishes: its files are written whole
    return []


def main(args: list[str] | None = None) -> int:
    # Several threads: a waiting service call must not block postures or a second call.
    return run_node(
        NODE_NAME,
        IdentifyNode,
        args=args,
        finish=_finish,
        make_executor=lambda: MultiThreadedExecutor(num_threads=4),
        startup_errors=(InvalidParameterValueException,),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
