"""The identify node's session weighs live postures by the scatter they carry (no DDS)."""

from __future__ import annotations

import logging
from pathlib import Path

from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.session import CalibrationSession, Settings
from hexacal_identify.session.node_settings import parameter_problem
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.parameters_file import save_parameters
from hexacal_msgs_py.readings import PostureReading, PostureScatter
import numpy as np
import pytest

JOINTS = MODELS['hexa_slide'].posture_names
NOISE = NoiseModel.from_microns(10.0)


class Sink:
    """A StatusSink that keeps nothing: the outcome carries the status values."""

    def status(self, name, level, message, values) -> None:
        """Drop a status."""

    def parameters(self, vector, model) -> None:
        """Drop a parameters message."""


def _postures(count: int, scatter: bool) -> list[PostureReading]:
    rng = np.random.default_rng(7)
    truth = table1_parameters()
    data = simulate_measurements(truth, sample_poses(truth, count, rng), noise=NOISE, rng=rng)
    # The true spread of each value: what a collector averaging the readings would report.
    spread = PostureScatter(tuple(NOISE.standard_deviations()), (25,) * 9) if scatter else None
    return [
        PostureReading.from_values(
            1_000_000_000 * (i + 1),
            [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]],
            scatter=spread,
        )
        for i in range(count)
    ]


def _calibrate(tmp_path: Path, postures, **changes):
    nominal = tmp_path / 'nominal.yaml'
    save_parameters(nominal, nominal_set(2, seed=0).vector)
    session = CalibrationSession(Sink(), logging.getLogger('scatter'), lambda: None, '/c')
    for posture in postures:
        session.receive_posture(JOINTS, lambda model, p=posture: p, str(nominal))
    values = {'nominal': str(nominal), 'output_dir': str(tmp_path), 'report_dir': ''}
    return session.calibrate(Settings(**{**values, **changes}))


def test_live_postures_with_scatter_are_weighed_by_it(tmp_path):
    outcome = _calibrate(tmp_path, _postures(40, scatter=True))
    assert outcome.success, outcome.message
    assert outcome.values['weights'] == 'scatter'
    assert 'measured scatter' in outcome.values['weights_note']
    assert outcome.values['adequacy.verdict'] == 'pass'


def test_a_device_prior_is_weighed_against_the_scatter(tmp_path):
    # No noise parameters: the postures' scatter is the reading noise the prior weighs against.
    prior = {'device.alpha0': 0.0, 'device.alpha0_std': 1e-4}
    outcome = _calibrate(tmp_path, _postures(40, scatter=True), device_prior=prior)
    assert outcome.success, outcome.message
    assert outcome.values['weights'] == 'scatter' and 'std.device.alpha0' in outcome.values


def test_without_scatter_the_noise_parameters_weigh_as_before(tmp_path):
    outcome = _calibrate(
        tmp_path, _postures(40, scatter=False), noise_slider_m=1e-5, noise_angle_rad=1e-5
    )
    assert outcome.success and outcome.values['weights'] == 'noise_model'


@pytest.mark.parametrize(
    ('scatter', 'weights', 'text'),
    [
        (False, 'scatter', '40 of 40 postures carry no scatter'),
        (True, 'noise-model', 'needs the noise model'),
    ],
)
def test_a_weighting_that_cannot_apply_is_refused(tmp_path, scatter, weights, text):
    outcome = _calibrate(tmp_path, _postures(40, scatter), weights=weights)
    assert not outcome.success
    assert outcome.values['outcome'] == 'invalid-options' and text in outcome.message


def test_weights_parameters_are_checked_when_set():
    def current(name, fallback):
        return fallback

    assert parameter_problem('weights', 'noise_model', current) is None
    assert 'weights must be one of' in parameter_problem('weights', 'loud', current)
    assert parameter_problem('scatter_floor_angle_rad', 1e-7, current) is None
    assert 'positive' in parameter_problem('scatter_floor_actuator_m', 0.0, current)
