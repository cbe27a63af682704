"""Unit tests of the hexacal interface contract."""

import dataclasses
import json
import math
from pathlib import Path
import subprocess
import sys
import textwrap

from hexacal_msgs_py import conversions as conv
from hexacal_msgs_py import names
from hexacal_msgs_py.errors import (
    HexacalContractError,
    InvalidParametersError,
    InvalidReadingError,
    ParameterFileError,
)
from hexacal_msgs_py.parameters_file import (
    chain_dict_to_parameters,
    load_parameters,
    load_parameters_file,
    parameters_to_chain_dict,
    save_parameters,
)
from hexacal_msgs_py.readings import (
    ActuatorReading,
    EncoderReading,
    InclinometerReading,
    PostureReading,
)
from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest

SLIDERS = (0.11, 0.12, 0.13, 0.14, 0.15, 0.16)


def example_vector() -> np.ndarray:
    """Return a physically valid 54-vector with distinct, non-round values."""
    rng = np.random.default_rng(7)
    chains = []
    for chain in range(6):
        angle = chain * math.pi / 3
        a0 = rng.uniform(-0.5, 0.5, 3)
        b = rng.uniform(-0.2, 0.2, 3)
        length = 0.9947 + rng.uniform(-1e-3, 1e-3)
        a_xy = 0.3 * np.array([math.cos(angle), math.sin(angle)])
        chains.append(np.concatenate([a0, b, [length], a_xy]))
    return np.concatenate(chains)


def dotted_yaml(vector: np.ndarray, node: str = '/**') -> str:
    lines = [f'{node}:', '  ros__parameters:']
    for chain, fields in enumerate(vector.reshape(6, 9).tolist(), start=1):
        lines.append(f'    chain_{chain}.A0: [{fields[0]!r}, {fields[1]!r}, {fields[2]!r}]')
        lines.append(f'    chain_{chain}.B: [{fields[3]!r}, {fields[4]!r}, {fields[5]!r}]')
        lines.append(f'    chain_{chain}.l: {fields[6]!r}')
        lines.append(f'    chain_{chain}.a: [{fields[7]!r}, {fields[8]!r}]')
    return '\n'.join(lines) + '\n'


# --- names ------------------------------------------------------------------


def test_names_layout():
    assert names.SLIDER_NAMES == tuple(f'slider_{i}' for i in range(1, 7))
    assert names.POSTURE_NAMES == names.SLIDER_NAMES + (
        'inclinometer_x',
        'inclinometer_y',
        'rotary',
    )
    assert names.N_PARAMETERS == 54 == len(names.PARAMETER_NAMES)
    assert names.PARAMETER_NAMES[names.parameter_index(3, 'ax')] == 'chain_3.ax'
    assert names.parameter_index(1, 'A0x') == 0
    assert names.parameter_index(6, 'ay') == 53
    for topic in (names.SLIDERS_TOPIC, names.POSTURE_TOPIC, names.CALIBRATE_SERVICE):
        assert not topic.startswith('/'), 'names are relative so namespaces apply'
    with pytest.raises(ValueError):
        names.parameter_index(7, 'l')


def test_ros_free_modules_do_not_import_ros():
    code = textwrap.dedent("""
        import sys
        import hexacal_msgs_py, hexacal_msgs_py.names, hexacal_msgs_py.readings
        import hexacal_msgs_py.errors, hexacal_msgs_py.parameters_file
        loaded = [m for m in ('rclpy', 'sensor_msgs', 'std_msgs', 'diagnostic_msgs')
                  if m in sys.modules]
        assert not loaded, loaded
    """)
    subprocess.run([sys.executable, '-c', code], check=True)


def test_error_hierarchy():
    for error in (InvalidReadingError, InvalidParametersError, ParameterFileError):
        assert issubclass(error, HexacalContractError)
        assert issubclass(error, ValueError)
    assert issubclass(ParameterFileError, InvalidParametersError)


# --- readings ---------------------------------------------------------------


def test_readings_normalise_to_float_tuples_and_are_frozen():
    reading = ActuatorReading(np.int64(3), [1, 2, 3, 4, 5, np.float32(6)])
    assert reading.actuator_positions == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    assert type(reading.stamp_ns) is int
    with pytest.raises(dataclasses.FrozenInstanceError):
        reading.stamp_ns = 4


