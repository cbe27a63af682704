"""
Verification without ground truth.

How well does a parameter set explain fresh measured postures?

A real machine has no truth to compare with.  What it has is the measuring
device: for postures that were *not* used in the fit, the device measures the
platform position (eq. 4 from the inclinometer, ``device.py``; the fixed point
of eq. 10 for a fixed-position posture) and phi (the rotary sensor), and the
actuators read lambda.  Forward kinematics of a parameter set at the measured
lambda says where that set puts the platform; the difference is the set's
residual, per posture:

* position error  ``|P_fk - P_measured|`` (m),
* rotary error    ``phi_measured - phi_fk`` (rad, wrapped to (-pi, pi]).

Forward kinematics starts where the identification starts it
(``CostFunction.initial_poses``: the measured position and phi, theta = psi = 0,
the two unmeasured tilts fitted first) with the identification's tolerances and
branch check (``SolverOptions``), so a posture is judged exactly as a residual of
the absolute cost function (eq. 7) would see it.  A posture whose forward
kinematics fails (no convergence, singular, another branch) is reported with
the reason, never dropped silently: the figures are over the postures that
converged and say how many did not.

``verify`` does it for the nominal and the calibrated parameters: the figures
{position_rms_m, position_max_m, rotary_rms_rad} of each, the improvement
(nominal position rms / calibrated position rms) and a verdict: ``pass`` when
the calibrated position rms is at most ``threshold_m`` and forward kinematics
converged on every posture with the calibrated parameters, else ``fail``.

The threshold.  The residual left after a calibration is the reading noise
carried through forward kinematics and eq. 4, plus what the model cannot explain
(and the calibrated parameters' own uncertainty).  With a known reading noise
(``noise``: uniform half-widths, as ``NoiseModel``) the noise part is predicted,
linearised at the calibrated FK solutions: E|r|^2 = sum of the squared
sensitivities of the position residual to the 6 actuator readings and the two
inclinometer angles, each times its variance a^2 / 3 (``expected_noise``);
the threshold is then ``NOISE_THRESHOLD_FACTOR`` = 3 x that rms.  Without it the
default is 50 um (``DEFAULT_THRESHOLD_M``).  Measured on the simulated Table 1
machine (nominal set 2, 60 fit + 40 fresh postures): single readings with
+-10 um / +-10 urad noise give a predicted noise rms of 21 um and a calibrated
residual of 29 um (the 3x threshold: 63 um), postures averaged over ~25 readings
(what the collector records) a few um; the nominal sets' residuals are ~10 mm.
So 50 um sits well above a calibrated machine with 10 um-class sensors and
~200x below the nominal error; a machine with noisier sensors gives its noise
(``hexacal verify --noise-um``) or its own threshold (``--threshold-um``,
identify's ``verify_threshold_m``).

Both parameter sets, and the postures when their model is known, must be of the
same machine model: ``VerificationModelError`` (reason ``model-mismatch``) otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..architectures import KinematicParameters
from ..errors import InvalidMeasurementError
from ..fit.compliance import ComplianceModel
from ..fit.residuals import ChannelSigma, CostFunction
from ..jsonsafe import json_safe as _plain
from ..machine.device import DeviceDefects, DeviceModel
from ..machine.kinematics import forward_kinematics, wrap_angle
from ..machine.measurements import MeasurementLimits, Measurements, NoiseModel

DEFAULT_THRESHOLD_M = 50e-6
NOISE_THRESHOLD_FACTOR = (
    3.0  # threshold = this x the predicted noise rms, when the reading noise is known
)
PASS, FAIL = 'pass', 'fail'
FIGURE_KEYS = ('position_rms_m', 'position_max_m', 'rotary_rms_rad')
SET_NAMES = ('nominal', 'calibrated')


class VerificationModelError(InvalidMeasurementError):
    """The nominal set, the calibrated set and the postures are not all of one machine model."""

    reason = 'model-mismatch'


@dataclass
class SetResiduals:
    """One parameter set's residuals at the measured postures (SI units; NaN where FK failed)."""

    poses: np.ndarray  # (N, 6) FK poses, NaN rows where failed
    position_error_m: np.ndarray  # (N,) |P_fk - P_measured|
    position_difference_m: np.ndarray  # (N, 3) P_fk - P_measured
    rotary_error_rad: np.ndarray  # (N,) phi_measured - phi_fk, wrapped
    failures: dict[int, str] = field(default_factory=dict)  # posture index -> why FK failed

    @property
    def converged(self) -> np.ndarray:
        return np.isfinite(self.position_error_m)

    def figures(self) -> dict[str, float]:
        """
        Return the verification figures over the converged postures.

        position_rms_m, position_max_m, rotary_rms_rad over the converged postures (NaN if none),
        plus position_mean_m, postures_converged and fk_failures.
        """
        ok = self.converged
        position, rotary = self.position_error_m[ok], self.rotary_error_rad[ok]
        if not ok.any():
            rms = peak = mean = rotary_rms = float('nan')
        else:
            rms = float(np.sqrt(np.mean(position**2)))
            peak = float(np.max(position))
            mean = float(np.mean(position))
            rotary_rms = float(np.sqrt(np.mean(rotary**2)))
        return {
            'position_rms_m': rms,
            'position_max_m': peak,
            'rotary_rms_rad': rotary_rms,
            'position_mean_m': mean,
            'postures_converged': int(ok.sum()),
            'fk_failures': len(self.failures),
        }


