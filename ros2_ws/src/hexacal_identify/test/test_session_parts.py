"""The small parts of hexacal_identify.session: settings, device prior, nominal cache, paths."""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.session import (
    DEFAULT_OUTPUT,
    device_prior,
    failure,
    file_identity,
    NominalFile,
    Outcome,
    output_path,
    parameter_problem,
    ReportQueue,
    Settings,
    SETTINGS_PARAMETERS,
)
from hexacal_identify.session.paths import interrupted_writes
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.parameters_file import save_parameters
import pytest


# ---------------------------------------------------------------------- settings


def test_settings_fields_are_the_node_parameters():
    assert SETTINGS_PARAMETERS == (
        'nominal',
        'output',
        'output_dir',
        'cost',
        'bag',
        'link_length',
        'identify_device',
        'noise_slider_m',
        'noise_angle_rad',
        'robust_loss',
        'verify_threshold_m',
        'report_dir',
        'calibration_store',
        'weights',
        'scatter_floor_actuator_m',
        'scatter_floor_angle_rad',
        'compliance',
        'physical_file',
        'compliance_prior',
        'deflection_check',
    )
    assert Settings().output == DEFAULT_OUTPUT == 'hexacal_calibration.yaml'
    assert Settings(noise_slider_m=1e-5).noise() is None
    noise = Settings(noise_slider_m=1e-5, noise_angle_rad=2e-5).noise()
    assert (noise.actuator_m, noise.angle_rad) == (1e-5, 2e-5)


@pytest.mark.parametrize(
    ('name', 'value', 'problem'),
    [
        ('identify_device', 'dL,gamma', None),
        ('identify_device', 'dL, wobble', "identify_device: unknown ['wobble']; choose from"),
        ('robust_loss', '', None),
        ('robust_loss', 'huber', None),
        ('robust_loss', 'cauchy', "robust_loss must be '', "),
        ('cost', 'absolute', None),
        ('cost', 'manhattan', 'cost must be one of '),
        ('link_length', float('nan'), 'link_length must be finite'),
        ('device.alpha0', float('inf'), 'device.alpha0 must be finite (SI units'),
        ('device.gamma_std', -1e-5, 'device.gamma_std must be a finite standard deviation'),
        ('device.link_length', -0.7, 'device.link_length is a length in m'),
        ('device.link_length_std', 1e-5, 'device.link_length_std > 0 makes a prior'),
        ('output', '../escape.yaml', "output '../escape.yaml' is outside output_dir"),
        ('output', '', 'output must name a file'),
        ('report_dir', '../report', 'report_dir: output '),
        ('report_dir', '', None),
    ],
)
def test_parameter_problem(name, value, problem):
    def current(parameter: str, fallback: object) -> object:  # the change applied, as the node's
        return value if parameter == name else fallback

    found = parameter_problem(name, value, current)
    if problem is None:
        assert found is None
    else:
        assert found is not None and found.startswith(problem), found


def test_link_prior_is_checked_with_the_other_value_as_changed():
    values = {'device.link_length': 0.7503, 'device.link_length_std': 1e-5}

    def current(name: str, fallback: object) -> object:
        return values.get(name, fallback)

    assert parameter_problem('device.link_length_std', 1e-5, current) is None
    values['device.link_length'] = 0.0
    assert parameter_problem('device.link_length', 0.0, current) is not None


# ---------------------------------------------------------------------- device prior


def test_device_prior_from_parameter_values():
    assert not device_prior({}, 0.75)
    prior = device_prior(
        {
            'device.link_length': 0.7503,
            'device.link_length_std': 1e-5,
            'device.gamma': 1e-4,
            'device.gamma_std': 5e-5,
            'device.alpha0': 3.0,  # no std: no prior
        },
        0.75,
    )
    assert [name for name, _, _ in prior.entries] == ['dL', 'gamma']
    assert prior.entries[0][1] == pytest.approx(3e-4) and prior.entries[1][1:] == (1e-4, 5e-5)
    with pytest.raises(ValueError, match='device.link_length is not set'):
        device_prior({'device.link_length_std': 1e-5}, 0.75)