@pytest.mark.parametrize(
    'make, expected',
    [
        (lambda: ActuatorReading(0, SLIDERS[:5]), 'must have 6 values, got 5'),
        (lambda: ActuatorReading(0, SLIDERS[:5] + (math.nan,)), 'slider_6 must be finite'),
        (lambda: ActuatorReading(0, 0.1), 'must be a sequence'),
        (lambda: ActuatorReading(-1, SLIDERS), 'stamp_ns must be >= 0'),
        (lambda: ActuatorReading(1.5, SLIDERS), 'stamp_ns must be an integer'),
        (lambda: InclinometerReading(0, math.inf, 0.0), 'alpha must be finite'),
        (lambda: InclinometerReading(0, 0.0, 'x'), 'beta must be a number'),
        (lambda: EncoderReading(0, -math.inf), 'phi must be finite'),
        (lambda: PostureReading(0, SLIDERS, 0.0, 0.0, math.nan), 'phi must be finite'),
        (lambda: PostureReading.from_values(0, range(8)), 'expected 9 values'),
    ],
)
def test_readings_reject_invalid_values(make, expected):
    with pytest.raises(InvalidReadingError, match=expected):
        make()


def test_posture_from_parts_and_values():
    posture = PostureReading.from_parts(
        ActuatorReading(10, SLIDERS), InclinometerReading(11, 0.1, -0.2), EncoderReading(12, 1.5)
    )
    assert posture == PostureReading(10, SLIDERS, 0.1, -0.2, 1.5)
    assert posture.values() == SLIDERS + (0.1, -0.2, 1.5)
    assert PostureReading.from_values(10, posture.values()) == posture


# --- message conversions ----------------------------------------------------


@pytest.mark.parametrize('ns', [0, 1, 999_999_999, 1_000_000_000, 1_732_000_000_123_456_789])
def test_stamp_round_trip(ns):
    stamp = conv.to_stamp(ns)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert conv.stamp_ns(stamp) == ns


READINGS = [
    (
        ActuatorReading(1_500_000_001, SLIDERS),
        conv.actuator_reading_to_joint_state,
        conv.joint_state_to_actuator_reading,
    ),
    (
        InclinometerReading(2, 0.0123, -0.0456),
        conv.inclinometer_reading_to_joint_state,
        conv.joint_state_to_inclinometer_reading,
    ),
    (
        EncoderReading(3, -2.5),
        conv.encoder_reading_to_joint_state,
        conv.joint_state_to_encoder_reading,
    ),
    (
        PostureReading(4, SLIDERS, 0.01, 0.02, 0.03),
        conv.posture_reading_to_joint_state,
        conv.joint_state_to_posture_reading,
    ),
]


@pytest.mark.parametrize('reading, to_msg, from_msg', READINGS)
def test_joint_state_round_trip(reading, to_msg, from_msg):
    msg = to_msg(reading, frame_id='base')
    assert msg.header.frame_id == 'base'
    assert from_msg(msg) == reading


@pytest.mark.parametrize('reading, to_msg, from_msg', READINGS)
def test_joint_state_lookup_is_by_name(reading, to_msg, from_msg):
    msg = to_msg(reading)
    pairs = list(zip(msg.name, msg.position))[::-1] + [('gripper', 7.0)]
    msg.name = [name for name, _ in pairs]
    msg.position = [position for _, position in pairs]
    assert from_msg(msg) == reading


@pytest.mark.parametrize('reading, to_msg, from_msg', READINGS)
def test_joint_state_errors_name_the_problem(reading, to_msg, from_msg):
    msg = to_msg(reading)
    missing = msg.name[-1]
    short = to_msg(reading)
    short.name = list(short.name[:-1])
    short.position = list(short.position[:-1])
    with pytest.raises(InvalidReadingError, match=f'lacks joint.*{missing}'):
        from_msg(short)

    mismatched = to_msg(reading)
    mismatched.position = list(mismatched.position) + [0.0]
    with pytest.raises(InvalidReadingError, match='names but .* positions'):
        from_msg(mismatched)

    for bad in (math.nan, math.inf):
        broken = to_msg(reading)
        positions = list(broken.position)
        positions[0] = bad
        broken.position = positions
        with pytest.raises(InvalidReadingError, match=f"joint '{broken.name[0]}' position"):
            from_msg(broken)


