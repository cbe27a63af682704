"""
The batched release rehearsal decides as the machine-by-machine one (the reference).

``Rehearser(batched=False)`` walks each move one machine and one candidate group at a time with
``solve_passive`` (release_rehearsal.rehearse); the default stacks every machine and candidate
in one Newton iteration (release_rehearsal.rehearse_stacked).  On seeded plans of both models
they must release the same actuators in the same order with the same jams, and leave the
machines standing at the same poses (closure to 1e-12 m).
"""

from hexacal_identify.core.architectures import Architecture, default_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import largest_conditions, release_conditions
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_identify.core.modes.release_moves import move
from hexacal_identify.core.modes.release_plan import in_order, RehearsalSettings, Rehearser, tour
from hexacal_identify.core.modes.release_rehearsal import (
    _sample_tolerance,
    MachineStack,
    predicted_starts,
    released_condition,
    sampled_machines,
    setpoint_samples,
    solve_stacked,
)
from hexacal_identify.core.modes.released_actuator import release_from_here
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')
CLOSURE_M = 1e-12


def _case(model: str, count: int, seed: int):
    params = default_parameters(model)
    workspace = params.architecture.default_workspace()
    poses = np.array(sample_poses(params, count, np.random.default_rng(seed), 'sphere', workspace))
    return params, poses, workspace


def _rehearsers(params, workspace, settings):
    return [
        Rehearser(params, workspace.link_length, workspace.actuator_stroke_m, 0.005, 0.01,
                  settings=settings, batched=batched)
        for batched in (True, False)
    ]


def _assert_same_legs(batched_legs, reference_legs):
    assert len(batched_legs) == len(reference_legs)
    for got, want in zip(batched_legs, reference_legs):
        assert got.released == want.released
        assert got.jams == want.jams
        assert got.worst == pytest.approx(want.worst, rel=1e-9)
        assert np.array_equal(np.isnan(got.ends.poses), np.isnan(want.ends.poses))
        assert np.nanmax(np.abs(got.ends.poses[:, :3] - want.ends.poses[:, :3])) <= CLOSURE_M
        assert np.nanmax(np.abs(got.ends.actuators - want.ends.actuators)) <= CLOSURE_M


@pytest.mark.slow
@pytest.mark.parametrize('model', MODELS)
def test_the_batched_tour_releases_what_the_reference_releases(model):
    params, poses, workspace = _case(model, 4, 7)
    # Machines far off the nominal (1 cm RMS) so that some candidates jam on the way.
    settings = RehearsalSettings(model_samples=1, model_error_m=0.01, seed=1, tour_tries=2)
    batched, reference = _rehearsers(params, workspace, settings)
    groups = np.zeros(len(poses), int)
    order, legs = tour(batched, poses, groups)
    want_order, want_legs = tour(reference, poses, groups)
    assert np.array_equal(order, want_order)
    _assert_same_legs(legs, want_legs)


@pytest.mark.parametrize('model', MODELS)
def test_the_batched_walk_in_order_from_a_start_matches_the_reference(model):
    params, poses, workspace = _case(model, 3, 8)
    settings = RehearsalSettings(model_samples=1, seed=2)
    batched, reference = _rehearsers(params, workspace, settings)
    start = poses[-1]
    _assert_same_legs(in_order(batched, poses[:2], start), in_order(reference, poses[:2], start))


@pytest.mark.parametrize('model', MODELS)
def test_the_stacked_newton_closes_as_solve_passive(model):
    params, poses, workspace = _case(model, 6, 5)
    length = workspace.link_length
    machines = sampled_machines(params, 3, 2e-3, seed=4)
    stack = MachineStack(machines)
    rng = np.random.default_rng(6)
    machine = rng.integers(0, len(machines), 3 * len(poses))
    released = rng.integers(0, 6, len(machine))
    targets = np.repeat(poses, 3, axis=0)
    commanded = np.array([
        stack.evaluate(np.array([k]), target[None])[0][0] for k, target in zip(machine, targets)
    ]) + rng.normal(0.0, 3e-3, (len(machine), 6))  # a few mm off: Newton has work to do
    solved = solve_stacked(stack, machine, commanded, released, targets, length)
    assert np.mean(solved.converged) > 0.5
    for i, k in enumerate(machine):
        one = solve_passive(machines[k], commanded[i][None], int(released[i]), targets[i][None],
                            length)
        assert bool(one.converged[0]) == bool(solved.converged[i])
        if one.converged[0]:
            assert np.max(np.abs(one.poses[0, :3] - solved.poses[i, :3])) <= CLOSURE_M
            assert np.max(np.abs(one.actuators[0] - solved.actuators[i])) <= CLOSURE_M
    ok = solved.converged
    conditions = released_condition(solved.jacobian[ok], solved.reachable[ok], solved.poses[ok],
                                    released[ok], length)
    for row, i in enumerate(np.flatnonzero(ok)):
        want = release_conditions(machines[machine[i]], solved.poses[i][None], length)[0]
        assert conditions[row] == pytest.approx(want[released[i]], rel=1e-9)


