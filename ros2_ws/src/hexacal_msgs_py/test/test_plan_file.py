"""Unit tests of the plan-file format: exact round trips, the written bytes, every refusal."""

from __future__ import annotations

from dataclasses import replace
import math

from hexacal_msgs_py.measuring_modes import (
    DEFAULT_MEASURING_MODE,
    measuring_mode,
    MeasuringMode,
)
from hexacal_msgs_py.names import DEVICE_JOINT_NAMES, LINK_LENGTH_JOINT, POSTURE_NAMES
from hexacal_msgs_py.plan_file import (
    METADATA_PREFIX,
    plan_document,
    plan_file_text,
    PlanError,
    PlanFile,
    read_plan_file,
    write_plan_file,
)
import numpy as np
import pytest

L = 0.75
SPHERE_POSE = [0.1, -0.2, -math.sqrt(L**2 - 0.05), 0.1, 0.0, -0.2]
FIXED_POSE = [0.0, 0.0, -L, 0.3, -0.1, 0.25]
GOOD = (
    'plan: {name: p, link_length: 0.75}\n'
    'postures: [{kind: fixed, pose: [0, 0, -0.75, 0, 0, 0]}]\n'
)


def _plan(**changes) -> PlanFile:
    plan = PlanFile('my-plan', L, np.array([SPHERE_POSE, FIXED_POSE]), ('sphere', 'fixed'))
    return replace(plan, **changes)


def test_a_plain_plan_is_written_as_every_earlier_release_wrote_it(tmp_path):
    path = write_plan_file(tmp_path / 'plans' / 'plan.yaml', _plan())
    assert [p.name for p in path.parent.iterdir()] == ['plan.yaml']  # atomic: no temporary left
    assert path.read_text() == (
        'plan:\n'
        '  name: "my-plan"\n'
        '  link_length: 0.75\n'
        'postures:\n'
        f'  - {{kind: sphere, pose: [{", ".join(repr(v) for v in SPHERE_POSE)}]}}\n'
        '  - {kind: fixed, pose: [0.0, 0.0, -0.75, 0.3, -0.1, 0.25]}\n'
    )
    back = read_plan_file(path)
    assert back.metadata is None and back.device_turns == ()
    assert (back.name, back.link_length, back.kinds) == ('my-plan', L, ('sphere', 'fixed'))
    np.testing.assert_array_equal(back.poses, _plan().poses)  # repr floats: exact


def test_model_mount_turns_and_metadata_round_trip(tmp_path):
    metadata = {'index': 'O1', 'rank': np.int64(54), 'limits': {'range': np.array([1.0, 2.0])}}
    standing = [[p[0], p[1], -p[2], *p[3:]] for p in (SPHERE_POSE, FIXED_POSE)]
    plan = _plan(
        model='gough_stewart',
        mount='standing',
        poses=np.array(standing),
        device_turns=(None, math.pi),
        metadata=metadata,
    )
    text = plan_file_text(plan)
    assert text.startswith(
        METADATA_PREFIX + '{"index": "O1", "limits": {"range": [1.0, 2.0]}, "rank": 54}\nplan:\n'
    )
    assert '  model: gough_stewart\n  mount: standing\npostures:\n' in text
    assert text.endswith(', device_turn: 3.141592653589793}\n')
    back = read_plan_file(write_plan_file(tmp_path / 'plan.yaml', plan))
    assert (back.model, back.mount) == ('gough_stewart', 'standing')
    assert back.device_turns == (None, math.pi)
    assert back.metadata == {'index': 'O1', 'limits': {'range': [1.0, 2.0]}, 'rank': 54}
    assert back.device_turn(0, 0.5) == 0.5 and back.device_turn(1, 0.5) == math.pi
    assert plan_file_text(back) == text
    document = plan_document(back)
    assert document['plan'] == {
        'name': 'my-plan',
        'link_length': L,
        'model': 'gough_stewart',
        'mount': 'standing',
    }
    assert 'device_turn' not in document['postures'][0]
    assert document['postures'][1]['device_turn'] == math.pi


