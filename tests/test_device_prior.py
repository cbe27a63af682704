"""Device priors (a caliper's link length, a certificate's inclinometer zero) everywhere a calibration runs.

calibrate and its status fields, the report's prior/posterior table, `hexacal calibrate
--device-prior` in a subprocess, and the identify node's device.* parameters over a real ROS graph.
"""

from __future__ import annotations

import json
from pathlib import Path

from hexacal_identify.core.machine.device import DeviceDefects, DevicePrior
from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses, Workspace
from hexacal_msgs_py.parameters_file import save_parameters
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest
from system_support import hexacal
from system_support import node_argv, probe  # noqa: F401 - fixture

REPO = Path(__file__).resolve().parents[1]
SAMPLE_BAG = REPO / 'bags' / 'sphere50_noise10'
TRUE_DL = 5e-4  # the link is 0.5 mm longer than the 0.75 m the device model assumes
CALIPER = DevicePrior((('dL', TRUE_DL, 10e-6),))
NOISE = NoiseModel.from_microns(10)


def _readings(data) -> list[PostureReading]:
    return [
        PostureReading.from_values(
            1_000_000_000 * (i + 1),
            [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]],
        )
        for i in range(len(data.rotary))
    ]


@pytest.fixture(scope='module')
def long_link_postures() -> list[PostureReading]:
    """40 sphere postures of the Table 1 machine measured with a link 0.5 mm longer than assumed (the postures
    lie on the sphere of the true length), 10 um / 10 urad noise."""
    truth = table1_parameters()
    rng = np.random.default_rng(7)
    poses = sample_poses(truth, 40, rng, 'sphere', Workspace(link_length=0.75 + TRUE_DL))
    data = simulate_measurements(
        truth, poses, 'sphere', noise=NOISE, rng=rng, defects=DeviceDefects(dL=TRUE_DL)
    )
    return _readings(data)


# ----------------------------------------------------------------- calibration_run (no ROS)


def test_a_caliper_prior_bounds_the_link_offset(long_link_postures):
    from hexacal_identify.calibration_steps.calibration_run import calibrate, status_fields

    nominal = nominal_set(2)
    with_prior = calibrate(nominal, long_link_postures, noise=NOISE, device_prior=CALIPER)
    without = calibrate(nominal, long_link_postures, noise=NOISE, identify_device=('dL',))
    assert with_prior.free_device == ('dL',)  # a prior makes the parameter identified
    fields = status_fields(with_prior, CALIPER)
    assert float(fields['std.device.dL']) <= 10e-6
    assert abs(float(fields['device.dL']) - TRUE_DL) < 3 * float(fields['std.device.dL'])
    assert float(fields['prior.device.dL']) == pytest.approx(TRUE_DL)
    assert float(fields['prior_std.device.dL']) == pytest.approx(10e-6)
    without_fields = status_fields(without)
    assert float(without_fields['std.device.dL']) > float(fields['std.device.dL'])
    assert not any(key.startswith('prior') for key in without_fields)


def test_a_prior_without_the_noise_model_is_a_clear_error(long_link_postures):
    from hexacal_identify.calibration_steps.calibration_run import calibrate

    with pytest.raises(ValueError, match='noise'):
        calibrate(nominal_set(2), long_link_postures, device_prior=CALIPER)


def test_measurements_carry_each_postures_device_turn():
    from hexacal_identify.calibration_steps.posture_checks import measurements_from_postures

    postures = [
        PostureReading(i + 1, (0.1,) * 6, 0.01, 0.02, 0.0, device_turn=turn)
        for i, turn in enumerate((0.0, np.pi, np.pi / 2))
    ]
    assert np.allclose(measurements_from_postures(postures).device_turn, [0.0, np.pi, np.pi / 2])
    assert (
        measurements_from_postures(postures[:1]).device_turn is None
    )  # all normal: as without turns


@pytest.mark.slow
def test_the_report_shows_prior_and_posterior(long_link_postures, tmp_path):
    from hexacal_identify.calibration_steps.calibration_run import calibrate
    from hexacal_identify.report.page import save_result, write_report

    result = calibrate(
        nominal_set(2),
        long_link_postures,
        noise=NOISE,
        device_prior=CALIPER,
        identify_device=('alpha0',),
    )
    saved = save_result(tmp_path / 'result.json', result, device_prior=CALIPER)
    assert json.loads(saved.read_text())['device_prior'] == {
        'dL': {'value': TRUE_DL, 'std': 10e-6}
    }
    page = write_report(saved, tmp_path / 'report').read_text()
    assert 'Device parameters: prior and posterior' in page
    assert "id='device-prior-dL'>500.000 +- 10.000 um<" in page
    assert "id='device-prior-alpha0'>none<" in page  # identified without a prior
    assert "id='device-posterior-alpha0'>" in page and 'urad' in page
    # Without identified device parameters the table is not there.
    plain = calibrate(nominal_set(2), long_link_postures)
    assert 'Device parameters: prior' not in write_report(plain, tmp_path / 'plain').read_text()


# --------------------------------------------------------------------------- hexacal calibrate


@pytest.fixture(scope='module')
def nominal_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('params') / 'nominal.yaml'
    save_parameters(path, nominal_set(2).vector)
    return path


