"""
A planned posture keeps the stroke margin the model change before walking needs.

The demo with ``--seed 1`` (Hexa Slide, nominal set 2 of seed 1) planned a verification posture
whose slider target was 0.8 mm inside the stroke on the nominal and -5.5 mm on the calibrated
machine, and the executor refused the plan.  The candidates are drawn here as that plan drew
them; the true machine stands in for the calibration.
"""

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.modes.release_rehearsal import model_error_rms_m
from hexacal_identify.core.planning.model_margin import (
    keep_model_margin,
    MARGIN_SIGMAS,
    model_change_margins,
)
from hexacal_identify.core.planning.planner import plan_postures
from hexacal_identify.core.planning.posture_limits import generate_candidates, PostureLimits
import numpy as np
import pytest

MODELS = ('hexa_slide', 'gough_stewart')


def _targets(params, poses):
    arch = params.architecture
    return arch.legs(arch.chains(params), poses).actuators


def _seed_one_candidates(model: str, count: int = 1000):
    nominal = nominal_set(2, seed=1, model=model)
    limits = PostureLimits.for_machine(nominal)
    poses, _ = generate_candidates(nominal, count, np.random.default_rng([1001, 0x91A4]), limits)
    return nominal, limits, poses


def test_the_margin_refuses_the_postures_the_calibration_drives_out_of_the_stroke():
    nominal, limits, poses = _seed_one_candidates('hexa_slide')
    low, high = limits.actuator_stroke_m
    truth = default_parameters('hexa_slide')
    on_truth = _targets(truth, poses)
    outside = np.any((on_truth < low) | (on_truth > high), axis=1)
    nominal_targets = _targets(nominal, poses)
    inside_nominal = np.all((nominal_targets >= low) & (nominal_targets <= high), axis=1)
    assert np.any(outside & inside_nominal)  # the failure: inside on the nominal, not on truth
    keep = keep_model_margin(nominal, poses, (low, high), model_error_rms_m(nominal))
    assert not np.any(keep & outside)
    assert np.mean(keep) > 0.9  # a margin, not a different workspace


@pytest.mark.parametrize('model', MODELS)
def test_the_margin_covers_the_change_to_the_true_machine(model):
    nominal, _, poses = _seed_one_candidates(model, 300)
    error = model_error_rms_m(nominal)
    margins = model_change_margins(nominal, poses, error)
    change = np.abs(_targets(default_parameters(model), poses) - _targets(nominal, poses))
    assert np.all(np.isfinite(margins)) and np.all(margins > 0)
    assert np.all(change < margins)
    # MARGIN_SIGMAS standard deviations: the change is a few of them at most, never all.
    assert np.max(change / margins) > 0.1 / MARGIN_SIGMAS
    assert np.allclose(model_change_margins(nominal, poses, 2 * error), 2 * margins)


def test_no_model_error_keeps_exactly_the_stroke():
    nominal, limits, poses = _seed_one_candidates('hexa_slide', 300)
    low, high = limits.actuator_stroke_m
    targets = _targets(nominal, poses)
    assert np.array_equal(keep_model_margin(nominal, poses, (low, high), 0.0),
                          np.all((targets >= low) & (targets <= high), axis=1))
    # A stroke ending just below the highest target refuses that posture with or without margin.
    top = int(np.argmax(targets.max(axis=1)))
    assert not keep_model_margin(nominal, poses[top][None], (low, targets[top].max() - 1e-6),
                                 0.0)[0]
    with pytest.raises(ValueError, match='model error'):
        keep_model_margin(nominal, poses, (low, high), -1e-3)


def test_a_plan_keeps_the_margin_and_refuses_clearly_when_it_cannot():
    nominal = nominal_set(2, seed=1, model='hexa_slide')
    limits = PostureLimits.for_machine(nominal)
    error = model_error_rms_m(nominal)
    result = plan_postures(
        nominal, 6, n_candidates=120, seed=1001, fixed_fraction=0.25, model_error_m=None
    )
    # Candidates short of the margin are replaced: the count and kind split asked for.
    assert len(result.candidates) == 120
    assert np.sum(result.candidates.kinds == 'fixed') == 30
    assert np.all(keep_model_margin(nominal, result.candidates.poses, limits.actuator_stroke_m,
                                    error))
    assert np.all(keep_model_margin(nominal, result.plan.poses, limits.actuator_stroke_m, error))
    with pytest.raises(ValueError, match='inside the stroke .* less the margin'):
        plan_postures(nominal, 6, n_candidates=120, seed=1001, model_error_m=0.2)
