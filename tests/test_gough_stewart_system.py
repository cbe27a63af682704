"""The ROS side on a Gough-Stewart platform (#10): names, nodes, bags and `hexacal calibrate` for either model.

Offline (no ROS graph):

* the recorded sample bag ``bags/gs_sphere50_noise10`` (driver + collector, model gough_stewart) through
  ``hexacal calibrate`` from the Gough-Stewart nominal set 2: rank 42, parameters and poses at the noise level
  of the known truth (the default Gough-Stewart machine);
* a bag's actuator joints name its model: a nominal file of the other model is one named line, exit 2 (both
  ways), as is a bag whose joints contradict the model its collector recorded;
* raw-stream re-detection of a Gough-Stewart bag (leg_1..6 on hexacal/sliders).

Nodes (real processes, Fast DDS, this session's domain):

* driver (model gough_stewart) -> collector (model from the nominal file) -> identify (GS nominal): the
  posture topic carries leg_1..6, the calibration over /hexacal/calibrate publishes 42 parameters with the
  Gough-Stewart layout, the saved file and the bag name the model;
* identify takes its model from the nominal file: the other model's postures are rejected on receipt
  (``rejected.model-mismatch``); postures received without a nominal file are refused at calibration when
  the nominal file then names another model, and calibrate with the right one;
* the collector and the driver validate model / parameters_file / true_params and refuse contradictions
  at start-up (exit 2, the reason in the log); a collector of the other model names the model the sliders
  carry.
"""

from __future__ import annotations

import json
from pathlib import Path

from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
from hexacal_identify.core.machine.measurements import (
    FIXED,
    Measurements,
    simulate_measurements,
    SPHERE,
)
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
from hexacal_msgs_py.parameters_file import (
    chain_dict_to_parameters,
    read_parameters_file,
    save_parameters,
)
import numpy as np
import pytest
from synthetic_recording import write_recording
from system_support import (
    fast_collector_parameters,
    fast_driver_parameters,
    hexacal,
    node_argv,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    STOP_TIMEOUT_S,
    write_parameter_files,
)
import yaml

GS = 'gough_stewart'
ARCH = architecture(GS)
TRUE = ARCH.default_parameters()
WORKSPACE = ARCH.default_workspace()
BAGS = Path(__file__).resolve().parent.parent / 'bags'
SAMPLE = BAGS / 'gs_sphere50_noise10'
LEGS = tuple(f'leg_{i}' for i in range(1, 7))
DEVICE_JOINTS = ('inclinometer_x', 'inclinometer_y', 'rotary')


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    """(GS truth, GS nominal set 2, Hexa Slide nominal set 2) parameter files."""
    directory = tmp_path_factory.mktemp('params')
    truth, nominal = write_parameter_files(directory, GS)
    _, hexa_nominal = write_parameter_files(directory)
    return truth, nominal, hexa_nominal


@pytest.fixture(scope='module')
def exact():
    """Noise-free GS readings: 36 sphere + 12 fixed postures of the default machine."""
    rng = np.random.default_rng(21)
    sphere = simulate_measurements(TRUE, sample_poses(TRUE, 36, rng, SPHERE, WORKSPACE))
    fixed = simulate_measurements(TRUE, sample_poses(TRUE, 12, rng, FIXED, WORKSPACE), FIXED)
    return Measurements(
        np.concatenate([sphere.actuator_positions, fixed.actuator_positions]),
        np.concatenate([sphere.inclinometer, fixed.inclinometer]),
        np.concatenate([sphere.rotary, fixed.rotary]),
        np.concatenate([sphere.kinds, fixed.kinds]),
    )


def _pose_errors(vector) -> dict:
    poses = validation_poses(TRUE, 50, 0, WORKSPACE)
    return pose_errors(TRUE, TRUE.with_vector(vector), poses).summary()


# --------------------------------------------------------------------------- offline