def test_plan_describes_itself_and_counts_its_kinds():
    plan = _plan(device_turns=(0.0, None))
    assert plan.counts() == {'sphere': 1, 'fixed': 1}
    assert plan.describe() == (
        "plan 'my-plan': 2 postures (1 sphere, 1 fixed), link length 0.75 m, 1 with a device turn"
    )
    assert _plan(device_turns=(None, None)).device_turns == ()


@pytest.mark.parametrize(
    'changes, message',
    [
        ({'name': ' '}, 'name must be a non-empty string'),
        ({'link_length': 0.0}, 'link_length must be a positive number of m, got 0.0'),
        ({'link_length': True}, 'link_length must be a positive number of m, got True'),
        ({'poses': np.zeros((0, 6)), 'kinds': ()}, 'has no postures'),
        ({'kinds': ('sphere',)}, '2 poses but 1 kinds'),
        (
            {'model': 'delta'},
            "model must be one of hexa_slide, gough_stewart, rotary_hexapod, got 'delta'",
        ),
        ({'mount': 'sideways'}, "mount must be one of hanging, standing, got 'sideways'"),
        ({'device_turns': (1.0,)}, '2 poses but 1 device turns'),
        ({'device_turns': (None, 7.0)}, 'posture 1: device_turn must be a finite angle'),
        (
            {'device_turns': (None, 'pi')},
            "posture 1: device_turn must be a number of rad, got 'pi'",
        ),
        ({'kinds': ('sphere', 'flat')}, "posture 1: kind must be one of ['sphere', 'fixed']"),
        (
            {'poses': np.array([SPHERE_POSE, [0, 0, np.nan, 0, 0, 0]])},
            'posture 1: pose must be finite',
        ),
    ],
)
def test_a_plan_with_a_problem_is_refused(changes, message):
    with pytest.raises(PlanError) as error:
        _plan(**changes)
    assert str(error.value).startswith("plan 'my-plan': " if 'name' not in changes else 'plan ')
    assert message in str(error.value)


def test_subclasses_add_the_checks_that_need_a_machine():
    class Upright(PlanFile):

        def posture_problem(self, pose, kind):
            return 'below O' if pose[2] < 0 else None

    with pytest.raises(PlanError, match="plan 'my-plan': posture 0: below O"):
        Upright('my-plan', L, np.array([SPHERE_POSE]), ('sphere',))


def _posture_line(extra: str) -> str:
    return f'plan: {{name: p, link_length: 0.75}}\npostures: [{{kind: fixed, {extra}}}]\n'


@pytest.mark.parametrize(
    'text, message',
    [
        (b'\xff\xfe', 'not readable as a plan file: not UTF-8 text'),
        ('plan: [1, 2\n', 'not readable as a plan file: invalid YAML'),
        ('x: ' + '[' * 5000 + '\n', 'not readable as a plan file: invalid YAML'),
        ('plan: !!python/object/apply:os.system ["true"]\n', 'invalid YAML'),
        ('- 1\n', "not a plan file: expected a mapping with keys 'plan' and 'postures'"),
        ('postures: []\n', "not a plan file: 'plan' must be a mapping with 'name'"),
        (GOOD + 'speed: 1\n', "unknown top-level key(s) ['speed']; expected 'plan'"),
        (
            GOOD.replace('0.75}', '0.75, speed: 2}'),
            "unknown key(s) ['speed'] in plan; expected ['link_length', 'name'] "
            "(optional ['model', 'mount'])",
        ),
        (GOOD.replace('name: p, ', ''), 'plan.name is missing'),
        (GOOD.replace(', link_length: 0.75', ''), 'plan.link_length is missing'),
        (GOOD.replace('0.75}', 'long}'), 'plan.link_length must be a number'),
        (GOOD.replace('0.75}', '-1}'), 'link_length must be a positive number'),
        ('plan: {name: p, link_length: 0.75}\n', "'postures' must be a non-empty list"),
        (GOOD.replace('[{kind', '[3, {kind'), 'posture 0: expected a mapping'),
        (
            _posture_line('pose: [0, 0, -0.75, 0, 0, 0], speed: 1'),
            "posture 0: keys must be ['kind', 'pose'], unknown ['speed'] "
            "(optional ['device_turn'])",
        ),
        (_posture_line('speed: 1'), "unknown ['speed'], missing ['pose']"),
        (_posture_line('pose: [0, 0, -0.75]'), 'posture 0: pose must be 6 numbers'),
        (_posture_line('pose: [0, 0, -0.75, 0, 0, true]'), 'posture 0: pose must be 6 numbers'),
        (_posture_line('pose: [0, 0, .nan, 0, 0, 0]'), 'posture 0: pose must be finite'),
        (
            _posture_line('pose: [0, 0, -0.75, 0, 0, 0], device_turn: null'),
            'posture 0: device_turn must be a number of rad, got null',
        ),
        (
            _posture_line('pose: [0, 0, -0.75, 0, 0, 0], device_turn: pi'),
            'posture 0: device_turn must be a number of rad',
        ),
        (
            _posture_line('pose: [0, 0, -0.75, 0, 0, 0], device_turn: 7.0'),
            'posture 0: device_turn must be a finite angle within +-2 pi rad',
        ),
        (GOOD.replace('0.75}', '0.75, model: delta}'), 'plan.model must be one of hexa_slide'),
        (GOOD.replace('0.75}', '0.75, mount: 3}'), 'plan.mount must be one of hanging, standing'),
        (GOOD.replace('name: p', "name: ''"), "plan '': name must be a non-empty string"),
        (METADATA_PREFIX + '[1, 2]\n' + GOOD, "its '# hexacal-plan:' comment is not a JSON"),
        (METADATA_PREFIX + '{broken\n' + GOOD, "its '# hexacal-plan:' comment is not a JSON"),
    ],
)
def test_every_refusal_names_the_file_and_the_problem(tmp_path, text, message):
    path = tmp_path / 'bad.yaml'
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    with pytest.raises(PlanError) as error:
        read_plan_file(path)
    assert str(error.value).startswith(f'{path}: ')
    assert message in str(error.value)


