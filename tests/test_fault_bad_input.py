"""Bad input (issue #7): each kind gets a named error and loses nothing already collected.

Offline (``hexacal calibrate``): exit code 2 and one line on stderr, or, for single
bad readings inside a bag, the reading skipped and reported while the rest
calibrates to exactly what the clean data gives. Nodes (real `identify` and
`collector` processes): the problem is logged and published on
/hexacal/calibration_status with its reason, and the postures already received
stay usable. tests/FAULTS.md maps every item of the issue to its test.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
import re
import time

from hexacal_identify.bag import BagWriter, message_definition
from hexacal_identify.cli import main as hexacal_main
from hexacal_identify.core.machine.model import HexaParameters
from hexacal_identify.nodes.identify import output_path
from hexacal_identify.calibration_steps.calibration_run import calibrate
from hexacal_msgs_py.names import JOINT_STATE_TYPE, POSTURE_NAMES, SLIDER_NAMES
from hexacal_msgs_py.parameters_file import load_parameters, save_parameters
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest
import system_support
from system_support import (
    joint_state_dict,
    node_argv,
    NODE_START_TIMEOUT_S,
    posture_bag,
    Probe,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    write_parameter_files,
)
import yaml

POSTURE_TOPIC = '/hexacal/posture'
ERROR, WARN, OK = 2, 1, 0
DELIMITER = '\n' + '=' * 80 + '\n'


# --------------------------------------------------------------------------- helpers


def rows(postures) -> list[list[float]]:
    return [list(p.values()) for p in postures]


def hexacal(capsys, *args) -> tuple[int, str, str]:
    """`hexacal ARGS` in this process: (exit code, stdout, stderr)."""
    code = hexacal_main([str(arg) for arg in args])
    out, err = capsys.readouterr()
    return code, out, err


def assert_named_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    assert 'Traceback' not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('hexacal calibrate: error: '), err
    for needle in needles:
        assert needle in err, err


@pytest.fixture(scope='module')
def files(tmp_path_factory):
    directory = tmp_path_factory.mktemp('params')
    truth, nominal = write_parameter_files(directory)
    return truth, nominal


# --------------------------------------------------------------------------- offline readings


def test_nan_and_inf_postures_are_skipped_and_never_reach_the_parameters(capsys, files, tmp_path):
    truth, nominal = files
    good = rows(simulated_postures(30, seed=11))
    bad = [list(r) for r in good[:3]]
    bad[0][2] = math.nan
    bad[1][6] = math.inf
    bad[2][8] = -math.inf
    dirty = posture_bag(tmp_path / 'dirty', good[:10] + bad + good[10:])
    clean = posture_bag(tmp_path / 'clean', good)
    code, out, err = hexacal(
        capsys,
        'calibrate',
        dirty,
        '--nominal',
        nominal,
        '--output',
        tmp_path / 'dirty.yaml',
        '--json',
    )
    assert code == 0, err
    assert json.loads(out)['bag']['invalid_messages'] == 3
    assert (
        hexacal(
            capsys, 'calibrate', clean, '--nominal', nominal, '--output', tmp_path / 'clean.yaml'
        )[0]
        == 0
    )
    # Bit for bit what the clean postures give: the bad ones had no influence at all.
    assert np.array_equal(
        load_parameters(tmp_path / 'dirty.yaml'), load_parameters(tmp_path / 'clean.yaml')
    )
    assert np.abs(load_parameters(tmp_path / 'dirty.yaml') - load_parameters(truth)).max() < 1e-3

    only_bad = posture_bag(tmp_path / 'only_bad', [[math.nan] * 9] * 20)
    code, _, err = hexacal(
        capsys, 'calibrate', only_bad, '--nominal', nominal, '--output', tmp_path / 'none.yaml'
    )
    assert_named_error(code, err, '0 usable posture', '20 invalid message(s) skipped')
    assert not (tmp_path / 'none.yaml').exists()


@pytest.mark.parametrize(
    'channel, value, reason',
    [
        (6, 1.5, 'angle-out-of-range'),  # alpha 86 deg: beyond the inclinometer's +-60 deg
        (7, -1.2, 'angle-out-of-range'),  # beta
        (8, 4.0, 'angle-out-of-range'),  # phi beyond +-pi
        (0, 1.5, 'slider-beyond-stroke'),  # slider_1 at 1.5 m on a 0.9 m rail
        (4, -0.2, 'slider-beyond-stroke'),
    ],
)
def test_readings_beyond_a_sensor_range_are_set_aside_with_the_reason(
    capsys, files, tmp_path, channel, value, reason
):
    _, nominal = files
    good = rows(simulated_postures(30, seed=12))
    beyond = [list(r) for r in good[:2]]
    for row in beyond:
        row[channel] = value
    bag = posture_bag(tmp_path / 'beyond', good[:5] + beyond + good[5:])
    code, out, err = hexacal(
        capsys, 'calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml', '--json'
    )
    assert code == 0, err
    result = json.loads(out)['bag']
    assert result['postures'] == 30
    assert [(r['index'], r['reason']) for r in result['rejected_postures']] == [
        (5, reason),
        (6, reason),
    ]
    assert POSTURE_NAMES[channel].split('_')[0] in result['rejected_postures'][0]['detail']
    clean = posture_bag(tmp_path / 'clean', good)
    assert (
        hexacal(
            capsys, 'calibrate', clean, '--nominal', nominal, '--output', tmp_path / 'clean.yaml'
        )[0]
        == 0
    )
    assert np.array_equal(
        load_parameters(tmp_path / 'out.yaml'), load_parameters(tmp_path / 'clean.yaml')
    )

    # Nothing usable left: a refusal that says what was set aside, and no file.
    all_beyond = [list(r) for r in good]
    for row in all_beyond:
        row[channel] = value
    bag = posture_bag(tmp_path / 'all_beyond', all_beyond)
    code, _, err = hexacal(
        capsys, 'calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'none.yaml'
    )
    assert_named_error(code, err, f'30 posture(s) set aside (30 {reason})')
    assert not (tmp_path / 'none.yaml').exists()


def test_identical_postures_repeated_are_refused_as_rank_deficient(capsys, files, tmp_path):
    _, nominal = files
    posture = rows(simulated_postures(1, seed=13))[0]
    bag = posture_bag(tmp_path / 'same', [posture] * 40)
    # The real console entry point: exit code and stderr as a user sees.
    completed = system_support.hexacal(
        'calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml', timeout=120
    )
    assert_named_error(
        completed.returncode, completed.stderr, 'rank 4 of 54', 'cannot be identified'
    )
    assert not (tmp_path / 'out.yaml').exists()


def test_too_few_postures_are_refused(capsys, files, tmp_path):
    _, nominal = files
    bag = posture_bag(tmp_path / 'few', rows(simulated_postures(5, seed=14)))
    code, _, err = hexacal(
        capsys, 'calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml'
    )
    assert_named_error(code, err, '5 usable posture')
    assert not (tmp_path / 'out.yaml').exists()


# --------------------------------------------------------------------------- parameter files


def _nominal_text(nominal: Path) -> str:
    return nominal.read_text()


@pytest.mark.parametrize(
    'edit, needles',
    [
        (
            lambda text: '\n'.join(line for line in text.splitlines() if 'chain_3.l:' not in line),
            ('missing key chain_3.l',),
        ),
        (
            lambda text: text.replace('chain_2.B: [', 'chain_2.B: [0.5, '),
            ('chain_2.B must have 3 values',),
        ),
        (
            lambda text: _replace_value(text, 'chain_4.a', '[0.8, 0.7]'),
            ('chain_4.a', 'not the x, y components of a unit vector'),
        ),
        (
            lambda text: _replace_value(text, 'chain_5.a', '[1.0, 0.0]'),
            ('chain_5.a', 'unit vector'),
        ),  # |a_xy| = 1: the rail would lie in the base plane
        (
            lambda text: text + '    extra: !!python/object/apply:os.system ["touch PWNED"]\n',
            ('invalid YAML', 'python/object'),
        ),
    ],
)
def test_bad_parameter_files_are_named_errors(capsys, files, tmp_path, edit, needles):
    _, nominal = files
    bag = posture_bag(tmp_path / 'bag', rows(simulated_postures(20, seed=15)))
    bad = tmp_path / 'bad.yaml'
    bad.write_text(edit(_nominal_text(nominal)))
    cwd = os.getcwd()
    os.chdir(tmp_path)  # where an unsafe loader would have run `touch PWNED`
    try:
        code, _, err = hexacal(
            capsys, 'calibrate', bag, '--nominal', bad, '--output', tmp_path / 'out.yaml'
        )
    finally:
        os.chdir(cwd)
    assert_named_error(code, err, str(bad), *needles)
    assert not (tmp_path / 'out.yaml').exists()
    assert not (tmp_path / 'PWNED').exists()


def _replace_value(text: str, key: str, value: str) -> str:
    lines = [
        f'    {key}: {value}' if line.strip().startswith(f'{key}:') else line
        for line in text.splitlines()
    ]
    return '\n'.join(lines) + '\n'


# --------------------------------------------------------------------------- bags


def test_a_topic_with_the_wrong_type_is_a_named_schema_error(capsys, files, tmp_path):
    _, nominal = files
    with BagWriter(tmp_path / 'wrong_type') as writer:
        writer.add_topic(POSTURE_TOPIC, 'std_msgs/msg/String')
        writer.write(POSTURE_TOPIC, {'data': 'not a posture'}, 10**9)
    code, _, err = hexacal(
        capsys,
        'calibrate',
        tmp_path / 'wrong_type',
        '--nominal',
        nominal,
        '--output',
        tmp_path / 'out.yaml',
    )
    assert_named_error(code, err, '/hexacal/posture', 'std_msgs/msg/String', JOINT_STATE_TYPE)


def _other_version_bag(path: Path, variant: str) -> Path:
    """A single-file MCAP whose JointState definition is another version of the message."""
    from mcap_ros2.writer import Writer

    own, dependencies = message_definition(JOINT_STATE_TYPE).split(DELIMITER, 1)
    if variant == 'extra field':
        own += '\nfloat64[] temperature\n'
    elif variant == 'renamed field':
        own = own.replace('float64[] position', 'float64[] positions')
    elif variant == 'retyped field':
        own = own.replace('float64[] position', 'float32[] position')
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef(JOINT_STATE_TYPE, own + DELIMITER + dependencies)
        for index, posture in enumerate(simulated_postures(20, seed=16)):
            message = joint_state_dict((index + 1) * 10**9, POSTURE_NAMES, posture.values())
            if variant == 'extra field':
                message['temperature'] = [21.5]
            elif variant == 'renamed field':
                message['positions'] = message.pop('position')
            writer.write_message(POSTURE_TOPIC, schema, message, (index + 1) * 10**9)
        writer.finish()
    return path


@pytest.mark.parametrize(
    'variant, needle',
    [
        ('extra field', 'extra field float64[] temperature'),
        ('renamed field', "no field 'position'"),
        ('retyped field', "field 'position' is float32[], not float64[]"),
    ],
)
def test_a_bag_from_another_message_version_is_a_named_schema_error(
    capsys, files, tmp_path, variant, needle
):
    _, nominal = files
    bag = _other_version_bag(tmp_path / 'other.mcap', variant)
    code, _, err = hexacal(
        capsys, 'calibrate', bag, '--nominal', nominal, '--output', tmp_path / 'out.yaml'
    )
    assert_named_error(code, err, 'another version of sensor_msgs/msg/JointState', needle)


def test_undecodable_messages_in_a_recorded_stream_are_skipped_not_fatal(capsys, files, tmp_path):
    """The collector records what arrived, garbage included: the bag still calibrates."""
    _, nominal = files
    good = rows(simulated_postures(24, seed=17))
    with BagWriter(tmp_path / 'garbage') as writer:
        writer.add_topic(POSTURE_TOPIC, JOINT_STATE_TYPE)
        for index, row in enumerate(good):
            stamp = (index + 1) * 10**9
            writer.write(POSTURE_TOPIC, joint_state_dict(stamp, POSTURE_NAMES, row), stamp)
            if index % 6 == 0:
                writer.write_raw(POSTURE_TOPIC, b'\x00\x01\x00\x00' + b'\xff' * 11, stamp + 1)
    code, out, err = hexacal(
        capsys,
        'calibrate',
        tmp_path / 'garbage',
        '--nominal',
        nominal,
        '--output',
        tmp_path / 'out.yaml',
        '--json',
    )
    assert code == 0, err
    assert json.loads(out)['bag']['invalid_messages'] == 4
    assert json.loads(out)['bag']['postures'] == 24


def test_yaml_is_loaded_safely_everywhere(tmp_path):
    """Parameters, bag metadata and plan files: a python tag is refused, never run."""
    from hexacal_driver.plan import load_plan, PlanError
    from hexacal_identify.bag import BagMetadataError, open_bag
    from hexacal_msgs_py.errors import ParameterFileError

    marker = tmp_path / 'PWNED'
    payload = f'!!python/object/apply:os.system ["touch {marker}"]'
    parameters = tmp_path / 'params.yaml'
    parameters.write_text(f'/**:\n  ros__parameters:\n    chain_1.l: {payload}\n')
    with pytest.raises(ParameterFileError, match='params.yaml'):
        load_parameters(parameters)
    bag = posture_bag(tmp_path / 'bag', rows(simulated_postures(2)))
    (bag / 'metadata.yaml').write_text(f'rosbag2_bagfile_information: {payload}\n')
    with pytest.raises(BagMetadataError):
        open_bag(bag)
    plan = tmp_path / 'plan.yaml'
    plan.write_text(f'postures: {payload}\n')
    with pytest.raises(PlanError):
        load_plan(plan)
    assert not marker.exists()


# --------------------------------------------------------------------------- paths


def test_output_paths_are_resolved_and_confined_to_the_output_directory(tmp_path):
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'link').symlink_to(tmp_path)  # a way out through a symlink
    assert output_path('calibration.yaml', str(out)) == out / 'calibration.yaml'
    assert output_path('sub/../calibration.yaml', str(out)) == out / 'calibration.yaml'
    for escape in (
        '../escape.yaml',
        str(tmp_path / 'escape.yaml'),
        'link/escape.yaml',
        '.',
        'sub/../..',
    ):
        with pytest.raises(ValueError, match='outside output_dir|must name a file'):
            output_path(escape, str(out))


# --------------------------------------------------------------------------- identify node


def _publish(probe: Probe, messages: list, topic: str = 'hexacal/posture') -> None:
    from hexacal_msgs_py.qos import POSTURE_QOS
    from sensor_msgs.msg import JointState

    publisher = probe.node.create_publisher(JointState, topic, POSTURE_QOS)
    own = 1 if any(s.topic_name == publisher.topic_name for s in probe.node.subscriptions) else 0
    probe.spin_until(
        lambda: publisher.get_subscription_count() >= 1 + own,
        NODE_START_TIMEOUT_S,
        f'a subscriber on {topic}',
    )
    for message in messages:
        publisher.publish(message)


def _joint_state(stamp_ns: int, names, positions):
    from hexacal_msgs_py.conversions import to_stamp
    from sensor_msgs.msg import JointState

    message = JointState(name=list(names), position=[float(p) for p in positions])
    message.header.stamp = to_stamp(stamp_ns)
    return message


def _collecting(probe: Probe) -> dict:
    found = [values for _, _, values in probe.statuses if values.get('outcome') == 'collecting']
    return found[-1] if found else {}


def _outcome(probe: Probe, outcome: str, after: int = 0):
    return probe.spin_until(
        lambda: [s for s in probe.statuses[after:] if s[2].get('outcome') == outcome],
        15.0,
        f'a {outcome!r} status',
    )[-1]


def _set_parameter(probe: Probe, client, name: str, value):
    from rclpy.parameter import Parameter

    future = client.set_parameters([Parameter(name, value=value)])
    return probe.spin_until(
        lambda: future.result() if future.done() else None, 15.0, f'setting {name}'
    ).results[0]


@pytest.mark.slow
def test_identify_rejects_bad_postures_refuses_repeated_ones_and_loses_nothing(
    ros_processes, tmp_path, probe
):
    truth, nominal = write_parameter_files(tmp_path)
    identify = ros_processes.start(
        node_argv(
            'identify',
            {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out'), 'report_dir': ''},
        )
    )
    probe.wait_for_node('identify', process=identify)
    probe.subscribe_status()
    received = probe.subscribe_parameters()
    calibration = tmp_path / 'out' / 'hexacal_calibration.yaml'

    # The same posture 20 times: enough residuals, no information. A named refusal.
    same = simulated_postures(1, seed=5)[0]
    _publish(
        probe, [_joint_state(same.stamp_ns + k, POSTURE_NAMES, same.values()) for k in range(20)]
    )
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 20,
        30.0,
        'identify to hold 20 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert not response.success and response.message.startswith('rank-deficient: ')
    level, _, values = _outcome(probe, 'rank-deficient')
    assert level == ERROR and values['postures_received'] == '20'
    assert not calibration.exists()

    # Bad postures: never stored, each counted by reason and reported.
    good = simulated_postures(1, seed=6)[0].values()
    stamp = 10**12
    bad = [
        _joint_state(stamp, POSTURE_NAMES, [*good[:2], math.nan, *good[3:]]),
        _joint_state(stamp + 1, POSTURE_NAMES, [*good[:6], math.inf, *good[7:]]),
        _joint_state(stamp + 2, POSTURE_NAMES[:-1], good[:-1]),  # no 'rotary'
        _joint_state(stamp + 3, ['elbow', *POSTURE_NAMES[1:]], good),  # wrong name
        _joint_state(stamp + 4, POSTURE_NAMES, good[:-1]),  # 9 names, 8 positions
        _joint_state(stamp + 5, POSTURE_NAMES, [*good[:6], 1.5, *good[7:]]),  # alpha 86 deg
        _joint_state(stamp + 6, POSTURE_NAMES, [1.5, *good[1:]]),  # slider_1 beyond the rail
    ]
    _publish(probe, bad)
    values = probe.spin_until(
        lambda: _collecting(probe).get('postures_rejected') == '7' and _collecting(probe),
        15.0,
        '7 rejections in the status',
        identify.describe,
    )
    assert values['postures_received'] == '20'
    assert values['rejected.invalid-reading'] == '5'
    assert values['rejected.angle-out-of-range'] == '1'
    assert values['rejected.slider-beyond-stroke'] == '1'
    assert values['last_rejection'].startswith('slider-beyond-stroke: slider_1 = 1.5 m')
    levels = [level for level, _, v in probe.statuses if v.get('postures_rejected')]
    assert levels and set(levels) == {WARN}
    assert 'ignored an invalid posture' in identify.log_text()

    # Nothing collected was lost: the 20 repeated postures count with 24 new ones.
    new = simulated_postures(24, seed=7)
    probe.publish_postures(new)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 44,
        30.0,
        'identify to hold 44 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert response.success, response.message
    assert '44 of 44 postures' in response.message
    _, _, values = _outcome(probe, 'converged')
    assert values['postures_rejected_on_receipt'] == '7'
    vector = probe.spin_until(lambda: received, 10.0, 'the parameters')[0]
    # Exactly the 44 valid postures (the same call offline gives the same numbers) ...
    repeated = [PostureReading.from_values(same.stamp_ns + k, same.values()) for k in range(20)]
    offline = calibrate(HexaParameters(load_parameters(nominal)), repeated + new)
    assert np.allclose(vector, offline.parameters.vector, rtol=0, atol=1e-9)
    assert np.abs(vector - load_parameters(truth)).max() < 2e-3  # ... and a sound calibration
    assert identify.running()


@pytest.mark.slow
def test_identify_names_bad_files_and_paths_and_writes_only_under_output_dir(
    ros_processes, tmp_path, probe
):
    from rclpy.parameter_client import AsyncParameterClient

    truth, nominal = write_parameter_files(tmp_path)
    text = nominal.read_text()
    broken = {
        'missing.yaml': (
            '\n'.join(l for l in text.splitlines() if 'chain_3.l:' not in l),
            'missing key chain_3.l',
        ),
        'length.yaml': (
            text.replace('chain_2.B: [', 'chain_2.B: [0.5, '),
            'chain_2.B must have 3 values',
        ),
        'rail.yaml': (
            _replace_value(text, 'chain_4.a', '[0.8, 0.7]'),
            'chain_4.a = [0.8, 0.7] is not the x, y components of a unit vector',
        ),
        'unsafe.yaml': (
            text + f'    x: !!python/object/apply:os.system ["touch {tmp_path}/PWNED"]\n',
            'invalid YAML',
        ),
    }
    for name, (content, _) in broken.items():
        (tmp_path / name).write_text(content)
    (tmp_path / 'not_a_bag.txt').write_text('hello\n')
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'link').symlink_to(tmp_path)
    before = {p for p in tmp_path.rglob('*') if 'logs' not in p.parts}

    identify = ros_processes.start(
        node_argv('identify', {'nominal': str(tmp_path / 'missing.yaml'), 'output_dir': str(out)})
    )
    probe.wait_for_node('identify', process=identify)
    probe.subscribe_status()
    probe.publish_postures(simulated_postures(20, seed=8))
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 20,
        30.0,
        'identify to hold 20 postures',
        identify.describe,
    )
    client = AsyncParameterClient(probe.node, '/identify')
    probe.spin_until(client.services_are_ready, 15.0, "identify's parameter services")

    for name, (_, needle) in broken.items():
        assert _set_parameter(probe, client, 'nominal', str(tmp_path / name)).successful
        count = len(probe.statuses)
        response = probe.call_trigger()
        assert not response.success and response.message.startswith('invalid-nominal: ')
        assert str(tmp_path / name) in response.message and needle in response.message
        level, message, _ = _outcome(probe, 'invalid-nominal', count)
        assert level == ERROR and needle in message
    assert not (tmp_path / 'PWNED').exists()
    assert _set_parameter(probe, client, 'nominal', str(nominal)).successful

    for bag, needle in (
        (tmp_path / 'not_a_bag.txt', 'not an MCAP file'),
        (tmp_path / 'nowhere', 'does not exist'),
        (out, 'neither'),
    ):
        assert _set_parameter(probe, client, 'bag', str(bag)).successful
        response = probe.call_trigger()
        assert response.message.startswith('invalid-bag: ') and needle in response.message
    assert _set_parameter(probe, client, 'bag', '').successful

    for name, value in (
        ('output', '../escape.yaml'),
        ('output', str(tmp_path / 'x.yaml')),
        ('output', 'link/escape.yaml'),
        ('report_dir', '../report'),
    ):
        refused = _set_parameter(probe, client, name, value)
        assert not refused.successful and 'outside output_dir' in refused.reason, refused.reason

    response = probe.call_trigger()
    assert response.success, response.message
    assert '20 of 20 postures' in response.message  # every refusal kept the postures
    assert (
        np.abs(load_parameters(out / 'hexacal_calibration.yaml') - load_parameters(truth)).max()
        < 1e-3
    )
    probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('report_state') == 'ready'],
        120.0,
        'the report (written after the answer)',
        identify.describe,
    )
    written = {p for p in tmp_path.rglob('*') if 'logs' not in p.parts} - before
    assert written and all(out in p.parents for p in written), sorted(map(str, written))
    assert (out / 'report' / 'index.html') in written


# --------------------------------------------------------------------------- collector


class SensorFeed:
    """The three sensor streams from the probe, with stamps under the test's control."""

    def __init__(self, probe: Probe, posture, period_ns: int = 10_000_000):
        from hexacal_msgs_py.qos import SENSOR_QOS
        from sensor_msgs.msg import JointState

        self.probe = probe
        self.values = list(posture.values())
        self.period_ns = period_ns
        self.stamp_ns = 2_000_000_000_000_000_000
        self.streams: set[str] = set()
        self.inclinometer_lag_ns = 0
        self.ticks = 0
        self.stop_encoder_after: int | None = None
        self.publishers = {
            name: probe.node.create_publisher(JointState, f'hexacal/{name}', SENSOR_QOS)
            for name in ('sliders', 'inclinometer', 'encoder')
        }
        probe.spin_until(
            lambda: all(p.get_subscription_count() >= 1 for p in self.publishers.values()),
            NODE_START_TIMEOUT_S,
            "the collector's sensor subscriptions",
        )
        self.timer = probe.node.create_timer(period_ns / 1e9, self.tick)

    def publish(self, name: str, stamp_ns: int, names=None, values=None) -> None:
        default_names, default_values = {
            'sliders': (SLIDER_NAMES, self.values[:6]),
            'inclinometer': (POSTURE_NAMES[6:8], self.values[6:8]),
            'encoder': (POSTURE_NAMES[8:], self.values[8:]),
        }[name]
        self.publishers[name].publish(
            _joint_state(
                stamp_ns,
                default_names if names is None else names,
                default_values if values is None else values,
            )
        )

    def tick(self) -> None:
        if not self.streams:
            return
        self.stamp_ns += self.period_ns
        self.ticks += 1
        for name in sorted(self.streams):
            if (
                name == 'encoder'
                and self.stop_encoder_after is not None
                and self.ticks > self.stop_encoder_after
            ):
                continue
            lag = self.inclinometer_lag_ns if name == 'inclinometer' else 0
            self.publish(name, self.stamp_ns - lag)


