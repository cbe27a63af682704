"""Posture planning: observability indices, greedy / exchange selection, limits, plan files."""


from hexacal_identify.core.machine.model import table1_parameters
from hexacal_identify.core.planning.candidate_set import build_candidate_set
from hexacal_identify.core.planning.observability import (
    INDICES,
    observability_index,
    observability_indices,
)
from hexacal_identify.core.planning.planner import Plan, plan_postures
from hexacal_identify.core.planning.posture_limits import generate_candidates, PostureLimits
from hexacal_identify.core.planning.selection import exchange_design, greedy_design
import numpy as np
import pytest

NOMINAL = table1_parameters()


def test_indices_of_a_matrix_with_known_singular_values():
    rng = np.random.default_rng(0)
    sigma = np.array([4.0, 2.0, 1.0, 0.5])
    u, _ = np.linalg.qr(rng.standard_normal((10, 4)))
    v, _ = np.linalg.qr(rng.standard_normal((4, 4)))
    jacobian = u @ np.diag(sigma) @ v.T
    m = 5  # postures
    expected = {
        'O1': (4 * 2 * 1 * 0.5) ** 0.25 / np.sqrt(m),
        'O2': 0.5 / 4,
        'O3': 0.5,
        'O4': 0.25 / 4,
    }
    for name, value in expected.items():
        assert observability_index(jacobian, m, name, scales=np.ones(4)) == pytest.approx(
            value, rel=1e-12
        )
    assert observability_indices(sigma[::-1], m) == pytest.approx(expected, rel=1e-12)
    # Column scaling: scaling a column and passing that scale gives the same indices back.
    scaled = jacobian * [1.0, 1e3, 1.0, 1e-2]
    assert observability_index(
        scaled, m, 'O3', scales=np.array([1.0, 1e3, 1.0, 1e-2])
    ) == pytest.approx(0.5)
    assert observability_indices(np.array([3.0, 0.0]), 1) == {name: 0.0 for name in INDICES}


@pytest.fixture(scope='module')
def candidates():
    poses, kinds = generate_candidates(
        NOMINAL, 400, np.random.default_rng(1), PostureLimits(), fixed_fraction=0.25
    )
    return build_candidate_set(NOMINAL, poses, kinds, 'sphere-fixed')


def test_greedy_picks_the_best_candidate_and_never_lowers_the_criterion(candidates):
    design, history = greedy_design(candidates, 24, 'O1')
    assert len(set(design.tolist())) == 24
    assert np.all(np.diff(history) > 0)  # log det(M + delta I) grows with every pick
    # Once full rank, O1 of every prefix is what greedy maximised: check the last pick by brute
    # force.
    prefix = design[:-1]
    best = max(
        candidates.indices(np.append(prefix, c))['O1']
        for c in np.setdiff1d(np.arange(len(candidates)), prefix)
    )
    assert candidates.indices(design)['O1'] == pytest.approx(best, rel=1e-9)
    ranks = [np.linalg.matrix_rank(candidates.design_jacobian(design[:k])) for k in (5, 15, 24)]
    assert ranks == sorted(ranks) and ranks[-1] == 54


@pytest.mark.slow
@pytest.mark.parametrize('index', ['O1', 'O3', 'I'])
def test_exchange_improves_on_greedy_monotonically(candidates, index):
    start, _ = greedy_design(candidates, 20, index)
    design, history = exchange_design(candidates, start, index, max_passes=3)
    assert np.all(np.diff(history) > 0)
    if index == 'I':  # a predicted error: lower is better
        assert candidates.predicted_position_error(design) <= candidates.predicted_position_error(
            start
        )
    else:
        assert candidates.indices(design)[index] >= candidates.indices(start)[index]
    assert len(set(design.tolist())) == 20


@pytest.mark.parametrize('weighted', [False, True])
def test_planned_20_postures_beat_random_20_on_o1(weighted):
    from hexacal_identify.core.machine.measurements import NoiseModel

    planning = plan_postures(
        NOMINAL,
        20,
        n_candidates=1000,
        seed=3,
        noise=NoiseModel.from_microns(10) if weighted else None,
    )
    random = planning.random_indices(draws=30, seed=4)
    assert planning.indices['O1'] > 1.3 * random['O1']
    assert planning.indices['O3'] > random['O3']
    assert planning.indices['I'] < random['I']  # predicted position error


def test_i_optimal_plan_predicts_a_smaller_position_error_than_the_d_optimal_one():
    from hexacal_identify.core.machine.measurements import NoiseModel

    noise = NoiseModel.from_microns(10)
    d_optimal = plan_postures(NOMINAL, 25, index='O1', n_candidates=1000, seed=8, noise=noise)
    i_optimal = plan_postures(NOMINAL, 25, index='I', n_candidates=1000, seed=8, noise=noise)
    assert i_optimal.indices['I'] < d_optimal.indices['I']
    assert (
        d_optimal.indices['O1'] >= i_optimal.indices['O1'] * 0.999
    )  # each wins on its own criterion
    assert (
        1e-6 < i_optimal.indices['I'] < 1e-4
    )  # metres: the weighted fit predicts a few um to tens of um


def test_the_exchange_selection_of_25_of_2000_is_at_least_as_good_as_the_greedy_one():
    # Its speed is measured in benchmarks/bench_plan_speed.py, not here.
    greedy = plan_postures(NOMINAL, 25, n_candidates=2000, method='greedy')
    exchange = plan_postures(NOMINAL, 25, n_candidates=2000, method='exchange')
    assert exchange.indices['O1'] >= greedy.indices['O1']