@pytest.mark.parametrize('model', MODELS)
def test_the_stacked_ik_is_each_machine_s_own(model):
    params, poses, _ = _case(model, 8, 2)
    machines = sampled_machines(params, 4, 2e-3)
    stack = MachineStack(machines)
    arch = params.architecture
    # Both shipped architectures vectorise the stacked IK (not the interface's looping default).
    assert type(arch).legs_stacked is not Architecture.legs_stacked
    machine = np.arange(len(poses)) % len(machines)
    actuators, jacobian, reachable = stack.evaluate(machine, poses)
    chains = [arch.chains(m) for m in machines]
    looped = Architecture.legs_stacked(arch, Architecture.stack_chains(arch, chains), machine,
                                       poses)
    assert np.array_equal(looped.actuators, actuators)
    assert np.allclose(looped.pose_jacobian, jacobian, rtol=1e-13, atol=1e-15)
    assert np.array_equal(looped.reachable, reachable)
    for i, k in enumerate(machine):
        arch = machines[k].architecture
        legs = arch.legs(arch.chains(machines[k]), poses[i][None])
        assert np.allclose(actuators[i], legs.actuators[0], rtol=0, atol=1e-15)
        assert np.allclose(jacobian[i], legs.pose_jacobian()[0], rtol=1e-13, atol=1e-15)
        assert reachable[i] == legs.reachable()[0]


@pytest.mark.parametrize('model', MODELS)
def test_rows_gathered_once_evaluate_as_the_stacked_ik(model):
    params, poses, _ = _case(model, 8, 3)
    machines = sampled_machines(params, 3, 2e-3)
    stack = MachineStack(machines)
    machine = np.arange(len(poses)) % len(machines)
    want = stack.evaluate(machine, poses)
    rows = stack.rows(machine)
    # The continuation evaluates the same gathered rows at new poses every Newton pass.
    for at in (poses, poses + 1e-3):
        got = stack.evaluate_rows(rows, at)
        expected = want if at is poses else stack.evaluate(machine, at)
        for a, b in zip(got, expected):
            assert np.array_equal(a, b)


@pytest.mark.slow
def test_release_from_here_batched_matches_the_reference():
    params, poses, workspace = _case('hexa_slide', 2, 9)
    length, stroke = workspace.link_length, workspace.actuator_stroke_m
    here, target = poses
    arch = params.architecture
    actuators = arch.legs(arch.chains(params), here[None]).actuators[0]
    settings = RehearsalSettings(model_samples=1)
    answers = []
    for batched in (True, False):
        answers.append([
            release_from_here(params, here, actuators, released, target, length, stroke, (),
                              rehearsal=settings, prefer=prefer, batched=batched)
            for released, prefer in ((0, 3), (2, None))
        ])
    assert answers[0] == answers[1]
    assert all(answer is not None for answer in answers[0])


def test_the_predicted_starts_save_newton_steps_on_the_same_branch():
    # A move walked sample by sample as the rehearsal walks it, with and without the prediction:
    # the samples on the way close in fewer Newton steps, and on the same branch.
    params, poses, workspace = _case('hexa_slide', 2, 11)
    length, stroke = workspace.link_length, workspace.actuator_stroke_m
    nominal = move(params, poses[0], poses[1], length, stroke, 0.01)
    released = int(np.argmin(np.max(release_conditions(params, nominal.poses, length), axis=0)))
    setpoints = setpoint_samples(np.zeros((1, 6)), nominal.actuators, 0.01)[:, 0]
    assert len(setpoints) > 10  # enough samples for the prediction to matter

    def walk(predict: bool) -> tuple[np.ndarray, int, int]:
        here, tangent = nominal.poses[:1].copy(), np.full((1, 6), np.nan)
        iterations, predicted = 0, 0
        for s, sample in enumerate(setpoints):
            tolerance = float(_sample_tolerance(s, len(setpoints)))
            starts, tangent = predicted_starts(
                params, sample[None], np.array([released]), here, tangent, length, tolerance,
                predict=predict and s > 0,
            )
            predicted += int(not np.array_equal(starts, here))
            solved = solve_passive(params, sample[None], released, starts, length,
                                   tolerance=tolerance)
            assert solved.converged[0], solved.failures
            iterations += int(solved.iterations[0])
            here = solved.poses
        return here[0], iterations, predicted

    end, steps, predicted = walk(True)
    plain_end, plain_steps, none = walk(False)
    assert none == 0
    assert predicted >= len(setpoints) // 2
    # A prediction costs what a Newton step does (one evaluation): 38 against 67 steps here.
    assert steps + predicted < 0.75 * plain_steps
    assert np.max(np.abs(end - plain_end)) <= 1e-9


def test_the_largest_condition_per_group_is_the_svd_s_taken_only_where_it_can_be():
    # Well and badly conditioned 6x6 systems, one exactly singular group apart: the maximum per
    # group equals np.linalg.cond's, bit for bit, whichever matrices the SVD was taken on.
    rng = np.random.default_rng(7)
    systems = rng.normal(size=(600, 6, 6))
    near = rng.choice(600, 40, replace=False)
    systems[near, 5] = systems[near, 4] + rng.normal(scale=1e-9, size=(40, 6))  # cond ~1e9
    groups = rng.integers(0, 25, size=600)
    want = np.zeros(26)
    np.maximum.at(want, groups, np.linalg.cond(systems))
    assert np.array_equal(largest_conditions(systems, groups, 26), want)  # group 25 empty: 0
    singular = systems.copy()
    singular[3, 2] = 0.0
    singular[3, :, 2] = 0.0
    singular[3, 2, 2] = 0.0
    singular[3, 1] = singular[3, 0]
    with np.errstate(divide='ignore'):
        want_singular = np.zeros(26)
        np.maximum.at(want_singular, groups, np.linalg.cond(singular))
        assert np.array_equal(largest_conditions(singular, groups, 26), want_singular)
