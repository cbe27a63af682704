"""The calibrated compliances at work: loaded poses and compensated commands (machine/live.py)."""

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.statics import MassModel, static_loads
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.live import (
    actuator_targets,
    home_pose,
    LoadedChains,
    solve_pose,
)
from hexacal_identify.core.machine.postures import sample_poses
import numpy as np
import pytest

MASSES = MassModel(platform_mass=20.0, leg_mass=2.0, link_mass=1.5)


@pytest.mark.parametrize('model', ['hexa_slide', 'gough_stewart'])
def test_compensated_commands_and_loaded_poses_round_trip(model):
    arch = architecture(model)
    params = arch.default_parameters()
    poses = sample_poses(params, 5, np.random.default_rng(2), 'sphere', arch.default_workspace())
    loaded = LoadedChains((2e-8, 3e-8, 2e-8, 4e-8, 2e-8, 1e-8), MASSES)
    assert loaded.masses.link_mass == 0.0  # the link is off the machine in operation
    for pose in poses:
        rigid = actuator_targets(params, pose, stroke=(-1.0, 2.0))
        targets = actuator_targets(params, pose, stroke=(-1.0, 2.0), loaded=loaded)
        # The encoders are commanded past the joints by each chain's deflection: six chains
        # carry the weight (no link), a leg's deflection is c F r (statics.py).
        loads = static_loads(params, pose[None], loaded.masses, 'lvdt')
        np.testing.assert_allclose(
            targets - rigid, loads.reading_loads[0] * loaded.compliances, atol=1e-15
        )
        assert np.max(np.abs(targets - rigid)) > 1e-7
        guess = pose + np.array([1e-3, -1e-3, 1e-3, 0.0, 0.0, 0.0])
        solved = solve_pose(params, targets, guess, loaded)
        np.testing.assert_allclose(solved, pose, atol=1e-11)
        # Read as rigid, the same encoders put the platform elsewhere.
        assert np.max(np.abs(solve_pose(params, targets, guess)[:3] - pose[:3])) > 1e-8
    np.testing.assert_allclose(rigid, inverse_kinematics(params, pose[None])[0])


def test_loaded_chains_from_the_file_section():
    assert LoadedChains.from_file_values({}, MASSES) is None
    assert LoadedChains.from_file_values({'link': 1e-7}, MASSES) is None  # the link: not in use
    shared = LoadedChains.from_file_values({'chains': 2e-8, 'link': 1e-7}, MASSES)
    assert shared.compliances == (2e-8,) * 6
    one = LoadedChains.from_file_values({'chain_3': 1e-8}, MASSES)
    assert one.compliances == (0.0, 0.0, 1e-8, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match='six finite chain compliances'):
        LoadedChains((1e-8,) * 5, MASSES)
    assert home_pose().shape == (6,)
