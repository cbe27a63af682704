"""
Parameter identification by least squares on forward-kinematics residuals (eqs. 5-13).

scipy's ``least_squares`` (trust-region reflective, columns scaled by their norms
at the start) minimises the residuals of the chosen cost function over the free
unknowns.  Each evaluation solves forward kinematics for every posture
(warm-started from the last accepted solution); the identification Jacobian
(eq. 6) is analytic, by implicit differentiation of IK(X, u) = lambda.  At each
accepted point the Jacobian is also reduced to its normal equations (J^T J,
J^T r: n x n, n = the architecture's parameters + 5), whose eigendecomposition
serves the stop (the Gauss-Newton step from there is below ``STOP_STEP``), the
convergence verdict, the covariance and the identifiability analysis.

Beyond the paper:

* The unknowns are the architecture's kinematic parameters (its layout's
  ``n_parameters``, 54 for a Hexa Slide) followed by the 5 device defects
  (``device.DEVICE_PARAMETER_NAMES``); masks choose which are identified.
* With a known noise model the residuals are whitened per posture by the
  covariance the reading noise propagates to them (through eq. 4 and FK), so the
  fit is weighted by what each row really knows and the covariance is the
  Cramer-Rao bound of that noise.  With ``scatter_weights`` the reading noise is
  each posture's own measured scatter (``Measurements.standard_errors``, the
  standard errors of its means, raised to ``scatter_floor``): a posture whose
  channels scattered more weighs less, channel by channel.
* Postures are screened: one whose residual is far above the others' (a glitched
  reading, a wrong FK branch) is excluded and reported; a Huber or soft-L1 loss
  (iteratively reweighted) is available as well.

This module runs the rounds around the solver (admitting postures, screening outliers,
reweighting); the parts are ``solver_options`` (what is asked), ``fit_problem`` (FK,
residuals and Jacobian of the postures in use), ``row_weights`` (whitening, robust weights),
``least_squares_run`` (one solver run, its normal equations and covariance) and
``identification_result`` (what is returned).
"""

from __future__ import annotations

from dataclasses import replace
import functools
import time

import numpy as np
from threadpoolctl import ThreadpoolController

from .fit_problem import FitProblem, split_unknowns
from .identification_result import (
    CONVERGED,
    DIVERGED,
    IdentificationResult,
    ITERATION_LIMIT,
)
from .least_squares_run import LeastSquaresRun
from .residuals import CostFunction, N_NOISE_SOURCES
from .solver_options import ROBUST_LOSSES, SolverOptions, unknown_names
from ..architectures import KinematicParameters
from ..errors import InvalidMeasurementError, RankDeficientError, TooFewPosturesError
from ..machine.device import DEVICE_PARAMETER_NAMES, N_DEVICE_PARAMETERS
from ..machine.measurements import Measurements, Weights
from ..machine.model import parameter_names

MAX_ROUNDS = 20  # outer rounds: re-admitting postures, screening outliers, refitting weights
IRLS_TOLERANCE = 1e-9  # robust reweighting stops when no unknown moves more than this (m)


@functools.lru_cache(maxsize=1)
def _blas_controller() -> ThreadpoolController:
    """Built once: inspecting the loaded BLAS libraries costs about a millisecond each time."""
    # scipy brings its own OpenBLAS: loaded first, so that the one-thread limit covers it too.
    import scipy.linalg  # noqa: F401

    return ThreadpoolController()


