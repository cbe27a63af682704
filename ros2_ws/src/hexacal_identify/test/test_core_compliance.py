"""Axial compliances identified with the geometry: Jacobians, recovery, adequacy, named limits."""

from dataclasses import replace

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.errors import InvalidMeasurementError, RankDeficientError
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.fit_problem import FitProblem
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.statics import MassModel, released_force_loads
from hexacal_identify.core.machine.kinematics import forward_kinematics
from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')
MASSES = MassModel(
    platform_mass=20.0, platform_com=(0.0, 0.0, 0.02), leg_mass=2.0, link_mass=1.5
)
LINK = 1e-7  # m/N: a 1e7 N/m measuring link
CHAIN = 2e-8  # m/N: 5e7 N/m legs
NOISE = NoiseModel.from_microns(2.0)


def _setup(model, n=50, seed=1, mode='passive_actuator'):
    arch = architecture(model)
    true = arch.default_parameters()
    rng = np.random.default_rng(seed)
    poses = sample_poses(true, n, rng, 'sphere', arch.default_workspace())
    # The released chain of each posture: the one that leaves the passive system best conditioned.
    released = np.argmin(release_conditions(true, poses, 0.75), axis=1)
    return arch, true, rng, poses, released


def _nominal(true, rng, scale=2e-4):
    return true.with_vector(true.vector + rng.normal(0.0, scale, true.vector.size))