# ---------------------------------------------------------------------- nominal file


def test_nominal_file_is_read_again_only_when_it_changes(tmp_path):
    path = tmp_path / 'nominal.yaml'
    save_parameters(path, nominal_set(2, seed=0).vector)
    nominal = NominalFile()
    first, mount = nominal.load(str(path))
    assert mount == 'hanging' and nominal.model(str(path)) == 'hexa_slide'
    assert nominal.load(str(path))[0] is first  # same file: the cached object
    gough_stewart = nominal_set(2, seed=0, model='gough_stewart')
    save_parameters(path, gough_stewart.vector, model='gough_stewart')
    assert nominal.model(str(path)) == 'gough_stewart'  # replaced: read again
    assert nominal.load(str(path))[0] is not first


def test_an_unreadable_nominal_file_has_no_model_and_loading_names_the_problem(tmp_path):
    path = tmp_path / 'broken.yaml'
    path.write_text('not: [a, parameters, file')
    nominal = NominalFile()
    assert nominal.model(str(path)) is None
    assert nominal.model('') is None and nominal.model(str(tmp_path / 'missing')) is None
    with pytest.raises(ParameterFileError):
        nominal.load(str(path))
    save_parameters(path, nominal_set(2, seed=0).vector)  # fixed: read again
    assert nominal.model(str(path)) == 'hexa_slide'


def test_file_identity_changes_with_the_content(tmp_path):
    path = tmp_path / 'f'
    path.write_text('a')
    before = file_identity(path)
    path.write_text('bb')
    assert before is not None and file_identity(path) != before
    assert file_identity(tmp_path / 'missing') is None


# ---------------------------------------------------------------------- paths and queue


def test_output_path_stays_under_output_dir(tmp_path):
    assert output_path('a/b.yaml', str(tmp_path)) == tmp_path / 'a' / 'b.yaml'
    for escaping in ('../x.yaml', '/etc/x.yaml', '.'):
        with pytest.raises(ValueError):
            output_path(escaping, str(tmp_path))
    assert output_path('x.yaml', '') == Path(os.getcwd()).resolve() / 'x.yaml'


def test_interrupted_writes_are_the_save_temporaries_of_that_file(tmp_path):
    target = tmp_path / 'cal[1].yaml'
    mine = tmp_path / '.cal[1].yaml.k3j4.tmp'
    for path in (mine, tmp_path / '.other.yaml.k3j4.tmp', target):
        path.write_text('')
    assert interrupted_writes(target) == [mine]


def test_report_queue_keeps_the_latest_of_each():
    queue = ReportQueue()
    one, two = Outcome(True, 'one', 'OK', {}), Outcome(True, 'two', 'OK', {})
    assert queue.put_calibration(1, one) is None
    assert queue.put_calibration(2, two) == 1
    assert queue.take() == ((2, two), None)
    assert queue.take() == (None, None)


def test_failure_puts_the_reason_first():
    outcome = failure('no-postures', 'measure', postures=0)
    assert (outcome.success, outcome.level) == (False, 'ERROR')
    assert outcome.message == 'no-postures: measure'
    assert outcome.values == {'outcome': 'no-postures', 'postures': 0}


def test_the_session_imports_without_ros():
    script = (
        'import sys\n'
        'for name in ("rclpy", "sensor_msgs", "std_msgs", "std_srvs", "diagnostic_msgs",\n'
        '             "rcl_interfaces", "builtin_interfaces"):\n'
        '    sys.modules[name] = None  # any import of these now raises ImportError\n'
        'import hexacal_identify.session\n'
        'import hexacal_identify.session.calibration, hexacal_identify.session.verification\n'
        'print(sorted(m for m in sys.modules if m.startswith("hexacal_identify.")))\n'
    )
    completed = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
    assert 'hexacal_identify.session.session' in completed.stdout
    # The solver and the calibration steps wait for the first calibration.
    assert 'hexacal_identify.calibration_steps' not in completed.stdout
