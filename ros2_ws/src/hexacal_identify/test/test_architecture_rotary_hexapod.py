"""
The rotary hexapod (6-RUS): its kinematics, derivatives, frames and identifiability.

IK on both crank branches, FK round trips on both, the analytic Jacobians
against central differences, frame motions against the exact frame change,
noise-free recovery from every nominal set and the ranks of every cost
function with the combinations each cannot see, named.
"""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_identify.core.architectures import architecture, default_parameters
from hexacal_identify.core.architectures.rotary_hexapod import (
    A_SLICE,
    ALPHA0_INDEX,
    AZ_INDEX,
    crank_ik,
    EL_INDEX,
    FIELDS_PER_CHAIN,
    MACHINE_BRANCH,
    R_INDEX,
    RotaryHexapod,
    RotaryHexapodParameters,
)
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.machine.kinematics import forward_kinematics, inverse_kinematics
from hexacal_identify.core.machine.measurements import FIXED, simulate_measurements, SPHERE
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.models import MODELS, ROTARY_HEXAPOD
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
import numpy as np
import pytest

ARCH = architecture(ROTARY_HEXAPOD)
TRUTH = default_parameters(ROTARY_HEXAPOD)
WORKSPACE = ARCH.default_workspace()


def _poses(n: int = 30, seed: int = 0, kind: str = SPHERE) -> np.ndarray:
    return sample_poses(TRUTH, n, np.random.default_rng(seed), kind, WORKSPACE)


# The other crank branch as a machine of its own: the generic FK runs on it unchanged.
_OTHER_BRANCH = RotaryHexapod(branch=-MACHINE_BRANCH)


@dataclass(frozen=True)
class _OtherBranchParameters(RotaryHexapodParameters):
    """The same 66 parameters, solved on the other crank branch."""


_OtherBranchParameters.architecture = _OTHER_BRANCH


def _rotation(vector: np.ndarray) -> np.ndarray:
    """Return exp([vector]x), the exact rotation of a rotation vector."""
    angle = float(np.linalg.norm(vector))
    k = np.asarray(vector) / angle
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew


def test_layout_and_default_machine_size():
    layout = MODELS[ROTARY_HEXAPOD]
    assert layout.title == 'Rotary hexapod (6-RUS)' and layout.n_parameters == 66
    assert layout.actuator_names == tuple(f'crank_{i}' for i in range(1, 7))
    assert layout.actuator_unit == 'rad'
    assert TRUTH.model == ROTARY_HEXAPOD
    base_radius = np.hypot(TRUTH.base_points[:, 0], TRUTH.base_points[:, 1])
    assert np.all((base_radius > 0.3) & (base_radius < 0.5))
    assert np.all((TRUTH.crank_lengths > 0.1) & (TRUTH.crank_lengths < 0.2))
    np.testing.assert_allclose(np.linalg.norm(TRUTH.axis_directions, axis=1), 1.0, atol=1e-15)


def test_ik_both_branches_close_every_chain():
    poses = _poses()
    for branch in (1, -1):
        legs = crank_ik(TRUTH, poses, branch)
        assert np.all(legs.reachable())
        # The crank tip on its circle and the rod at its length.
        tips = TRUTH.base_points + TRUTH.crank_lengths[:, None] * TRUTH.crank_directions(
            legs.actuators
        )
        rotations = legs.rotations
        joints = poses[:, None, :3] + np.einsum('nij,cj->nci', rotations, TRUTH.platform_points)
        np.testing.assert_allclose(
            np.linalg.norm(joints - tips, axis=2),
            np.broadcast_to(TRUTH.rod_lengths, (len(poses), 6)),
            atol=1e-12,
        )
        # The branch is the sign of E.t (module doc): the machine's rods hang below their cranks.
        assert np.all(np.sign(legs.leverage) == -branch)
    machine = inverse_kinematics(TRUTH, poses)
    np.testing.assert_array_equal(machine, crank_ik(TRUTH, poses, MACHINE_BRANCH).actuators)
    other = crank_ik(TRUTH, poses, -1).actuators
    assert np.min(np.abs(machine - other)) > 0.5  # the branches are well apart in the workspace
    with pytest.raises(ValueError, match='branch'):
        crank_ik(TRUTH, poses, 0)


