"""
Uncertainty a user can trust: predicted pose errors from the covariance, checked by Monte Carlo.

The identification covariance (whitened by the known noise, it is the
Cramer-Rao bound of Gaussian noise with the same variance) maps to pose errors
through the FK sensitivity dX/du.  ``monte_carlo`` repeats one calibration over
many noise seeds (same machine, same postures) and compares:

* each parameter's predicted std with its empirical spread over the seeds;
* the mean pose error over validation postures with what the linearised
  covariance predicts for it (sampling the Gaussian of the linear model);
* the efficiency CRB variance / empirical mean squared error per parameter
  (1 = as good as any unbiased estimator can be for Gaussian noise).

``position_error`` holds the position covariances and their map over the workspace.

Written against the parameters object: any architecture, n = its number of parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, cast

import numpy as np

from .position_error import position_covariances
from .validation import pose_errors, validation_poses
from ..architectures import default_parameters, KinematicParameters
from ..fit.identification import identify, SolverOptions
from ..machine.kinematics import euler_rate_axes, pose_sensitivities
from ..machine.measurements import NoiseModel, simulate_measurements
from ..machine.model import nominal_set
from ..machine.postures import sample_poses


@dataclass
class PredictedPoseErrors:
    position_mean_m: np.ndarray  # (N,) expected |position error| per pose
    orientation_mean_rad: np.ndarray  # (N,) expected rotation-angle error per pose
    position_std_m: np.ndarray  # (N, 3) std of x, y, z


def predicted_pose_errors(
    params: KinematicParameters,
    covariance: np.ndarray,
    poses: np.ndarray,
    samples: int = 4000,
    seed: int = 0,
) -> PredictedPoseErrors:
    """
    Pose errors the parameter covariance predicts at ``poses`` (linearised: dX = dX/du du).

    ``covariance`` may carry the device defects after the n kinematic parameters: only the
    kinematic block is used.
    """
    n = params.layout.n_parameters
    covariance = np.asarray(covariance)[:n, :n]
    sensitivity = pose_sensitivities(params, poses).wrt_parameters  # (N, 6, n)
    # Draw du ~ N(0, C) once and push it through every pose's linear map.
    eigenvalues, eigenvectors = np.linalg.eigh((covariance + covariance.T) / 2)
    root = eigenvectors * np.sqrt(np.clip(eigenvalues, 0.0, None))
    draws = np.random.default_rng(seed).standard_normal((samples, n)) @ root.T
    d_pose = np.einsum('nik,sk->nsi', sensitivity, draws)  # (N, samples, 6)
    rotation_axes = euler_rate_axes(poses[:, 3:6])  # angle rates -> rotation vector
    rotation = np.einsum('nij,nsj->nsi', rotation_axes, d_pose[:, :, 3:6])
    position_covariance = position_covariances(params, covariance, poses, sensitivity)
    return PredictedPoseErrors(
        position_mean_m=np.linalg.norm(d_pose[:, :, :3], axis=2).mean(axis=1),
        orientation_mean_rad=np.linalg.norm(rotation, axis=2).mean(axis=1),
        position_std_m=np.sqrt(np.einsum('nii->ni', position_covariance)),
    )


@dataclass
class MonteCarloSummary:
    seeds: int
    predicted_std: (
        np.ndarray
    )  # (n,) from the covariance (mean over seeds); n = 54 for a Hexa Slide
    empirical_std: np.ndarray  # (n,) spread of the estimates over seeds
    empirical_rmse: np.ndarray  # (n,) root mean squared error vs the truth
    crb_std: (
        np.ndarray
    )  # (n,) Cramer-Rao bound for Gaussian noise of the same variance, at the truth
    pose_error_mean_m: float  # measured, mean over seeds and validation postures
    predicted_pose_error_mean_m: float  # linearised prediction from the covariance
    orientation_error_mean_rad: float
    predicted_orientation_error_mean_rad: float
    variance_factor_mean: float

    @property
    def std_ratio(self) -> np.ndarray:
        return self.empirical_std / self.predicted_std

    @property
    def efficiency(self) -> np.ndarray:
        """CRB variance / empirical mean squared error, per parameter."""
        return self.crb_std**2 / self.empirical_rmse**2


def monte_carlo(
    seeds: int = 200,
    postures: int = 50,
    noise_um: float = 10.0,
    nominal_set_number: int = 2,
    validation_count: int = 50,
    weighted: bool = True,
    progress: Callable[[str], None] = lambda _: None,
    true_params: KinematicParameters | None = None,
    model: str | None = None,
) -> MonteCarloSummary:
    """
    One calibration (same machine, same postures) repeated over noise seeds.

    The machine is ``true_params``, else the default machine of ``model`` (default: the Table 1
    Hexa Slide); postures come from its architecture's default workspace.
    """
    if true_params is None:
        true_params = default_parameters(model)
    workspace = true_params.architecture.default_workspace()
    poses = sample_poses(true_params, postures, np.random.default_rng(12345), 'sphere', workspace)
    noise = NoiseModel.from_microns(noise_um)
    options = SolverOptions(noise=noise if weighted else None)
    nominal = nominal_set(nominal_set_number, seed=0, exact=true_params)
    validation = validation_poses(true_params, validation_count, 0, workspace)
    estimates, stds, position, orientation, factors = [], [], [], [], []
    first_covariance = None
    for seed in range(seeds):
        progress(f'Monte Carlo seed {seed + 1}/{seeds}')
        measurements = simulate_measurements(
            true_params, poses, noise=noise, rng=np.random.default_rng([seed, 77])
        )
        result = identify(nominal, measurements, options)
        estimates.append(result.parameters.vector)
        stds.append(result.std)
        factors.append(result.variance_factor)
        if first_covariance is None:
            first_covariance = result.covariance
        errors = pose_errors(true_params, result.parameters, validation).summary()
        position.append(errors['position_mean_m'])
        orientation.append(errors['orientation_mean_rad'])
    estimate_array = np.array(estimates)
    # None only when no seed gave a covariance (then predicted_pose_errors fails).
    predicted = predicted_pose_errors(true_params, cast(np.ndarray, first_covariance), validation)
    return MonteCarloSummary(
        seeds=seeds,
        predicted_std=np.mean(stds, axis=0),
        empirical_std=estimate_array.std(axis=0, ddof=1),
        empirical_rmse=np.sqrt(np.mean((estimate_array - true_params.vector) ** 2, axis=0)),
        crb_std=_crb_std(true_params, poses, noise, options),
        pose_error_mean_m=float(np.mean(position)),
        predicted_pose_error_mean_m=float(predicted.position_mean_m.mean()),
        orientation_error_mean_rad=float(np.mean(orientation)),
        predicted_orientation_error_mean_rad=float(predicted.orientation_mean_rad.mean()),
        variance_factor_mean=float(np.mean(factors)),
    )


def _crb_std(
    true_params: KinematicParameters, poses: np.ndarray, noise: NoiseModel, options: SolverOptions
) -> np.ndarray:
    """
    Return the std of the Cramer-Rao bound at the truth.

    Exact readings, residuals whitened by the noise covariance.
    """
    exact = simulate_measurements(true_params, poses)
    crb_options = SolverOptions(noise=noise, cost=options.cost)
    result = identify(true_params, exact, crb_options)
    return np.sqrt(np.diag(result.covariance)[: true_params.layout.n_parameters])


__all__ = [
    'MonteCarloSummary',
    'PredictedPoseErrors',
    'monte_carlo',
    'position_covariances',
    'predicted_pose_errors',
]
