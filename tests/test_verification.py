"""Verification without ground truth (#11 section 3): core/assessment/verification.py, `hexacal verify`, identify's hexacal/verify.

The verification postures are never the fit's: the core tests calibrate on one
simulated set and verify on another of the same true machine; the CLI tests
calibrate a bag and verify a second recording (synthetic bags written with
tests/synthetic_recording.py, and the two recorded sample bags of Table 1); the
node test sends fresh postures after the calibration.
"""

from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

from hexacal_identify.core.architectures import architecture, default_parameters
from hexacal_identify.core.errors import InvalidMeasurementError
from hexacal_identify.core.fit.identification import CONVERGED, identify, SolverOptions
from hexacal_identify.core.assessment.verification import (
    DEFAULT_THRESHOLD_M,
    FAIL,
    PASS,
    VerificationModelError,
    verify,
)
from hexacal_identify.core.machine.device import DeviceModel
from hexacal_identify.core.machine.measurements import (
    FIXED,
    Measurements,
    NoiseModel,
    simulate_measurements,
    SPHERE,
)
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np
import pytest
from system_support import (
    hexacal,
    node_argv,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    write_parameter_files,
)

REPO = Path(__file__).resolve().parents[1]
SAMPLE_FIT_BAG = REPO / 'bags' / 'sphere60_fixed20_noise10'  # Table 1, seed 2
SAMPLE_VERIFY_BAG = (
    REPO / 'bags' / 'sphere50_noise10'
)  # Table 1, seed 1: another recording of the same machine
JSON_KEYS = {'model', 'postures', 'nominal', 'calibrated', 'improvement', 'threshold_m', 'verdict'}
FIGURE_KEYS = {'position_rms_m', 'position_max_m', 'rotary_rms_rad'}
TRUTH = default_parameters()  # Table 1


def _postures(
    truth,
    seed: int,
    sphere: int,
    fixed: int = 0,
    noise_um: float = 0.0,
    model: str | None = None,
    device: DeviceModel = DeviceModel(),
) -> Measurements:
    rng = np.random.default_rng(seed)
    workspace = architecture(model).default_workspace()
    noise = NoiseModel.from_microns(noise_um) if noise_um else NoiseModel()
    parts = [
        simulate_measurements(
            truth,
            sample_poses(truth, count, rng, kind, workspace),
            kind,
            device=device,
            noise=noise,
            rng=rng,
        )
        for kind, count in ((SPHERE, sphere), (FIXED, fixed))
        if count
    ]
    return Measurements.concatenate(parts)


@pytest.fixture(scope='module')
def noisy_calibration():
    """Nominal set 2 calibrated on 60 noisy postures (+-10 um / urad); 40 fresh postures of the same machine."""
    fit = _postures(TRUTH, 1, 45, 15, noise_um=10.0)
    result = identify(nominal_set(2, seed=0), fit, SolverOptions())
    assert result.reason == CONVERGED
    fresh = _postures(TRUTH, 2, 30, 10, noise_um=10.0)
    return result.parameters, fresh


# --------------------------------------------------------------------------- core


def test_exact_data_gives_zero_residual_for_the_true_machine_and_mm_for_the_nominal():
    exact = _postures(TRUTH, 3, 20, 5)
    result = verify(nominal_set(2, seed=0), TRUTH, exact)
    after, before = result.calibrated.figures(), result.nominal.figures()
    assert (
        after['position_rms_m'] < 1e-10
        and after['position_max_m'] < 1e-10
        and after['rotary_rms_rad'] < 1e-10
    )
    assert after['fk_failures'] == 0 and after['postures_converged'] == 25
    assert 1e-3 < before['position_rms_m'] < 0.05  # Table 2's errors: millimetres
    assert before['rotary_rms_rad'] > 1e-3
    assert result.verdict == PASS and result.improvement > 1e6
    assert result.threshold_m == DEFAULT_THRESHOLD_M and result.threshold_source == 'default'