@dataclass
class VerificationResult:
    """Nominal against calibrated on the same fresh postures."""

    model: str
    kinds: np.ndarray  # (N,) 'sphere' or 'fixed'
    measured_position_m: (
        np.ndarray
    )  # (N, 3) device position (eq. 4; the fixed point for fixed postures)
    measured_phi_rad: np.ndarray  # (N,) rotary reading minus phi0
    nominal: SetResiduals
    calibrated: SetResiduals
    threshold_m: float
    link_length: float
    mount: str
    threshold_source: str = 'default'  # 'given', 'default' or '3x expected noise'
    expected_noise: dict[str, float] | None = (
        None  # position_rms_m, rotary_rms_rad predicted from the noise
    )

    @property
    def postures(self) -> int:
        return len(self.kinds)

    @property
    def improvement(self) -> float:
        """
        Return nominal position rms / calibrated position rms.

        Nominal position rms / calibrated position rms (NaN when either is unknown, inf for an
        exact fit).
        """
        before = self.nominal.figures()['position_rms_m']
        after = self.calibrated.figures()['position_rms_m']
        if not (np.isfinite(before) and np.isfinite(after)):
            return float('nan')
        return float(before / after) if after > 0 else float('inf')

    @property
    def verdict(self) -> str:
        return PASS if self.verdict_reason().startswith(PASS) else FAIL

    def verdict_reason(self) -> str:
        figures = self.calibrated.figures()
        rms, threshold = figures['position_rms_m'], self.threshold_m
        if figures['fk_failures']:
            return (
                f'{FAIL}: forward kinematics with the calibrated parameters failed on '
                f'{figures["fk_failures"]} of {self.postures} posture(s)'
            )
        if not np.isfinite(rms):
            return f'{FAIL}: no posture to judge'
        comparison = '<=' if rms <= threshold else '>'
        verdict = PASS if rms <= threshold else FAIL
        return (
            f'{verdict}: calibrated position rms {rms * 1e6:.2f} um {comparison} threshold '
            f'{threshold * 1e6:.2f} um'
        )

    def to_json(self, per_posture: bool = False) -> dict:
        """
        Return the result as the JSON object of ``hexacal verify --json``.

        {"model", "postures", "nominal": {figures}, "calibrated": {figures}, "improvement",
        "threshold_m", "verdict"} plus "verdict_reason", "link_length_m", "mount", per set its FK
        failures (``failed_postures``: index, reason) and with ``per_posture`` the per-posture
        arrays (``per_posture``: kinds, measured positions, both sets' errors). NaN and inf are
        null.
        """
        payload: dict = {'model': self.model, 'postures': self.postures}
        for name in SET_NAMES:
            residuals: SetResiduals = getattr(self, name)
            figures: dict[str, object] = dict(residuals.figures())
            figures['failed_postures'] = [
                {'index': int(i), 'reason': why} for i, why in sorted(residuals.failures.items())
            ]
            payload[name] = figures
        payload.update(
            {
                'improvement': self.improvement,
                'threshold_m': self.threshold_m,
                'verdict': self.verdict,
                'verdict_reason': self.verdict_reason(),
                'threshold_source': self.threshold_source,
                'expected_noise': self.expected_noise,
                'link_length_m': self.link_length,
                'mount': self.mount,
            }
        )
        if per_posture:
            payload['per_posture'] = {
                'kinds': [str(k) for k in self.kinds],
                'measured_position_m': self.measured_position_m,
                'measured_phi_rad': self.measured_phi_rad,
                **{
                    f'{name}_position_error_m': getattr(self, name).position_error_m
                    for name in SET_NAMES
                },
                **{
                    f'{name}_rotary_error_rad': getattr(self, name).rotary_error_rad
                    for name in SET_NAMES
                },
            }
        return _plain(payload)

    def status_values(self) -> dict[str, str]:
        """
        Return the JSON keys flattened for a status topic, as strings.

        The JSON keys flattened for a status topic ('nominal.position_rms_m', ...), as strings.
        """
        values: dict[str, str] = {'model': self.model, 'postures': str(self.postures)}
        for name in SET_NAMES:
            for key, value in getattr(self, name).figures().items():
                values[f'{name}.{key}'] = _text(value)
        values.update(
            {
                'improvement': _text(self.improvement),
                'threshold_m': _text(self.threshold_m),
                'verdict': self.verdict,
                'verdict_reason': self.verdict_reason(),
                'threshold_source': self.threshold_source,
            }
        )
        for key, value in (self.expected_noise or {}).items():
            values[f'expected_noise.{key}'] = _text(value)
        for index, why in sorted(self.calibrated.failures.items())[:20]:
            values[f'calibrated.failed.{index}'] = why
        for index, why in sorted(self.nominal.failures.items())[:20]:
            values[f'nominal.failed.{index}'] = why
        return values