@pytest.mark.slow
def test_cli_prints_prior_and_posterior(nominal_file, tmp_path):
    common = (
        SAMPLE_BAG,
        '--nominal',
        nominal_file,
        '--output',
        tmp_path / 'out.yaml',
        '--noise-um',
        '10',
        '--device-prior',
        'dL=0:10e-6,alpha0=0:50e-6',
    )
    completed = hexacal('calibrate', *common, '--json')
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert result['device_prior'] == {
        'dL': {'value': 0.0, 'std': 10e-6},
        'alpha0': {'value': 0.0, 'std': 50e-6},
    }
    assert set(result['device_identified']) == {'dL', 'alpha0'}
    assert 0 < result['device_std']['dL'] <= 10e-6 and 0 < result['device_std']['alpha0'] <= 50e-6
    assert set(result['device']) >= {'dL', 'alpha0'}
    text = hexacal('calibrate', *common)
    assert text.returncode == 0, text.stderr
    assert 'dL: prior 0.000 +- 10.000 um, identified' in text.stdout
    assert 'alpha0: prior 0.000 +- 50.000 urad, identified' in text.stdout


@pytest.mark.parametrize(
    'text, message',
    [
        ('dL=0', 'expected NAME=VALUE:STD'),
        ('length=0:1e-5', "unknown parameter 'length'"),
        ('dL=0:-1e-5', 'std positive'),
    ],
)
def test_cli_bad_device_prior_exits_2_with_the_message(nominal_file, tmp_path, text, message):
    completed = hexacal(
        'calibrate',
        SAMPLE_BAG,
        '--nominal',
        nominal_file,
        '--output',
        tmp_path / 'out.yaml',
        '--noise-um',
        '10',
        '--device-prior',
        text,
    )
    assert completed.returncode == 2
    assert '--device-prior' in completed.stderr and message in completed.stderr, completed.stderr
    assert 'Traceback' not in completed.stderr


def test_cli_prior_without_noise_is_refused_in_one_line(nominal_file, tmp_path):
    completed = hexacal(
        'calibrate',
        SAMPLE_BAG,
        '--nominal',
        nominal_file,
        '--output',
        tmp_path / 'out.yaml',
        '--device-prior',
        'dL=0:10e-6',
    )
    assert completed.returncode == 2
    assert 'noise' in completed.stderr and 'Traceback' not in completed.stderr
    assert len(completed.stderr.strip().splitlines()) == 1
    assert not (tmp_path / 'out.yaml').exists()


# --------------------------------------------------------------------------- the identify node


def _start_identify(ros_processes, tmp_path, probe, **parameters):
    parameters.setdefault('output_dir', str(tmp_path / 'out'))
    parameters.setdefault('report_dir', '')
    process = ros_processes.start(node_argv('identify', parameters), name='identify')
    probe.wait_for_node('identify', '/', process)
    return process


def _calibration_status(probe, outcome_check, what):
    return probe.spin_until(
        lambda: [
            s
            for s in probe.statuses
            if s[2].get('outcome') not in ('collecting', 'running', None) and outcome_check(s[2])
        ],
        30.0,
        what,
    )[-1]


@pytest.mark.slow
def test_identify_publishes_prior_and_posterior(
    ros_processes, tmp_path, probe, long_link_postures
):
    nominal = tmp_path / 'nominal.yaml'
    save_parameters(nominal, nominal_set(2).vector)
    identify = _start_identify(
        ros_processes,
        tmp_path,
        probe,
        nominal=str(nominal),
        report_dir='report',
        noise_slider_m=10e-6,
        noise_angle_rad=10e-6,
        **{'device.link_length': 0.75 + TRUE_DL, 'device.link_length_std': 10e-6},
    )
    probe.subscribe_status()
    probe.publish_postures(long_link_postures)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == len(long_link_postures),
        30.0,
        'identify to hold the postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert response.success, response.message
    _, _, values = _calibration_status(probe, lambda v: 'device.dL' in v, 'the result status')
    assert float(values['prior.device.dL']) == pytest.approx(TRUE_DL, abs=1e-9)
    assert float(values['prior_std.device.dL']) == pytest.approx(10e-6)
    assert float(values['std.device.dL']) <= 10e-6
    assert abs(float(values['device.dL']) - TRUE_DL) < 30e-6
    # The report written after the answer shows the prior beside the posterior.
    _, _, ready = probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('report_state') == 'ready'],
        60.0,
        'the report',
        identify.describe,
    )[-1]
    page = Path(ready['report']).read_text()
    assert (
        'Device parameters: prior and posterior' in page
        and "id='device-prior-dL'>500.000 +- 10.000 um<" in page
    )


@pytest.mark.slow
def test_identify_prior_without_noise_is_a_named_failure(
    ros_processes, tmp_path, probe, long_link_postures
):
    nominal = tmp_path / 'nominal.yaml'
    save_parameters(nominal, nominal_set(2).vector)
    identify = _start_identify(
        ros_processes, tmp_path, probe, nominal=str(nominal), **{'device.alpha0_std': 50e-6}
    )
    probe.subscribe_status()
    probe.publish_postures(long_link_postures[:20])
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 20,
        30.0,
        'identify to hold the postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert not response.success
    assert response.message.startswith('device-prior-without-noise:'), response.message
    assert 'noise_slider_m' in response.message
    level, _, _ = _calibration_status(
        probe, lambda v: v.get('outcome') == 'device-prior-without-noise', 'the ERROR status'
    )
    assert level == 2
    assert identify.running()


def test_identify_rejects_a_link_std_without_the_measured_length(ros_processes, tmp_path):
    process = ros_processes.start(
        node_argv('identify', {'output_dir': str(tmp_path), 'device.link_length_std': 10e-6}),
        name='identify',
    )
    from rosproc import wait_for

    wait_for(
        lambda: not process.running(),
        30.0,
        what='identify to refuse its parameters',
        details=process.describe,
    )
    assert process.popen.returncode != 0
    assert 'device.link_length is not set' in process.log_text(), process.describe()