def test_noisy_data_nominal_at_millimetres_calibrated_at_the_noise_level(noisy_calibration):
    calibrated, fresh = noisy_calibration
    noise = NoiseModel.from_microns(10.0)
    result = verify(nominal_set(2, seed=0), calibrated, fresh, noise=noise)
    before, after = result.nominal.figures(), result.calibrated.figures()
    expected = result.expected_noise['position_rms_m']
    assert 5e-6 < expected < 60e-6  # +-10 um / urad single readings carried through FK and eq. 4
    assert 0.7 * expected < after['position_rms_m'] < 2.0 * expected, (after, expected)
    assert after['position_max_m'] < 10 * expected  # the worst-conditioned posture
    assert 1e-3 < before['position_rms_m']  # the nominal set: millimetres
    assert result.improvement > 100
    assert result.threshold_source == '3x expected noise' and result.threshold_m == pytest.approx(
        3 * expected
    )
    assert result.verdict == PASS
    # A threshold below what the noise allows fails: the verdict is about the threshold, not the improvement.
    strict = verify(nominal_set(2, seed=0), calibrated, fresh, threshold_m=1e-6)
    assert strict.verdict == FAIL and strict.threshold_source == 'given'
    assert strict.verdict_reason().startswith('fail: calibrated position rms')


def test_json_and_status_values_carry_the_contract_keys(noisy_calibration):
    calibrated, fresh = noisy_calibration
    result = verify(nominal_set(2, seed=0), calibrated, fresh)
    payload = result.to_json()
    assert JSON_KEYS <= set(payload)
    assert payload['model'] == 'hexa_slide' and payload['postures'] == 40
    for name in ('nominal', 'calibrated'):
        assert FIGURE_KEYS <= set(payload[name])
    assert payload['verdict'] in (PASS, FAIL)
    assert payload['improvement'] == pytest.approx(
        payload['nominal']['position_rms_m'] / payload['calibrated']['position_rms_m']
    )
    json.dumps(payload, allow_nan=False)  # strict JSON
    values = result.status_values()
    for key in ('model', 'postures', 'improvement', 'threshold_m', 'verdict'):
        assert key in values
    for name in ('nominal', 'calibrated'):
        for key in FIGURE_KEYS:
            assert float(values[f'{name}.{key}']) == pytest.approx(payload[name][key], rel=1e-5)
    per_posture = result.to_json(per_posture=True)['per_posture']
    assert len(per_posture['calibrated_position_error_m']) == 40


def test_fixed_position_postures_are_compared_with_the_fixed_point():
    exact = _postures(TRUTH, 4, 6, 4)
    # An inclinometer that reads a few urad at the fixed position: the postures stay fixed-position ones,
    # compared with [0, 0, -L], not with what eq. 4 makes of the reading.
    exact.inclinometer[exact.kinds == FIXED] += 2e-5
    result = verify(nominal_set(1, seed=0), TRUTH, exact)
    fixed = result.kinds == FIXED
    assert fixed.sum() == 4
    assert np.allclose(result.measured_position_m[fixed], [0.0, 0.0, -0.75], atol=1e-15)
    assert result.calibrated.figures()['position_max_m'] < 1e-10


def test_forward_kinematics_failures_are_reported_per_posture_not_dropped():
    exact = _postures(TRUTH, 5, 12)
    exact.actuator_positions[7] += np.array(
        [0.08, -0.08, 0.08, -0.08, 0.08, -0.08]
    )  # no pose near the measured one
    result = verify(nominal_set(2, seed=0), TRUTH, exact)
    assert 7 in result.calibrated.failures and 7 in result.nominal.failures
    figures = result.calibrated.figures()
    assert figures['fk_failures'] == 1 and figures['postures_converged'] == 11
    assert figures['position_rms_m'] < 1e-10  # over the postures that converged
    assert result.verdict == FAIL
    assert (
        'forward kinematics with the calibrated parameters failed on 1 of 12'
        in result.verdict_reason()
    )
    failed = result.to_json()['calibrated']['failed_postures']
    assert [f['index'] for f in failed] == [7] and failed[0]['reason']
    assert 'calibrated.failed.7' in result.status_values()


