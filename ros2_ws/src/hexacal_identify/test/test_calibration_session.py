"""
session.CalibrationSession without DDS: postures, calibrations, verifications, reports.

The session publishes through a StatusSink; here a list records what the node would publish.
Postures are simulated on the Table 1 machine; the nominal file is nominal set 2.
"""

from __future__ import annotations

import logging
from pathlib import Path
import sys

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.session import (
    CalibrationSession,
    Level,
    Reason,
    ReportState,
    Settings,
)
from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.names import CALIBRATION_STATUS_NAME, VERIFICATION_STATUS_NAME
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest

HEXA_SLIDE_JOINTS = MODELS['hexa_slide'].posture_names
GOUGH_STEWART_JOINTS = MODELS['gough_stewart'].posture_names
NOISE_UM = 10.0


class Recorder:
    """A StatusSink that keeps what was published, in order."""

    def __init__(self) -> None:
        self.published: list[tuple] = []

    def status(self, name, level, message, values) -> None:
        self.published.append(('status', name, level, message, dict(values)))

    def parameters(self, vector, model) -> None:
        self.published.append(('parameters', tuple(vector), model))

    def statuses(self, name: str = CALIBRATION_STATUS_NAME) -> list[tuple]:
        return [p for p in self.published if p[0] == 'status' and p[1] == name]

    def parameter_messages(self) -> list[tuple]:
        return [p for p in self.published if p[0] == 'parameters']


def simulated(count: int, seed: int, model: str | None = None) -> list[PostureReading]:
    rng = np.random.default_rng([seed, 42])
    arch = architecture(model)
    truth = arch.default_parameters()
    poses = sample_poses(truth, count, rng, 'sphere', arch.default_workspace())
    data = simulate_measurements(
        truth, poses, 'sphere', noise=NoiseModel.from_microns(NOISE_UM), rng=rng
    )
    return [
        PostureReading.from_values(
            1_000_000_000 * (i + 1),
            [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]],
        )
        for i in range(count)
    ]


@pytest.fixture
def nominal(tmp_path: Path) -> Path:
    path = tmp_path / 'nominal_set2.yaml'
    save_parameters(path, nominal_set(2, seed=0).vector)
    return path


def make_session() -> tuple[CalibrationSession, Recorder, list[int]]:
    recorder, scheduled = Recorder(), []
    session = CalibrationSession(
        recorder,
        logging.getLogger('test_calibration_session'),
        lambda: scheduled.append(1),
        '/hexacal/calibrate',
    )
    return session, recorder, scheduled


def settings(tmp_path: Path, nominal_file: Path | str, **changes) -> Settings:
    values = {'nominal': str(nominal_file), 'output_dir': str(tmp_path), 'report_dir': ''}
    return Settings(**{**values, **changes})


def receive(session: CalibrationSession, postures, nominal, joints=HEXA_SLIDE_JOINTS) -> list:
    return [session.receive_posture(joints, lambda model, p=p: p, str(nominal)) for p in postures]


# ---------------------------------------------------------------------- calibration


def test_calibrates_on_the_postures_received_and_publishes_parameters_then_status(
    tmp_path, nominal
):
    session, recorder, scheduled = make_session()
    receipts = receive(session, simulated(40, 0), nominal)
    assert [r.count for r in receipts] == list(range(1, 41)) and all(r.stored for r in receipts)
    outcome = session.calibrate(settings(tmp_path, nominal))
    assert outcome.success and outcome.level == Level.OK, outcome.message
    assert outcome.values['outcome'] == 'converged'
    assert outcome.values['postures_received'] == 40
    assert outcome.values['source'] == 'live postures'
    assert outcome.values['report_state'] == 'disabled' and scheduled == []
    written = read_parameters_file(tmp_path / 'hexacal_calibration.yaml')
    assert np.array_equal(written.vector, outcome.parameters.vector)
    # 'running' first, then the parameters, then the result status.
    kinds = [p[0] if p[0] == 'parameters' else p[4]['outcome'] for p in recorder.published]
    assert kinds[-3:] == ['running', 'parameters', 'converged']
    assert session.latest.number == 1 and session.latest.verify_from == 40
    truth = architecture(None).default_parameters().vector
    assert np.abs(outcome.parameters.vector - truth).max() < 1e-3