def test_joint_state_duplicate_joint_is_rejected():
    msg = conv.actuator_reading_to_joint_state(ActuatorReading(0, SLIDERS))
    msg.name = list(msg.name) + ['slider_2']
    msg.position = list(msg.position) + [9.0]
    with pytest.raises(InvalidReadingError, match="'slider_2' appears more than once"):
        conv.joint_state_to_actuator_reading(msg)


def test_parameters_multiarray_round_trip_is_bit_exact():
    vector = example_vector()
    msg = conv.parameters_to_multiarray(vector)
    assert [(d.label, d.size, d.stride) for d in msg.layout.dim] == [
        ('chain', 6, 54),
        ('A0x,A0y,A0z,Bx,By,Bz,l,ax,ay', 9, 9),
    ]
    back = conv.multiarray_to_parameters(msg)
    assert back.shape == (54,)
    assert back.tobytes() == vector.tobytes()


def test_multiarray_validation():
    msg = conv.parameters_to_multiarray(example_vector())
    msg.data = list(msg.data)[:53]
    with pytest.raises(InvalidParametersError, match='must hold 54 values, got 53'):
        conv.multiarray_to_parameters(msg)

    msg = conv.parameters_to_multiarray(example_vector())
    msg.layout.dim[0].label = 'leg'
    with pytest.raises(InvalidParametersError, match='layout'):
        conv.multiarray_to_parameters(msg)

    msg = conv.parameters_to_multiarray(example_vector())
    msg.layout.data_offset = 1
    with pytest.raises(InvalidParametersError, match='data_offset'):
        conv.multiarray_to_parameters(msg)

    msg = conv.parameters_to_multiarray(example_vector())
    data = list(msg.data)
    data[6] = math.nan
    msg.data = data
    with pytest.raises(InvalidParametersError, match='chain_1.l'):
        conv.multiarray_to_parameters(msg)

    with pytest.raises(InvalidParametersError, match=r'shape \(54,\)'):
        conv.parameters_to_multiarray(np.zeros(53))


def test_diagnostic_status_builder():
    from diagnostic_msgs.msg import DiagnosticStatus

    array = conv.diagnostic_status(
        DiagnosticStatus.WARN,
        'hexacal/identify',
        'converging',
        {'iterations': 12, 'rms_residual_m': np.float64(1.25e-05), 'converged': False},
        hardware_id='hsm',
        stamp=3_000_000_007,
    )
    assert conv.stamp_ns(array.header.stamp) == 3_000_000_007
    (status,) = array.status
    assert status.level == DiagnosticStatus.WARN
    assert (status.name, status.message, status.hardware_id) == (
        'hexacal/identify',
        'converging',
        'hsm',
    )
    assert conv.status_values(status) == {
        'iterations': '12',
        'rms_residual_m': '1.25e-05',
        'converged': 'false',
    }
    # the level's name goes along as the last value (ros2 topic echo shows the level as a byte)
    assert (status.values[-1].key, status.values[-1].value) == ('level_name', 'WARN')
    assert conv.diagnostic_status(2, 'n', 'm').status[0].level == DiagnosticStatus.ERROR
    assert conv.diagnostic_status('stale', 'n', 'm').status[0].values[0].value == 'STALE'
    assert conv.diagnostic_status('stale', 'n', 'm').status[0].level == DiagnosticStatus.STALE
    with pytest.raises(ValueError):
        conv.diagnostic_status(4, 'n', 'm')


def test_qos_profiles():
    from hexacal_msgs_py import qos
    from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, ReliabilityPolicy

    assert qos.SENSOR_QOS == qos_profile_sensor_data
    assert qos.POSTURE_QOS.reliability == ReliabilityPolicy.RELIABLE
    assert qos.POSTURE_QOS.depth == 1000
    for profile in (qos.PARAMETERS_QOS, qos.STATUS_QOS):
        assert profile.reliability == ReliabilityPolicy.RELIABLE
        assert profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert profile.depth == 1


# --- parameters YAML ----------------------------------------------------------