def test_gough_stewart_hanging_and_standing():
    from hexacal_identify.core.architectures.gough_stewart import GoughStewartParameters

    gs = 'gough_stewart'
    truth = default_parameters(gs)
    exact = _postures(truth, 6, 15, 3, model=gs)
    result = verify(nominal_set(2, seed=0, model=gs), truth, exact, postures_model=gs)
    assert result.model == gs and result.calibrated.figures()['position_rms_m'] < 1e-10
    assert result.nominal.figures()['position_rms_m'] > 1e-3
    # An upright machine (the default hexapod reflected, z -> -z) with a standing device: positions from -p.
    mirror = np.diag([1.0, 1.0, -1.0])
    upright = GoughStewartParameters.from_parts(
        truth.base_points @ mirror, truth.platform_points @ mirror, truth.leg_offsets
    )
    poses = sample_poses(
        truth, 10, np.random.default_rng(7), SPHERE, architecture(gs).default_workspace()
    )
    poses[:, [2, 3, 4]] *= -1.0
    standing = DeviceModel(mount='standing')
    measured = simulate_measurements(upright, poses, SPHERE, device=standing)
    checked = verify(upright, upright, measured, device=standing)
    assert checked.mount == 'standing' and checked.calibrated.figures()['position_rms_m'] < 1e-10
    assert np.all(checked.measured_position_m[:, 2] > 0)
    # The same readings taken for a hanging device put the platform below O: FK says otherwise.
    wrong = verify(upright, upright, measured)
    assert wrong.verdict == FAIL


def test_a_rotary_hexapod_verifies_as_the_sliders_do():
    rh = 'rotary_hexapod'
    truth = default_parameters(rh)
    exact = _postures(truth, 6, 15, 3, model=rh)
    result = verify(nominal_set(2, seed=0, model=rh), truth, exact, postures_model=rh)
    assert result.model == rh and result.verdict == PASS
    assert result.calibrated.figures()['position_rms_m'] < 1e-10
    assert result.nominal.figures()['position_rms_m'] > 1e-3
    assert verify(truth, nominal_set(2, seed=0, model=rh), exact, postures_model=rh).verdict == FAIL


def test_model_mismatch_is_a_named_error():
    exact = _postures(TRUTH, 8, 5)
    with pytest.raises(VerificationModelError, match='same machine model') as error:
        verify(nominal_set(2, seed=0), default_parameters('gough_stewart'), exact)
    assert error.value.reason == 'model-mismatch'
    with pytest.raises(VerificationModelError, match='postures are of a gough_stewart'):
        verify(nominal_set(2, seed=0), TRUTH, exact, postures_model='gough_stewart')


def test_bad_input_is_refused():
    exact = _postures(TRUTH, 9, 5)
    with pytest.raises(InvalidMeasurementError, match='no postures'):
        verify(TRUTH, TRUTH, exact.subset(np.array([], dtype=int)))
    with pytest.raises(ValueError, match='positive length'):
        verify(TRUTH, TRUTH, exact, threshold_m=-1.0)
    exact.actuator_positions[2, 0] = np.nan
    with pytest.raises(InvalidMeasurementError, match='non-finite'):
        verify(TRUTH, TRUTH, exact)


# --------------------------------------------------------------------------- CLI

@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """A calibration bag and a verification bag, two recordings of the Table 1 machine (synthetic writer);
    nominal set 2; the calibration of the first bag (hexacal calibrate)."""
    from synthetic_recording import write_recording

    root = tmp_path_factory.mktemp('verify_cli')
    nominal, calibrated = root / 'nominal2.yaml', root / 'calibrated.yaml'
    save_parameters(nominal, nominal_set(2, seed=0).vector)
    fit_bag = write_recording(
        root / 'fit', _postures(TRUTH, 11, 36, 12), seed=11, rate_hz=25.0, raw=False
    )
    verify_bag = write_recording(
        root / 'verify', _postures(TRUTH, 12, 24, 6), seed=12, rate_hz=25.0, raw=False
    )
    completed = hexacal('calibrate', fit_bag, '--nominal', nominal, '--output', calibrated)
    assert completed.returncode == 0, completed.stderr
    return {
        'root': root,
        'nominal': nominal,
        'calibrated': calibrated,
        'fit': fit_bag,
        'verify': verify_bag,
    }