def check_models(
    nominal: KinematicParameters,
    calibrated: KinematicParameters,
    postures_model: str | None = None,
    names: tuple[str, str] = ('nominal', 'calibrated'),
) -> str:
    """
    Return the one model of both parameter sets.

    The one model of both parameter sets (and of the postures, when known); VerificationModelError
    if not.
    """
    if nominal.model != calibrated.model:
        raise VerificationModelError(
            f"the {names[0]} parameters are a {nominal.model}'s and the {names[1]} parameters a "
            f"{calibrated.model}'s: verify two parameter sets of the same machine model"
        )
    if postures_model is not None and postures_model != nominal.model:
        raise VerificationModelError(
            f'the postures are of a {postures_model} but the {names[0]} and {names[1]} parameters '
            'are a '
            f"{nominal.model}'s: verify with the parameters of the machine that measured them"
        )
    return nominal.model


def set_residuals(
    params: KinematicParameters,
    measurements: Measurements,
    device: DeviceModel = DeviceModel(),
    defects: DeviceDefects = DeviceDefects(),
    compliance: tuple[ComplianceModel, np.ndarray] | None = None,
) -> tuple[SetResiduals, np.ndarray]:
    """
    (residuals of ``params``, the expected poses FK started from) at the measured postures.

    ``defects``: the device defects this parameter set assumes (identified jointly, or none).
    ``compliance``: (model, values) of compliances identified with ``params``: the readings are
    corrected by the static loads at the set's own poses (core/fit/compliance.py) before FK.
    """
    from ..fit.identification import SolverOptions

    if compliance is not None:
        model, values = compliance
        corrected = measurements
        for _ in range(2):  # loads at the rigid poses, then at the loaded ones
            first, expected = set_residuals(params, corrected, device, defects)
            poses = np.where(first.converged[:, None], first.poses, expected)
            loads = model.loads(params, poses, np.arange(len(measurements)), values)
            corrected = model.corrected(measurements, loads, values, device.link_length)
        measurements = corrected

    options = SolverOptions()
    cost = CostFunction('absolute', measurements, device, ChannelSigma())
    expected = cost.initial_poses(defects)
    fk = forward_kinematics(
        params,
        measurements.actuator_positions,
        expected,
        tolerance=options.fk_tolerance,
        branch_tolerance_m=options.branch_tolerance_m,
        branch_tolerance_rad=options.branch_tolerance_rad,
        fit_tilt_first=True,
    )
    difference = fk.poses[:, :3] - expected[:, :3]
    rotary = wrap_angle(expected[:, 5] - fk.poses[:, 5])
    failures = {int(i): why for i, why in sorted(fk.failures.items())}
    residuals = SetResiduals(
        fk.poses, np.linalg.norm(difference, axis=1), difference, rotary, failures
    )
    return residuals, expected