def test_yaml_round_trip_is_bit_exact_and_keeps_extras(tmp_path):
    vector = example_vector()
    vector[0] = 1e-5  # repr '1e-05' would read back as a string in YAML 1.1
    vector[1] = -1e16
    vector[2] = -0.0
    extras = {
        'device': {'link_length': 0.51, 'serial': 'HX-7 "b"'},
        'iterations': 12,
        'converged': True,
        'weights': [1.0, 2.5e-07],
    }
    path = tmp_path / 'params.yaml'
    save_parameters(path, vector, extras=extras, header_comment='identified\nby hexacal')
    text = path.read_text()
    assert text.startswith('# identified\n# by hexacal\n/**:\n  ros__parameters:\n')
    assert '    chain_3.a: [' in text
    loaded, loaded_extras = load_parameters_file(path)
    assert loaded.tobytes() == vector.tobytes()
    assert loaded_extras == {
        'device.link_length': 0.51,
        'device.serial': 'HX-7 "b"',
        'iterations': 12,
        'converged': True,
        'weights': [1.0, 2.5e-07],
    }
    assert load_parameters(path).tobytes() == vector.tobytes()


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.floats(min_value=-1e6, max_value=1e6, allow_subnormal=True), min_size=54, max_size=54
    )
)
def test_yaml_round_trip_bit_exact_for_any_floats(tmp_path_factory, values):
    vector = np.array(values)
    fields = vector.reshape(6, 9)
    fields[:, 6] = np.abs(fields[:, 6]) + 1e-3  # l > 0
    fields[:, 7:9] = np.clip(fields[:, 7:9], -0.7, 0.7)  # ax^2 + ay^2 < 1
    path = tmp_path_factory.mktemp('yaml') / 'p.yaml'
    save_parameters(path, vector)
    assert load_parameters(path).tobytes() == vector.tobytes()


def test_nested_and_dotted_forms_load_the_same(tmp_path):
    vector = example_vector()
    dotted = tmp_path / 'dotted.yaml'
    dotted.write_text(dotted_yaml(vector))
    nested_lines = ['/**:', '  ros__parameters:']
    for chain, fields in enumerate(vector.reshape(6, 9).tolist(), start=1):
        if chain % 2:  # odd chains as nested mappings, even ones in flow style
            nested_lines += [
                f'    chain_{chain}:',
                f'      A0: [{fields[0]!r}, {fields[1]!r}, {fields[2]!r}]',
                f'      B: [{fields[3]!r}, {fields[4]!r}, {fields[5]!r}]',
                f'      l: {fields[6]!r}',
                f'      a: [{fields[7]!r}, {fields[8]!r}]',
            ]
        else:
            nested_lines.append(
                f'    chain_{chain}: {{A0: [{fields[0]!r}, {fields[1]!r}, {fields[2]!r}], '
                f'B: [{fields[3]!r}, {fields[4]!r}, {fields[5]!r}], l: {fields[6]!r}, '
                f'a: [{fields[7]!r}, {fields[8]!r}]}}'
            )
    nested_lines += ['    device:', '      link_length: 0.5']
    nested = tmp_path / 'nested.yaml'
    nested.write_text('\n'.join(nested_lines) + '\n')
    assert load_parameters(dotted).tobytes() == vector.tobytes()
    loaded, extras = load_parameters_file(nested)
    assert loaded.tobytes() == vector.tobytes()
    assert extras == {'device.link_length': 0.5}


def test_named_and_namespaced_nodes_load(tmp_path):
    vector = example_vector()
    named = tmp_path / 'named.yaml'
    named.write_text(dotted_yaml(vector, node='identify'))
    assert load_parameters(named).tobytes() == vector.tobytes()
    namespaced = tmp_path / 'namespaced.yaml'
    namespaced.write_text('hsm:\n' + textwrap.indent(dotted_yaml(vector, node='identify'), '  '))
    assert load_parameters(namespaced).tobytes() == vector.tobytes()


def test_scientific_notation_without_dot_is_a_number(tmp_path):
    path = tmp_path / 'sci.yaml'
    path.write_text(
        dotted_yaml(example_vector()).replace('chain_2.A0: [', 'chain_2.A0: [1e-3, 2E+2, 3e0] #')
    )
    vector = load_parameters(path)
    assert vector[9:12].tolist() == [1e-3, 200.0, 3.0]


def _replace_line(text: str, key: str, new_value: str) -> str:
    lines = text.splitlines()
    (index,) = [i for i, line in enumerate(lines) if line.strip().startswith(key + ':')]
    lines[index] = f'    {key}: {new_value}'
    return '\n'.join(lines) + '\n'