@pytest.mark.parametrize('cost', ['absolute', 'sphere-fixed', 'relative'])
def test_every_planned_posture_respects_every_limit(cost):
    limits = PostureLimits(
        inclinometer_range_rad=np.radians(30.0),
        max_u_joint_angle_rad=np.radians(45.0),
        max_s_joint_angle_rad=np.radians(80.0),
        actuator_stroke_m=(0.05, 0.85),
        max_condition=60.0,
    )
    planning = plan_postures(NOMINAL, 30, n_candidates=600, cost=cost, limits=limits, seed=5)
    plan = planning.plan
    checks = limits.check(NOMINAL, plan.poses)
    for name, ok in checks.items():
        assert ok.all(), f'limit {name} violated by postures {np.flatnonzero(~ok).tolist()}'
    fixed = plan.kinds == 'fixed'
    np.testing.assert_allclose(
        plan.poses[fixed, :3], np.tile([0.0, 0.0, -limits.link_length], (fixed.sum(), 1))
    )
    # The limits bite: the same draw without them contains postures that break them.
    loose = PostureLimits(
        inclinometer_range_rad=np.radians(90.0),
        max_u_joint_angle_rad=np.radians(89.0),
        max_s_joint_angle_rad=np.radians(179.0),
    )
    poses, _ = generate_candidates(NOMINAL, 600, np.random.default_rng(6), loose)
    assert not limits.feasible(NOMINAL, poses).all()
    if cost in ('sphere-fixed', 'relative'):
        assert fixed.any() and (~fixed).any()  # these costs need both kinds (eqs. 8/12 and 10/13)


def test_plan_file_round_trip(tmp_path):
    planning = plan_postures(NOMINAL, 16, n_candidates=500, cost='sphere-fixed', seed=7)
    path = planning.plan.save(tmp_path / 'plans' / 'plan.yaml')
    assert not [
        p for p in path.parent.iterdir() if p.name != 'plan.yaml'
    ]  # atomic: no temporary left
    loaded = Plan.load(path)
    assert loaded.name == planning.plan.name and loaded.name.endswith(planning.plan.fingerprint())
    assert loaded.link_length == 0.75
    np.testing.assert_array_equal(loaded.poses, planning.plan.poses)  # repr floats: exact
    np.testing.assert_array_equal(loaded.kinds, planning.plan.kinds)
    assert loaded.metadata['index'] == 'O1' and loaded.metadata['cost'] == 'sphere-fixed'


def test_bad_plan_files_are_refused(tmp_path):
    path = tmp_path / 'bad.yaml'
    path.write_text(
        'plan: {name: x, link_length: 0.75}\n'
        'postures: [{kind: wobbly, pose: [0, 0, -0.75, 0, 0, 0]}]\n'
    )
    with pytest.raises(ValueError, match='kind'):
        Plan.load(path)
    path.write_text('postures: []\n')
    with pytest.raises(ValueError, match='not a plan file'):
        Plan.load(path)
    path.write_text('plan: {name: x\n  : [broken\n')
    with pytest.raises(ValueError, match='not readable as a plan file'):
        Plan.load(path)
    with pytest.raises(ValueError, match='observability index'):
        plan_postures(NOMINAL, 5, index='O9', n_candidates=50)


def test_plan_command_writes_a_plan(tmp_path, capsys):
    import json

    from hexacal_identify.cli import main

    out = tmp_path / 'plan.yaml'
    code = main(
        [
            'plan',
            '--postures',
            '18',
            '--index',
            'O1',
            '--method',
            'exchange',
            '--candidates',
            '400',
            '--cost',
            'sphere-fixed',
            '--seed',
            '2',
            '--out',
            str(out),
            '--json',
        ]
    )
    assert code == 0
    printed = capsys.readouterr()
    summary = json.loads(printed.out)  # --json: one JSON object, nothing else
    assert printed.err == ''
    assert (
        summary['postures'] == 18
        and summary['indices']['O1'] > summary['random_mean_indices']['O1']
    )
    plan = Plan.load(out)
    assert plan.name == summary['name'] and len(plan) == 18
    assert plan.metadata['method'] == 'exchange' and plan.metadata['cost'] == 'sphere-fixed'
    assert (
        main(['plan', '--postures', '5', '--candidates', '2', '--out', str(tmp_path / 'x.yaml')])
        == 2
    )


@pytest.mark.slow
def test_study_plan_mode_prints_a_table_and_checks_the_claim(tmp_path, capsys):
    import json

    from hexacal_identify.cli import main

    code = main(
        [
            'study',
            '--plan',
            '--plan-ks',
            '25',
            '--plan-seeds',
            '1',
            '--candidates',
            '500',
            '--json',
        ]
    )
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    assert result['ks'] == [25, 50]
    assert set(result['variants']) == {
        'random',
        'planned-O1',
        'planned-I',
        'planned-O1-unweighted',
    }
    for variant in result['variants'].values():
        assert all(v is None or 0 < v < 1e-3 for v in variant['position_mean_m'])
    assert set(result['claims']) == {'planned-O1', 'planned-I', 'planned-O1-unweighted'}
    code = main(
        [
            'study',
            '--plan',
            '--plan-ks',
            '25',
            '--plan-seeds',
            '1',
            '--candidates',
            '500',
            '--out',
            str(tmp_path),
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert (
        'claim (planned-O1)' in printed
        and (tmp_path / 'plan_accuracy_vs_postures.png').stat().st_size > 1000
    )
