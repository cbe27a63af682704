"""
What a solve is asked to do: the cost function, the unknowns identified, the weights, the stops.

``SolverOptions`` is the one argument of ``identification.identify`` besides the nominal
parameters and the postures; ``unknown_names`` names the unknown vector it masks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .compliance import ComplianceModel
from .residuals import ChannelSigma, COSTS
from ..assessment.identifiability import DEFAULT_RANK_TOLERANCE
from ..machine.device import (
    DEVICE_PARAMETER_NAMES,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
)
from ..machine.measurements import (
    MeasurementLimits,
    NoiseModel,
    ScatterFloor,
    Weights,
)
from ..machine.model import parameter_names

ROBUST_LOSSES = ('huber', 'soft_l1')


def unknown_names(model: str, compliance: ComplianceModel | None = None) -> list[str]:
    """
    Return the names of the model's kinematic parameters followed by the 5 device defects.

    With a ``compliance`` choice its unknowns (``compliance.<name>``) follow.
    """
    names = parameter_names(model) + [f'device.{name}' for name in DEVICE_PARAMETER_NAMES]
    return names + (compliance.unknown_names if compliance is not None else [])


@dataclass(frozen=True)
class SolverOptions:
    cost: str = 'absolute'
    device: DeviceModel = DeviceModel()
    sigma: ChannelSigma = ChannelSigma()
    limits: MeasurementLimits = MeasurementLimits()
    free_parameters: tuple[bool, ...] | None = (
        None  # mask over the kinematic parameters; None = all
    )
    device_defects: DeviceDefects = DeviceDefects()  # assumed (and starting) device defects
    free_device: tuple[
        str, ...
    ] = ()  # device defects to identify, names from DEVICE_PARAMETER_NAMES
    device_prior: DevicePrior = (
        DevicePrior()
    )  # prior value +- std per device defect (identified, MAP rows)
    noise: NoiseModel | None = None  # known reading noise: whiten the residuals by it
    # Whiten by each posture's measured scatter (Measurements.standard_errors, every posture)
    # raised to scatter_floor, instead of one noise model shared by every posture.
    scatter_weights: bool = False
    scatter_floor: ScatterFloor = ScatterFloor()
    robust_loss: str | None = None  # None, 'huber' or 'soft_l1'
    outlier_threshold: float | None = (
        6.0  # a posture whose RMS residual exceeds this x the median is excluded
    )
    outlier_floor: float = (
        1e-7  # ... and exceeds this (m or rad, unweighted): below, it is rounding, not a glitch
    )
    max_iterations: int = 100  # steps taken per solve
    step_tolerance: float = 1e-12  # least_squares' xtol: a step below this x |unknowns| converges
    relative_cost_tolerance: float = (
        1e-9  # least_squares' ftol: ... or an accepted step lowers the cost by less than this
    )
    rank_tolerance: float = DEFAULT_RANK_TOLERANCE
    allow_rank_deficient: bool = (
        False  # hold the unidentifiable unknowns fixed instead of refusing
    )
    fk_tolerance: float = 1e-12
    # Branch check (section 3.3): a nominal model with Table 2's set-3 errors already moves FK
    # solutions ~70 mm from the measured position, another FK branch moves them much further.
    branch_tolerance_m: float = 0.2
    branch_tolerance_rad: float = 0.5
    # Axial compliances identified with the geometry from the static loads
    # (core/fit/compliance.py).
    compliance: ComplianceModel = ComplianceModel()

    def free_mask(self, n_parameters: int) -> np.ndarray:
        """Return the mask over the unknowns: n_parameters kinematic (the layout's) + 5 device."""
        kinematic = (
            np.ones(n_parameters, bool)
            if self.free_parameters is None
            else np.asarray(self.free_parameters, bool)
        )
        if kinematic.shape != (n_parameters,):
            raise ValueError(f'free_parameters must be a mask of {n_parameters} booleans')
        unknown = sorted(set(self.free_device) - set(DEVICE_PARAMETER_NAMES))
        if unknown:
            raise ValueError(
                f'unknown device parameter(s) {unknown}; choose from '
                f'{", ".join(DEVICE_PARAMETER_NAMES)}'
            )
        identified = set(self.free_device) | set(self.device_prior.names)
        device = np.array([name in identified for name in DEVICE_PARAMETER_NAMES])
        if self.compliance.active:
            return np.concatenate([kinematic, device, self.compliance.free()])
        return np.concatenate([kinematic, device])

    def validate(self, n_parameters: int) -> None:
        if self.cost not in COSTS:
            raise ValueError(
                f'unknown cost function {self.cost!r}; choose one of {", ".join(COSTS)}'
            )
        if self.robust_loss not in (None, *ROBUST_LOSSES):
            raise ValueError(
                f'unknown robust loss {self.robust_loss!r}; choose one of '
                f'{", ".join(ROBUST_LOSSES)}'
            )
        if self.noise is not None and not self.noise.known:
            raise ValueError('a noise model for weighting needs positive slider and angle noise')
        if self.noise is not None and self.scatter_weights:
            raise ValueError(
                "weigh by the postures' scatter or by a noise model, not both: give one"
            )
        if self.device_prior and self.weights == Weights.NONE:
            raise ValueError(
                f'a device prior ({self.device_prior.describe()}) is weighed against the data by '
                'the reading noise: give the noise model too (noise_slider_m and '
                'noise_angle_rad, --noise-um / --weighted), or postures that carry their scatter'
            )
        if self.compliance.prior and self.weights == Weights.NONE:
            raise ValueError(
                'a compliance prior is weighed against the data by the reading noise: give the '
                'noise model too (--noise-um / --weighted), or postures that carry their scatter'
            )
        self.free_mask(n_parameters)

    @property
    def weights(self) -> Weights:
        """Return what whitens the residuals: the postures' scatter, the noise model, or none."""
        if self.scatter_weights:
            return Weights.SCATTER
        return Weights.NOISE_MODEL if self.noise is not None else Weights.NONE
