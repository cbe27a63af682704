"""
The deflection check (core/assessment/deflection.py): a bias the residuals cannot show.

A Gough-Stewart in the lvdt mode whose legs (5e7 N/m) deflect under the platform's weight:
the rigid fit absorbs the deflections, passes its adequacy, and misses the machine by several
times the rigid machine's error; the check, from the calibration alone and the machine's
described compliances, names that bias.  With no compliance it finds none.
"""

from __future__ import annotations

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.assessment.deflection import deflection_bias
from hexacal_identify.core.assessment.validation import pose_errors
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.physical_file import default_physical
import numpy as np
import pytest

MODEL = 'gough_stewart'
NOISE = NoiseModel.from_microns(2.0)


@pytest.fixture(scope='module')
def fits():
    truth = architecture(MODEL).default_parameters()
    physical = default_physical(MODEL)
    compliance = ComplianceModel('per_chain', MassModel.from_physical(physical), 'lvdt')
    values = 1.0 / np.asarray(physical.structure_axial_stiffness)
    poses = sample_poses(truth, 30, np.random.default_rng(1), 'sphere',
                         truth.architecture.default_workspace())
    options = SolverOptions(noise=NOISE)
    fitted = {}
    for name, scale in (('loaded', 1.0), ('rigid', 0.0)):
        measurements, _ = simulate_loaded_measurements(
            truth, poses, compliance, scale * values, noise=NOISE, rng=np.random.default_rng(5)
        )
        result = identify(nominal_set(2, seed=0, model=MODEL), measurements, options)
        fresh = sample_poses(truth, 200, np.random.default_rng(9), 'sphere',
                             truth.architecture.default_workspace())
        error = float(np.nanmean(pose_errors(truth, result.parameters, fresh).position_m))
        check = deflection_bias(result, options, compliance, scale * values, 'shipped')
        fitted[name] = (result, error, check)
    return fitted


def test_the_check_names_the_bias_a_passing_rigid_fit_hides(fits):
    result, error, check = fits['loaded']
    _, rigid_error, _ = fits['rigid']
    assert result.adequacy.verdict == 'pass'  # the residuals cannot show it
    assert error > 2.0 * rigid_error  # the machine's deflections cost that much
    assert check.significant and check.largest_deflection_m > 1e-6
    assert 0.5 * error < check.pose_bias_mean_m < 2.0 * error
    assert max(check.visible_rms.values()) < 1e-6  # what a residual test could see
    assert 'identify the compliances' in check.text()
    assert check.to_json()['significant'] is True


def test_no_compliance_no_bias(fits):
    _, _, check = fits['rigid']
    assert check.pose_bias_mean_m < 1e-9 and not check.significant
    assert 'within the calibration' in check.text()