def test_sample_bag_says_its_model_and_calibrates_to_the_noise_level(files, tmp_path):
    _, nominal, _ = files
    metadata = yaml.safe_load((SAMPLE / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information'
    ]
    assert metadata['custom_data']['hexacal.model'] == GS
    bag = postures_from_bag(SAMPLE)
    assert (
        bag.model == GS and len(bag.postures) == 50 and bag.plan['hexacal.collector.model'] == GS
    )

    output = tmp_path / 'calibrated.yaml'
    completed = hexacal('calibrate', SAMPLE, '--nominal', nominal, '--output', output, '--json')
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert result['model'] == GS and result['bag']['model'] == GS
    assert (
        result['reason'] == 'converged' and result['rank'] == 42 and result['postures_used'] == 50
    )
    identified = chain_dict_to_parameters(result['parameters'], GS)
    saved = read_parameters_file(output)
    assert saved.model == GS and np.array_equal(saved.vector, identified)
    # 10 um / 10 urad noise, averaged over each dwell: measured 0.054 mm, 2.2 / 5.4 um (bags/README.md).
    assert np.max(np.abs(identified - TRUE.vector)) < 0.2e-3
    assert np.max(np.abs(nominal_set(2, model=GS).vector - TRUE.vector)) > 2e-3  # it was off by mm
    after = _pose_errors(identified)
    assert after['position_mean_m'] < 5e-6 and after['position_max_m'] < 15e-6, after
    assert after['failed_postures'] == 0
    info = hexacal('bag-info', SAMPLE)
    assert info.returncode == 0 and 'hexacal.collector.model = gough_stewart' in info.stdout


@pytest.mark.parametrize('bag_model', [GS, 'hexa_slide'])
def test_a_nominal_file_of_the_other_model_is_a_named_error(files, tmp_path, bag_model):
    _, gs_nominal, hexa_nominal = files
    bag, nominal = (
        (SAMPLE, hexa_nominal) if bag_model == GS else (BAGS / 'sphere50_noise10', gs_nominal)
    )
    other = 'hexa_slide' if bag_model == GS else GS
    completed = hexacal('calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml')
    assert completed.returncode == 2, completed.stderr
    lines = completed.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('hexacal calibrate: error: '), lines
    assert f'holds {bag_model} postures' in lines[0] and f"are a {other}'s" in lines[0], lines[0]
    assert not (tmp_path / 'out.yaml').exists()


@pytest.mark.slow
def test_raw_streams_of_a_gough_stewart_bag_are_redetected(files, exact, tmp_path):
    _, nominal, hexa_nominal = files
    bag = write_recording(
        tmp_path / 'gs_raw', exact, seed=3, postures=False, model=GS, record_model=GS
    )
    found = postures_from_bag(bag)
    assert (
        found.model == GS
        and found.source == 'raw streams (re-detected)'
        and len(found.postures) == 48
    )
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml', '--json'
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert result['rank'] == 42 and result['bag']['source'] == 'raw streams (re-detected)'
    assert (
        np.max(np.abs(chain_dict_to_parameters(result['parameters'], GS) - TRUE.vector)) < 0.3e-3
    )
    refused = hexacal(
        'calibrate', bag, '--nominal', hexa_nominal, '--output', tmp_path / 'no.yaml'
    )
    assert refused.returncode == 2 and 'holds gough_stewart postures' in refused.stderr


def test_joints_contradicting_the_recorded_model_are_refused(files, exact, tmp_path):
    _, nominal, _ = files
    bag = write_recording(
        tmp_path / 'liar', exact, seed=4, raw=False, model=GS, record_model='hexa_slide'
    )
    completed = hexacal('calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml')
    assert completed.returncode == 2
    assert (
        'carry gough_stewart joints' in completed.stderr
        and 'recorded a hexa_slide' in completed.stderr
    )


# --------------------------------------------------------------------------- nodes

POSTURES = 30


@pytest.mark.slow
def test_driver_collector_identify_calibrate_a_gough_stewart(ros_processes, tmp_path, probe):
    truth_path, nominal_path = write_parameter_files(tmp_path, GS)
    probe.subscribe_postures(model=GS)
    probe.subscribe_status()
    published = probe.subscribe_parameters()
    collector = ros_processes.start(
        node_argv(
            'collector',
            fast_collector_parameters(
                tmp_path / 'bags', bag_name='gs', parameters_file=str(nominal_path)
            ),
        )
    )
    identify = ros_processes.start(
        node_argv(
            'identify',
            {'nominal': str(nominal_path), 'output_dir': str(tmp_path / 'out'), 'report_dir': ''},
        )
    )
    probe.wait_for_node('collector', process=collector)
    probe.wait_for_node('identify', process=identify)
    probe.spin_until(
        lambda: (
            probe.node.count_publishers('/hexacal/posture') >= 1
            and probe.node.count_subscribers('/hexacal/posture') >= 2
        ),
        30.0,
        'collector -> identify on /hexacal/posture',
    )
    driver = ros_processes.start(
        node_argv(
            'driver',
            fast_driver_parameters(
                postures=POSTURES, model=GS, slider_noise_m=1e-5, angle_noise_rad=1e-5
            ),
        )
    )
    nodes = (driver, collector, identify)

    def collected() -> bool:
        for process in nodes:
            if not process.running():
                raise AssertionError(f'a node exited early\n{process.describe()}')
        return probe.postures_received_by_identify() >= POSTURES

    probe.spin_until(
        collected,
        4.0 * POSTURES + 120.0,  # a condition, not a sleep: generous for a loaded machine
        f'identify to receive {POSTURES} postures',
        lambda: '\n'.join(p.describe(10) for p in nodes),
    )
    assert set(probe.posture_joint_names) == {LEGS + DEVICE_JOINTS}
    assert 'model gough_stewart, actuator joints leg_1..leg_6' in collector.log_text()

    response = probe.call_trigger(timeout=120.0)
    assert response.success, response.message
    assert (
        f'{POSTURES} of {POSTURES} postures' in response.message and 'rank 42' in response.message
    )
    calibrated = probe.spin_until(lambda: published, 10.0, 'hexacal/parameters')[0]
    assert calibrated.shape == (42,)
    assert np.abs(calibrated - TRUE.vector).max() < 0.5e-3
    after = _pose_errors(calibrated)
    assert after['position_max_m'] < 50e-6 and after['failed_postures'] == 0, after
    # The result status is published beside the answer and the parameters, not before them.
    result = probe.spin_until(
        lambda: [
            values for _, _, values in probe.statuses if values.get('outcome') == 'converged'
        ],
        30.0,
        'the converged status',
    )[-1]
    assert result['model'] == GS and 'std.chain_6.l0' in result
    saved = read_parameters_file(tmp_path / 'out' / 'hexacal_calibration.yaml')
    assert saved.model == GS and np.array_equal(saved.vector, calibrated)

    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0
    bag = tmp_path / 'bags' / 'gs'
    metadata = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert metadata['custom_data']['hexacal.model'] == GS
    recorded = postures_from_bag(bag)
    assert recorded.model == GS and len(recorded.postures) == POSTURES
    assert recorded.plan['hexacal.collector.model'] == GS


def _collecting(probe) -> dict:
    found = [values for _, _, values in probe.statuses if values.get('outcome') == 'collecting']
    return found[-1] if found else {}


def _set_parameter(probe, node: str, name: str, value):
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    client = AsyncParameterClient(probe.node, node)
    probe.spin_until(client.services_are_ready, 30.0, f"{node}'s parameter services")
    future = client.set_parameters([Parameter(name, value=value)])
    return probe.spin_until(
        lambda: future.result() if future.done() else None, 15.0, f'setting {name}'
    ).results[0]


@pytest.mark.slow
def test_identify_takes_its_model_from_the_nominal_file(ros_processes, tmp_path, probe):
    _, gs_nominal = write_parameter_files(tmp_path, GS)
    _, hexa_nominal = write_parameter_files(tmp_path)
    identify = ros_processes.start(
        node_argv('identify', {'output_dir': str(tmp_path / 'out'), 'report_dir': ''})
    )
    probe.wait_for_node('identify', process=identify)
    probe.subscribe_status()
    gs_postures = simulated_postures(20, seed=3, noise_um=0.0, model=GS)

    # No nominal file yet: the joints decide, the postures are kept.
    probe.publish_postures(gs_postures, model=GS)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 20,
        30.0,
        'identify to hold 20 Gough-Stewart postures',
        identify.describe,
    )
    # A Hexa Slide nominal file: the Gough-Stewart postures are refused at calibration, by name.
    assert _set_parameter(probe, 'identify', 'nominal', str(hexa_nominal)).successful
    response = probe.call_trigger()
    assert not response.success and response.message.startswith('model-mismatch: '), (
        response.message
    )
    assert 'gough_stewart' in response.message and 'hexa_slide' in response.message
    # ... and on receipt, the next ones too: never stored.
    probe.publish_postures(gs_postures[:2], model=GS)
    values = probe.spin_until(
        lambda: _collecting(probe).get('rejected.model-mismatch') == '2' and _collecting(probe),
        15.0,
        '2 model-mismatch rejections',
        identify.describe,
    )
    assert values['postures_received'] == '20'
    assert values['last_rejection'].startswith(
        'model-mismatch: posture carries the actuator joints of a gough_stewart (leg_1..leg_6)'
    ), values

    # The Gough-Stewart nominal file: the 20 postures kept calibrate it (noise-free: to the truth).
    received = probe.subscribe_parameters()
    assert _set_parameter(probe, 'identify', 'nominal', str(gs_nominal)).successful
    response = probe.call_trigger()
    assert response.success, response.message
    calibrated = probe.spin_until(lambda: received, 10.0, 'hexacal/parameters')[-1]
    assert np.abs(calibrated - TRUE.vector).max() < 1e-9
    # Hexa Slide postures are now the other model's.
    probe.publish_postures(simulated_postures(1, seed=4))
    probe.spin_until(
        lambda: _collecting(probe).get('rejected.model-mismatch') == '3',
        15.0,
        'a Hexa Slide posture rejected',
        identify.describe,
    )


