"""hexacal_msgs_py.calibrate_answer: the calibrate answer a client ties its result to."""

from hexacal_msgs_py.calibrate_answer import (
    calibrate_answer,
    CalibrateAnswer,
    header_names_summary,
    parse_calibrate_answer,
)
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np

CHAIN = [0.4, 0.1, 0.0, 0.1, 0.02, 0.0, 0.5, 0.3, 0.1]  # A0, B, l, a (x, y): Hexa Slide
SUMMARY = '30 of 30 postures, absolute cost, 7 iterations, rank 54, rms residual x 1.2e-06'


def test_the_answer_round_trips():
    message = calibrate_answer('converged', SUMMARY, '/out/hexacal_calibration.yaml')
    assert message == f'converged: {SUMMARY}; wrote /out/hexacal_calibration.yaml'
    assert parse_calibrate_answer(message) == CalibrateAnswer(
        'converged', SUMMARY, '/out/hexacal_calibration.yaml'
    )


def test_refusals_and_other_answers_name_no_file():
    for message in (
        'busy: a calibration is running',
        'too-few-postures: 5 postures give 25 residuals for 54 unknowns',
        'calibrated',
        f'converged: {SUMMARY}; wrote ',
    ):
        assert parse_calibrate_answer(message) is None


def test_the_file_header_carries_the_summary(tmp_path):
    path = tmp_path / 'p.yaml'
    header = f'hexacal calibration 2026-11-24T06:00:00+00:00\nfrom live postures: {SUMMARY}'
    save_parameters(path, np.tile(CHAIN, 6), header_comment=header)
    text = path.read_text()
    assert header_names_summary(text, SUMMARY)
    assert not header_names_summary(text, SUMMARY.replace('30 of 30', '40 of 40'))
    assert not header_names_summary(f'/**:\n# from x: {SUMMARY}\n', SUMMARY)  # not the header