def test_collecting_status_is_held_back_while_a_calibration_runs(tmp_path, nominal):
    session, recorder, _ = make_session()
    receive(session, simulated(3, 0), nominal)
    last = recorder.statuses()[-1]
    assert last[4] == {
        'outcome': 'collecting',
        'postures_received': 3,
        'last_calibration': 'none',
    }
    assert last[3] == '3 postures received'
    session.calibrate(settings(tmp_path, nominal))  # too few: refused
    receive(session, simulated(1, 1), nominal)
    assert recorder.statuses()[-1][4]['last_calibration'] == 'too-few-postures'


@pytest.mark.parametrize(
    ('change', 'reason'),
    [
        ({'nominal': ''}, 'missing-parameter'),
        ({'nominal': '/nonexistent/nominal.yaml'}, 'invalid-nominal'),
        ({'bag': '/nonexistent/bag'}, 'invalid-bag'),
        ({'device_prior': {'device.link_length_std': 1e-5}}, 'invalid-device-prior'),
        ({'device_prior': {'device.alpha0_std': 1e-4}}, 'device-prior-without-noise'),
        ({'robust_loss': 'cauchy'}, 'invalid-options'),
    ],
)
def test_refusals_name_the_reason_and_publish_no_parameters(tmp_path, nominal, change, reason):
    session, recorder, _ = make_session()
    receive(session, simulated(40, 0), nominal)
    outcome = session.calibrate(settings(tmp_path, nominal, **change))
    assert not outcome.success and outcome.level == Level.ERROR
    assert outcome.values['outcome'] == reason and outcome.message.startswith(f'{reason}: ')
    assert recorder.parameter_messages() == [] and session.latest is None
    assert recorder.statuses()[-1][3] == outcome.message
    assert not (tmp_path / 'hexacal_calibration.yaml').exists()
    assert len(session.postures) == 40  # kept either way


def test_too_few_postures_is_the_core_reason(tmp_path, nominal):
    session, _, _ = make_session()
    receive(session, simulated(5, 0), nominal)
    outcome = session.calibrate(settings(tmp_path, nominal))
    assert outcome.values['outcome'] == 'too-few-postures'
    assert outcome.values['postures_rejected_on_receipt'] == 0


def test_unexpected_error_is_an_internal_error_not_a_crash(tmp_path, nominal):
    session, recorder, _ = make_session()
    # An output_dir that escapes validation (set in code, not as a parameter) still answers.
    outcome = session.calibrate(settings(tmp_path, nominal, output='../outside.yaml'))
    assert outcome.values['outcome'] == 'internal-error'
    assert 'ValueError' in outcome.message and recorder.statuses()[-1][2] == Level.ERROR


# ---------------------------------------------------------------------- postures