def expected_noise(
    params: KinematicParameters,
    residuals: SetResiduals,
    measurements: Measurements,
    noise: NoiseModel,
    device: DeviceModel = DeviceModel(),
    defects: DeviceDefects = DeviceDefects(),
) -> dict[str, float]:
    """
    Return the residual rms that reading noise alone gives.

    The residual rms that reading noise alone gives (module doc), at the converged FK poses.

    position: sqrt(mean_n E|r_n|^2), E|r_n|^2 = sum_k |dP/d lambda_k|^2 a_s^2/3 + sum_j |dP_meas/d
    angle_j|^2 a_a^2/3 (a fixed-position posture is placed at a zero reading, within the same
    noise); rotary:
    sqrt(mean_n (sum_k (dphi/d lambda_k)^2 a_s^2/3 + a_a^2/3)).
    """
    from ..machine.device import device_position
    from ..machine.kinematics import pose_sensitivities

    ok = residuals.converged
    if not ok.any():
        return {'position_rms_m': float('nan'), 'rotary_rms_rad': float('nan')}
    actuator_var, angle_var = noise.actuator_m**2 / 3.0, noise.angle_rad**2 / 3.0
    sensitivity = pose_sensitivities(
        params, residuals.poses[ok]
    ).wrt_actuators  # dX/d lambda (k, 6, 6)
    alpha, beta = measurements.inclinometer[ok].T
    lengths = (
        measurements.link_lengths[ok]
        if measurements.link_lengths is not None
        else device.link_length
    )
    readings = device_position(alpha, beta, lengths, defects, device.mount).d_readings  # (k, 3, 2)
    position = (
        np.sum(sensitivity[:, :3, :] ** 2, axis=(1, 2)) * actuator_var
        + np.sum(readings**2, axis=(1, 2)) * angle_var
    )
    rotary = np.sum(sensitivity[:, 5, :] ** 2, axis=1) * actuator_var + angle_var
    return {
        'position_rms_m': float(np.sqrt(np.mean(position))),
        'rotary_rms_rad': float(np.sqrt(np.mean(rotary))),
    }


def verify(
    nominal: KinematicParameters,
    calibrated: KinematicParameters,
    measurements: Measurements,
    *,
    device: DeviceModel = DeviceModel(),
    threshold_m: float | None = None,
    noise: NoiseModel | None = None,
    postures_model: str | None = None,
    nominal_defects: DeviceDefects = DeviceDefects(),
    calibrated_defects: DeviceDefects = DeviceDefects(),
    limits: MeasurementLimits = MeasurementLimits(),
    calibrated_compliance: tuple[ComplianceModel, np.ndarray] | None = None,
) -> VerificationResult:
    """
    Verify nominal and calibrated parameters at fresh measured postures.

    Residuals of the nominal and the calibrated parameters at fresh measured postures (module doc).

    ``threshold_m``: the verdict's threshold (None: 3x the expected noise rms with a known
    ``noise``, else DEFAULT_THRESHOLD_M).  ``noise``: the reading noise half-widths, for the
    expected noise figures. ``postures_model``: the model whose actuator joints the postures carry
    (None: not known, not checked). ``calibrated_defects``: device defects identified with the
    calibration (its device), if any. ``calibrated_compliance``: (model, values) of compliances
    identified with it (set_residuals). Raises VerificationModelError on a model mismatch,
    InvalidMeasurementError on no or invalid postures, ValueError on a threshold that is not a
    positive length.
    """
    model = check_models(nominal, calibrated, postures_model)
    if threshold_m is not None and not (np.isfinite(threshold_m) and threshold_m > 0):
        raise ValueError(
            f'the verification threshold must be a positive length in m, got {threshold_m}'
        )
    if noise is not None and not noise.known:
        raise ValueError(
            'the reading noise for the expected residual needs positive actuator and angle noise'
        )
    if len(measurements) == 0:
        raise InvalidMeasurementError(
            'no postures to verify on: measure fresh postures (not used in the fit)'
        )
    measurements.validate(limits, nominal.layout.actuator_unit)
    before, _ = set_residuals(nominal, measurements, device, nominal_defects)
    after, expected_after = set_residuals(
        calibrated, measurements, device, calibrated_defects, calibrated_compliance
    )
    predicted = None
    if noise is not None:
        predicted = expected_noise(
            calibrated, after, measurements, noise, device, calibrated_defects
        )
    if threshold_m is not None:
        threshold, source = float(threshold_m), 'given'
    elif (
        predicted is not None
        and np.isfinite(predicted['position_rms_m'])
        and predicted['position_rms_m'] > 0
    ):
        threshold, source = (
            NOISE_THRESHOLD_FACTOR * predicted['position_rms_m'],
            '3x expected noise',
        )
    else:
        threshold, source = DEFAULT_THRESHOLD_M, 'default'
    # The measured side is the calibrated device's (identical to the nominal's without identified
    # defects).
    return VerificationResult(
        model,
        np.asarray(measurements.kinds).astype(str),
        expected_after[:, :3].copy(),
        expected_after[:, 5].copy(),
        before,
        after,
        threshold,
        float(device.link_length),
        device.mount,
        source,
        predicted,
    )


def _text(value: float) -> str:
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if not np.isfinite(value):
        return 'nan' if np.isnan(value) else 'inf'
    return f'{value:.6g}'


__all__ = [
    'DEFAULT_THRESHOLD_M',
    'FAIL',
    'FIGURE_KEYS',
    'NOISE_THRESHOLD_FACTOR',
    'PASS',
    'SetResiduals',
    'VerificationModelError',
    'VerificationResult',
    'check_models',
    'expected_noise',
    'set_residuals',
    'verify',
]
