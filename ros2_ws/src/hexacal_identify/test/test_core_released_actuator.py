"""
Choosing the released actuator of a passive-actuator plan, and the plans that carry it (#18).

The chooser prefers the best-conditioned release, refuses one that leaves its stroke along
the move, says so when none is left; planning writes the mode and the released actuators into
the plan, which every reader reads back, and a plan without a mode is written as before.
"""

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.kinematics import inverse_kinematics
from hexacal_identify.core.measuring_plan import check_measuring_mode
from hexacal_identify.core.passive_actuator import release_conditions
from hexacal_identify.core.planning import Plan, plan_postures
from hexacal_identify.core.postures import sample_poses
from hexacal_identify.core.released_actuator import (
    choose_released_actuators,
    move_samples,
    ReleaseError,
)
from hexacal_msgs_py.plan_file import read_plan_file
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')


def _poses(model: str, count: int, seed: int):
    params = default_parameters(model)
    workspace = params.architecture.default_workspace()
    poses = np.array(sample_poses(params, count, np.random.default_rng(seed), 'sphere', workspace))
    return params, poses, workspace


@pytest.mark.parametrize('model', MODELS)
def test_with_a_wide_stroke_the_best_conditioned_actuator_is_released(model):
    params, poses, workspace = _poses(model, 20, 4)
    length = workspace.link_length
    choice = choose_released_actuators(params, poses, length, (-10.0, 10.0))
    conditions = release_conditions(params, poses, length)
    np.testing.assert_array_equal(choice.released, np.argmin(conditions, axis=1))
    assert np.all(choice.chosen_conditions <= choice.worst_conditions)
    assert np.median(choice.worst_conditions) > 2 * np.median(choice.chosen_conditions)
    names = choice.names(params.layout.actuator_names)
    assert len(names) == 20 and set(names) <= set(params.layout.actuator_names)


def _leaving_case():
    """
    Return a Hexa Slide move whose best release leaves its stroke (less the margin) mid-move.

    The stroke is set so that the executor takes the direct path (all six inside) and the
    margin so that the best release is inside it at both ends of the move but not in the
    middle, while another chain stays inside all along.  Both stroke ends are tried (the
    actuators mirrored for the low one).
    """
    params, poses, workspace = _poses('hexa_slide', 60, 3)
    length = workspace.link_length
    for i in range(len(poses) - 1):
        pair = poses[i:i + 2]
        along, owners, _ = move_samples(params, pair, length, (-10.0, 10.0), 0.005)
        along = along[owners == 1]
        ends = inverse_kinematics(params, pair)
        best = int(np.argmin(release_conditions(params, pair, length)[1]))
        for sign in (1.0, -1.0):  # the high end, then the low one
            values, at_ends = sign * along, sign * ends
            peak, end = values[:, best].max(), at_ends[:, best].max()
            lowest_other = min(values[:, c].max() for c in range(6) if c != best)
            threshold = (peak + max(end, lowest_other)) / 2
            if peak > max(end, lowest_other) + 2e-4:
                far, near = values.min() - 1.0, values.max() + 5e-4  # all six inside
                stroke = (far, near) if sign > 0 else (-near, -far)
                return params, pair, length, best, stroke, near - threshold
    raise AssertionError('no such move among the drawn postures')


def test_an_actuator_that_leaves_its_stroke_along_the_move_is_not_released():
    params, pair, length, best, stroke, margin = _leaving_case()
    wide = choose_released_actuators(params, pair, length, (-10.0, 10.0))
    assert wide.released[1] == best
    narrow = choose_released_actuators(params, pair, length, stroke, margin_m=margin)
    assert not narrow.via_centre[1]  # the direct move, as the executor would take it
    assert narrow.released[1] != best and not narrow.inside[1, best]
    assert narrow.inside[1, narrow.released[1]]
    assert narrow.chosen_conditions[1] > wide.chosen_conditions[1]  # the price of the stroke
    with pytest.raises(ReleaseError, match='no actuator can be released') as error:
        choose_released_actuators(params, pair, length, stroke, margin_m=0.45)
    assert str(error.value).startswith(f'posture {error.value.posture}: ')
    assert 'slider_1, slider_2, slider_3, slider_4, slider_5, slider_6 leaves' in str(error.value)


