"""
Postures that six commanded actuators can hold on a machine unlike the nominal.

A posture is planned on the nominal model, and the executor commands the nominal IK. With all
six actuators stiff (``lvdt``, ``compliant``) the true machine then stands where its own
forward kinematics of those setpoints puts it, and near the workspace's edge that may be nowhere:
a Hexa Slide posture with a condition number of 66 on the nominal (Table 1 with nominal set 2)
lies past a fold of the true machine's direct kinematics (its smallest singular value goes to
zero 70 % of the way from the true setpoints to the nominal ones), so the true drives cannot
reach it and a real machine would be driven into a singularity.  `hold_on_machines` keeps the
candidates whose nominal setpoints close, by forward kinematics from the planned pose, on the
nominal and on the rehearsal's machines (release_rehearsal.py: errors of a machine built to its
drawing) with a condition number within ``max_condition`` there; for an LVDT link also with
its extension within the stroke less a margin there (model error extends it by millimetres).
"""

from __future__ import annotations

import numpy as np

from ..architectures import KinematicParameters
from ..machine.kinematics import forward_kinematics, inverse_kinematics
from ..modes.release_rehearsal import DEFAULT_MODEL_SAMPLES, model_error_rms_m, sampled_machines


def _conditions(params: KinematicParameters, poses: np.ndarray, link_length: float) -> np.ndarray:
    """Return the machine's condition number at `poses` (N,), angles scaled by L."""
    arch = params.architecture
    jacobian = np.array(arch.legs(arch.chains(params), poses).pose_jacobian())
    jacobian[:, :, 3:] /= link_length
    return np.linalg.cond(jacobian)


def hold_on_machines(
    nominal: KinematicParameters,
    poses: np.ndarray,
    link_length: float,
    max_condition: float,
    samples: int = DEFAULT_MODEL_SAMPLES,
    seed: int = 0,
    max_extension_m: float = np.inf,
) -> np.ndarray:
    """
    Return which poses (N,) every sampled machine holds with the nominal setpoints (doc).

    With `max_extension_m` (an LVDT link), also only where three times the RMS of the link's
    extension |P| - L over the machines stays within it.
    """
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    setpoints = inverse_kinematics(nominal, poses)
    holds = np.all(np.isfinite(setpoints), axis=1)
    machines = sampled_machines(nominal, samples, model_error_rms_m(nominal), seed)[1:]
    extensions = np.full((len(machines), len(poses)), np.nan)
    for k, machine in enumerate(machines):
        rows = np.flatnonzero(holds)
        if not rows.size:
            break
        solved = forward_kinematics(machine, setpoints[rows], poses[rows])
        converged = np.asarray(solved.converged, bool)
        ok = np.zeros(len(rows), bool)
        if np.any(converged):
            stood = solved.poses[converged]
            ok[converged] = _conditions(machine, stood, link_length) <= max_condition
            extensions[k, rows[converged]] = np.linalg.norm(stood[:, :3], axis=1) - link_length
        holds[rows[~ok]] = False
    if np.isfinite(max_extension_m) and len(machines):
        # The true machine is not among the drawn ones: its extension is judged by the spread
        # of theirs (three RMS, the extension being nearly linear in the parameter errors).
        spread = 3.0 * np.sqrt(np.mean(extensions**2, axis=0))
        with np.errstate(invalid='ignore'):
            holds &= spread <= max_extension_m
    return holds


__all__ = ['hold_on_machines']
