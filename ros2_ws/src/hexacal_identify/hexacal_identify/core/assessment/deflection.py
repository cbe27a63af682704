"""
What a machine's known compliances would do to a rigid calibration: the bias its residuals hide.

The adequacy verdict (adequacy.py) judges the residuals, and a misfit the geometric parameters
absorb leaves none: on the MuJoCo Gough-Stewart in the lvdt mode the legs' deflection under
the platform's weight is nearly a function of the pose, the rigid fit passes adequacy and
verification (variance factor 1.10, 5.3 um rms) and its pose error is 3.4x the rigid
machine's (docs/results.md).  No test of the residuals can see that; the machine's physical
description can.  Here the calibrated machine is loaded by the description's weights and
compliances (the compliance model's statics, compliance.simulate_loaded_measurements) at the
calibration's own postures, the same rigid fit is run on those noise-free readings from the
calibration, and what it moves is the bias the compliances put into a rigid calibration:

* ``pose_bias``: the rigid fit of the loaded readings against the calibrated machine, as a
  controller would use it, at fresh postures of the workspace (validation.pose_errors);
* ``visible_rms``: what that fit leaves in its residuals (what adequacy could have seen);
* ``largest_deflection_m``: the largest encoder-side deflection or link stretch it comes from.

``significant`` says whether the bias exceeds the calibration's own statistical pose error
(the parameter covariance's, uncertainty.predicted_pose_errors): then the reported accuracy
is not the machine's, and the compliance model (``--compliance``) is what to use.  First
order in the compliances, exact in the geometry; the description's figures are taken as
given (a datasheet's).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .uncertainty import predicted_pose_errors
from .validation import pose_errors, validation_poses
from ..fit.compliance import ComplianceModel, NONE, simulate_loaded_measurements
from ..fit.identification import IdentificationResult, identify, SolverOptions

FRESH_POSTURES = 200  # workspace postures the bias is judged at
FRESH_SEED = 0xDEF1
COVARIANCE_SAMPLES = 1000
POSITION_CHANNELS = ('x', 'y', 'z')  # residual channels in m; the others (phi) in rad


@dataclass(frozen=True)
class DeflectionBias:
    """A rigid calibration's bias from its machine's described compliances (module doc)."""

    source: str  # the physical description the compliances came from
    postures: int  # the calibration's postures it was judged at
    largest_deflection_m: float
    visible_rms: dict[str, float]  # per channel (m; phi rad), the loaded readings' rigid fit
    pose_bias_mean_m: float
    pose_bias_max_m: float
    orientation_bias_mean_rad: float
    statistical_mean_m: float  # the calibration's own predicted position error (covariance)

    @property
    def significant(self) -> bool:
        """Return True when the hidden bias exceeds the calibration's statistical error."""
        return self.pose_bias_mean_m > self.statistical_mean_m

    def text(self) -> str:
        """Return the check in one line (mm / um / urad for display)."""
        lengths = [v for name, v in self.visible_rms.items() if name in POSITION_CHANNELS]
        angles = [v for name, v in self.visible_rms.items() if name not in POSITION_CHANNELS]
        visible = f'{max(lengths, default=0.0) * 1e6:.2f} um'
        if angles:
            visible += f' / {max(angles) * 1e6:.2f} urad'
        statistical = f'{self.statistical_mean_m * 1e6:.2f} um'
        verdict = (
            f"larger than the calibration's statistical error ({statistical}): its reported "
            "accuracy is not the machine's; identify the compliances (--compliance "
            'shared|per_chain)'
            if self.significant
            else f"within the calibration's statistical error ({statistical})"
        )
        return (
            f'deflection check ({self.source}, {self.postures} postures): deflections up to '
            f'{self.largest_deflection_m * 1e6:.1f} um that a rigid fit absorbs leave '
            f'{visible} in its residuals (rms) and bias its poses by '
            f'{self.pose_bias_mean_m * 1e6:.2f} um mean ({self.pose_bias_max_m * 1e6:.2f} um max, '
            f'{self.orientation_bias_mean_rad * 1e6:.1f} urad), {verdict}'
        )

    def to_json(self) -> dict:
        """Return the check as the JSON of ``hexacal calibrate --json`` (SI units)."""
        return {
            'source': self.source,
            'postures': self.postures,
            'largest_deflection_m': self.largest_deflection_m,
            'visible_rms': dict(self.visible_rms),
            'pose_bias_mean_m': self.pose_bias_mean_m,
            'pose_bias_max_m': self.pose_bias_max_m,
            'orientation_bias_mean_rad': self.orientation_bias_mean_rad,
            'statistical_pose_error_mean_m': self.statistical_mean_m,
            'significant': self.significant,
        }


def deflection_bias(
    result: IdentificationResult,
    options: SolverOptions,
    compliance: ComplianceModel,
    values: np.ndarray,
    source: str,
) -> DeflectionBias:
    """
    Return the bias `compliance` (with its `values`, m/N) puts into the rigid fit `result`.

    `options`: the rigid fit's own (its cost, device and unknowns); `compliance`: the
    measuring mode, masses and released chains of the postures the fit was given (all of them:
    the used ones are taken from ``result.used_postures``; -1: not recorded, left out).
    """
    params = result.parameters
    if result.poses is None or not len(result.used_postures):
        raise ValueError("the deflection check needs the poses of the calibration's postures")
    used = np.asarray(result.used_postures)
    fitted = np.asarray(result.poses)
    released = None
    if compliance.released is not None:
        released = np.asarray(compliance.released)[used]
        known = released >= 0  # a posture with no released chain recorded is left out
        released, fitted = released[known], fitted[known]
        if not len(released):
            raise ValueError('no posture of the calibration records its released chain')
    model = replace(compliance, released=released)
    loaded, poses = simulate_loaded_measurements(
        params, fitted, model, values, device=options.device
    )
    loads = model.loads(params, poses, np.arange(len(poses)), values)
    shifts, stretch = model.deflections(loads, values)
    rigid_options = replace(
        options, noise=None, scatter_weights=False, robust_loss=None,
        compliance=ComplianceModel(NONE), allow_rank_deficient=True, outlier_threshold=None,
    )
    biased = identify(params, loaded, rigid_options)
    fresh = validation_poses(params, FRESH_POSTURES, FRESH_SEED)
    errors = pose_errors(params, biased.parameters, fresh)
    statistical = predicted_pose_errors(
        params, result.covariance, fresh, samples=COVARIANCE_SAMPLES
    ).position_mean_m
    return DeflectionBias(
        source=source,
        postures=len(poses),
        largest_deflection_m=float(max(np.max(np.abs(shifts), initial=0.0),
                                       np.max(np.abs(stretch), initial=0.0))),
        visible_rms=dict(biased.rms_residual),
        pose_bias_mean_m=float(np.nanmean(errors.position_m)),
        pose_bias_max_m=float(np.nanmax(errors.position_m)),
        orientation_bias_mean_rad=float(np.nanmean(errors.orientation_rad)),
        statistical_mean_m=float(np.nanmean(statistical)),
    )


__all__ = ['DeflectionBias', 'deflection_bias']