@pytest.mark.slow
def test_nodes_refuse_contradicting_models_and_name_the_other_models_joints(
    ros_processes, tmp_path, probe
):
    truth, nominal = write_parameter_files(tmp_path, GS)
    bad = {
        'driver-unknown-model': node_argv('driver', {'model': 'tripod'}),
        'driver-contradiction': node_argv(
            'driver', {'model': 'hexa_slide', 'true_params': str(truth)}
        ),
        'collector-unknown-model': node_argv('collector', {'model': 'tripod', 'record': False}),
        'collector-contradiction': node_argv(
            'collector', {'model': 'hexa_slide', 'record': False, 'parameters_file': str(nominal)}
        ),
    }
    started = {name: ros_processes.start(argv, name=name) for name, argv in bad.items()}
    for name, process in started.items():
        probe.spin_until(
            lambda: not process.running(), 60.0, f'{name} to refuse to start', process.describe
        )
        assert process.popen.returncode == 2, process.describe()
    assert (
        "model must be '' or one of hexa_slide, gough_stewart, rotary_hexapod"
        in started['driver-unknown-model'].log_text()
    )
    assert (
        "model 'hexa_slide' contradicts true_params" in started['driver-contradiction'].log_text()
    )
    assert "model must be '' or one of" in started['collector-unknown-model'].log_text()
    assert 'contradicts parameters_file' in started['collector-contradiction'].log_text()

    # A Hexa Slide collector fed by a Gough-Stewart driver: every sliders message is invalid, by name.
    probe.subscribe_status()
    collector = ros_processes.start(node_argv('collector', {'record': False}))
    driver = ros_processes.start(
        node_argv('driver', fast_driver_parameters(true_params=str(truth)))
    )
    probe.wait_for_node('collector', process=collector)

    def invalid_sliders() -> bool:
        return any(
            int(values.get('invalid.hexacal/sliders', 0)) > 0
            for _, _, values in probe.statuses
            if 'received.hexacal/sliders' in values
        )

    probe.spin_until(
        invalid_sliders,
        60.0,
        'the collector to count invalid sliders messages',
        lambda: collector.describe() + '\n' + driver.describe(),
    )
    log = collector.log_text()
    assert 'carries the actuator joints of a gough_stewart (leg_1..leg_6)' in log, log