@pytest.mark.parametrize(
    'key, value, expected',
    [
        ('chain_3.a', '[0.1, 0.2, 0.3]', 'chain_3.a must have 2 values, got 3'),
        ('chain_2.A0', '[0.1, 0.2]', 'chain_2.A0 must have 3 values, got 2'),
        ('chain_4.B', '0.5', 'chain_4.B must be a list of 3 values'),
        ('chain_5.l', 'abc', "chain_5.l must be numeric, got 'abc'"),
        ('chain_5.l', 'true', 'chain_5.l must be numeric, got True'),
        ('chain_1.B', '[0.1, .nan, 0.2]', 'chain_1.B must be finite, got nan'),
        ('chain_6.l', '.inf', 'chain_6.l must be finite, got inf'),
        ('chain_2.a', '[0.8, 0.6]', r'chain_2.a = \[0.8, 0.6\] is not the x, y components'),
        ('chain_2.a', '[0.9, 0.9]', 'chain_2.a .* >= 1'),
        ('chain_6.l', '0.0', 'chain_6.l must be > 0 m, got 0.0'),
        ('chain_1.l', '-0.99', 'chain_1.l must be > 0 m'),
    ],
)
def test_each_validation_error_names_file_and_key(tmp_path, key, value, expected):
    path = tmp_path / 'params.yaml'
    path.write_text(_replace_line(dotted_yaml(example_vector()), key, value))
    with pytest.raises(ParameterFileError, match=f'params.yaml: {expected}'):
        load_parameters(path)


def test_missing_key_is_named(tmp_path):
    path = tmp_path / 'params.yaml'
    text = ''.join(
        line + '\n'
        for line in dotted_yaml(example_vector()).splitlines()
        if 'chain_4.B:' not in line
    )
    path.write_text(text)
    with pytest.raises(ParameterFileError, match='params.yaml: missing key chain_4.B'):
        load_parameters(path)


def test_key_given_nested_and_dotted_is_rejected(tmp_path):
    path = tmp_path / 'params.yaml'
    path.write_text(dotted_yaml(example_vector()) + '    chain_1:\n      l: 1.0\n')
    with pytest.raises(ParameterFileError, match='chain_1.l is given twice'):
        load_parameters(path)


@pytest.mark.parametrize(
    'content, expected',
    [
        ('/**:\n  ros__parameters: [1, 2]\n', "ros__parameters of node '/.*' must be a mapping"),
        ('just a string\n', 'expected a mapping'),
        ('/**:\n  ros__parameters: {chain_1.A0: [1, 2\n', 'invalid YAML'),
        ('', 'expected a mapping'),
    ],
)
def test_malformed_files_are_reported(tmp_path, content, expected):
    path = tmp_path / 'bad.yaml'
    path.write_text(content)
    with pytest.raises(ParameterFileError, match=f'bad.yaml: {expected}'):
        load_parameters(path)


def test_missing_file_is_reported(tmp_path):
    with pytest.raises(ParameterFileError, match='absent.yaml: cannot read'):
        load_parameters(tmp_path / 'absent.yaml')


def test_save_is_atomic_and_creates_parent_directories(tmp_path):
    path = tmp_path / 'out' / 'deeper' / 'params.yaml'
    save_parameters(path, example_vector())
    second = example_vector()
    second[6] = 1.25
    save_parameters(path, second)
    assert [p.name for p in path.parent.iterdir()] == ['params.yaml']
    assert load_parameters(path)[6] == 1.25


def test_failed_save_leaves_no_temp_file(tmp_path):
    target = tmp_path / 'params.yaml'
    target.mkdir()  # os.replace cannot replace a directory with a file
    (target / 'keep').write_text('x')
    with pytest.raises(ParameterFileError, match='params.yaml: cannot write'):
        save_parameters(target, example_vector())
    assert sorted(p.name for p in tmp_path.iterdir()) == ['params.yaml']


def test_save_rejects_invalid_vectors_and_extras(tmp_path):
    path = tmp_path / 'params.yaml'
    bad = example_vector()
    bad[8 + 9] = 1.0
    with pytest.raises(ParameterFileError, match='params.yaml: chain_2.a'):
        save_parameters(path, bad)
    with pytest.raises(ParameterFileError, match='collides'):
        save_parameters(path, example_vector(), extras={'chain_1': {'l': 2.0}})
    with pytest.raises(ParameterFileError, match='unsupported type'):
        save_parameters(path, example_vector(), extras={'when': object()})
    with pytest.raises(ParameterFileError, match='not a valid ROS 2 parameter name'):
        save_parameters(path, example_vector(), extras={'bad key': 1})
    assert not path.exists()