def test_cli_passes_on_a_fresh_recording_with_the_contract_json(bags):
    completed = hexacal(
        'verify',
        bags['verify'],
        '--nominal',
        bags['nominal'],
        '--calibrated',
        bags['calibrated'],
        '--json',
    )
    assert completed.returncode == 0, completed.stderr
    payload = json.loads(completed.stdout)
    assert JSON_KEYS <= set(payload)
    assert payload['model'] == 'hexa_slide' and payload['postures'] == 30
    for name in ('nominal', 'calibrated'):
        assert FIGURE_KEYS <= set(payload[name])
    assert payload['verdict'] == 'pass' and payload['threshold_m'] == DEFAULT_THRESHOLD_M
    assert payload['nominal']['position_rms_m'] > 1e-3  # millimetres before
    assert payload['calibrated']['position_rms_m'] < 15e-6  # the noise of averaged readings after
    assert payload['improvement'] > 100


def test_cli_fails_with_exit_1(bags):
    # The nominal set as 'calibrated': millimetres, far beyond the threshold.
    completed = hexacal(
        'verify',
        bags['verify'],
        '--nominal',
        bags['nominal'],
        '--calibrated',
        bags['nominal'],
        '--json',
    )
    assert completed.returncode == 1, completed.stderr
    payload = json.loads(completed.stdout)
    assert payload['verdict'] == 'fail' and payload['improvement'] == pytest.approx(1.0)
    # A threshold tighter than the noise: exit 1 too.
    completed = hexacal(
        'verify',
        bags['verify'],
        '--nominal',
        bags['nominal'],
        '--calibrated',
        bags['calibrated'],
        '--json',
        '--threshold-um',
        '0.01',
    )
    assert completed.returncode == 1
    payload = json.loads(completed.stdout)
    assert payload['verdict'] == 'fail' and payload['threshold_m'] == pytest.approx(1e-8)


@pytest.mark.parametrize(
    'case', ['gough_stewart_nominal', 'missing_bag', 'bad_threshold', 'bad_calibrated']
)
def test_cli_bad_input_exits_2_with_one_line(bags, case):
    from hexacal_identify.core.machine.model import nominal_set as nominal_of

    root = bags['root']
    argv = [bags['verify'], '--nominal', bags['nominal'], '--calibrated', bags['calibrated']]
    if case == 'gough_stewart_nominal':
        gs = root / 'gs_nominal.yaml'
        save_parameters(
            gs, nominal_of(2, seed=0, model='gough_stewart').vector, model='gough_stewart'
        )
        argv[4] = gs  # a Gough-Stewart 'calibrated' set against a Hexa Slide nominal and bag
        expected = 'same machine model'
    elif case == 'missing_bag':
        argv[0] = root / 'no_such_bag'
        expected = 'no_such_bag'
    elif case == 'bad_threshold':
        argv += ['--threshold-um', '-5']
        expected = '--threshold-um'
    else:
        broken = root / 'broken.yaml'
        broken.write_text('not: [a parameters file\n')
        argv[4] = broken
        expected = 'broken.yaml'
    completed = hexacal('verify', *argv, '--json')
    assert completed.returncode == 2, (completed.stdout, completed.stderr)
    assert completed.stdout == ''
    lines = completed.stderr.strip().splitlines()
    assert (
        len(lines) == 1 and lines[0].startswith('hexacal verify: error:') and expected in lines[0]
    ), lines


