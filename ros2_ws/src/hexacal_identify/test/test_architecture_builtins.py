"""
The plugin test's checks on every built-in model (Hexa Slide, Gough-Stewart, rotary hexapod).

Each built-in architecture goes through what a plugged-in one must pass
(``test_architecture_plugin``): known under its name in the contract and the
core, IK/FK round trip, both analytic Jacobians against central differences,
noise-free recovery of its default machine from a nominal set, the base
rotation about Y named under the sphere cost, a bit-exact parameters file and
its layout's physical checks by field name.
"""

from __future__ import annotations

from hexacal_identify.core.architectures import architecture, ARCHITECTURES, default_parameters
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.machine.kinematics import forward_kinematics, inverse_kinematics
from hexacal_identify.core.machine.measurements import simulate_measurements
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE, MODELS, PositiveField, ROTARY_HEXAPOD
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
import numpy as np
import pytest

BUILT_IN = (HEXA_SLIDE, GOUGH_STEWART, ROTARY_HEXAPOD)


def _poses(name: str, n: int, seed: int) -> np.ndarray:
    arch = architecture(name)
    return sample_poses(
        arch.default_parameters(), n, np.random.default_rng(seed), 'sphere',
        arch.default_workspace(),
    )


@pytest.mark.parametrize('name', BUILT_IN)
def test_the_model_is_known_in_the_contract_and_the_core(name):
    arch = architecture(name)
    assert ARCHITECTURES[name] is arch and arch.layout is MODELS[name]
    assert arch.parameters_type.architecture is arch
    truth = default_parameters(name)
    assert truth.model == name and truth.vector.shape == (MODELS[name].n_parameters,)
    assert MODELS[name].physical_problem(truth.vector) is None


@pytest.mark.parametrize('name', BUILT_IN)
def test_ik_fk_round_trip(name):
    truth = default_parameters(name)
    poses = _poses(name, 40, 3)
    readings = inverse_kinematics(truth, poses)
    fk = forward_kinematics(truth, readings, poses + 1e-3)
    np.testing.assert_allclose(fk.poses, poses, rtol=0, atol=1e-10)


@pytest.mark.parametrize('name', BUILT_IN)
def test_both_jacobians_match_central_differences(name):
    arch, truth = architecture(name), default_parameters(name)
    chains = arch.chains(truth)
    poses = _poses(name, 6, 4)
    legs = arch.legs(chains, poses)
    step = 1e-6
    jacobian = legs.pose_jacobian()
    for k in range(6):
        delta = np.zeros(6)
        delta[k] = step
        numeric = (
            arch.legs(chains, poses + delta).actuators - arch.legs(chains, poses - delta).actuators
        ) / (2 * step)
        np.testing.assert_allclose(jacobian[:, :, k], numeric, rtol=0, atol=1e-6)
    blocks = legs.parameter_blocks(chains)
    fields = truth.layout.fields_per_chain
    for index in range(truth.layout.n_parameters):
        up, down = truth.vector.copy(), truth.vector.copy()
        up[index] += step
        down[index] -= step
        numeric = (
            arch.legs(arch.chains(truth.with_vector(up)), poses).actuators
            - arch.legs(arch.chains(truth.with_vector(down)), poses).actuators
        ) / (2 * step)
        chain, field = divmod(index, fields)
        np.testing.assert_allclose(numeric[:, chain], blocks[:, chain, field], rtol=0, atol=1e-6)


@pytest.mark.parametrize('name', BUILT_IN)
def test_noise_free_identification_recovers_the_machine(name):
    truth = default_parameters(name)
    nominal = nominal_set(2, seed=1, model=name)
    assert nominal.model == name and np.max(np.abs(nominal.vector - truth.vector)) > 1e-3
    result = identify(nominal, simulate_measurements(truth, _poses(name, 30, 0)), SolverOptions())
    n = truth.layout.n_parameters
    assert result.reason == CONVERGED and result.parameters.model == name
    assert result.rank == n and result.identifiability.identifiable
    np.testing.assert_allclose(result.parameters.vector, truth.vector, rtol=0, atol=1e-9)


@pytest.mark.parametrize('name', BUILT_IN)
def test_identifiability_names_the_base_rotation_under_the_sphere_cost(name):
    truth = default_parameters(name)
    options = SolverOptions(cost='sphere', allow_rank_deficient=True)
    # 40 postures: two rows each, more than the 66 unknowns of the rotary hexapod.
    report = identify(truth, simulate_measurements(truth, _poses(name, 40, 0)), options)
    assert report.identifiability.rank == truth.layout.n_parameters - 1
    assert [d.description for d in report.identifiability.null_directions] == [
        'a rotation of the base frame about Y'
    ]


@pytest.mark.parametrize('name', BUILT_IN)
def test_parameters_file_round_trip_and_physical_checks(name, tmp_path):
    truth = default_parameters(name)
    layout = truth.layout
    path = tmp_path / f'{name}.yaml'
    save_parameters(path, truth.vector, model=name)
    contents = read_parameters_file(path)
    assert contents.model == name and contents.vector.tobytes() == truth.vector.tobytes()
    positive = [check for check in layout.physical_checks if isinstance(check, PositiveField)]
    assert positive, 'every built-in model has a length that must be positive'
    for check in positive:
        vector = truth.vector.copy()
        vector[layout.parameter_index(2, check.field)] = 0.0
        assert layout.physical_problem(vector).startswith(f'chain_2.{check.field} must be > 0')