def _identify_once(
    nominal: KinematicParameters, measurements: Measurements, options: SolverOptions
) -> IdentificationResult:
    """
    Identify the parameters (and chosen device defects) from measured postures.

    The solve starts from ``nominal``.  Postures whose forward kinematics fails (with the nominal
    parameters, or at a trial step near a singularity of the current model) are set aside; once the
    parameters have converged they are tried again and, where FK now succeeds, the solve continues
    with them.  Postures whose residual stands out (``outlier_threshold``) are excluded and
    reported.  Raises InvalidMeasurementError, TooFewPosturesError or RankDeficientError (each with
    a ``reason``); otherwise returns a result whose ``reason`` is 'converged', 'iteration-limit' or
    'diverged'.
    """
    started = time.perf_counter()
    n_parameters = nominal.layout.n_parameters
    options.validate(n_parameters)
    measurements.validate(options.limits, nominal.layout.actuator_unit)
    if options.scatter_weights and measurements.standard_errors is None:
        raise InvalidMeasurementError(
            "weighing by the postures' scatter needs the standard errors of every posture; "
            'these postures carry none: weigh by a noise model, or not at all'
        )
    free = options.free_mask(n_parameters)
    options.compliance.validate(options.cost, len(measurements))
    start = np.concatenate([nominal.vector, options.device_defects.vector])
    if options.compliance.active:
        start = np.concatenate([start, options.compliance.start()])
    start[n_parameters + options.device_prior.indices] = (
        options.device_prior.values
    )  # start at the prior
    cost = CostFunction(options.cost, measurements, options.device, options.sigma)
    missing = cost.missing_postures()
    if missing is not None:
        raise TooFewPosturesError(missing)
    usable = cost.usable()
    unused = {
        int(i): f'not used by the {options.cost} cost function' for i in np.flatnonzero(~usable)
    }
    # Small dense problems run fastest on one BLAS thread; more threads only add contention.
    with _blas_controller().limit(limits=1, user_api='blas'):
        problem, poses, set_aside = _admit(
            start,
            FitProblem(measurements, np.flatnonzero(usable), options, free, nominal.architecture),
            'with the nominal parameters',
        )
        problem.check_enough({**unused, **set_aside})
        solver = _run(problem, start, poses, options)
        initial_block, iterations = solver.initial_block, solver.iterations
        previous = start
        for round_number in range(MAX_ROUNDS):
            set_aside.update(solver.dropped)
            problem, vector, poses = solver.problem, solver.vector, solver.poses
            changed = False
            if solver.reason == CONVERGED:
                problem, poses, changed = _readmit(problem, vector, poses, set_aside, options)
            outliers = _outliers(problem, vector, poses, options)
            if outliers:
                set_aside.update(outliers)
                outlying = np.isin(problem.used, list(outliers))
                problem, poses = problem.without(np.flatnonzero(outlying)), poses[~outlying]
                problem.check_enough({**unused, **set_aside})
                changed = True
            # Noise weights depend on the poses: refit them once at the solution. Robust weights
            # depend on the residuals: iterate (IRLS) until the solution stops moving.
            moved = float(np.max(np.abs(vector - previous)))
            reweight = (round_number == 0 and options.weights != Weights.NONE) or (
                options.robust_loss is not None and moved > IRLS_TOLERANCE
            )
            # Compliances: the loads were held through the run; run again while they move.
            reweight = reweight or problem.loads_moved(vector, poses)
            if not changed and not reweight:
                break
            previous = vector
            solver = _run(problem, vector, poses, options)
            iterations += solver.iterations
        solver.iterations, solver.initial_block = iterations, initial_block
        result = solver.result(nominal, {**unused, **set_aside}, started)
    if not result.identifiability.identifiable and not options.allow_rank_deficient:
        # Identifiable at the start but not at the solution: the apparent information came from the
        # nominal model's errors, not from the data. Refuse rather than return a number that means
        # nothing.
        raise RankDeficientError(
            'at the identified parameters the measurements do not determine every parameter: '
            + result.identifiability.verdict(),
            result.identifiability,
        )
    return result


def identify(
    nominal: KinematicParameters,
    measurements: Measurements,
    options: SolverOptions = SolverOptions(),
) -> IdentificationResult:
    """
    Identify the parameters (and chosen device defects) from measured postures.

    The solve starts from ``nominal``.  See ``_identify_once`` for the procedure.  With
    ``allow_rank_deficient`` a problem found rank-deficient is solved again from the start with the
    unknowns the analysis names held at their start values (fixing the gauge: a minimum-norm step
    would still drift along the unseen directions); the result reports them in
    ``held_for_identifiability`` and its identifiability analysis covers everything that was asked
    for.
    """
    result = _identify_once(nominal, measurements, options)
    if result.identifiability.identifiable or not options.allow_rank_deficient:
        return result
    held = result.identifiability.unidentifiable_parameters
    n = nominal.layout.n_parameters
    compliance = options.compliance
    free = options.free_mask(n) & ~np.isin(unknown_names(nominal.model, compliance), held)
    offset = n + N_DEVICE_PARAMETERS
    reduced = replace(
        options,
        free_parameters=tuple(bool(f) for f in free[:n]),
        free_device=tuple(name for name, f in zip(DEVICE_PARAMETER_NAMES, free[n:offset]) if f),
        compliance=replace(
            compliance,
            held=tuple(
                name for name, f in zip(compliance.names, free[offset:]) if not f
            ),
        ),
    )
    again = _identify_once(nominal, measurements, reduced)
    again.identifiability, again.rank = result.identifiability, result.rank
    again.held_for_identifiability = held
    again.std[np.isin(parameter_names(nominal.model), held)] = np.nan
    for name in again.compliance_std:
        if compliance.unknown_names and f'compliance.{name}' in held:
            again.compliance_std[name] = float('nan')
    return again