def test_cli_model_of_the_bag_must_be_the_nominal_one(bags):
    gs = bags['root'] / 'gs_nominal_for_bag.yaml'
    save_parameters(
        gs, nominal_set(2, seed=0, model='gough_stewart').vector, model='gough_stewart'
    )
    completed = hexacal('verify', bags['verify'], '--nominal', gs, '--calibrated', gs)
    assert completed.returncode == 2
    assert 'holds hexa_slide postures' in completed.stderr


def test_cli_table_and_report(bags, tmp_path):
    out = tmp_path / 'report'
    completed = hexacal(
        'verify',
        bags['verify'],
        '--nominal',
        bags['nominal'],
        '--calibrated',
        bags['calibrated'],
        '--report',
        out,
        '--noise-um',
        '2',
    )
    assert completed.returncode == 0, completed.stderr
    text = completed.stdout
    for label in (
        'position rms [um]',
        'position max [um]',
        'rotary rms [urad]',
        'improvement:',
        'threshold:',
        'verdict: pass',
        'expected from the reading noise alone',
    ):
        assert label in text, text
    page = (out / 'index.html').read_text()
    assert 'Verification on fresh postures' in page and "id='verification-figures'" in page
    assert 'data:image/png;base64,' in page
    assert (out / 'verification.png').stat().st_size > 1000


def test_cli_sample_bags_calibrate_on_one_recording_verify_on_another(tmp_path):
    """The recorded sample bags (driver + collector) are two recordings of the Table 1 machine: calibrate on one,
    verify on the other, whose postures the fit never saw."""
    nominal, calibrated = tmp_path / 'nominal2.yaml', tmp_path / 'calibrated.yaml'
    save_parameters(nominal, nominal_set(2, seed=0).vector)
    completed = hexacal('calibrate', SAMPLE_FIT_BAG, '--nominal', nominal, '--output', calibrated)
    assert completed.returncode == 0, completed.stderr
    completed = hexacal(
        'verify', SAMPLE_VERIFY_BAG, '--nominal', nominal, '--calibrated', calibrated, '--json'
    )
    assert completed.returncode == 0, completed.stderr
    payload = json.loads(completed.stdout)
    assert payload['postures'] == 50 and payload['verdict'] == 'pass'
    assert payload['nominal']['position_rms_m'] > 1e-3
    assert payload['calibrated']['position_rms_m'] < 15e-6
    assert payload['calibrated']['fk_failures'] == 0
    # FK with the nominal set fails at a posture of this bag: reported, not dropped.
    assert payload['nominal']['fk_failures'] == len(payload['nominal']['failed_postures'])


def test_cli_gough_stewart_recordings(tmp_path):
    """The same on the default Gough-Stewart platform: calibrate one recording, verify another."""
    from synthetic_recording import write_recording

    gs = 'gough_stewart'
    truth = default_parameters(gs)
    nominal, calibrated = tmp_path / 'nominal2_gs.yaml', tmp_path / 'calibrated_gs.yaml'
    save_parameters(nominal, nominal_set(2, seed=0, model=gs).vector, model=gs)
    fit = write_recording(
        tmp_path / 'fit',
        _postures(truth, 41, 40, 0, model=gs),
        seed=41,
        rate_hz=25.0,
        raw=False,
        model=gs,
        record_model=gs,
    )
    fresh = write_recording(
        tmp_path / 'verify',
        _postures(truth, 42, 20, 5, model=gs),
        seed=42,
        rate_hz=25.0,
        raw=False,
        model=gs,
        record_model=gs,
    )
    completed = hexacal('calibrate', fit, '--nominal', nominal, '--output', calibrated)
    assert completed.returncode == 0, completed.stderr
    completed = hexacal(
        'verify', fresh, '--nominal', nominal, '--calibrated', calibrated, '--json'
    )
    assert completed.returncode == 0, completed.stderr
    payload = json.loads(completed.stdout)
    assert payload['model'] == gs and payload['postures'] == 25 and payload['verdict'] == 'pass'
    assert (
        payload['nominal']['position_rms_m'] > 1e-3
        and payload['calibrated']['position_rms_m'] < 15e-6
    )


