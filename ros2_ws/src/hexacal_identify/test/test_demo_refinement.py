"""The demo's drive figures split before / after target refinement (cli/demo_refinement.py)."""

from hexacal_identify.cli.demo_refinement import (
    refined_at,
    refinement_lines,
    refinement_summary,
    RestLog,
)


def status(rests: int, deviation: float, force: float = 0.0, move_force: float = 0.0) -> dict:
    """Return the driver's status values at a rest (compliant), as strings."""
    return {
        'rests': str(rests),
        'actuator_deviation_m': str(deviation),
        'force_n': str(force),
        'move_max_force_n': str(move_force),
        'link_extension_m': '',
        'move_max_link_extension_m': '',
    }


def test_refined_at_reads_the_executor_targets_model():
    assert refined_at('calibration after 22 postures') == 22
    assert refined_at('nominal') is None and refined_at('') is None
    assert refined_at('calibration after many postures') is None


def test_rest_log_records_each_rest_once_and_counts_missed_ones():
    log = RestLog()
    assert log.hear(status(1, 3e-3, 6e3, 7e3), refined=False)
    assert not log.hear(status(1, 3e-3, 6e3, 7e3), refined=False)  # the periodic repeat
    assert not log.hear({'rests': ''}, refined=False)  # no rest count: not a rest
    assert log.hear(status(3, 2e-6, 4.0, 5e3), refined=True)  # rest 2 replaced before delivery
    assert [rest.refined for rest in log.rests] == [False, True]
    assert log.missed == 1


def test_summary_splits_rests_and_postures_by_the_targets_model():
    log = RestLog()
    log.hear(status(1, 3.0e-3, 6000.0, 7000.0), refined=False)
    log.hear(status(2, 3.9e-3, 7800.0, 7900.0), refined=False)
    log.hear(status(3, 4.0e-6, 8.0, 6500.0), refined=True)  # the move away from the strain
    log.hear(status(4, 1.0e-6, 2.0, 9.0), refined=True)
    summary = refinement_summary(
        log,
        'compliant',
        refine=True,
        targets_models=['nominal', 'calibration after 22 postures',
                        'calibration after 44 postures'],
        calibration_postures=50,
        verification_postures=20,
    )
    assert summary['refine_targets'] is True
    assert summary['targets_models'] == ['calibration after 22 postures',
                                         'calibration after 44 postures']
    assert summary['postures_on_nominal'] == 22
    assert summary['postures_on_refined'] == 28 + 20  # the verification on the calibration
    assert summary['verification_targets'] == 'calibration'
    before, after = summary['before'], summary['after']
    assert before == {'rests': 2, 'max_actuator_deviation_m': 3.9e-3, 'max_force_n': 7800.0,
                      'max_link_extension_m': None, 'max_move_force_n': 7900.0,
                      'max_move_link_extension_m': None}
    assert after['rests'] == 2 and after['max_actuator_deviation_m'] == 4.0e-6
    assert after['max_force_n'] == 8.0 and after['max_move_force_n'] == 6500.0
    lines = refinement_lines(summary)
    assert '22 postures on nominal targets -> 48 on refined ones' in lines[0]
    assert 'deviation 3900.0 -> 4.0 um' in lines[0]
    assert 'force at rest 7800.0 -> 8.0 N' in lines[1]


def test_without_refinement_everything_is_before_and_after_is_empty():
    log = RestLog()
    log.hear(status(1, 3.0e-3), refined=False)
    summary = refinement_summary(
        log, 'lvdt', refine=False, targets_models=['nominal'], calibration_postures=50,
        verification_postures=20,
    )
    assert summary['postures_on_nominal'] == 70 and summary['postures_on_refined'] == 0
    assert summary['verification_targets'] == 'nominal'
    assert summary['after'] == {'rests': 0, 'max_actuator_deviation_m': None,
                                'max_force_n': None, 'max_link_extension_m': None,
                                'max_move_force_n': None, 'max_move_link_extension_m': None}
    assert summary['before']['max_force_n'] is None  # lvdt: no servo force
    assert 'deviation 3000.0 -> - um' in refinement_lines(summary)[0]
    assert refinement_lines(None) == []