def test_rejected_postures_are_counted_by_reason_and_never_stored(tmp_path, nominal):
    session, recorder, _ = make_session()
    receive(session, simulated(2, 0), nominal)
    beyond = PostureReading.from_values(1, [5.0, 0, 0, 0, 0, 0, 0, 0, 0])

    def unreadable(model: str) -> PostureReading:
        raise InvalidReadingError('slider_3 is NaN')

    receipt = session.receive_posture(HEXA_SLIDE_JOINTS, lambda model: beyond, str(nominal))
    assert not receipt.stored and receipt.rejection.startswith('slider-beyond-stroke: ')
    receipt = session.receive_posture(HEXA_SLIDE_JOINTS, unreadable, str(nominal))
    assert receipt.rejection == 'invalid-reading: slider_3 is NaN'
    receipt = session.receive_posture(GOUGH_STEWART_JOINTS, lambda model: beyond, str(nominal))
    assert receipt.rejection.startswith('model-mismatch: posture carries the actuator joints')
    assert (receipt.count, receipt.rejected, len(session.postures)) == (2, 3, 2)
    level, message, values = recorder.statuses()[-1][2:]
    assert level == Level.WARN
    assert message == f'2 postures received, 3 rejected (last: {receipt.rejection})'
    assert values == {
        'outcome': 'collecting',
        'postures_received': 2,
        'last_calibration': 'none',
        'postures_rejected': 3,
        'rejected.invalid-reading': 1,
        'rejected.model-mismatch': 1,
        'rejected.slider-beyond-stroke': 1,
        'last_rejection': receipt.rejection,
    }
    outcome = session.calibrate(settings(tmp_path, nominal))
    assert outcome.values['postures_rejected_on_receipt'] == 3


def test_without_a_nominal_file_the_joints_name_the_model(tmp_path):
    session, _, _ = make_session()
    models = []

    def convert(model: str) -> PostureReading:
        models.append(model)
        return simulated(1, 0, 'gough_stewart')[0]

    assert session.receive_posture(GOUGH_STEWART_JOINTS, convert, '').stored
    assert models == ['gough_stewart']


def test_postures_of_another_model_than_the_nominal_are_refused_at_calibration(tmp_path):
    gough_stewart = tmp_path / 'gs.yaml'
    save_parameters(
        gough_stewart, nominal_set(2, seed=0, model='gough_stewart').vector, model='gough_stewart'
    )
    session, _, _ = make_session()
    receive(session, simulated(30, 0), '')  # no nominal yet: the joints say hexa_slide
    outcome = session.calibrate(settings(tmp_path, gough_stewart))
    assert outcome.values['outcome'] == 'model-mismatch'
    assert outcome.values['model'] == 'gough_stewart'


# ---------------------------------------------------------------------- verification


def test_verification_uses_only_the_postures_after_the_calibration(tmp_path, nominal):
    session, recorder, _ = make_session()
    outcome = session.verify(settings(tmp_path, nominal))
    assert outcome.values['outcome'] == 'no-calibration'
    assert '/hexacal/calibrate' in outcome.message
    receive(session, simulated(40, 0), nominal)
    assert session.calibrate(settings(tmp_path, nominal)).success
    outcome = session.verify(settings(tmp_path, nominal))
    assert outcome.values['outcome'] == 'no-postures'
    assert outcome.values['postures_before_calibration'] == 40
    receive(session, simulated(12, 7), nominal)
    assert recorder.statuses()[-1][4]['verification_postures'] == 12
    outcome = session.verify(settings(tmp_path, nominal, verify_threshold_m=1e-6))
    assert not outcome.success and outcome.level == Level.WARN
    assert outcome.values['verdict'] == 'fail' and float(outcome.values['threshold_m']) == 1e-6
    outcome = session.verify(settings(tmp_path, nominal, verify_threshold_m=5e-4))
    assert outcome.success and outcome.level == Level.OK, outcome.message
    values = outcome.values
    assert values['outcome'] == 'verified' and values['verdict'] == 'pass'
    assert values['calibration_number'] == 1 and values['calibration'] == 'live postures'
    assert values['report_state'] == 'disabled'
    assert outcome.message.endswith('12 postures since calibration 1')
    published = recorder.statuses(VERIFICATION_STATUS_NAME)
    assert [p[4]['outcome'] for p in published] == [
        'no-calibration',
        'no-postures',
        'verified',
        'verified',
    ]
    # The next calibration fits on every posture, and is verified on those after it.
    assert session.calibrate(settings(tmp_path, nominal)).values['postures_received'] == 52
    assert session.verify(settings(tmp_path, nominal)).values['outcome'] == 'no-postures'


