"""The measuring-mode study (#18): each mode's simulated readings, refinement, the CLI."""

from dataclasses import replace
import json
import subprocess
import sys

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.walk_refine.refinement import refinement_checkpoints, walk_refined
from hexacal_identify.studies.measuring_mode_accuracy import (
    calibrate,
    ModeStudyRun,
    run_mode,
)
import numpy as np
import pytest

L = ModeStudyRun().device.link_length


def _nominal_batch(run: ModeStudyRun):
    """Measure every posture of the run once, on the nominal targets (no refinement)."""
    outcome = run_mode(replace(run, refine=False))
    return outcome, outcome.walk.batches[0]


def test_passive_five_stand_at_their_setpoints_and_the_released_one_follows_the_link():
    outcome, batch = _nominal_batch(ModeStudyRun(mode='passive_actuator', postures=20,
                                                 noise_um=0.0))
    assert batch.released is not None and np.all(batch.measured)
    readings, chosen = batch.exact.actuator_positions, batch.released
    assert len(set(chosen.tolist())) > 1  # chosen per posture
    commanded = np.ones_like(readings, bool)
    commanded[np.arange(len(readings)), chosen] = False
    assert np.max(np.abs(readings - batch.setpoints)[commanded]) < 1e-9
    # The released one is where the true machine's constraint put it: mm from the nominal
    # prediction, exactly the true IK of a pose on the true link sphere.
    assert np.max(batch.released_offset_m) > 1e-4
    assert np.allclose(np.linalg.norm(batch.true_poses[:, :3], axis=1), L, atol=1e-9)
    np.testing.assert_allclose(
        readings, inverse_kinematics(outcome.run.true_params, batch.true_poses), atol=1e-12
    )
    assert np.max(batch.deviation_m) < 1e-9


def test_lvdt_reads_the_link_length_and_the_calibration_recovers_the_truth_with_it():
    run = ModeStudyRun(mode='lvdt', postures=30, noise_um=0.0, lvdt_noise_m=0.0, refine=False)
    outcome, batch = _nominal_batch(run)
    lengths = np.linalg.norm(batch.true_poses[:, :3], axis=1)
    np.testing.assert_allclose(batch.measurements.link_lengths, lengths, atol=1e-15)
    np.testing.assert_allclose(batch.extension_m, lengths - L, atol=1e-15)
    assert np.max(np.abs(batch.extension_m)) > 1e-4  # the nominal targets stretch the link
    assert np.max(batch.deviation_m) < 1e-9  # the six stand at their setpoints
    error = outcome.result.parameters.vector - run.true_params.vector
    assert np.max(np.abs(error)) < 1e-8
    # Without L_m (the constant L in eq. 4) the same readings do not give the truth.
    rigid = replace(batch.measurements, link_lengths=None)
    wrong = calibrate(run, rigid).parameters.vector - run.true_params.vector
    assert np.max(np.abs(wrong)) > 1e-5


def test_compliant_servos_stand_on_the_true_sphere_and_carry_the_strain():
    outcome, batch = _nominal_batch(ModeStudyRun(mode='compliant', postures=20, noise_um=0.0))
    assert np.allclose(np.linalg.norm(batch.true_poses[:, :3], axis=1), L, atol=1e-9)
    np.testing.assert_allclose(
        batch.exact.actuator_positions,
        inverse_kinematics(outcome.run.true_params, batch.true_poses),
        atol=1e-12,
    )
    assert np.max(batch.deviation_m) > 1e-4
    figures = outcome.figures()
    assert figures['max_force_n'] == pytest.approx(2e6 * figures['max_actuator_deviation_m'])


@pytest.mark.parametrize(
    ('mode', 'key'),
    [
        ('compliant', 'max_actuator_deviation_m'),
        ('lvdt', 'max_link_extension_m'),
        ('passive_actuator', 'max_released_offset_m'),
    ],
)
def test_refinement_shrinks_the_strain_ten_fold_on_nominal_set_2(mode, key):
    outcome = run_mode(ModeStudyRun(mode=mode, postures=30, first_calibration=22))
    assert outcome.walk.calibrated_at == [22]
    before, after = outcome.figures(False)[key], outcome.figures(True)[key]
    assert before > 1e-3 and after * 10 <= before
    assert outcome.result.rank == outcome.run.true_params.layout.n_parameters