def test_verify_help_imports_no_matplotlib_nor_ros():
    script = (
        "import sys\nfrom hexacal_identify import cli\ntry:\n    cli.main(['verify', '--help'])\n"
        'except SystemExit:\n    pass\n'
        "print([m for m in sys.modules if m.startswith(('matplotlib', 'rclpy', 'hexacal_identify.report'))])"
    )
    completed = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
    assert '--calibrated' in completed.stdout and completed.stdout.strip().endswith('[]')


# --------------------------------------------------------------------------- node


def _named_statuses(probe) -> list:
    """(name, level, message, values) of every status on hexacal/calibration_status, appended as they arrive."""
    from diagnostic_msgs.msg import DiagnosticArray
    from hexacal_msgs_py.conversions import status_values
    from hexacal_msgs_py.qos import STATUS_MONITOR_QOS

    received: list = []

    def on_status(message: DiagnosticArray) -> None:
        for status in message.status:
            level = (
                int.from_bytes(status.level, 'little')
                if isinstance(status.level, bytes)
                else int(status.level)
            )
            received.append((status.name, level, status.message, status_values(status)))

    probe.node.create_subscription(
        DiagnosticArray, 'hexacal/calibration_status', on_status, STATUS_MONITOR_QOS
    )
    return received


@pytest.mark.slow
def test_identify_verifies_the_latest_calibration_on_the_postures_received_after_it(
    ros_processes, tmp_path, probe
):
    from hexacal_msgs_py.names import (
        CALIBRATION_STATUS_NAME,
        VERIFICATION_STATUS_NAME,
        VERIFY_SERVICE,
    )

    _, nominal = write_parameter_files(tmp_path)
    out = tmp_path / 'out'
    identify = ros_processes.start(
        node_argv(
            'identify',
            {
                'nominal': str(nominal),
                'output_dir': str(out),
                'noise_slider_m': 1e-5,
                'noise_angle_rad': 1e-5,
            },
        )
    )
    probe.wait_for_node('identify', process=identify)
    probe.subscribe_status()
    named = _named_statuses(probe)

    def verification(after: int, predicate) -> tuple:
        return probe.spin_until(
            lambda: [
                s for s in named[after:] if s[0] == VERIFICATION_STATUS_NAME and predicate(s[3])
            ],
            120.0,
            'a verification status',
            identify.describe,
        )[-1]

    refused = probe.call_trigger(VERIFY_SERVICE)
    assert not refused.success and refused.message.startswith('no-calibration:'), refused.message
    assert verification(0, lambda v: v.get('outcome') == 'no-calibration')[1] == 2  # ERROR

    probe.publish_postures(simulated_postures(50, seed=21))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 50,
        60.0,
        'identify to hold 50 postures',
        identify.describe,
    )
    calibrated = probe.call_trigger()
    assert calibrated.success and '50 of 50 postures' in calibrated.message, calibrated.message
    mark = len(named)
    refused = probe.call_trigger(VERIFY_SERVICE)
    assert not refused.success and refused.message.startswith('no-postures:'), refused.message
    verification(mark, lambda v: v.get('outcome') == 'no-postures')

    # Fresh postures of the same machine, never in the fit: the verification set.
    probe.publish_postures(simulated_postures(30, seed=22))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 80,
        60.0,
        'identify to hold 80 postures',
        identify.describe,
    )
    collecting = [v for _, _, v in probe.statuses if v.get('outcome') == 'collecting'][-1]
    assert collecting['verification_postures'] == '30'
    # The calibration's report is written (and followed up) before the verification rewrites it.
    probe.spin_until(
        lambda: [
            s
            for s in named
            if s[0] == CALIBRATION_STATUS_NAME and s[3].get('report_state') == 'ready'
        ],
        120.0,
        'the calibration report',
    )
    mark = len(named)
    response = probe.call_trigger(VERIFY_SERVICE)
    assert response.success, response.message
    assert response.message.startswith('pass: calibrated position rms'), response.message
    _, level, message, values = verification(mark, lambda v: v.get('outcome') == 'verified')
    assert level == 0 and values['verdict'] == 'pass' and values['postures'] == '30'
    assert values['report_state'] == 'writing' and values['calibration_number'] == '1'
    assert values['postures_before_calibration'] == '50'
    nominal_rms, calibrated_rms = (
        float(values['nominal.position_rms_m']),
        float(values['calibrated.position_rms_m']),
    )
    noise_rms = float(values['expected_noise.position_rms_m'])
    assert 1e-3 < nominal_rms < 0.05  # millimetres with the nominal set
    assert 0.5 * noise_rms < calibrated_rms < 2.5 * noise_rms, values  # the noise level after
    assert calibrated_rms < 60e-6 and float(values['improvement']) > 100
    assert float(values['threshold_m']) == pytest.approx(3 * noise_rms, rel=1e-4)
    for key in (
        'nominal.position_max_m',
        'nominal.rotary_rms_rad',
        'calibrated.position_max_m',
        'calibrated.rotary_rms_rad',
        'model',
    ):
        assert key in values

    # The report gains the verification section; the follow-up says so on the verification status.
    _, _, ready_message, ready = verification(mark, lambda v: v.get('report_state') == 'ready')
    page = out / 'report' / 'index.html'
    assert ready['report'] == str(page) and f'report ready: {page}' in ready_message
    text = page.read_text()
    assert 'Verification on fresh postures' in text and "id='verification-figures'" in text
    assert (
        text.rstrip().endswith('</html>') and 'converged' in text
    )  # still the calibration's report
    assert (out / 'report' / 'verification.png').stat().st_size > 1000
    assert {k: v for k, v in ready.items() if k not in ('report_state', 'report')} == {
        k: v for k, v in values.items() if k != 'report_state'
    }