def test_chain_dict_round_trip_and_json_shape():
    vector = example_vector()
    chains = parameters_to_chain_dict(vector)
    assert list(chains) == [f'chain_{i}' for i in range(1, 7)]
    assert set(chains['chain_1']) == {'A0', 'B', 'a', 'l'}
    assert chains['chain_2']['a'] == vector[16:18].tolist()
    assert chains['chain_2']['l'] == vector[15]
    decoded = json.loads(json.dumps(chains))
    assert chain_dict_to_parameters(decoded).tobytes() == vector.tobytes()


def test_chain_dict_errors_name_the_key():
    chains = parameters_to_chain_dict(example_vector())
    chains['chain_3']['a'] = [0.1]
    with pytest.raises(InvalidParametersError, match='chain_3.a must have 2 values, got 1'):
        chain_dict_to_parameters(chains)
    del chains['chain_5']
    with pytest.raises(InvalidParametersError, match='missing key chain_3.a|chain_3.a'):
        chain_dict_to_parameters(chains)
    with pytest.raises(InvalidParametersError, match='expected a mapping'):
        chain_dict_to_parameters([1, 2])


def test_paths_may_be_strings(tmp_path):
    path = str(Path(tmp_path) / 'p.yaml')
    save_parameters(path, example_vector())
    assert load_parameters(path).tobytes() == example_vector().tobytes()


# --- models (models.py) and Gough-Stewart parameters files ---------------------


def gs_example_vector() -> np.ndarray:
    """Return a valid Gough-Stewart 42-vector with distinct, non-round values."""
    rng = np.random.default_rng(11)
    chains = []
    for chain in range(6):
        angle = chain * math.pi / 3
        base = [0.5 * math.cos(angle), 0.5 * math.sin(angle), 0.0] + rng.uniform(-1e-3, 1e-3, 3)
        platform = [0.2 * math.cos(angle + 0.5), 0.2 * math.sin(angle + 0.5), 0.015] + rng.uniform(
            -1e-3, 1e-3, 3
        )
        chains.append(np.concatenate([base, platform, [0.6 + rng.uniform(-1e-3, 1e-3)]]))
    return np.concatenate(chains)


def gs_dotted_yaml(vector: np.ndarray, model_line: str | None = '    model: gough_stewart') -> str:
    lines = ['/**:', '  ros__parameters:'] + ([model_line] if model_line else [])
    for chain, f in enumerate(vector.reshape(6, 7).tolist(), start=1):
        lines.append(f'    chain_{chain}.A: [{f[0]!r}, {f[1]!r}, {f[2]!r}]')
        lines.append(f'    chain_{chain}.B: [{f[3]!r}, {f[4]!r}, {f[5]!r}]')
        lines.append(f'    chain_{chain}.l0: {f[6]!r}')
    return '\n'.join(lines) + '\n'


def test_model_layouts():
    from hexacal_msgs_py import models

    assert set(models.MODELS) == {'hexa_slide', 'gough_stewart', 'rotary_hexapod'}
    assert models.DEFAULT_MODEL == 'hexa_slide' and models.MODEL_KEY == 'model'
    slide, gs = models.MODELS['hexa_slide'], models.MODELS['gough_stewart']
    assert slide.n_parameters == 54 and slide.parameter_names == names.PARAMETER_NAMES
    assert (
        slide.actuator_names == names.SLIDER_NAMES and slide.posture_names == names.POSTURE_NAMES
    )
    assert gs.n_parameters == 42 and gs.fields_per_chain == 7
    assert gs.fields == ('Ax', 'Ay', 'Az', 'Bx', 'By', 'Bz', 'l0')
    assert gs.parameter_units == ('m',) * 42
    assert gs.parameter_names[:8] == (
        'chain_1.Ax',
        'chain_1.Ay',
        'chain_1.Az',
        'chain_1.Bx',
        'chain_1.By',
        'chain_1.Bz',
        'chain_1.l0',
        'chain_2.Ax',
    )
    assert gs.parameter_index(6, 'l0') == 41 and gs.parameter_index(3, 'By') == 18
    assert gs.parameter_names[gs.parameter_index(4, 'Az')] == 'chain_4.Az'
    assert gs.actuator_names == tuple(f'leg_{i}' for i in range(1, 7))
    assert gs.posture_names == gs.actuator_names + ('inclinometer_x', 'inclinometer_y', 'rotary')
    assert gs.chain_key_names == frozenset(
        f'chain_{c}.{k}' for c in range(1, 7) for k in ('A', 'B', 'l0')
    )
    with pytest.raises(ValueError, match='l0'):
        gs.parameter_index(1, 'A0x')
    with pytest.raises(ValueError, match='1..6'):
        gs.parameter_index(0, 'l0')


