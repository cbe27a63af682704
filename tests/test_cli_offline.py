"""``hexacal calibrate`` and ``hexacal bag-info`` on bags of known content, as a user runs them."""

import base64
import json
from pathlib import Path

from hexacal_identify.core import sample_poses, simulate_measurements, table1_parameters
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.parameters_file import load_parameters, save_parameters
import numpy as np
import pytest
from synthetic_recording import write_recording
from system_support import hexacal

TRUE = table1_parameters()


@pytest.fixture(scope='module')
def exact_postures():
    return simulate_measurements(TRUE, sample_poses(TRUE, 40, np.random.default_rng(11)))


@pytest.fixture(scope='module')
def nominal_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('params') / 'nominal.yaml'
    save_parameters(path, nominal_set(2).vector)
    return path


@pytest.fixture(scope='module')
def recorded(tmp_path_factory, exact_postures):
    return write_recording(tmp_path_factory.mktemp('bags') / 'recorded', exact_postures, seed=1)


@pytest.mark.slow
def test_calibrate_from_the_posture_topic(recorded, nominal_file, tmp_path):
    output = tmp_path / 'calibrated.yaml'
    completed = hexacal(
        'calibrate', recorded, '--nominal', nominal_file, '--output', output, '--json'
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert result['reason'] == 'converged' and result['rank'] == 54
    assert result['bag']['postures'] == 40 and result['bag']['source'] == 'posture topic'
    assert set(result) >= {
        'parameters',
        'std',
        'rank',
        'condition_number',
        'solve_seconds',
        'postures_used',
        'postures_rejected',
        'iterations',
        'reason',
    }
    identified = load_parameters(output)
    assert np.max(np.abs(identified - TRUE.vector)) < 5e-4  # 10 um noise averaged over each dwell
    assert (
        np.max(np.abs(identified - nominal_set(2).vector)) > 1e-3
    )  # it did move from the nominal


@pytest.mark.slow
def test_raw_streams_only_are_redetected_and_foreign_topics_ignored(
    exact_postures, nominal_file, tmp_path
):
    bag = write_recording(
        tmp_path / 'raw_only', exact_postures, seed=2, postures=False, extra_topic='/chatter'
    )
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml', '--json'
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert (
        result['bag']['source'] == 'raw streams (re-detected)' and result['bag']['postures'] == 40
    )
    assert result['bag']['ignored_topics'] == ['/chatter']
    assert np.max(np.abs(load_parameters(tmp_path / 'out.yaml') - TRUE.vector)) < 5e-4


def test_redetection_gives_scatter_and_refuses_the_removed_window_detector(
    exact_postures, nominal_file, tmp_path
):
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    bag = write_recording(tmp_path / 'raw', exact_postures, seed=5, postures=False)
    truth = np.column_stack(
        [exact_postures.actuator_positions, exact_postures.inclinometer, exact_postures.rotary]
    )
    settled = postures_from_bag(bag).postures
    assert len(settled) == 40
    assert all(new.scatter is not None for new in settled)
    with pytest.raises(ValueError, match="'window' was removed in hexacal 0.2.0: use 'settled'"):
        postures_from_bag(bag, detector='window')
    # (The recording opens with 0.6 s of the first posture without noise: from the second on.)
    for new, exact in zip(settled[1:], truth[1:]):
        errors = np.array(new.scatter.standard_errors)
        # Uniform +-10 um noise: ~1 um standard errors; the means within 5 of them.
        assert np.all((errors > 2e-7) & (errors < 2e-6))
        assert np.all(np.abs(np.array(new.values()) - exact) < 5 * errors)
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml',
        '--json', '--detector', 'settled', '--clock-offset', 'inclinometer=0.0',
    )
    assert completed.returncode == 0, completed.stderr
    assert json.loads(completed.stdout)['bag']['postures'] == 40
    removed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml',
        '--detector', 'window',
    )
    assert removed.returncode == 2
    assert "detector 'window' was removed in hexacal 0.2.0: use 'settled'" in removed.stderr
    refused = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml',
        '--clock-offset', 'sliders=0.1',
    )
    assert refused.returncode == 2 and 'inclinometer=S or encoder=S' in refused.stderr


def test_a_missing_stream_is_named(exact_postures, nominal_file, tmp_path):
    bag = write_recording(
        tmp_path / 'no_encoder',
        exact_postures,
        seed=3,
        postures=False,
        drop_topic='hexacal/encoder',
    )
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml'
    )
    assert completed.returncode == 2
    assert '/hexacal/encoder' in completed.stderr and 'Traceback' not in completed.stderr
    assert len(completed.stderr.strip().splitlines()) == 1
    assert not (tmp_path / 'out.yaml').exists()


@pytest.mark.parametrize('damage', ['random bytes', 'empty', 'missing'])
def test_unreadable_bags_give_one_line_errors(damage, nominal_file, tmp_path):
    path = tmp_path / 'bag.mcap'
    if damage == 'random bytes':
        path.write_bytes(np.random.default_rng(0).bytes(5000))
    elif damage == 'empty':
        path.write_bytes(b'')
    completed = hexacal(
        'calibrate', path, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml'
    )
    assert completed.returncode == 2, completed.stdout
    assert 'Traceback' not in completed.stderr and len(completed.stderr.strip().splitlines()) == 1