def test_a_missing_file_is_a_plan_error(tmp_path):
    with pytest.raises(PlanError, match='absent.yaml: not readable as a plan file: cannot read'):
        read_plan_file(tmp_path / 'absent.yaml')


def test_the_last_metadata_comment_counts_and_other_comments_are_ignored(tmp_path):
    path = tmp_path / 'plan.yaml'
    path.write_text(
        f'# a hand-written note\n{METADATA_PREFIX}{{"a": 1}}\n{METADATA_PREFIX}{{"b": 2}}\n{GOOD}'
    )
    assert read_plan_file(path).metadata == {'b': 2}


# --------------------------------------------------------------------------- measuring modes


def test_measuring_mode_and_released_actuators_round_trip(tmp_path):
    plan = _plan(measuring_mode='passive_actuator', released_actuators=('slider_3', None))
    text = plan_file_text(plan)
    assert '  link_length: 0.75\n  measuring_mode: passive_actuator\npostures:\n' in text
    assert text.splitlines()[-2].endswith(', released_actuator: slider_3}')
    assert 'released_actuator' not in text.splitlines()[-1]
    back = read_plan_file(write_plan_file(tmp_path / 'plan.yaml', plan))
    assert back.measuring_mode == plan.measuring_mode
    assert back.released_actuators == plan.released_actuators
    assert back.measuring_mode == MeasuringMode.PASSIVE_ACTUATOR
    assert back.released_actuators == ('slider_3', None)
    assert (back.released_actuator(0), back.released_actuator(1)) == ('slider_3', None)
    assert plan_file_text(back) == text
    document = plan_document(back)
    assert document['plan']['measuring_mode'] == 'passive_actuator'
    assert document['postures'][0]['released_actuator'] == 'slider_3'
    assert 'released_actuator' not in document['postures'][1]
    assert back.describe().endswith(
        ', measuring mode passive_actuator, 1 with a released actuator'
    )


def test_a_plan_without_the_new_keys_is_written_byte_for_byte_as_before(tmp_path):
    before = plan_file_text(_plan(model='gough_stewart', device_turns=(None, math.pi)))
    after = plan_file_text(
        _plan(model='gough_stewart', device_turns=(None, math.pi), released_actuators=(None, None))
    )
    assert after == before and 'measuring' not in before and 'released' not in before
    path = tmp_path / 'old.yaml'
    path.write_text(before)
    back = read_plan_file(path)
    assert back.measuring_mode is None and back.released_actuators == ()
    assert plan_file_text(back) == before