def test_model_lookups_name_the_problem():
    from hexacal_msgs_py import models

    assert models.model_layout('gough_stewart').name == 'gough_stewart'
    for bad in ('stewart', None, 3):
        with pytest.raises(InvalidParametersError, match='gough_stewart, hexa_slide'):
            models.model_layout(bad)
    assert models.model_for_vector_size(54).name == 'hexa_slide'
    assert models.model_for_vector_size(42).name == 'gough_stewart'
    with pytest.raises(InvalidParametersError, match='43 values'):
        models.model_for_vector_size(43)
    assert (
        models.model_for_actuator_names(['leg_%d' % i for i in range(6, 0, -1)] + ['rotary']).name
        == 'gough_stewart'
    )
    assert models.model_for_actuator_names(names.POSTURE_NAMES).name == 'hexa_slide'
    assert models.model_for_actuator_names(['leg_1', 'leg_2', 'slider_3']) is None


def test_gough_stewart_file_round_trips_bit_exact_with_model_and_extras(tmp_path):
    from hexacal_msgs_py.parameters_file import read_parameters_file

    vector = gs_example_vector()
    vector[2] = 1e-5
    vector[5] = -0.0
    path = tmp_path / 'gs.yaml'
    save_parameters(path, vector, extras={'bag': 'bags/gs', 'rank': 42}, header_comment='hexapod')
    text = path.read_text()
    assert text.startswith(
        '# hexapod\n/**:\n  ros__parameters:\n    model: gough_stewart\n    chain_1.A: ['
    )
    assert '    chain_6.l0: ' in text and 'A0' not in text
    contents = read_parameters_file(path)
    assert contents.model == 'gough_stewart' and contents.layout.n_parameters == 42
    assert contents.vector.tobytes() == vector.tobytes()
    assert contents.extras == {'bag': 'bags/gs', 'rank': 42}
    # Written explicitly as a Gough-Stewart: the same file.
    again = tmp_path / 'again.yaml'
    save_parameters(
        again,
        vector,
        extras={'bag': 'bags/gs', 'rank': 42},
        header_comment='hexapod',
        model='gough_stewart',
    )
    assert again.read_bytes() == path.read_bytes()


def test_gough_stewart_nested_form_and_hexa_slide_defaults(tmp_path):
    from hexacal_msgs_py.parameters_file import load_model, read_parameters_file

    vector = gs_example_vector()
    nested = ['/**:', '  ros__parameters:', '    model: gough_stewart']
    for chain, f in enumerate(vector.reshape(6, 7).tolist(), start=1):
        nested.append(
            f'    chain_{chain}: {{A: [{f[0]!r}, {f[1]!r}, {f[2]!r}], '
            f'B: [{f[3]!r}, {f[4]!r}, {f[5]!r}], l0: {f[6]!r}}}'
        )
    path = tmp_path / 'nested.yaml'
    path.write_text('\n'.join(nested) + '\n')
    assert read_parameters_file(path).vector.tobytes() == vector.tobytes()
    # No model key: a Hexa Slide, written as before (no model line); an explicit hexa_slide loads
    # too.
    slide = tmp_path / 'slide.yaml'
    save_parameters(slide, example_vector())
    assert 'model' not in slide.read_text() and load_model(slide) == 'hexa_slide'
    explicit = tmp_path / 'explicit.yaml'
    explicit.write_text(
        dotted_yaml(example_vector()).replace(
            '  ros__parameters:\n', '  ros__parameters:\n    model: hexa_slide\n'
        )
    )
    assert load_model(explicit) == 'hexa_slide'
    assert load_parameters(explicit).tobytes() == example_vector().tobytes()


