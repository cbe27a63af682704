"""The result of an identification: parameters, their covariance, residuals and verdicts."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..architectures import KinematicParameters
from ..assessment.adequacy import Adequacy, assess, WhitenedResiduals
from ..assessment.identifiability import IdentifiabilityReport
from ..machine.device import DEVICE_PARAMETER_NAMES, DeviceDefects, N_DEVICE_PARAMETERS
from ..machine.measurements import Weights

CONVERGED = 'converged'
ITERATION_LIMIT = 'iteration-limit'
DIVERGED = 'diverged'


@dataclass
class IdentificationResult:
    parameters: KinematicParameters
    initial_parameters: KinematicParameters
    std: np.ndarray  # (n,), n = the layout's n_parameters; NaN for fixed or unidentifiable ones
    covariance: np.ndarray  # (n + 5, n + 5): kinematic then 5 device; zero rows for fixed ones
    rank: int
    condition_number: float
    iterations: int
    reason: str
    cost: str
    solve_seconds: float
    used_postures: list[int]
    rejected_postures: dict[int, str]
    rms_residual: dict[str, float]  # per channel, after, unweighted units (m, rad)
    initial_rms_residual: dict[str, float]
    residuals: np.ndarray  # final residual rows (unweighted units)
    residual_channels: np.ndarray
    residual_postures: np.ndarray  # original posture index of each row
    identifiability: IdentifiabilityReport
    poses: np.ndarray | None = field(repr=False, default=None)  # FK poses of the used postures
    device: DeviceDefects = field(default_factory=DeviceDefects)
    device_std: np.ndarray = field(default_factory=lambda: np.full(N_DEVICE_PARAMETERS, np.nan))
    free_device: tuple[str, ...] = ()
    variance_factor: float = float(
        'nan'
    )  # residual variance / expected: ~1 when the noise model fits
    weighted: bool = False  # whitened by the noise model (JSON weighted_by_noise_model)
    robust_loss: str | None = None
    held_for_identifiability: list[str] = field(default_factory=list)  # held at their start values
    # The rows whitened by the noise model, prior rows included (None without one): adequacy.py.
    whitened: WhitenedResiduals | None = field(repr=False, default=None)
    # What whitened the rows (the std, covariance and adequacy are under it), and why (one line).
    weights: str = Weights.NONE.value
    weights_note: str = ''
    # Identified axial compliances (m/N) and their std (NaN: held or unidentifiable); empty: rigid.
    compliance_mode: str = 'none'
    compliance: dict[str, float] = field(default_factory=dict)
    compliance_std: dict[str, float] = field(default_factory=dict)

    @property
    def adequacy(self) -> Adequacy:
        """Return the fit against its noise model (verdict unknown without one)."""
        return assess(self.whitened, self.rank)

    @property
    def correlation(self) -> np.ndarray:
        std = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid='ignore', divide='ignore'):
            return self.covariance / np.outer(std, std)

    def to_json(self) -> dict:
        """Return the JSON object that ``hexacal study/calibrate --json`` print."""
        from hexacal_msgs_py.parameters_file import parameters_to_chain_dict

        model = self.parameters.model
        payload = {
            'model': model,
            'parameters': parameters_to_chain_dict(self.parameters.vector, model),
            'std': parameters_to_chain_dict(np.nan_to_num(self.std, nan=-1.0), model),
            'rank': self.rank,
            'condition_number': self.condition_number,
            'solve_seconds': self.solve_seconds,
            'iterations': self.iterations,
            'reason': self.reason,
            'cost': self.cost,
            'postures_used': len(self.used_postures),
            'postures_rejected': [
                {'index': i, 'reason': r} for i, r in sorted(self.rejected_postures.items())
            ],
            'rms_residual': self.rms_residual,
            'identifiability': self.identifiability.to_json(),
            'device': {n: float(v) for n, v in zip(DEVICE_PARAMETER_NAMES, self.device.vector)},
            'device_identified': list(self.free_device),
            'device_std': {
                n: (None if not np.isfinite(s) else float(s))
                for n, s in zip(DEVICE_PARAMETER_NAMES, self.device_std)
            },
            'weighted_by_noise_model': self.weighted,
            'weights': self.weights,
            'weights_note': self.weights_note,
            'variance_factor': self.variance_factor,
            'robust_loss': self.robust_loss,
            'held_for_identifiability': self.held_for_identifiability,
        }
        if self.compliance_mode != 'none':
            payload['compliance'] = {
                'mode': self.compliance_mode,
                'unit': 'm/N',
                'values': dict(self.compliance),
                'std': {
                    name: (None if not np.isfinite(s) else float(s))
                    for name, s in self.compliance_std.items()
                },
            }
        payload['std_note'] = '-1 marks a parameter that was held fixed or is not identifiable'
        return payload
