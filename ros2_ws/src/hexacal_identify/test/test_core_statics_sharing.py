"""The compliant mode's load shared by the drives' and the members' stiffness (statics.py)."""

from dataclasses import replace

from hexacal_identify.calibration_steps.calibration_run import drive_stiffness_of
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.compliance import ComplianceModel
from hexacal_identify.core.fit.statics import LoadSharing, MassModel, static_loads
from hexacal_identify.core.machine.postures import sample_poses
import numpy as np
import pytest

MASSES = MassModel(
    platform_mass=20.0, platform_com=(0.01, -0.02, 0.03), leg_mass=2.0, leg_com_fraction=0.4,
    link_mass=1.5, actuator_moving_mass=1.2,
)
GAINS = (1.0e8, 0.8e8, 1.2e8, 1.0e8, 0.9e8, 1.1e8)  # N/m, unequal drives


def _machine(model, n=10, seed=5):
    arch = architecture(model)
    params = arch.default_parameters()
    poses = sample_poses(params, n, np.random.default_rng(seed), 'sphere',
                         arch.default_workspace())
    jacobian = np.array(arch.legs(arch.chains(params), poses).pose_jacobian())
    link_row = np.zeros((n, 6))
    link_row[:, :3] = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    return params, poses, jacobian, link_row


@pytest.mark.parametrize('model', ['hexa_slide', 'gough_stewart'])
def test_stiff_members_and_equal_drives_share_as_the_rigid_rule(model):
    params, poses, _, _ = _machine(model)
    rule = static_loads(params, poses, MASSES, 'compliant')
    shared = static_loads(params, poses, MASSES, 'compliant', sharing=LoadSharing.of(2e7))
    np.testing.assert_allclose(shared.thrust, rule.thrust, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(shared.link, rule.link, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize('model', ['hexa_slide', 'gough_stewart'])
def test_the_shared_load_balances_and_is_one_displacement(model):
    params, poses, jacobian, link_row = _machine(model)
    sharing = LoadSharing.of(GAINS, 2e-8, 1e-7)
    loads = static_loads(params, poses, MASSES, 'compliant', sharing=sharing)
    rule = static_loads(params, poses, MASSES, 'compliant')
    # Both hold the same weights: the same generalised force on the platform.
    wrench = np.einsum('ncx,nc->nx', jacobian, loads.thrust) - loads.link[:, None] * link_row
    expected = np.einsum('ncx,nc->nx', jacobian, rule.thrust) - rule.link[:, None] * link_row
    np.testing.assert_allclose(wrench, expected, atol=1e-9 * np.abs(expected).max())
    # Each drive yields thrust / kp, its leg's spring c r^2 (thrust - the weight it does not
    # carry) = c reading_loads; the platform's one displacement y gives all six and the link's
    # stretch: J y = deflection, j_L y = -c_L T.
    deflection = loads.thrust / np.asarray(GAINS) + 2e-8 * loads.reading_loads
    displacement = np.linalg.solve(jacobian, deflection[..., None])[..., 0]
    stretch = np.einsum('nx,nx->n', link_row, displacement)
    np.testing.assert_allclose(stretch, -1e-7 * loads.link, rtol=1e-6, atol=1e-12)
    assert np.max(np.abs(loads.link - rule.link)) > 10.0, 'the soft link carries less'


def test_a_softer_link_carries_less():
    params, poses, _, _ = _machine('gough_stewart')
    tensions = [
        np.abs(static_loads(params, poses, MASSES, 'compliant',
                            sharing=LoadSharing.of(1e7, 2e-8, c)).link).mean()
        for c in (0.0, 2e-8, 1e-7, 4e-7)
    ]
    assert all(a > b for a, b in zip(tensions, tensions[1:])), tensions
    assert tensions[0] > 2 * tensions[-1]


def test_the_compliance_model_shares_by_its_values_in_the_compliant_mode_only():
    params, poses, _, _ = _machine('hexa_slide', n=4)
    used = np.arange(len(poses))
    compliant = ComplianceModel('shared', MASSES, 'compliant', drive_stiffness=GAINS)
    sharing = compliant.sharing(np.array([3e-8, 1e-7]))
    np.testing.assert_allclose(sharing.chain_compliance, 3e-8)
    assert sharing.link_compliance == 1e-7
    assert compliant.sharing(np.array([-1e-9, -1e-9])).link_compliance == 0.0  # rigid
    expected = static_loads(params, poses, MASSES, 'compliant', sharing=sharing)
    np.testing.assert_allclose(
        compliant.loads(params, poses, used, np.array([3e-8, 1e-7])).link, expected.link
    )
    lvdt = replace(compliant, measuring_mode='lvdt')
    assert lvdt.sharing(np.array([3e-8])) is None
    assert ComplianceModel('shared', MASSES, 'compliant').sharing(np.zeros(2)) is None
    with pytest.raises(ValueError, match='drive stiffness'):
        ComplianceModel('shared', MASSES, 'compliant', drive_stiffness=(0.0,) * 6)


def test_the_drive_gain_is_read_from_a_physical_description(tmp_path):
    assert drive_stiffness_of(None, 'gough_stewart') == (1.0e7,) * 6
    masses_only = tmp_path / 'masses.yaml'
    masses_only.write_text('platform: {mass: 20.0}\ndrives: {kp: 2.0e7}\n')
    assert drive_stiffness_of(str(masses_only), 'hexa_slide') == (2.0e7,) * 6
    masses_only.write_text('platform: {mass: 20.0}\n')
    assert drive_stiffness_of(str(masses_only), 'hexa_slide') is None
    masses_only.write_text('drives: {kp: [1.0, 2.0]}\n')
    with pytest.raises(ValueError, match='drives.kp'):
        drive_stiffness_of(str(masses_only), 'hexa_slide')