def _publish_after_restart(probe, postures: list, restarted) -> None:
    """Publish postures to a restarted identify and wait until it holds them all. The first node's
    statuses counted through the same numbers: look only at those that arrive after the restart."""
    after_restart = len(probe.statuses)
    probe.publish_postures(postures)
    count = str(len(postures))
    probe.spin_until(
        lambda: [
            s
            for s in probe.statuses[after_restart:]
            if s[2].get('outcome') == 'collecting' and s[2].get('postures_received') == count
        ],
        60.0,
        f'{count} postures after the restart',
        restarted.describe,
    )


@pytest.mark.slow
def test_restarted_identify_verifies_the_saved_calibration(ros_processes, tmp_path, probe):
    from hexacal_msgs_py.names import VERIFICATION_STATUS_NAME, VERIFY_SERVICE
    from system_support import STOP_TIMEOUT_S

    _, nominal = write_parameter_files(tmp_path)
    out = tmp_path / 'out'
    parameters = {'nominal': str(nominal), 'output_dir': str(out)}
    first = ros_processes.start(node_argv('identify', parameters), name='identify-first')
    probe.wait_for_node('identify', process=first)
    probe.subscribe_status()
    probe.publish_postures(simulated_postures(40, seed=31))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 40,
        60.0,
        'identify to hold 40 postures',
        first.describe,
    )
    assert probe.call_trigger().success
    assert ros_processes.stop(first, STOP_TIMEOUT_S) == 0
    calibration_page = (out / 'report' / 'index.html').read_text()

    restarted = ros_processes.start(node_argv('identify', parameters), name='identify-restarted')
    probe.spin_until(
        lambda: 'republished the saved calibration' in restarted.log_text(),
        30.0,
        'the restarted node to republish',
        restarted.describe,
    )
    named = _named_statuses(probe)
    refused = probe.call_trigger(VERIFY_SERVICE)
    assert (
        not refused.success
        and refused.message.startswith('no-postures:')
        and 'saved calibration' in refused.message
    ), refused.message
    _publish_after_restart(probe, simulated_postures(25, seed=32), restarted)
    response = probe.call_trigger(VERIFY_SERVICE)
    assert response.success, response.message
    _, _, _, ready = probe.spin_until(
        lambda: [
            s
            for s in named
            if s[0] == VERIFICATION_STATUS_NAME and s[3].get('report_state') == 'ready'
        ],
        120.0,
        'the verification report',
        restarted.describe,
    )[-1]
    assert ready['calibration_number'] == '0' and ready['calibration'].startswith(
        'saved calibration'
    )
    assert (
        float(ready['calibrated.position_rms_m'])
        < 50e-6
        < 1e-3
        < float(ready['nominal.position_rms_m'])
    )
    page = out / 'report' / 'verification' / 'index.html'
    assert ready['report'] == str(page)
    assert 'Verification on fresh postures' in page.read_text()
    assert (
        out / 'report' / 'index.html'
    ).read_text() == calibration_page  # the earlier report is left alone


