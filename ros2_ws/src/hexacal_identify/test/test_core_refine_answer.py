"""
core/walk_refine/refine_answer.py: the executor takes only its own intermediate calibration.

(#18, no DDS)

The calibrations are the identify node's own (session.CalibrationSession, the code behind
``hexacal/calibrate``): their answers' messages and the files they write are the real ones.
"""

from __future__ import annotations

import logging
from pathlib import Path

from hexacal_identify.core.machine.measurements import simulate_measurements
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.walk_refine.refine_answer import choose_parameters, read_own_result
from hexacal_identify.core.walk_refine.refined_targets import RefineCall, RefineState
from hexacal_identify.session import CalibrationSession, Settings
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.parameters_file import save_parameters
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest

NOMINAL = nominal_set(2, seed=0)
TRUTH = table1_parameters()
JOINTS = MODELS['hexa_slide'].posture_names


class _Published:
    """The session's StatusSink: what the identify node would publish."""

    def __init__(self) -> None:
        self.vectors: list[np.ndarray] = []

    def status(self, name, level, message, values) -> None:
        """Publish nothing: the status is not what the executor matches on."""

    def parameters(self, vector, model) -> None:
        self.vectors.append(np.array(vector, dtype=float))


@pytest.fixture
def identify(tmp_path: Path):
    """Return calibrate(count): a calibration of the first `count` postures, as the node runs."""
    nominal = tmp_path / 'nominal.yaml'
    save_parameters(nominal, NOMINAL.vector)
    published = _Published()
    session = CalibrationSession(published, logging.getLogger('refine'), lambda: None, 'c')
    poses = sample_poses(TRUTH, 40, np.random.default_rng(5))
    data = simulate_measurements(TRUTH, poses)
    readings = [
        PostureReading.from_values(
            10**9 * (i + 1), [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]]
        )
        for i in range(len(poses))
    ]
    settings = Settings(nominal=str(nominal), output_dir=str(tmp_path / 'out'), report_dir='')

    def calibrate(count: int):
        while len(session.postures) < count:
            reading = readings[len(session.postures)]
            session.receive_posture(JOINTS, lambda model, p=reading: p, str(nominal))
        outcome = session.calibrate(settings)
        assert outcome.success, outcome.message
        return outcome, published.vectors[-1]

    return calibrate


def test_the_answers_file_is_taken_not_the_last_parameters_heard(identify):
    ours, published = identify(30)
    call = RefineCall(NOMINAL, timeout_s=5.0)
    assert call.start(0.0, 30, service_ready=True)
    call.parameters(published)  # the identify node publishes, then answers
    call.parameters(TRUTH.vector)  # another client's calibration, or a stale latched one
    call.answer(True, ours.message)
    call.poll(0.1)
    assert call.state == RefineState.DONE and call.ignored == 1
    np.testing.assert_array_equal(call.model.vector, ours.parameters.vector)
    assert call.message == 'targets from the calibration after 30 postures'
    notes = ' '.join(text for _, text in call.messages)
    assert 'the published parameters match' in notes and '1 other parameter set' in notes


def test_the_answers_file_serves_before_its_publication_is_heard(identify):
    ours, _ = identify(30)
    call = RefineCall(NOMINAL, timeout_s=5.0)
    call.start(0.0, 30, True)
    call.parameters(TRUTH.vector)  # not ours: ignored
    call.answer(True, ours.message)
    call.poll(0.1)
    np.testing.assert_array_equal(call.model.vector, ours.parameters.vector)


def test_a_file_a_later_calibration_overwrote_is_not_taken(identify):
    ours, published = identify(30)
    later, later_published = identify(40)  # another client's: the same output file
    own = read_own_result(ours.message)
    assert own.vector is None and 'holds another calibration' in own.problem
    assert read_own_result(later.message).vector is not None
    # Then the published sets decide: ours alone is taken, ours and the later one are ambiguous.
    alone = choose_parameters(own, [published, published])
    np.testing.assert_array_equal(alone.vector, ours.parameters.vector)
    both = choose_parameters(own, [published, later_published])
    assert both.vector is None and not both.waiting and both.ignored == 2
    assert 'the targets stay' in both.note


def test_an_answers_file_out_of_reach_waits_for_the_one_published_set(tmp_path):
    message = f'converged: 30 of 30 postures; wrote {tmp_path / "elsewhere.yaml"}'
    own = read_own_result(message)  # the identify node on another host
    assert own.vector is None and own.problem.startswith('cannot read')
    assert choose_parameters(own, []).waiting
    call = RefineCall(NOMINAL, timeout_s=5.0)
    call.start(0.0, 30, True)
    call.answer(True, message)
    call.poll(6.0)
    assert call.model is None and 'cannot read' in call.message
    assert 'the parameters did not come within 5 s' in call.message
    call.start(10.0, 30, True)
    call.answer(True, message)
    call.parameters(TRUTH.vector)
    call.poll(10.1)
    np.testing.assert_array_equal(call.model.vector, TRUTH.vector)


def test_an_answer_that_names_no_file():
    own = read_own_result('calibrated')
    assert own.vector is None and own.problem == 'the answer names no parameters file'