def test_truncated_bag_keeps_what_was_complete(recorded, nominal_file, tmp_path):
    mcap = next(Path(recorded).glob('*.mcap'))
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(mcap.read_bytes()[: int(mcap.stat().st_size * 0.7)])
    completed = hexacal(
        'calibrate', cut, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml', '--json'
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert 15 <= result['bag']['postures'] < 40


def test_bad_parameter_file_is_named(recorded, tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    chain_1.A0: [0.1, 0.2]\n')
    completed = hexacal('calibrate', recorded, '--nominal', bad, '--output', tmp_path / 'out.yaml')
    assert completed.returncode == 2 and 'chain_1.A0' in completed.stderr


def test_bag_info_lists_topics_counts_and_postures(recorded):
    completed = hexacal('bag-info', recorded)
    assert completed.returncode == 0, completed.stderr
    text = completed.stdout
    assert 'Topic: /hexacal/posture | Type: sensor_msgs/msg/JointState | Count: 40' in text
    assert '/hexacal/sliders' in text and 'Duration:' in text
    assert 'Postures:          40 (from the posture topic)' in text


@pytest.mark.slow
def test_calibrate_writes_a_report_and_a_result_the_report_command_reads(
    recorded, nominal_file, tmp_path
):
    completed = hexacal(
        'calibrate',
        recorded,
        '--nominal',
        nominal_file,
        '--output',
        tmp_path / 'out.yaml',
        '--report',
        tmp_path / 'report',
        '--save-result',
        tmp_path / 'result.json',
    )
    assert completed.returncode == 0, completed.stderr
    page = (tmp_path / 'report' / 'index.html').read_text()
    assert 'converged' in page and '54' in page
    images = [part.split('"')[0] for part in page.split('src="')[1:]]
    assert len(images) >= 4
    for source in images:  # embedded PNGs (self-contained page) or files beside it
        if source.startswith('data:image/png;base64,'):
            png = base64.b64decode(source.split(',', 1)[1])
        else:
            png = (tmp_path / 'report' / source).read_bytes()
        assert png.startswith(b'\x89PNG') and len(png) > 1000
    again = hexacal('report', tmp_path / 'result.json', '--out', tmp_path / 'again')
    assert again.returncode == 0, again.stderr
    assert (tmp_path / 'again' / 'index.html').exists()


@pytest.mark.slow
def test_namespaced_bag_with_glitched_readings_is_redetected(
    exact_postures, nominal_file, tmp_path
):
    bag = write_recording(
        tmp_path / 'left', exact_postures, seed=4, postures=False, namespace='left', nan_every=97
    )
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml', '--json'
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert (
        result['bag']['postures'] == 40 and result['bag']['invalid_messages'] == 40
    )  # one NaN per posture
    assert np.max(np.abs(load_parameters(tmp_path / 'out.yaml') - TRUE.vector)) < 5e-4


@pytest.mark.parametrize('cost', ['fixed', 'sphere-fixed', 'relative'])
def test_a_cost_needing_fixed_postures_on_a_sphere_only_bag_is_named(
    recorded, nominal_file, cost, tmp_path
):
    completed = hexacal(
        'calibrate',
        recorded,
        '--nominal',
        nominal_file,
        '--output',
        tmp_path / 'out.yaml',
        '--cost',
        cost,
    )
    assert completed.returncode == 2, completed.stdout
    assert f'the {cost} cost function needs at least' in completed.stderr
    assert '0 fixed-position' in completed.stderr and 'Traceback' not in completed.stderr
    assert not (tmp_path / 'out.yaml').exists()


# --------------------------------------------------------------------------- a user's drivers (#11)

ACTUATORS = ['lift_1', 'lift_2', 'lift_3', 'lift_4', 'lift_5', 'lift_6']


def write_mapped_recording(
    directory,
    exact,
    *,
    seed: int = 0,
    imu_type: str = 'sensor_msgs/msg/Imu',
    drop_imu: bool = False,
    mapping_overrides: dict | None = None,
    noise: float = 1e-5,
    rate_hz: float = 100.0,
):
    """A bag as the collector records a ros2_control machine with an IMU: /joint_states (custom
    actuator names, the rotary joint, another joint) and /imu (alpha reversed, offsets), no posture
    topic, the input mapping in the hexacal.collector record."""
    from hexacal_identify.bag import BagWriter
    from hexacal_msgs_py.inputs import inclinometer_angles_to_quaternion, InputMapping

    mapping = InputMapping(
        ACTUATORS,
        rotary_joint='roll',
        inclinometer_type='imu',
        inclinometer_signs=(-1, 1),
        inclinometer_offsets_rad=(0.003, -0.001),
        topics=('/joint_states', '/imu', '/joint_states'),
    )
    record = {'namespace': '/', 'model': 'hexa_slide', 'window_s': '0.3', **mapping.to_metadata()}
    record.update(mapping_overrides or {})
    rng = np.random.default_rng(seed)
    values = np.column_stack([exact.actuator_positions, exact.inclinometer, exact.rotary])
    period = int(1e9 / rate_hz)
    stamp = 1_700_000_000 * 1_000_000_000
    with BagWriter(directory) as writer:
        writer.write_metadata('hexacal.collector', record)
        writer.add_topic('/joint_states', 'sensor_msgs/msg/JointState')
        if not drop_imu:
            writer.add_topic('/imu', imu_type)
        previous = values[0]
        for target in values:
            moving = [previous + (target - previous) * (k + 1) / 60 for k in range(60)]
            dwell = target + rng.uniform(-1, 1, (100, 9)) * noise
            for sample in moving + list(dwell):
                stamp += period
                header = {
                    'stamp': {'sec': stamp // 1_000_000_000, 'nanosec': stamp % 1_000_000_000},
                    'frame_id': 'base_link',
                }
                writer.write(
                    '/joint_states',
                    {
                        'header': header,
                        'name': ['roll', *reversed(ACTUATORS), 'gripper'],
                        'position': [float(sample[8]), *map(float, reversed(sample[:6])), 0.5],
                        'velocity': [],
                        'effort': [],
                    },
                    stamp,
                )
                if drop_imu:
                    continue
                raw = mapping.raw_inclinometer(sample[6], sample[7])
                x, y, z, w = inclinometer_angles_to_quaternion(*raw, yaw=-1.2)
                if imu_type.endswith('Imu'):
                    writer.write(
                        '/imu',
                        {
                            'header': header,
                            'orientation': {'x': x, 'y': y, 'z': z, 'w': w},
                            'orientation_covariance': [0.0] * 9,
                        },
                        stamp,
                    )
                else:
                    writer.write(
                        '/imu',
                        {
                            'header': header,
                            'name': ['x', 'y'],
                            'position': list(raw),
                            'velocity': [],
                            'effort': [],
                        },
                        stamp,
                    )
            previous = target
    return directory


@pytest.mark.slow
def test_a_mapped_bag_of_joint_states_and_an_imu_calibrates(
    exact_postures, nominal_file, tmp_path
):
    bag = write_mapped_recording(tmp_path / 'mapped', exact_postures, seed=5)
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml', '--json'
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    assert (
        result['bag']['source'] == 'raw streams (re-detected)' and result['bag']['postures'] == 40
    )
    assert result['bag']['ignored_topics'] == [] and result['bag']['invalid_messages'] == 0
    assert np.max(np.abs(load_parameters(tmp_path / 'out.yaml') - TRUE.vector)) < 5e-4
    info = hexacal('bag-info', bag)
    assert 'hexacal.collector.inclinometer_type = imu' in info.stdout
    assert 'hexacal.collector.actuator_joints = ["lift_1"' in info.stdout


@pytest.mark.slow
def test_a_mapped_bag_reads_as_the_contracts_recording_of_the_same_readings(
    exact_postures, tmp_path
):
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    mapped = postures_from_bag(
        write_mapped_recording(tmp_path / 'mapped', exact_postures, seed=6, noise=0.0)
    )
    contract = postures_from_bag(
        write_recording(
            tmp_path / 'contract',
            exact_postures,
            seed=6,
            noise_m=0.0,
            noise_rad=0.0,
            dwell_s=1.0,
            move_s=0.6,
            postures=False,
        )
    )
    assert len(mapped.postures) == len(contract.postures) == 40
    difference = np.abs(
        np.array([p.values() for p in mapped.postures])
        - np.array([p.values() for p in contract.postures])
    ).max()
    assert difference < 1e-12, difference


@pytest.mark.parametrize(
    'case, text',
    [
        ('no imu', 'lacks the raw stream(s) /imu (the inclinometer input)'),
        (
            'imu is a joint state',
            'topic /imu has type sensor_msgs/msg/JointState, expected sensor_msgs/msg/Imu',
        ),
        (
            'bad mapping',
            'the input mapping its collector recorded (hexacal.collector) is invalid: '
            'inclinometer_signs: each sign must be 1 or -1',
        ),
    ],
)
def test_mapped_bag_problems_are_named(exact_postures, nominal_file, tmp_path, case, text):
    options = {
        'no imu': dict(drop_imu=True),
        'imu is a joint state': dict(imu_type='sensor_msgs/msg/JointState'),
        'bad mapping': dict(mapping_overrides={'inclinometer_signs': '[1, 3]'}),
    }[case]
    few = type(exact_postures)(
        exact_postures.actuator_positions[:3],
        exact_postures.inclinometer[:3],
        exact_postures.rotary[:3],
        exact_postures.kinds[:3],
    )
    bag = write_mapped_recording(tmp_path / 'bag', few, **options)
    completed = hexacal(
        'calibrate', bag, '--nominal', nominal_file, '--output', tmp_path / 'out.yaml'
    )
    assert completed.returncode == 2, completed.stdout
    assert text in completed.stderr and len(completed.stderr.strip().splitlines()) == 1, (
        completed.stderr
    )