@pytest.mark.parametrize('mode', ['passive_actuator', 'lvdt', 'compliant'])
def test_gough_stewart_modes_read_the_truth_and_refine(mode):
    run = ModeStudyRun(mode=mode, true_params=default_parameters('gough_stewart'), postures=25,
                       first_calibration=17, noise_um=0.0, lvdt_noise_m=0.0)
    outcome = run_mode(run)
    for batch in outcome.walk.batches:
        np.testing.assert_allclose(
            batch.exact.actuator_positions,
            inverse_kinematics(run.true_params, batch.true_poses[batch.measured]),
            atol=1e-12,
        )
    key = {'passive_actuator': 'max_released_offset_m', 'lvdt': 'max_link_extension_m',
           'compliant': 'max_actuator_deviation_m'}[mode]
    assert outcome.figures(True)[key] * 10 <= outcome.figures(False)[key]
    assert outcome.after.summary()['position_max_m'] < 1e-8  # exact data: the truth


def test_an_lvdt_stroke_too_short_is_reported():
    outcome = run_mode(ModeStudyRun(mode='lvdt', postures=25, lvdt_stroke_m=1e-3, refine=False))
    data = outcome.to_json()
    assert data['lvdt_inside_stroke'] is False and data['lvdt_postures_outside_stroke'] > 0
    with pytest.raises(ValueError, match='first calibration'):
        ModeStudyRun(first_calibration=0)


def test_checkpoints_grow_geometrically_and_the_walk_retargets_after_each_calibration():
    assert refinement_checkpoints(50, 22) == (22, 44)
    assert refinement_checkpoints(50, None) == () == refinement_checkpoints(10, 22)
    seen = []
    walk = walk_refined(
        10,
        0,
        lambda model, indices: np.full((len(indices), 6), float(model)),
        lambda indices, setpoints: seen.append(setpoints[:, 0].tolist()) or len(indices),
        lambda batches: None if sum(batches) < 6 else len(batches),
        (3, 6, 8),
    )
    assert seen == [[0.0] * 3, [0.0] * 3, [2.0] * 2, [3.0] * 2]  # no full rank at 3 postures
    assert walk.calibrated_at == [6, 8] and walk.stages.tolist() == [0] * 6 + [1] * 2 + [2] * 2


def test_a_posture_the_true_machine_cannot_assemble_is_skipped_and_counted():
    # Seed 3, posture 16: chain 0 released (best conditioned on the nominal model), the five
    # nominal setpoints and the link have no assembly near the plan on the true machine.
    outcome = run_mode(ModeStudyRun(mode='passive_actuator', seed=3, refine=False))
    assert outcome.failed_postures == 1 and not outcome.walk.batches[0].measured[16]
    assert len(outcome.walk.batches[0].measurements) == 49
    assert outcome.to_json()['failed_postures'] == 1


@pytest.mark.slow
def test_study_cli_compares_all_modes_as_json():
    done = subprocess.run(
        [sys.executable, '-m', 'hexacal_identify.cli', 'study', '--measuring-mode', 'all',
         '--postures', '30', '--first-calibration', '22', '--validation-postures', '10',
         '--json'],
        capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    rows = json.loads(done.stdout)
    assert [(r['measuring_mode'], r['refine']) for r in rows] == [
        ('passive_actuator', True), ('lvdt', True), ('compliant', True), ('compliant', False),
    ]
    for row in rows:
        assert row['postures'] == 30 and row['failed_postures'] == 0
        assert 0 < row['pose_error_mean_m'] <= row['pose_error_max_m']
        assert (row['max_link_extension_m'] is None) == (row['measuring_mode'] != 'lvdt')
        assert (row['max_force_n'] is None) == (row['measuring_mode'] != 'compliant')
    assert rows[1]['lvdt_inside_stroke'] is True
    baseline = rows[3]
    assert baseline['after_refinement']['max_actuator_deviation_m'] is None
    assert rows[2]['after_refinement']['max_force_n'] < baseline['max_force_n'] / 10
