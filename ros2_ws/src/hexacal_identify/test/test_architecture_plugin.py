"""
A third architecture plugs in through its module and two registrations only.

The architecture below is defined here and nowhere else: a 6-SPS whose strut
encoders read the leg length through an affine map, ``|P + R B - A| = g lambda
+ r0`` (gain ``g``, offset ``r0`` per strut), 8 fields and 48 parameters per
machine.  Its contract layout goes through ``hexacal_msgs_py.models.register_model``
and its kinematics through ``core.architectures.register_architecture``; then
the generic code - nominal sets, posture sampling, simulated measurements, the
identification with its identifiability analysis, the parameters file - runs
on it unchanged: a noise-free calibration recovers the machine and its file
round-trips bit for bit, with its physical checks derived from the layout.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from hexacal_identify.core.architectures import (
    architecture,
    ARCHITECTURES,
    default_parameters,
    register_architecture,
)
from hexacal_identify.core.architectures.base import Architecture, KinematicParameters
from hexacal_identify.core.architectures.common import (
    condition_ok,
    move_joint_points,
    platform_point_derivatives,
    PlatformPoints,
    pose_jacobian_rows,
)
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.machine.kinematics import forward_kinematics, inverse_kinematics
from hexacal_identify.core.machine.measurements import simulate_measurements
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses, Workspace
from hexacal_msgs_py.errors import InvalidParametersError, ParameterFileError
from hexacal_msgs_py.models import ChainKey, ModelLayout, MODELS, PositiveField, register_model
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
import numpy as np
import pytest

NAME = 'test_gain_sps'
LAYOUT = ModelLayout(
    name=NAME,
    title='6-SPS with affine strut encoders (test)',
    fields=('Ax', 'Ay', 'Az', 'Bx', 'By', 'Bz', 'r0', 'g'),
    field_units=('m',) * 7 + ('1',),
    chain_keys=(
        ChainKey('A', 0, 3, 'base joint centre, base frame (m)'),
        ChainKey('B', 3, 3, 'platform joint centre, platform frame (m)'),
        ChainKey('r0', 6, None, 'strut length at reading zero (m)'),
        ChainKey('g', 7, None, 'strut length per unit of reading'),
    ),
    actuator_prefix='strut',
    actuator_description='strut reading lambda = (strut length - r0) / g',
    physical_checks=(PositiveField('r0'), PositiveField('g', ' (the encoder gain)')),
)


@dataclass(frozen=True)
class GainSpsParameters(KinematicParameters):
    """The 48 parameters of the test architecture, chain-major."""


class _Chains:
    """Per-chain constants, coordinate-major."""

    def __init__(self, params: KinematicParameters):
        per_chain = params.per_chain
        self.base = np.ascontiguousarray(per_chain[:, 0:3].T)
        self.platform = np.ascontiguousarray(per_chain[:, 3:6].T)
        self.offsets, self.gains = per_chain[:, 6].copy(), per_chain[:, 7].copy()


class _ChainIK:
    """lambda = (|P + R B - A| - r0) / g for N poses x 6 struts."""

    def __init__(self, chains: _Chains, poses: np.ndarray):
        points = PlatformPoints(chains.platform, chains.base, poses)
        self.tilt_trig, self.rotations, self.rotated = (
            points.tilt_trig,
            points.rotations,
            points.rotated,
        )
        self.legs = points.offsets
        self.lengths = np.sqrt(np.sum(self.legs * self.legs, axis=0))
        self.gains = chains.gains
        self.actuators = (self.lengths - chains.offsets) / chains.gains

    def subset(self, mask: np.ndarray) -> '_ChainIK':
        out = object.__new__(_ChainIK)
        out.tilt_trig, out.rotations = self.tilt_trig[:, mask], self.rotations[mask]
        out.rotated, out.legs = self.rotated[:, mask], self.legs[:, mask]
        out.lengths, out.actuators, out.gains = (
            self.lengths[mask],
            self.actuators[mask],
            self.gains,
        )
        return out

    def replace_rows(self, mask: np.ndarray, rows: '_ChainIK') -> None:
        self.rotations[mask], self.lengths[mask] = rows.rotations, rows.lengths
        self.actuators[mask] = rows.actuators
        self.tilt_trig[:, mask], self.rotated[:, mask] = rows.tilt_trig, rows.rotated
        self.legs[:, mask] = rows.legs

    def reachable(self) -> np.ndarray:
        return np.all(self.lengths > 0.0, axis=1)

    def unit_legs(self) -> np.ndarray:
        with np.errstate(divide='ignore', invalid='ignore'):
            return self.legs / self.lengths

    def pose_jacobian(self, unit: np.ndarray | None = None) -> np.ndarray:
        unit = self.unit_legs() if unit is None else unit
        return pose_jacobian_rows(self.rotated, unit / self.gains, self.tilt_trig)

    def parameter_blocks(self, chains: _Chains, unit: np.ndarray | None = None) -> np.ndarray:
        unit = self.unit_legs() if unit is None else unit
        blocks = np.empty(unit.shape[1:] + (8,))
        blocks[..., 0:3] = -unit.transpose(1, 2, 0)
        blocks[..., 3:6] = platform_point_derivatives(self.rotations, unit)
        blocks[..., 6] = -1.0
        blocks[..., 7] = -self.actuators
        return blocks / self.gains[None, :, None]


class GainSps(Architecture):
    """The test architecture (module docstring)."""

    name = NAME
    layout = LAYOUT
    parameters_type = GainSpsParameters
    unreachable_reason = 'a strut of zero length'
    nominal_error_stats_mm = {1: (1.8, 0.80, 0.87), 2: (2.8, 1.33, 1.45)}

    def default_parameters(self) -> KinematicParameters:
        # The default Gough-Stewart's joints and leg offsets, gains slightly off 1.
        per_chain = default_parameters('gough_stewart').per_chain
        gains = 1.0 + np.array([2.0, -1.0, 3.0, -2.0, 1.0, -3.0]) * 1e-3
        return GainSpsParameters(np.column_stack([per_chain, gains]).reshape(-1))

    def default_workspace(self) -> Workspace:
        return architecture('gough_stewart').default_workspace()

    def chains(self, params: KinematicParameters) -> _Chains:
        return _Chains(params)

    def legs(self, chains: _Chains, poses: np.ndarray) -> _ChainIK:
        return _ChainIK(chains, poses)

    def acceptable_poses(
        self, params: KinematicParameters, poses: np.ndarray, workspace: Workspace
    ) -> np.ndarray:
        legs = _ChainIK(_Chains(params), np.asarray(poses, dtype=float))
        low, high = workspace.actuator_stroke_m
        ok = legs.reachable() & np.all((legs.actuators >= low) & (legs.actuators <= high), axis=1)
        conditioned = np.zeros(len(poses), bool)
        if np.any(ok):
            conditioned[ok] = condition_ok(
                legs.subset(ok).pose_jacobian(), workspace.link_length, workspace.max_condition
            )
        return ok & conditioned

    def joint_cosines(
        self, params: KinematicParameters, poses: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        legs = _ChainIK(_Chains(params), np.asarray(poses, dtype=float))
        unit = legs.unit_legs()
        normal = legs.rotations[:, :, 2]
        return np.abs(unit[2]), np.abs(np.einsum('inc,ni->nc', unit, normal))

    def frame_motion(
        self,
        params: KinematicParameters,
        base_translation=None,
        base_rotation=None,
        platform_translation=None,
        platform_rotation=None,
    ) -> np.ndarray:
        delta = np.zeros((6, 8))
        move_joint_points(
            delta,
            params.base_points,
            params.platform_points,
            base_translation,
            base_rotation,
            platform_translation,
            platform_rotation,
        )
        return delta.reshape(-1)

    def actuator_zero_shift(
        self, params: KinematicParameters, chain: int
    ) -> tuple[str, np.ndarray]:
        # |d| = g (lambda + offset) + r0: an encoder zero offset is a change g * offset of r0.
        delta = np.zeros((6, 8))
        delta[chain, 6] = params.per_chain[chain, 7]
        return f"chain_{chain + 1}'s strut offset r0 (an encoder zero offset)", delta.reshape(-1)

    def in_frames(
        self,
        params: KinematicParameters,
        base_rotation: np.ndarray,
        platform_rotation: np.ndarray,
    ) -> KinematicParameters:
        per_chain = params.per_chain.copy()
        per_chain[:, 0:3] = per_chain[:, 0:3] @ base_rotation.T
        per_chain[:, 3:6] = per_chain[:, 3:6] @ platform_rotation.T
        return params.with_vector(per_chain.reshape(-1))

    def drawing(
        self, params: KinematicParameters, pose: np.ndarray, actuators: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        drawn = super().drawing(params, pose, actuators)
        base = params.base_points
        drawn.update(
            base_joints=base.copy(), legs=np.stack([base, drawn['platform_joints']], axis=1)
        )
        return drawn


@pytest.fixture(scope='module')
def arch() -> Iterator[Architecture]:
    """Register the test architecture (contract layout, then kinematics); forget it afterwards."""
    register_model(LAYOUT)
    instance = GainSps()
    GainSpsParameters.architecture = instance
    try:
        yield register_architecture(instance)
    finally:
        # Unregistering is for tests only: the built-in models stay as the other tests expect.
        ARCHITECTURES.pop(NAME, None)
        MODELS.pop(NAME, None)


def test_registration_makes_the_architecture_known_everywhere(arch):
    assert architecture(NAME) is arch and MODELS[NAME] is LAYOUT
    truth = default_parameters(NAME)
    assert truth.model == NAME and truth.vector.shape == (48,)
    assert LAYOUT.actuator_names == tuple(f'strut_{i}' for i in range(1, 7))
    assert LAYOUT.key_slices == {
        'A': slice(0, 3),
        'B': slice(3, 6),
        'r0': slice(6, 7),
        'g': slice(7, 8),
    }
    with pytest.raises(ValueError, match='already registered'):
        register_model(LAYOUT)
    with pytest.raises(ValueError, match='already registered'):
        register_architecture(arch)


def test_ik_fk_round_trip(arch):
    truth = arch.default_parameters()
    poses = sample_poses(truth, 40, np.random.default_rng(3), 'sphere', arch.default_workspace())
    readings = inverse_kinematics(truth, poses)
    fk = forward_kinematics(truth, readings, poses + 1e-3)
    np.testing.assert_allclose(fk.poses, poses, rtol=0, atol=1e-10)


def test_noise_free_identification_recovers_the_machine(arch):
    truth = arch.default_parameters()
    nominal = nominal_set(2, seed=1, model=NAME)
    assert nominal.model == NAME and np.max(np.abs(nominal.vector - truth.vector)) > 1e-3
    poses = sample_poses(truth, 30, np.random.default_rng(0), 'sphere', arch.default_workspace())
    result = identify(nominal, simulate_measurements(truth, poses), SolverOptions())
    assert result.reason == CONVERGED and result.parameters.model == NAME
    assert result.rank == 48 and result.identifiability.identifiable
    np.testing.assert_allclose(result.parameters.vector, truth.vector, rtol=0, atol=1e-9)


def test_identifiability_names_the_architectures_gauge(arch):
    # Without the absolute position the base rotation about Y is invisible (as for any model).
    truth = arch.default_parameters()
    poses = sample_poses(truth, 30, np.random.default_rng(0), 'sphere', arch.default_workspace())
    options = SolverOptions(cost='sphere', allow_rank_deficient=True)
    result = identify(truth, simulate_measurements(truth, poses), options)
    report = result.identifiability
    assert report.rank == 47 and len(report.null_directions) == 1
    assert 'rotation of the base frame about' in report.null_directions[0].description


def test_parameters_file_round_trip_and_physical_checks(arch, tmp_path):
    truth = arch.default_parameters()
    path = tmp_path / 'sps.yaml'
    save_parameters(path, truth.vector, model=NAME)
    text = path.read_text()
    assert f'model: {NAME}' in text and 'chain_6.g: ' in text
    contents = read_parameters_file(path)
    assert contents.model == NAME
    assert contents.vector.tobytes() == truth.vector.tobytes()
    # The layout's checks, by field name: chain 3's gain must be positive.
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text.replace('chain_3.g: ', 'chain_3.g: -'))
    with pytest.raises(ParameterFileError, match=r'chain_3\.g must be > 0 \(the encoder gain\)'):
        read_parameters_file(bad)
    vector = truth.vector.copy()
    vector[LAYOUT.parameter_index(2, 'r0')] = 0.0
    assert LAYOUT.physical_problem(vector) == 'chain_2.r0 must be > 0 m, got 0.0'
    with pytest.raises((InvalidParametersError, ValueError), match=r'chain_2\.r0'):
        save_parameters(tmp_path / 'zero.yaml', vector, model=NAME)


def test_mjcf_export_of_a_machine_without_its_mechanism_is_a_named_error(arch, tmp_path, capsys):
    # The architecture does not describe its mechanism: no MuJoCo model, said in one line.
    from hexacal_identify.cli import main

    parameters = tmp_path / 'sps.yaml'
    save_parameters(parameters, arch.default_parameters().vector, model=NAME)
    out = tmp_path / 'sps.xml'
    assert main(['export', str(parameters), '--format', 'mjcf', '--out', str(out)]) == 2
    err = capsys.readouterr().err
    assert f'the {NAME} architecture does not describe its mechanism' in err
    assert 'Traceback' not in err and not out.exists()