@pytest.mark.parametrize('branch', [1, -1])
def test_ik_fk_round_trip_on_both_branches(branch):
    params = TRUTH if branch == MACHINE_BRANCH else _OtherBranchParameters(TRUTH.vector)
    poses = _poses(40, seed=3)
    readings = inverse_kinematics(params, poses)
    fk = forward_kinematics(params, readings, poses + np.array([2e-3] * 3 + [5e-3] * 3))
    assert np.all(fk.converged)
    np.testing.assert_allclose(fk.poses, poses, rtol=0, atol=1e-10)


@pytest.mark.parametrize('branch', [1, -1])
def test_pose_jacobian_matches_finite_differences(branch):
    arch = RotaryHexapod(branch)
    chains = arch.chains(TRUTH)
    poses = _poses(8, seed=5)
    analytic = arch.legs(chains, poses).pose_jacobian()
    step = 1e-6
    for k in range(6):
        delta = np.zeros(6)
        delta[k] = step
        numeric = (
            arch.legs(chains, poses + delta).actuators - arch.legs(chains, poses - delta).actuators
        ) / (2 * step)
        np.testing.assert_allclose(analytic[:, :, k], numeric, rtol=0, atol=2e-7)


@pytest.mark.parametrize('branch', [1, -1])
def test_parameter_blocks_match_finite_differences(branch):
    arch = RotaryHexapod(branch)
    poses = _poses(8, seed=6)
    analytic = arch.legs(arch.chains(TRUTH), poses).parameter_blocks(arch.chains(TRUTH))
    assert analytic.shape == (8, 6, FIELDS_PER_CHAIN)
    step = 1e-6
    for chain in range(6):
        for field in range(FIELDS_PER_CHAIN):
            index = chain * FIELDS_PER_CHAIN + field
            up, down = TRUTH.vector.copy(), TRUTH.vector.copy()
            up[index] += step
            down[index] -= step
            numeric = (
                arch.legs(arch.chains(TRUTH.with_vector(up)), poses).actuators
                - arch.legs(arch.chains(TRUTH.with_vector(down)), poses).actuators
            ) / (2 * step)
            # Only chain `chain` depends on its own parameters.
            np.testing.assert_allclose(numeric[:, chain], analytic[:, chain, field], atol=2e-7)
            others = np.delete(numeric, chain, axis=1)
            assert np.max(np.abs(others)) == 0.0


def test_frame_motion_is_the_first_order_of_the_exact_frame_change():
    rng = np.random.default_rng(7)
    for _ in range(3):
        omega_base, omega_platform = rng.normal(size=3), rng.normal(size=3)
        eps = 1e-6
        moved = ARCH.in_frames(TRUTH, _rotation(eps * omega_base), _rotation(eps * omega_platform))
        exact = (moved.vector - TRUTH.vector) / eps
        first_order = ARCH.frame_motion(
            TRUTH, base_rotation=omega_base, platform_rotation=omega_platform
        )
        np.testing.assert_allclose(exact, first_order, rtol=0, atol=1e-5)


def test_in_frames_is_the_same_machine():
    # A base rotation about z and a platform rotation about z' (the pose's phi): the readings of
    # the machine in the turned frames at the turned poses equal the original readings.
    turn, spin = 0.4, -0.3
    base_rotation = _rotation(np.array([0.0, 0.0, turn]))
    platform_rotation = _rotation(np.array([0.0, 0.0, spin]))
    moved = ARCH.in_frames(TRUTH, base_rotation, platform_rotation)
    poses = _poses(10, seed=8)
    poses[:, 3:5] = 0.0  # pure rotations about z: phi adds
    turned = poses.copy()
    turned[:, :3] = poses[:, :3] @ base_rotation.T
    turned[:, 5] = poses[:, 5] + turn - spin  # R' = R_base R R_platform^T
    np.testing.assert_allclose(
        inverse_kinematics(moved, turned), inverse_kinematics(TRUTH, poses), atol=1e-12
    )