def test_restarted_identify_verifies_through_the_device_it_calibrated_with(
    ros_processes, tmp_path, probe
):
    """A joint calibration's file keeps its device defects: the restarted node verifies with them."""
    from hexacal_identify.core.machine.device import DeviceDefects
    from hexacal_identify.core.machine.model import table1_parameters
    from hexacal_identify.core.machine.postures import Workspace
    from hexacal_identify.calibration_steps.machine_files import load_device_defects
    from hexacal_msgs_py.names import VERIFICATION_STATUS_NAME, VERIFY_SERVICE
    from hexacal_msgs_py.readings import PostureReading
    from system_support import STOP_TIMEOUT_S

    defects = DeviceDefects(dL=5e-4, alpha0=2e-4, gamma=1e-4)

    def measured(count: int, seed: int) -> list:
        rng = np.random.default_rng(seed)
        poses = sample_poses(
            table1_parameters(), count, rng, 'sphere', Workspace(link_length=0.75 + defects.dL)
        )
        data = simulate_measurements(
            table1_parameters(),
            poses,
            SPHERE,
            noise=NoiseModel.from_microns(10),
            rng=rng,
            defects=defects,
        )
        return [
            PostureReading.from_values(
                10**9 * (i + 1),
                [*data.actuator_positions[i], *data.inclinometer[i], data.rotary[i]],
            )
            for i in range(count)
        ]

    _, nominal = write_parameter_files(tmp_path)
    out = tmp_path / 'out'
    parameters = {'nominal': str(nominal), 'output_dir': str(out), 'report_dir': ''}
    first = ros_processes.start(
        node_argv('identify', {**parameters, 'identify_device': 'dL,alpha0,gamma'}),
        name='identify-joint',
    )
    probe.wait_for_node('identify', process=first)
    probe.subscribe_status()
    probe.publish_postures(measured(50, 41))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 50,
        60.0,
        'identify to hold 50 postures',
        first.describe,
    )
    assert probe.call_trigger().success
    assert ros_processes.stop(first, STOP_TIMEOUT_S) == 0
    saved, names = load_device_defects(out / 'hexacal_calibration.yaml')
    assert names == ('dL', 'alpha0', 'gamma') and abs(saved.dL - defects.dL) < 0.25e-3, saved

    named = _named_statuses(probe)
    restarted = ros_processes.start(node_argv('identify', parameters), name='identify-restarted')
    probe.spin_until(
        lambda: 'republished the saved calibration' in restarted.log_text(),
        30.0,
        'the restarted node to republish',
        restarted.describe,
    )
    _publish_after_restart(probe, measured(30, 42), restarted)
    response = probe.call_trigger(VERIFY_SERVICE)
    assert response.success, response.message
    _, _, _, values = probe.spin_until(
        lambda: [
            s
            for s in named
            if s[0] == VERIFICATION_STATUS_NAME and 'calibrated.position_rms_m' in s[3]
        ],
        60.0,
        'the verification status',
        restarted.describe,
    )[-1]
    # Through an ideal device this machine verifies at ~530 um (the device's own error); through the
    # device it was calibrated with, at the noise level.
    assert float(values['calibrated.position_rms_m']) < 100e-6, values