@pytest.mark.parametrize('model', MODELS)
@pytest.mark.parametrize('choice, mode', [
    ('shared', 'passive_actuator'), ('per_chain', 'passive_actuator'),
    ('shared', 'compliant'), ('per_chain', 'compliant'),
])
def test_compliance_columns_match_finite_differences(model, choice, mode):
    arch, true, rng, poses, released = _setup(model, n=12)
    if mode == 'compliant':  # the loads move with the compliances (load_sharing.py)
        compliance = ComplianceModel(choice, MASSES, mode, drive_stiffness=(3e7,) * 6)
    else:
        compliance = ComplianceModel(choice, MASSES, mode, released)
    truth = np.array([CHAIN] * (1 if choice == 'shared' else 6) + [LINK])
    measurements, _ = simulate_loaded_measurements(true, poses, compliance, truth)
    options = SolverOptions(compliance=compliance, free_device=('dL', 'alpha0'))
    n = true.layout.n_parameters
    free = options.free_mask(n)
    problem = FitProblem(measurements, np.arange(len(poses)), options, free, arch)
    vector = np.concatenate([_nominal(true, rng).vector, np.zeros(5), truth * 0.7])
    vector[n] = 1e-4  # dL
    fk = problem.solve_fk(vector_params := arch.parameters(vector[:n]), poses)
    problem.update_loads(vector, fk.poses)
    fk = problem.solve_fk(vector_params, fk.poses, vector=vector)
    analytic = problem.jacobian(vector, fk.poses).jacobian
    columns = np.flatnonzero(free)
    # Every compliance column, the dL column and a few kinematic ones.
    checked = [k for k, c in enumerate(columns) if c >= n] + [0, 5, n // 2]
    for k in checked:
        unknown = columns[k]
        step = 1e-6 if unknown < n + 5 else 1e-11  # T(c_L) is curved: a small step
        values = []
        for sign in (1.0, -1.0):
            trial = vector.copy()
            trial[unknown] += sign * step
            params = arch.parameters(trial[:n])
            poses_k = forward_kinematics(
                params,
                problem.cost_at(trial).measurements.actuator_positions,
                fk.poses,
                tolerance=1e-14,
            ).poses
            values.append(problem.residuals(trial, poses_k).values)
        numeric = (values[0] - values[1]) / (2 * step)
        scale = np.max(np.abs(numeric)) + 1e-30
        np.testing.assert_allclose(
            analytic[:, k], numeric, atol=2e-5 * scale, err_msg=f'column {unknown}'
        )
        assert scale > 0.0


@pytest.mark.parametrize('model', MODELS)
@pytest.mark.parametrize('choice, mode', [
    ('shared', 'passive_actuator'), ('per_chain', 'passive_actuator'), ('shared', 'compliant'),
])
def test_known_compliances_are_recovered_within_their_std(model, choice, mode):
    arch, true, rng, poses, released = _setup(model)
    if mode == 'compliant':  # drives of 3e7 N/m share the load with the compliances
        compliance = ComplianceModel(choice, MASSES, mode, drive_stiffness=(3e7,) * 6)
    else:
        compliance = ComplianceModel(choice, MASSES, mode, released)
    chains = [CHAIN] if choice == 'shared' else list(CHAIN * np.linspace(0.6, 1.4, 6))
    truth = np.array(chains + [LINK])
    measurements, _ = simulate_loaded_measurements(
        true, poses, compliance, truth, noise=NOISE, rng=rng
    )
    result = identify(
        _nominal(true, rng), measurements, SolverOptions(noise=NOISE, compliance=compliance)
    )
    assert result.identifiability.identifiable
    estimate = np.array(list(result.compliance.values()))
    std = np.array(list(result.compliance_std.values()))
    assert np.all(np.isfinite(std)) and np.all(std > 0)
    # Within 3.3 reported standard deviations (two-sided 0.1 %) each, and the link well known.
    assert np.all(np.abs(estimate - truth) < 3.3 * std), (estimate, truth, std)
    # Released, the link bears the load and its compliance is well known.  With all six drives
    # powered a softer link bears less and stretches about as much: barely told (the Gough-
    # Stewart's std 3.7x the value, results.md); the chains' is (43 %).
    if mode == 'passive_actuator':
        assert std[-1] < 0.05 * LINK
    else:
        assert std[0] < 0.5 * CHAIN, std
    assert result.adequacy.verdict == 'pass', result.adequacy.reason
    payload = result.to_json()['compliance']
    assert payload['mode'] == choice and set(payload['values']) == set(compliance.names)


@pytest.mark.parametrize('model', MODELS)
def test_a_rigid_fit_of_a_loaded_machine_fails_its_adequacy(model):
    arch, true, rng, poses, released = _setup(model)
    compliance = ComplianceModel('shared', MASSES, 'passive_actuator', released)
    measurements, _ = simulate_loaded_measurements(
        true, poses, compliance, np.array([CHAIN, LINK]), noise=NOISE, rng=rng
    )
    nominal = _nominal(true, rng)
    rigid = identify(nominal, measurements, SolverOptions(noise=NOISE))
    assert rigid.adequacy.failed and rigid.variance_factor > 20.0, rigid.variance_factor
    assert 'compliance' not in rigid.to_json()
    compliant = identify(nominal, measurements, SolverOptions(noise=NOISE, compliance=compliance))
    assert compliant.adequacy.verdict == 'pass' and compliant.variance_factor < 2.0
    # The geometry the compliant fit finds is the true one; the rigid fit's is bent by the loads.
    rigid_error = np.max(np.abs(rigid.parameters.vector - true.vector))
    compliant_error = np.max(np.abs(compliant.parameters.vector - true.vector))
    assert compliant_error < rigid_error / 3.0, (compliant_error, rigid_error)


def test_lvdt_mode_has_no_link_compliance_and_recovers_the_chains():
    arch, true, rng, poses, _ = _setup('gough_stewart')
    compliance = ComplianceModel('shared', MASSES, 'lvdt')
    assert compliance.names == ('chains',)
    measurements, _ = simulate_loaded_measurements(
        true, poses, compliance, np.array([5 * CHAIN]), noise=NOISE, rng=rng
    )
    result = identify(
        _nominal(true, rng), measurements, SolverOptions(noise=NOISE, compliance=compliance)
    )
    assert abs(result.compliance['chains'] - 5 * CHAIN) < 3.3 * result.compliance_std['chains']


def test_a_compliance_without_load_is_named_unidentifiable():
    arch, true, rng, poses, released = _setup('hexa_slide', n=30)
    weightless = ComplianceModel('shared', MassModel(), 'passive_actuator', released)
    measurements, _ = simulate_loaded_measurements(true, poses, weightless, np.zeros(2))
    with pytest.raises(RankDeficientError, match='axial compliance of link has no effect'):
        identify(_nominal(true, rng), measurements, SolverOptions(compliance=weightless))
    result = identify(
        _nominal(true, rng),
        measurements,
        SolverOptions(compliance=weightless, allow_rank_deficient=True),
    )
    assert 'compliance.link' in result.held_for_identifiability
    assert np.isnan(result.compliance_std['link'])


def test_a_prior_holds_a_compliance_the_data_barely_see():
    arch, true, rng, poses, released = _setup('hexa_slide')
    compliance = ComplianceModel('per_chain', MASSES, 'passive_actuator', released)
    truth = np.array([CHAIN] * 6 + [LINK])
    measurements, _ = simulate_loaded_measurements(
        true, poses, compliance, truth, noise=NOISE, rng=rng
    )
    datasheet = replace(compliance, prior={'chain_1': (CHAIN, 0.01 * CHAIN)})
    result = identify(
        _nominal(true, rng), measurements, SolverOptions(noise=NOISE, compliance=datasheet)
    )
    assert abs(result.compliance['chain_1'] - CHAIN) < 0.03 * CHAIN
    assert result.compliance_std['chain_1'] <= 0.0101 * CHAIN
    with pytest.raises(ValueError, match='reading noise'):
        identify(_nominal(true, rng), measurements, SolverOptions(compliance=datasheet))


def test_bad_compliance_input_is_named():
    arch, true, rng, poses, released = _setup('hexa_slide', n=12)
    measurements, _ = simulate_loaded_measurements(
        true, poses, ComplianceModel('shared', MASSES, 'lvdt'), np.array([CHAIN])
    )
    with pytest.raises(InvalidMeasurementError, match='released chain of every posture'):
        identify(true, measurements, SolverOptions(compliance=ComplianceModel('shared', MASSES)))
    with pytest.raises(ValueError, match='relative cost'):
        identify(
            true,
            measurements,
            SolverOptions(
                cost='relative', compliance=ComplianceModel('shared', MASSES, 'lvdt')
            ),
        )
    with pytest.raises(ValueError, match='unknown compliance choice'):
        ComplianceModel('stiff')
    with pytest.raises(ValueError, match=r"unknown compliance\(s\) \['link'\]"):
        ComplianceModel('shared', MASSES, 'lvdt', prior={'link': (LINK, LINK)})


def test_verification_uses_the_compliances_on_fresh_postures():
    from hexacal_identify.core.assessment.verification import verify

    arch, true, rng, poses, released = _setup('hexa_slide', n=70)
    compliance = ComplianceModel('shared', MASSES, 'passive_actuator', released[:50])
    truth = np.array([CHAIN, LINK])
    measurements, _ = simulate_loaded_measurements(
        true, poses, replace(compliance, released=released), truth, noise=NOISE, rng=rng
    )
    fit, fresh = measurements.subset(np.arange(50)), measurements.subset(np.arange(50, 70))
    nominal = _nominal(true, rng)
    result = identify(nominal, fit, SolverOptions(noise=NOISE, compliance=compliance))
    values = np.array(list(result.compliance.values()))
    fresh_model = replace(compliance, released=released[50:])
    loaded = verify(
        nominal,
        result.parameters,
        fresh,
        noise=NOISE,
        calibrated_compliance=(fresh_model, values),
    )
    rigid = verify(nominal, result.parameters, fresh, noise=NOISE)
    loaded_rms = loaded.calibrated.figures()['position_rms_m']
    rigid_rms = rigid.calibrated.figures()['position_rms_m']
    assert loaded.verdict == 'pass', loaded.verdict_reason
    # Read as rigid, the same readings show the link's stretch at the fresh postures.
    assert loaded_rms < 8e-6 and rigid_rms > 3 * loaded_rms, (loaded_rms, rigid_rms)


def _with_stiction(true, poses, compliance, truth, forces, rng):
    """Return a loaded machine's readings with ``forces`` (N) held by the released actuators."""
    poses = poses.copy()
    direction = poses[:, :3] / np.linalg.norm(poses[:, :3], axis=1, keepdims=True)
    used = np.arange(len(poses))
    for _ in range(4):  # the platform stands where the loaded link's length puts it
        loads = compliance.loads(true, poses, used)
        unit = released_force_loads(true, poses, compliance.released)
        tension = loads.link + forces * unit.link
        poses[:, :3] = direction * (0.75 + truth[-1] * tension)[:, None]
    rigid = simulate_measurements(true, poses, noise=NOISE, rng=rng)
    shifts = truth[0] * (loads.reading_loads + forces[:, None] * unit.reading_loads)
    return replace(rigid, actuator_positions=rigid.actuator_positions + shifts)


def test_released_friction_weighed_as_noise_keeps_the_adequacy_honest():
    arch, true, rng, poses, released = _setup('hexa_slide', n=40)
    friction = 20.0  # N: the released actuator stops anywhere its stiction holds it
    compliance = ComplianceModel('shared', MASSES, 'passive_actuator', released)
    truth = np.array([CHAIN, LINK])
    forces = rng.uniform(-friction, friction, len(poses))
    measurements = _with_stiction(true, poses, compliance, truth, forces, rng)
    nominal = _nominal(true, rng)
    unweighed = identify(nominal, measurements, SolverOptions(noise=NOISE, compliance=compliance))
    assert unweighed.adequacy.failed, unweighed.variance_factor
    weighed = identify(
        nominal,
        measurements,
        SolverOptions(noise=NOISE, compliance=replace(compliance, released_friction=friction)),
    )
    assert weighed.adequacy.verdict == 'pass', (weighed.variance_factor, weighed.adequacy.reason)
    assert weighed.variance_factor < unweighed.variance_factor / 2.0
    estimate, std = weighed.compliance['link'], weighed.compliance_std['link']
    assert abs(estimate - LINK) < 3.3 * std, (estimate, std)
    # Nothing changes where no actuator is released or there is no friction.
    assert not replace(compliance, measuring_mode='lvdt', released=None,
                       released_friction=friction).weighs_friction
    with pytest.raises(ValueError, match='released_friction'):
        replace(compliance, released_friction=-1.0)


def test_the_calibration_builder_weighs_the_described_friction(tmp_path):
    from hexacal_identify.calibration_steps.calibration_run import (
        compliance_for_postures,
        released_friction_of,
    )
    from hexacal_msgs_py.physical_file import default_physical, write_physical_file

    shipped = default_physical('hexa_slide')
    assert released_friction_of('', 'hexa_slide') == shipped.released_coulomb > 0.0
    complete = tmp_path / 'machine.yaml'
    write_physical_file(complete, replace(shipped, released_coulomb=25.0))
    assert released_friction_of(str(complete), 'hexa_slide') == 25.0
    masses_only = tmp_path / 'masses.yaml'
    masses_only.write_text('platform: {mass: 20.0}\n')
    assert released_friction_of(str(masses_only), 'hexa_slide') == 0.0
    masses_only.write_text('platform: {mass: 20.0}\nreleased_friction: {coulomb: 7.5}\n')
    assert released_friction_of(str(masses_only), 'hexa_slide') == 7.5
    masses_only.write_text('released_friction: {coulomb: -1}\n')
    with pytest.raises(ValueError, match='released_friction.coulomb'):
        released_friction_of(str(masses_only), 'hexa_slide')
    names = ('slider_1', 'slider_2', 'slider_3', 'slider_4', 'slider_5', 'slider_6')
    passive = compliance_for_postures(
        'shared', MASSES, 'passive_actuator', ['slider_2', 'slider_5'], names,
        released_friction=25.0,
    )
    assert passive.weighs_friction and passive.released_friction == 25.0
    lvdt = compliance_for_postures('shared', MASSES, 'lvdt', None, names, released_friction=25.0)
    assert lvdt.released_friction == 0.0 and not lvdt.weighs_friction