def _collector_status(probe: Probe) -> dict:
    found = [
        values
        for _, _, values in probe.statuses
        if values.get('outcome') in ('recording', 'not-recording', 'recording-stopped')
    ]
    return found[-1] if found else {}


def _count(probe: Probe, key: str) -> int:
    return int(_collector_status(probe).get(key, 0))


@pytest.mark.slow
def test_collector_names_bad_stamps_stale_and_stopped_streams(ros_processes, tmp_path, probe):
    collector = ros_processes.start(
        node_argv(
            'collector',
            {
                'output_dir': str(tmp_path / 'bags'),
                'bag_name': 'feed',
                'window_s': 0.2,
                'capture_s': 1.0,
                'detector': 'settled',
            },
        )
    )
    probe.wait_for_node('collector', process=collector)
    probe.subscribe_status()
    probe.subscribe_postures()
    feed = SensorFeed(probe, simulated_postures(1, seed=9)[0])

    def status_has(predicate, what, repeat=None):
        """Spin until the collector's status satisfies predicate; call repeat() every 0.3 s
        meanwhile (best effort: a message may be lost, so the test sends until it is seen)."""
        last = [0.0]

        def check():
            if repeat is not None and time.monotonic() - last[0] > 0.3:
                last[0] = time.monotonic()
                repeat()
            return predicate(_collector_status(probe)) and _collector_status(probe)

        return probe.spin_until(check, 20.0, what, collector.describe)

    # Wrong names, missing names, names and positions of different lengths.
    def send_invalid():
        for names, values in (
            (['elbow', *SLIDER_NAMES[1:]], [0.3] * 6),
            (SLIDER_NAMES[:5], [0.3] * 5),
            (SLIDER_NAMES, [0.3] * 5),
        ):
            feed.publish('sliders', feed.stamp_ns, names, values)

    status_has(
        lambda s: int(s.get('invalid.hexacal/sliders', 0)) >= 3,
        'invalid slider messages counted',
        send_invalid,
    )

    # Duplicated and out-of-order stamps.
    def send_bad_stamps():
        feed.stamp_ns += 10**9
        for offset in (0, 0, -5_000_000):
            feed.publish('sliders', feed.stamp_ns + offset)

    status_has(
        lambda s: (
            int(s.get('rejected.sliders.duplicate_stamp', 0)) >= 1
            and int(s.get('rejected.sliders.out_of_order', 0)) >= 1
        ),
        'the rejected stamps',
        send_bad_stamps,
    )
    warned = [level for level, _, v in probe.statuses if 'rejected.sliders.out_of_order' in v]
    assert warned[0] == WARN
    # The collector logs the rejection just after publishing the status that counts it.
    probe.spin_until(
        lambda: 'not used: ' in collector.log_text(),
        20.0,
        'the rejection logged',
        collector.describe,
    )

    # Stale inclinometer stamps (5 s behind the sliders): judged without (3 s behind is too
    # late), never a posture.
    feed.inclinometer_lag_ns = 5 * 10**9
    feed.streams = {'sliders', 'inclinometer', 'encoder'}
    status_has(
        lambda s: int(s.get('behind.inclinometer', 0)) >= 30,
        '1.5 s (30 blocks of 50 ms) judged without the late inclinometer',
    )
    assert probe.postures == []

    # Fresh stamps; the encoder stops in the middle of a capture (0.2 s window + 1 s capture).
    feed.inclinometer_lag_ns = 0
    feed.ticks, feed.stop_encoder_after = 0, 60
    status = status_has(
        lambda s: s.get('dropped.stream_stopped') == '1', 'the partial posture dropped'
    )
    assert status['streams_stopped'] == '/hexacal/encoder'
    assert probe.postures == []  # half a capture is never published
    assert 'stream(s) stopped: no message on /hexacal/encoder' in collector.log_text()
    assert 'dropped a partial posture' in collector.log_text()

    # The encoder is back: the status clears and the standing posture is measured in full.
    feed.stop_encoder_after = None
    probe.spin_until(
        lambda: probe.postures, 20.0, 'a posture after the encoder resumed', collector.describe
    )
    status_has(lambda s: 'streams_stopped' not in s, 'the stopped stream cleared')
    feed.streams = set()
    assert collector.running()
    assert ros_processes.stop(collector) == 0
    log = collector.log_path.read_text()
    assert re.search(r"stamps rejected \{'sliders': \{'duplicate_stamp': \d+, 'out_of_order'", log)