def test_a_move_that_leaves_the_stroke_goes_by_way_of_the_centre():
    params, poses, workspace = _poses('hexa_slide', 12, 5)
    length = workspace.link_length
    wide = choose_released_actuators(params, poses, length, (-10.0, 10.0), margin_m=0.0)
    assert not np.any(wide.via_centre)
    # A stroke that the highest posture's top actuator overshoots by 0.1 mm: the moves into
    # and out of it leave the stroke on the direct path, so the executor goes by the centre.
    tops = np.sort(inverse_kinematics(params, poses).max(axis=1))
    stroke = (-10.0, float(tops[-1]) - 1e-4)
    along, owners, _ = move_samples(params, poses, length, (-10.0, 10.0))
    leaves = np.array([np.any(along[owners == k] > stroke[1]) for k in range(12)])
    leaves[0] = False  # posture 0 has no move: where the machine starts is unknown
    assert np.any(leaves)
    choice = choose_released_actuators(params, poses, length, stroke, margin_m=0.0)
    np.testing.assert_array_equal(choice.via_centre, leaves)
    assert np.all(choice.inside[np.arange(12), choice.released])


@pytest.mark.parametrize('model', MODELS)
def test_a_passive_plan_carries_its_released_actuators_through_every_reader(tmp_path, model):
    params = default_parameters(model)
    result = plan_postures(params, 12, n_candidates=300, measuring_mode='passive_actuator')
    plan = result.plan
    assert plan.measuring_mode == 'passive_actuator'
    release = result.measuring.release
    assert plan.released_actuators == release.names(params.layout.actuator_names)
    plain = plan_postures(params, 12, n_candidates=300).plan
    assert plain.name == plan.name  # the fingerprint names the postures, not the mode
    path = plan.save(tmp_path / 'passive.yaml')
    back = Plan.load(path)
    assert back.measuring_mode == 'passive_actuator'
    assert back.released_actuators == plan.released_actuators
    assert back.to_text() == path.read_text()
    contract = read_plan_file(path)  # the format's owner, which the driver's reader extends
    assert contract.released_actuators == plan.released_actuators
    text = plain.to_text()
    assert 'measuring_mode' not in text and 'released_actuator' not in text


@pytest.mark.parametrize('model', MODELS)
def test_an_lvdt_plan_reports_its_extensions_and_gains(model):
    params, poses, workspace = _poses(model, 8, 2)
    check = check_measuring_mode(
        params, poses, workspace.link_length, workspace.actuator_stroke_m, 'lvdt', 0.005
    )
    assert check.release is None and check.lvdt.inside
    assert np.max(np.abs(check.lvdt.extensions)) < 1e-9  # planned on the sphere
    assert np.all(check.lvdt.gains > 0.5)  # an actuator error does extend the link
    assert check.lvdt.tolerated_error_m == pytest.approx(0.005 / np.max(check.lvdt.gains))
    compliant = check_measuring_mode(
        params, poses, workspace.link_length, workspace.actuator_stroke_m, 'compliant'
    )
    assert compliant.release is None and compliant.lvdt is None
    with pytest.raises(ValueError, match='measuring_mode must be one of'):
        check_measuring_mode(params, poses, 0.75, workspace.actuator_stroke_m, 'rigid')


def test_the_executor_warns_before_walking_a_plan_it_cannot_measure_as_made():
    from hexacal_identify.core.measuring_plan import walking_notice

    assert walking_notice(None) is None
    assert walking_notice('compliant') is None
    for mode in ('passive_actuator', 'lvdt'):
        notice = walking_notice(mode)
        assert mode in notice and 'all six actuators' in notice and 'torque-limited' in notice