def test_actuator_zero_shift_is_a_crank_zero():
    name, delta = ARCH.actuator_zero_shift(TRUTH, 2)
    assert 'chain_3' in name and 'alpha0' in name
    poses = _poses(5, seed=9)
    shifted = inverse_kinematics(TRUTH.with_vector(TRUTH.vector + 1e-3 * delta), poses)
    np.testing.assert_allclose(shifted - inverse_kinematics(TRUTH, poses), np.where(
        np.arange(6) == 2, -1e-3, 0.0
    )[None].repeat(5, 0), atol=1e-12)


def _measurements(seed: int = 0):
    sphere, fixed = _poses(40, seed), _poses(40, seed + 1, FIXED)
    kinds = np.array([SPHERE] * len(sphere) + [FIXED] * len(fixed))
    return simulate_measurements(TRUTH, np.vstack([sphere, fixed]), kinds)


@pytest.mark.parametrize('set_number', [1, 2, 3])
def test_noise_free_identification_recovers_every_nominal_set(set_number):
    nominal = nominal_set(set_number, seed=1, model=ROTARY_HEXAPOD)
    assert np.max(np.abs(nominal.vector - TRUTH.vector)) > 1e-3
    result = identify(nominal, _measurements(), SolverOptions())
    assert result.reason == CONVERGED and result.rank == 66
    # 1e-9 m on lengths and 1e-9 rad on angles (the vector is SI: m and rad).
    np.testing.assert_allclose(result.parameters.vector, TRUTH.vector, rtol=0, atol=1e-9)


# Rank and the named combinations each cost function cannot see (core/identifiability names them
# from the architecture's frame_motion and the machine's scale).  Angles as readings make the
# machine's size invisible to the relative cost (eqs. 12, 13 see differences only), which no
# slider machine has.  The fixed cost sees each chain only through its platform joint on a sphere
# about the fixed point: besides the base rotation about Y through it, combinations of the rod
# lengths l with the crank circles' heights Az it cannot see (listed, not named).
EXPECTED_NULL = {
    'absolute': (66, []),
    'sphere': (65, ['a rotation of the base frame about Y']),
    'sphere-fixed': (66, []),
    'relative': (
        64,
        [
            'a rotation of the base frame about Y',
            'a scaling of the machine about the base origin (every length, the angles kept)',
        ],
    ),
}


@pytest.mark.parametrize('cost', sorted(EXPECTED_NULL))
def test_identifiability_per_cost_function(cost):
    rank, named = EXPECTED_NULL[cost]
    options = SolverOptions(cost=cost, allow_rank_deficient=True)
    report = identify(TRUTH, _measurements(), options).identifiability
    assert report.n_parameters == 66 and report.rank == rank
    assert [d.description for d in report.null_directions] == named


def test_fixed_cost_cannot_see_rod_lengths_against_crank_heights():
    options = SolverOptions(cost='fixed', allow_rank_deficient=True)
    report = identify(TRUTH, _measurements(), options).identifiability
    assert report.rank == 59
    descriptions = [d.description for d in report.null_directions]
    assert descriptions[0] == (
        'a rotation of the base frame about the Y axis through the fixed-position point '
        '[0, 0, -0.75] m'
    )
    assert len(descriptions) == 7
    for direction in report.null_directions[1:]:
        assert direction.description.startswith('parameters that move together')
        fields = {name.split('.')[1] for name in direction.coefficients}
        assert fields <= {'l', 'Az', 'Ax', 'Ay'} and 'l' in fields