@pytest.mark.parametrize(
    'text_change, expected',
    [
        (
            ('chain_3.A:', 'chain_3.A0:'),
            'gs.yaml: chain_3.A0 is not a gough_stewart parameter .*A, B, l0',
        ),
        (
            ('    chain_2.l0: ', '    chain_2.l: '),
            'gs.yaml: chain_2.l is not a gough_stewart parameter',
        ),
        (('model: gough_stewart', 'model: stewart'), "gs.yaml: model: unknown model 'stewart'"),
        (('model: gough_stewart', 'model: 7'), 'gs.yaml: model: unknown model 7'),
        (('    model: gough_stewart\n', ''), 'gs.yaml: chain_1.A is not a hexa_slide parameter'),
    ],
)
def test_gough_stewart_file_errors_name_file_and_key(tmp_path, text_change, expected):
    path = tmp_path / 'gs.yaml'
    path.write_text(gs_dotted_yaml(gs_example_vector()).replace(*text_change, 1))
    with pytest.raises(ParameterFileError, match=expected):
        load_parameters(path)


@pytest.mark.parametrize(
    'key, value, expected',
    [
        ('chain_4.l0', '0.0', 'chain_4.l0 must be > 0 m'),
        ('chain_1.l0', '-0.6', 'chain_1.l0 must be > 0 m'),
        ('chain_2.A', '[0.1, 0.2]', 'chain_2.A must have 3 values, got 2'),
        ('chain_5.B', '[0.1, .nan, 0.2]', 'chain_5.B must be finite'),
        ('chain_6.l0', '[0.6]', 'chain_6.l0 must be numeric'),
    ],
)
def test_gough_stewart_validation_errors(tmp_path, key, value, expected):
    path = tmp_path / 'gs.yaml'
    path.write_text(_replace_line(gs_dotted_yaml(gs_example_vector()), key, value))
    with pytest.raises(ParameterFileError, match=f'gs.yaml: {expected}'):
        load_parameters(path)


def test_gough_stewart_missing_key_is_named(tmp_path):
    path = tmp_path / 'gs.yaml'
    path.write_text(
        ''.join(
            line + '\n'
            for line in gs_dotted_yaml(gs_example_vector()).splitlines()
            if 'chain_5.l0' not in line
        )
    )
    with pytest.raises(ParameterFileError, match='gs.yaml: missing key chain_5.l0'):
        load_parameters(path)


def test_vector_sizes_pick_or_check_the_model(tmp_path):
    from hexacal_msgs_py.parameters_file import as_parameter_vector, validate_parameters

    assert as_parameter_vector(gs_example_vector()).shape == (42,)
    with pytest.raises(InvalidParametersError, match='shape'):
        as_parameter_vector(np.zeros(43))
    with pytest.raises(InvalidParametersError, match=r'\(54,\) for a hexa_slide'):
        as_parameter_vector(gs_example_vector(), 'hexa_slide')
    with pytest.raises(InvalidParametersError, match=r'\(42,\) for a gough_stewart'):
        as_parameter_vector(example_vector(), 'gough_stewart')
    bad = gs_example_vector()
    bad[13] = -1.0
    with pytest.raises(InvalidParametersError, match='chain_2.l0 must be > 0'):
        validate_parameters(bad)
    path = tmp_path / 'gs.yaml'
    with pytest.raises(ParameterFileError, match='gs.yaml: .*42'):
        save_parameters(path, example_vector(), model='gough_stewart')
    with pytest.raises(ParameterFileError, match='contradicts'):
        save_parameters(path, gs_example_vector(), extras={'model': 'hexa_slide'})
    with pytest.raises(ParameterFileError, match='collides'):
        save_parameters(path, gs_example_vector(), extras={'chain_1': {'l0': 0.6}})
    assert not path.exists()


def test_gough_stewart_chain_dict_round_trip():
    vector = gs_example_vector()
    chains = parameters_to_chain_dict(vector)
    assert list(chains) == [f'chain_{i}' for i in range(1, 7)]
    assert chains['chain_2'] == {
        'A': vector[7:10].tolist(),
        'B': vector[10:13].tolist(),
        'l0': vector[13],
    }
    assert parameters_to_chain_dict(vector, 'gough_stewart') == chains
    decoded = json.loads(json.dumps(chains))
    assert chain_dict_to_parameters(decoded, model='gough_stewart').tobytes() == vector.tobytes()
    with pytest.raises(InvalidParametersError, match='chain_1.A is not a hexa_slide parameter'):
        chain_dict_to_parameters(decoded)  # the default model is the Hexa Slide
    decoded['chain_4']['l0'] = 0.0
    with pytest.raises(InvalidParametersError, match='chain_4.l0 must be > 0'):
        chain_dict_to_parameters(decoded, model='gough_stewart')