@pytest.mark.parametrize('mode', ['lvdt', 'compliant'])
def test_other_modes_round_trip_without_released_actuators(tmp_path, mode):
    back = read_plan_file(write_plan_file(tmp_path / 'p.yaml', _plan(measuring_mode=mode)))
    assert back.measuring_mode == mode and back.released_actuators == ()


@pytest.mark.parametrize(
    'changes, message',
    [
        ({'measuring_mode': 'rigid'}, 'measuring_mode must be one of passive_actuator, lvdt, '),
        (
            {'measuring_mode': 'passive_actuator', 'released_actuators': ('slider_1',)},
            '2 poses but 1 released actuators',
        ),
        (
            {'measuring_mode': 'passive_actuator', 'released_actuators': (None, 'leg_2')},
            'posture 1: released_actuator must be one of the hexa_slide actuators slider_1, '
            "slider_2, slider_3, slider_4, slider_5, slider_6, got 'leg_2'",
        ),
        (
            {'measuring_mode': 'lvdt', 'released_actuators': ('slider_1', None)},
            'posture 0: released_actuator is only meaningful with measuring_mode '
            "passive_actuator (the plan is lvdt), got 'slider_1'",
        ),
        (
            {'released_actuators': (None, 'slider_6')},
            'posture 1: released_actuator is only meaningful with measuring_mode '
            "passive_actuator (the plan names none), got 'slider_6'",
        ),
    ],
)
def test_a_bad_measuring_mode_or_released_actuator_is_refused(changes, message):
    with pytest.raises(PlanError, match="^plan 'my-plan': ") as error:
        _plan(**changes)
    assert message in str(error.value)


def _mode_text(header: str = '', posture: str = '') -> str:
    return (
        f'plan: {{name: p, link_length: 0.75{header}}}\n'
        f'postures: [{{kind: fixed, pose: [0, 0, -0.75, 0, 0, 0]{posture}}}]\n'
    )


@pytest.mark.parametrize(
    'text, message',
    [
        (_mode_text(', measuring_mode: null'), 'plan.measuring_mode must be one of'),
        (_mode_text(', measuring_mode: LVDT'), 'passive_actuator, lvdt, compliant (absent: the '),
        (
            _mode_text(', measuring_mode: passive_actuator', ', released_actuator: 3'),
            'posture 0: released_actuator must be an actuator joint name, got 3',
        ),
        (
            _mode_text(', measuring_mode: passive_actuator', ', released_actuator: slider_7'),
            'posture 0: released_actuator must be one of the hexa_slide actuators',
        ),
        (
            _mode_text(', measuring_mode: compliant', ', released_actuator: slider_2'),
            "plan 'p': posture 0: released_actuator is only meaningful with measuring_mode",
        ),
        (
            _mode_text(', measuring_mode: passive_actuator, model: gough_stewart',
                       ', released_actuator: slider_2'),
            'posture 0: released_actuator must be one of the gough_stewart actuators leg_1',
        ),
        (
            _mode_text(', speed: 2'),
            "(optional ['model', 'mount']), measuring mode ['measuring_mode']",
        ),
        (
            _mode_text(posture=', speed: 2'),
            "(optional ['device_turn']), measuring mode ['released_actuator']",
        ),
    ],
)
def test_a_file_with_a_bad_mode_key_names_the_file_the_posture_and_the_problem(
    tmp_path, text, message
):
    path = tmp_path / 'modes.yaml'
    path.write_text(text)
    with pytest.raises(PlanError) as error:
        read_plan_file(path)
    assert str(error.value).startswith(f'{path}: ')
    assert message in str(error.value)


def test_the_contract_names_the_modes_and_reserves_the_link_length_joint():
    assert [mode.value for mode in MeasuringMode] == ['passive_actuator', 'lvdt', 'compliant']
    assert DEFAULT_MEASURING_MODE == 'passive_actuator'
    assert measuring_mode('lvdt') is MeasuringMode.LVDT
    with pytest.raises(ValueError, match="got 'rigid'"):
        measuring_mode('rigid')
    assert LINK_LENGTH_JOINT == 'link_length'
    assert LINK_LENGTH_JOINT not in POSTURE_NAMES and LINK_LENGTH_JOINT not in DEVICE_JOINT_NAMES