def test_parameters_file_round_trip_and_physical_checks(tmp_path):
    path = tmp_path / 'rotary.yaml'
    save_parameters(path, TRUTH.vector, model=ROTARY_HEXAPOD)
    text = path.read_text()
    assert f'model: {ROTARY_HEXAPOD}' in text and 'chain_6.alpha0: ' in text
    contents = read_parameters_file(path)
    assert contents.model == ROTARY_HEXAPOD
    assert contents.vector.tobytes() == TRUTH.vector.tobytes()
    vertical = TRUTH.vector.copy()
    vertical[1 * FIELDS_PER_CHAIN + EL_INDEX] = np.pi / 2
    assert 'chain_2.axis_el must be within' in MODELS[ROTARY_HEXAPOD].physical_problem(vertical)
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text.replace('chain_4.r: ', 'chain_4.r: -'))
    with pytest.raises(ParameterFileError, match=r'chain_4\.r must be > 0 m \(the crank length\)'):
        read_parameters_file(bad)


def test_field_indices_follow_the_layout():
    layout = MODELS[ROTARY_HEXAPOD]
    assert layout.fields[A_SLICE] == ('Ax', 'Ay', 'Az')
    assert layout.fields[R_INDEX] == 'r' and layout.fields[ALPHA0_INDEX] == 'alpha0'
    assert layout.fields[AZ_INDEX] == 'axis_az' and layout.fields[EL_INDEX] == 'axis_el'


def test_acceptable_poses_and_joint_limits():
    poses = sample_poses(TRUTH, 200, np.random.default_rng(11), SPHERE, WORKSPACE)
    crank_cos, platform_cos = ARCH.joint_cosines(TRUTH, poses)
    assert np.all(crank_cos > WORKSPACE.min_joint_cosine)
    assert np.all(platform_cos > WORKSPACE.min_joint_cosine)
    low, high = WORKSPACE.actuator_stroke_m
    readings = inverse_kinematics(TRUTH, poses)
    assert np.all((readings >= low) & (readings <= high))
    # Lower the platform until a rod cannot reach: rejected, and IK says why.
    far = np.array([[0.0, 0.0, -2.0, 0.0, 0.0, 0.0]])
    assert not ARCH.acceptable_poses(TRUTH, far, WORKSPACE)[0]
    with pytest.raises(Exception, match='a rod cannot reach its crank circle'):
        inverse_kinematics(TRUTH, far)


def test_drawing_joins_cranks_and_rods():
    pose = _poses(1, seed=12)[0]
    drawn = ARCH.drawing(TRUTH, pose)
    np.testing.assert_allclose(drawn['cranks'][:, 1], drawn['rods'][:, 0])
    np.testing.assert_allclose(drawn['rods'][:, 1], drawn['platform_joints'])
    np.testing.assert_allclose(
        np.linalg.norm(drawn['rods'][:, 1] - drawn['rods'][:, 0], axis=1), TRUTH.rod_lengths,
        atol=1e-12,
    )
    np.testing.assert_allclose(
        np.linalg.norm(drawn['cranks'][:, 1] - drawn['cranks'][:, 0], axis=1),
        TRUTH.crank_lengths, atol=1e-12,
    )


def test_the_link_length_offset_is_the_machines_size():
    # Nothing a rotary hexapod reads carries a length but the device's link: its offset dL cannot
    # be told from a scaling of the whole machine (a slider machine's readings tell them apart).
    options = SolverOptions(free_device=('dL',), allow_rank_deficient=True)
    report = identify(TRUTH, _measurements(), options).identifiability
    assert report.rank == 66
    assert [d.description for d in report.null_directions] == [
        "the device's dL cannot be told apart from a scaling of the machine about the base origin "
        '(every length, the angles kept)'
    ]
    slide = default_parameters('hexa_slide')
    poses = sample_poses(slide, 40, np.random.default_rng(0), SPHERE)
    slide_report = identify(slide, simulate_measurements(slide, poses), options).identifiability
    assert slide_report.identifiable
