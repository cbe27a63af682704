"""``hexacal study --device-defects ... --procedure NAME --device-prior ...`` as a user runs it."""

import json

from system_support import hexacal

DEFECTS = 'dL=0.0005,alpha0=2e-4,beta0=-1.5e-4,gamma=1e-4,phi0=1e-4'


def study_json(*extra):
    done = hexacal(
        'study',
        '--json',
        '--postures',
        50,
        '--noise-um',
        10,
        '--seed',
        6,
        '--weighted',
        '--device-defects',
        DEFECTS,
        *extra,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_quarter_turns_identify_the_zero_offsets_and_judge_in_the_true_frames(tmp_path):
    turned = study_json(
        '--procedure', 'quarter-turns', '--identify-device', 'dL,alpha0,beta0,gamma'
    )
    assert turned['study']['procedure'] == 'quarter-turns'
    assert set(turned['device_identified']) == {'dL', 'alpha0', 'beta0', 'gamma'}
    assert abs(turned['device']['beta0'] + 1.5e-4) < 3 * turned['device_std']['beta0']
    # beta0 identified: the calibration works in the true base frame (phi0 turns only the platform frame, which
    # moves no position), so both figures agree.
    validation = turned['validation']
    assert (
        abs(
            validation['after']['position_mean_m']
            / validation['after_true_frames']['position_mean_m']
            - 1
        )
        < 1e-6
    )
    one_mounting = study_json('--identify-device', 'dL,alpha0,gamma')
    # One mounting cannot see beta0: in the true frames the base stays tilted by it (~1.5e-4 rad x 0.75 m).
    assert one_mounting['validation']['after_true_frames']['position_mean_m'] > 60e-6
    assert (
        validation['after_true_frames']['position_mean_m']
        < 0.5 * one_mounting['validation']['after_true_frames']['position_mean_m']
    )


def test_device_prior_reaches_the_solver_and_the_json():
    with_prior = study_json('--identify-device', 'alpha0,gamma', '--device-prior', 'dL=5e-4:10e-6')
    assert with_prior['study']['device_prior'] == {'dL': {'value': 5e-4, 'std': 10e-6}}
    assert 'dL' in with_prior['device_identified']
    assert with_prior['device_std']['dL'] < 10e-6


def test_bad_device_prior_and_procedure_are_usage_errors():
    done = hexacal('study', '--json', '--device-prior', 'dL=0.0005')
    assert done.returncode == 2 and 'NAME=VALUE:STD' in done.stderr
    done = hexacal('study', '--json', '--procedure', 'spin')
    assert done.returncode == 2 and 'quarter-turns' in done.stderr
    done = hexacal(
        'study', '--json', '--device-prior', 'dL=5e-4:1e-5'
    )  # no --weighted: no noise model
    assert done.returncode != 0 and 'reading noise' in done.stderr


def test_plan_for_a_turning_procedure_groups_the_mountings(tmp_path):
    from hexacal_identify.core.planning.planner import Plan

    out = tmp_path / 'turns.yaml'
    done = hexacal(
        'plan',
        '--postures',
        24,
        '--candidates',
        200,
        '--index',
        'I',
        '--procedure',
        'quarter-turns',
        '--identify-device',
        'dL,alpha0,beta0,gamma',
        '--out',
        out,
        '--json',
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary['procedure'] == 'quarter-turns' and summary['device_columns'] == [
        'dL',
        'alpha0',
        'beta0',
        'gamma',
    ]
    assert sum(summary['device_turns'].values()) == 24 and summary['rank'] == 54 + 4
    plan = Plan.load(out)
    assert len(set(plan.turns.round(9))) >= 2 and all(plan.turns[1:] >= plan.turns[:-1])
    refused = hexacal(
        'plan',
        '--postures',
        24,
        '--candidates',
        200,
        '--device-prior',
        'dL=0:1e-5',
        '--unweighted',
        '--out',
        tmp_path / 'x.yaml',
    )
    assert refused.returncode == 2 and 'noise' in refused.stderr
