"""
Fixed-position postures with an LVDT link (#18): the direction is fixed, the length measured.

A telescopic link's length is free: a fixed-position posture holds the inclinometer at zero (P
on the vertical through O) and the LVDT says where along it, so its fixed position is
(0, 0, -L_m) of its own posture in eqs. 10 and 13 (core/fit/residuals.py), not (0, 0, -L).
"""

from dataclasses import replace

from hexacal_identify.core import sample_poses, simulate_measurements, table1_parameters
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.residuals import ChannelSigma, CostFunction
from hexacal_identify.core.machine.device import DeviceDefects, DeviceModel, fixed_position
from hexacal_identify.core.machine.kinematics import pose_sensitivities
from hexacal_identify.core.machine.measurements import FIXED, Measurements, SPHERE
from hexacal_identify.core.machine.model import nominal_set
import numpy as np
import pytest

TRUE = table1_parameters()
L = 0.75
N_SPHERE, N_FIXED = 30, 20
EXTENSION_M = 3e-3  # the LVDT link's true length varies by up to +-3 mm about L
DEFECTS = DeviceDefects(dL=4e-4, alpha0=2e-4, beta0=-1.5e-4, gamma=1e-4, phi0=1e-4)


def _true_poses(defects: DeviceDefects = DeviceDefects()) -> tuple[np.ndarray, np.ndarray]:
    """
    Return poses and kinds: sphere postures and fixed ones, each at its own link length.

    A fixed posture stands where the (defective) inclinometer reads zero with the link at its
    true length L + e: the executor's corrections aim at a zero reading, the LVDT is free.
    """
    rng = np.random.default_rng(18)
    poses = np.vstack(
        [sample_poses(TRUE, N_SPHERE, rng), sample_poses(TRUE, N_FIXED, rng, FIXED)]
    )
    kinds = np.array([SPHERE] * N_SPHERE + [FIXED] * N_FIXED)
    extension = np.random.default_rng(7).uniform(-EXTENSION_M, EXTENSION_M, len(poses))
    radius = np.linalg.norm(poses[:, :3], axis=1)
    poses[:, :3] *= ((radius + extension) / radius)[:, None]
    fixed = kinds == FIXED
    # |P| = L + e along the direction of a zero reading (L_m + dL with L_m = L + e - dL).
    zero = fixed_position(1.0, replace(defects, dL=0.0)).position[0]
    poses[fixed, :3] = (L + extension[fixed])[:, None] * zero
    return poses, kinds


def _measurements(defects: DeviceDefects = DeviceDefects()) -> Measurements:
    poses, kinds = _true_poses(defects)
    measured = simulate_measurements(TRUE, poses, kinds, defects=defects, lvdt=True)
    fixed = kinds == FIXED
    np.testing.assert_allclose(measured.inclinometer[fixed], 0.0, atol=1e-12)  # reads zero
    assert np.ptp(measured.link_lengths[fixed]) > 4e-3  # fixed postures at different lengths
    return measured


def _at_nominal_length(measured: Measurements) -> Measurements:
    """Return the readings with the fixed postures' lengths replaced by L: eq. 10 at (0, 0, -L)."""
    lengths = np.where(measured.kinds == FIXED, L, measured.link_lengths)
    return replace(measured, link_lengths=lengths)


def _pose_error_m(measured: Measurements, cost: str, defects=DeviceDefects()) -> float:
    options = SolverOptions(cost=cost, device_defects=defects)
    result = identify(nominal_set(2), measured, options)
    errors = pose_errors(TRUE, result.parameters, validation_poses(TRUE, 50, seed=0))
    return float(errors.summary()['position_max_m'])


def test_the_fixed_position_is_at_the_posture_s_measured_length():
    measured = _measurements()
    for mount, sign in (('hanging', -1.0), ('standing', 1.0)):
        cost = CostFunction('fixed', measured, DeviceModel(L, mount), ChannelSigma())
        index = np.flatnonzero(measured.kinds == FIXED)
        where, _ = cost.fixed_positions(DeviceDefects(), index)
        expected = np.zeros((len(index), 3))
        expected[:, 2] = sign * measured.link_lengths[index]
        np.testing.assert_array_equal(where, expected)


def test_without_link_lengths_nothing_changes():
    """The constant L: the same residuals and Jacobian, bit for bit, as L_m = L everywhere."""
    measured = replace(_measurements(), link_lengths=None)
    constant = replace(measured, link_lengths=np.full(len(measured), L))
    poses, _ = _true_poses()
    sensitivity = pose_sensitivities(TRUE, poses)
    for name in ('fixed', 'sphere-fixed', 'relative'):
        blocks = [
            CostFunction(name, m, DeviceModel(L), ChannelSigma()).residuals(
                poses, sensitivity, DEFECTS, with_device=True
            )
            for m in (measured, constant)
        ]
        np.testing.assert_array_equal(blocks[0].values, blocks[1].values)
        np.testing.assert_array_equal(blocks[0].jacobian, blocks[1].jacobian)


@pytest.mark.parametrize('cost', ['sphere-fixed', 'relative', 'fixed'])
def test_lvdt_fixed_postures_calibrate_to_the_truth(cost):
    measured = _measurements()
    assert _pose_error_m(measured, cost) < 1e-9
    # The same postures with their fixed position at (0, 0, -L): millimetres off.
    assert _pose_error_m(_at_nominal_length(measured), cost) > 5e-4


@pytest.mark.parametrize('cost', ['sphere-fixed', 'relative'])
def test_with_known_device_defects(cost):
    """A zero reading of a defective inclinometer points off the vertical: F^j - F^k too."""
    measured = _measurements(DEFECTS)
    assert _pose_error_m(measured, cost, DEFECTS) < 1e-9


def test_the_relative_rows_device_derivatives():
    """Eq. 13 with an LVDT depends on alpha0, beta0, gamma through F^j - F^k: analytic = FD."""
    measured = _measurements(DEFECTS)
    poses, _ = _true_poses(DEFECTS)
    cost = CostFunction('relative', measured, DeviceModel(L), ChannelSigma())
    block = cost.residuals(poses, pose_sensitivities(TRUE, poses), DEFECTS, with_device=True)
    analytic = block.jacobian[:, -5:]
    step = 1e-7
    for column in range(5):
        shifted = []
        for sign in (1.0, -1.0):
            vector = DEFECTS.vector.copy()
            vector[column] += sign * step
            moved = DeviceDefects.from_vector(vector)
            shifted.append(cost.residuals(poses, None, moved).values)
        numeric = (shifted[0] - shifted[1]) / (2 * step)
        np.testing.assert_allclose(analytic[:, column], numeric, atol=1e-8)
    fixed_rows = np.char.endswith(block.channels.astype(str), '_difference')
    assert np.abs(analytic[fixed_rows, 1:4]).max() > 1e-4  # ~ (L_m^j - L_m^k): not zero