def test_a_restarted_session_verifies_the_saved_calibration(tmp_path, nominal):
    first, _, _ = make_session()
    receive(first, simulated(40, 0), nominal)
    assert first.calibrate(settings(tmp_path, nominal)).success
    leftover = tmp_path / '.hexacal_calibration.yaml.abc123.tmp'
    leftover.write_text('interrupted')
    session, recorder, _ = make_session()
    session.republish_saved(settings(tmp_path, nominal))
    assert not leftover.exists()
    assert recorder.parameter_messages()[0][2] == 'hexa_slide'
    assert session.latest.number == 0 and session.latest.outcome is None
    receive(session, simulated(10, 3), nominal)
    outcome = session.verify(settings(tmp_path, nominal))
    assert outcome.values['outcome'] == 'verified', outcome.message
    assert outcome.values['postures_before_calibration'] == 0
    assert outcome.values['calibration'].startswith('saved calibration ')


# ---------------------------------------------------------------------- reports


def test_a_newer_calibration_replaces_a_report_waiting_to_start(tmp_path, nominal):
    (tmp_path / 'report').write_text('a file where the report directory would go')
    session, recorder, scheduled = make_session()
    receive(session, simulated(40, 0), nominal)
    first = session.calibrate(settings(tmp_path, nominal, report_dir='report'))
    second = session.calibrate(settings(tmp_path, nominal, report_dir='report'))
    assert first.values['report_state'] == second.values['report_state'] == 'writing'
    assert len(scheduled) == 2
    session.write_reports()  # the first scheduled run writes the latest: calibration 2's
    session.write_reports()  # the second finds nothing waiting
    follow_ups = [p for p in recorder.statuses() if p[4].get('report_state') == 'failed']
    assert len(follow_ups) == 1
    level, message, values = follow_ups[0][2:]
    assert level == second.level and message.startswith(second.message + '; report failed: ')
    assert values['report_error'].startswith(('FileExistsError', 'NotADirectoryError'))
    # The parameters and the outcome stay as they are.
    assert (tmp_path / 'hexacal_calibration.yaml').exists()
    assert session.latest.number == 2


def test_a_verification_of_an_older_calibration_is_superseded(tmp_path, nominal):
    (tmp_path / 'report').write_text('no report directory: fast failures')
    session, recorder, _ = make_session()
    receive(session, simulated(40, 0), nominal)
    with_report = settings(tmp_path, nominal, report_dir='report')
    session.calibrate(with_report)
    session.write_reports()
    receive(session, simulated(10, 5), nominal)
    verification = session.verify(with_report)
    assert verification.values['report_state'] == 'writing'
    session.calibrate(with_report)  # calibration 2 queued behind the verification of 1
    session.write_reports()
    states = [p[4]['report_state'] for p in recorder.statuses(VERIFICATION_STATUS_NAME)]
    assert states == ['writing', 'superseded']
    assert recorder.statuses(VERIFICATION_STATUS_NAME)[-1][3].endswith(
        'report superseded by calibration 2'
    )


@pytest.mark.slow
def test_the_report_of_the_latest_calibration_is_written(tmp_path, nominal):
    session, recorder, _ = make_session()
    receive(session, simulated(40, 0), nominal)
    session.calibrate(settings(tmp_path, nominal, report_dir='report'))
    session.write_reports()
    state, report = (recorder.statuses()[-1][4].get(k) for k in ('report_state', 'report'))
    assert state == ReportState.READY and Path(report).is_file()
    assert Path(report).is_relative_to(tmp_path / 'report')


def test_enum_values_are_the_status_strings():
    assert [str(r) for r in (Reason.VERIFIED, ReportState.WRITING, Level.WARN)] == [
        'verified',
        'writing',
        'WARN',
    ]
    assert f'{Reason.NO_POSTURES}: x' == 'no-postures: x'


if __name__ == '__main__':
    sys.exit(pytest.main([__file__, '-q']))