def _run(
    problem: 'FitProblem', vector: np.ndarray, poses: np.ndarray, options: SolverOptions
) -> 'LeastSquaresRun':
    if problem.update_loads(vector, poses):  # compliances: loads held through the run
        # The corrected readings changed with the loads: start from their own FK poses.
        fk = problem.solve_fk(split_unknowns(vector, problem.arch)[0], poses, vector=vector)
        poses = np.where(fk.converged[:, None], fk.poses, poses)
    solver = LeastSquaresRun(problem, vector, poses, problem.row_transform(vector, poses))
    solver.run()
    return solver


def _admit(vector: np.ndarray, problem: 'FitProblem', context: str):
    """Solve FK from the expected postures; keep those that converge, set the others aside."""
    params, defects = split_unknowns(vector, problem.arch)
    fk = problem.solve_fk(
        params, problem.expected_poses(defects), fit_tilt_first=True, vector=vector
    )
    failed = sorted(fk.failures)
    set_aside = {
        int(problem.used[i]): f'forward kinematics {context}: {fk.failures[i]}' for i in failed
    }
    return problem.without(failed), fk.poses[fk.converged], set_aside


def _readmit(
    problem: 'FitProblem',
    vector: np.ndarray,
    poses: np.ndarray,
    set_aside: dict[int, str],
    options: SolverOptions,
) -> tuple['FitProblem', np.ndarray, bool]:
    """Retry set-aside FK failures with the identified parameters; keep those that now pass."""
    retry_indices = np.array(
        sorted(i for i, why in set_aside.items() if why.startswith('forward kinematics'))
    )
    if retry_indices.size == 0:
        return problem, poses, False
    retry = FitProblem(problem.measurements, retry_indices, options, problem.free, problem.arch)
    readmitted, readmitted_poses, still = _admit(vector, retry, 'with the identified parameters')
    for index in retry_indices:
        set_aside.pop(int(index), None)
    set_aside.update(still)
    if not len(readmitted.used):
        return problem, poses, False
    merged = np.concatenate([problem.used, readmitted.used])
    order = np.argsort(merged)
    merged_poses = np.concatenate([poses, readmitted_poses])[order]
    return (
        FitProblem(problem.measurements, merged[order], options, problem.free, problem.arch),
        merged_poses,
        True,
    )


def _outliers(
    problem: 'FitProblem', vector: np.ndarray, poses: np.ndarray, options: SolverOptions
) -> dict[int, str]:
    """Return postures whose residual stands far above the others' (glitch or wrong FK branch)."""
    if options.outlier_threshold is None or len(poses) < 3:
        return {}
    block = problem.residuals(vector, poses)
    whitened = options.weights != Weights.NONE
    values = block.values
    if whitened:
        values = problem.row_transform(vector, poses, robust=False).values(block)
    count = np.bincount(block.postures, minlength=len(poses))
    rms = np.sqrt(
        np.bincount(block.postures, weights=values**2, minlength=len(poses)) / np.maximum(count, 1)
    )
    typical = np.median(rms) + 1e-300
    if whitened:
        typical = max(
            typical, 1.0
        )  # whitened rows are ~1 by construction; exact data must not make 1e-12 "big"
    floor = 0.0 if whitened else options.outlier_floor
    flagged = np.flatnonzero((rms > options.outlier_threshold * typical) & (rms > floor))
    return {
        int(problem.used[i]): (
            f"outlier: residual {rms[i] / typical:.0f} x the median posture's "
            '(glitched reading or wrong forward-kinematics branch)'
        )
        for i in flagged
    }


__all__ = [
    'CONVERGED',
    'DIVERGED',
    'ITERATION_LIMIT',
    'N_NOISE_SOURCES',
    'ROBUST_LOSSES',
    'IdentificationResult',
    'InvalidMeasurementError',
    'SolverOptions',
    'identify',
    'unknown_names',
]
