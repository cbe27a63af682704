"""
Test by property-based fuzzing (issue #7): malformed input raises only named errors.

Targets: the parameter-file loader, sensor readings and JointState conversions,
the stream synchroniser and posture detector, and the bag reader behind
``hexacal calibrate`` (postures_from_bag) with malformed content, schemas and
metadata. Byte-level damage of MCAP files is fuzzed in tests/test_bag_io.py.
Every property is bounded (max_examples) so the suite stays fast; for a deeper
search set HEXACAL_FUZZ_SCALE (e.g. 50: fifty times the examples).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
import tempfile

from hexacal_identify.bag import BagError, BagWriter, message_definition, open_bag
from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
from hexacal_identify.core.detection.dwell_detector import DwellDetector
from hexacal_identify.core.detection.stream_synchronizer import StreamSynchronizer
from hexacal_identify.core.errors import CalibrationError
from hexacal_identify.core.machine.model import nominal_set
from hexacal_msgs_py.errors import (
    HexacalContractError,
    InvalidParametersError,
    InvalidReadingError,
    ParameterFileError,
)
from hexacal_msgs_py.names import JOINT_STATE_TYPE, POSTURE_NAMES
from hexacal_msgs_py.parameters_file import (
    chain_dict_to_parameters,
    load_parameters,
    parameters_to_chain_dict,
    save_parameters,
    validate_parameters,
)
from hexacal_msgs_py.readings import (
    ActuatorReading,
    EncoderReading,
    InclinometerReading,
    PostureReading,
)
from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest
import yaml

SCALE = max(1, int(os.environ.get('HEXACAL_FUZZ_SCALE', '1')))
FAST = settings(
    max_examples=60 * SCALE,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
PROJECT_ERRORS = (HexacalContractError, CalibrationError, BagError)

# Any value a YAML document (or a careless caller) can put where a number belongs.
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**80), 2**80),
    st.floats(allow_nan=True),
    st.text(max_size=8),
    st.binary(max_size=4),
    st.just(10**400),
    st.just(-(10**400)),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=12,
)


def _scratch_file(name: str, data: bytes) -> Path:
    directory = Path(tempfile.mkdtemp(prefix='hexacal-fuzz-'))
    path = directory / name
    path.write_bytes(data)
    return path


# --------------------------------------------------------------------------- parameter files


_VALID = parameters_to_chain_dict(nominal_set(1).vector)


def _document(chains: dict, dotted: bool) -> dict:
    if dotted:
        parameters = {
            f'{chain}.{key}': value
            for chain, entry in chains.items()
            for key, value in (entry.items() if isinstance(entry, dict) else [('x', entry)])
        }
    else:
        parameters = chains
    return {'/**': {'ros__parameters': parameters}}


@st.composite
def mutated_parameter_documents(draw) -> str:
    chains = {chain: dict(entry) for chain, entry in _VALID.items()}
    for _ in range(draw(st.integers(1, 4))):
        chain = draw(st.sampled_from(sorted(chains)))
        key = draw(st.sampled_from(['A0', 'B', 'a', 'l', 'extra']))
        action = draw(st.sampled_from(['drop', 'replace', 'resize', 'element']))
        entry = chains[chain]
        if action == 'drop':
            entry.pop(key, None)
        elif action == 'replace':
            entry[key] = draw(values)
        elif action == 'resize' and isinstance(entry.get(key), list):
            if entry[key] and draw(st.booleans()):
                entry[key] = entry[key][: draw(st.integers(0, len(entry[key]) - 1))]
            else:
                entry[key] = entry[key] + [0.1] * draw(st.integers(1, 3))
        elif action == 'element' and isinstance(entry.get(key), list) and entry[key]:
            entry[key][draw(st.integers(0, len(entry[key]) - 1))] = draw(scalars)
    if draw(st.booleans()):
        chains[draw(st.sampled_from(sorted(chains)))] = draw(values)
    try:
        return yaml.safe_dump(_document(chains, draw(st.booleans())), allow_unicode=True)
    except yaml.YAMLError:  # a value safe_dump cannot represent: use it as text instead
        return draw(st.text(max_size=200))


@pytest.mark.slow
@FAST
@given(mutated_parameter_documents())
def test_parameter_loader_on_mutated_documents_raises_only_parameter_file_errors(text):
    path = _scratch_file('params.yaml', text.encode('utf-8', errors='surrogatepass'))
    try:
        vector = load_parameters(path)
    except ParameterFileError as error:
        assert str(path) in str(error)  # names the file
        return
    validate_parameters(vector)  # what loads is a usable parameter set


@pytest.mark.slow
@FAST
@given(
    st.one_of(
        st.text(max_size=300),
        st.binary(max_size=300).map(repr),
        st.integers(1, 3000).map(lambda depth: '[' * depth),
        st.integers(1, 2000).map(lambda depth: '{a: ' * depth),
    )
)
def test_parameter_loader_on_arbitrary_text_raises_only_parameter_file_errors(text):
    path = _scratch_file('params.yaml', text.encode('utf-8', errors='surrogatepass'))
    try:
        validate_parameters(load_parameters(path))
    except ParameterFileError:
        pass


@FAST
@given(st.binary(max_size=200))
def test_parameter_loader_on_arbitrary_bytes_raises_only_parameter_file_errors(data):
    try:
        load_parameters(_scratch_file('params.yaml', data))
    except ParameterFileError:
        pass


@FAST
@given(values)
def test_chain_dicts_raise_only_invalid_parameters_errors(chains):
    try:
        validate_parameters(chain_dict_to_parameters(chains))
    except InvalidParametersError:
        pass


@settings(max_examples=25 * SCALE, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=54, max_size=54))
def test_what_save_accepts_loads_back_bit_exact_and_what_it_refuses_is_named(vector):
    path = Path(tempfile.mkdtemp(prefix='hexacal-fuzz-')) / 'out.yaml'
    try:
        save_parameters(path, vector)
    except ParameterFileError:
        assert not path.exists()
        return
    assert np.array_equal(load_parameters(path), np.array(vector))


# --------------------------------------------------------------------------- readings


@FAST
@given(st.integers(-(2**70), 2**70) | scalars, st.lists(scalars, max_size=8), scalars, scalars)
def test_readings_raise_only_invalid_reading_errors(stamp, sliders, alpha, phi):
    for make in (
        lambda: ActuatorReading(stamp, sliders),
        lambda: InclinometerReading(stamp, alpha, phi),
        lambda: EncoderReading(stamp, phi),
        lambda: PostureReading(stamp, sliders, alpha, alpha, phi),
    ):
        try:
            reading = make()
        except InvalidReadingError:
            continue
        assert all(math.isfinite(v) for v in getattr(reading, 'actuator_positions', ()))


names_pool = st.sampled_from([*POSTURE_NAMES, 'elbow', '', 'slider_7', 'SLIDER_1'])


@FAST
@given(
    st.lists(names_pool, max_size=12),
    st.lists(st.floats(width=64), max_size=12),
    st.integers(-(2**31), 2**31 - 1),
    st.integers(0, 2**32 - 1),
)
def test_joint_state_conversions_raise_only_invalid_reading_errors(names, positions, sec, nanosec):
    from hexacal_msgs_py import conversions
    from sensor_msgs.msg import JointState

    message = JointState(name=names, position=positions)
    message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
    for convert in (
        conversions.joint_state_to_actuator_reading,
        conversions.joint_state_to_inclinometer_reading,
        conversions.joint_state_to_encoder_reading,
        conversions.joint_state_to_posture_reading,
    ):
        try:
            convert(message)
        except InvalidReadingError:
            pass


# --------------------------------------------------------------------------- detector


sample_values = st.floats(allow_nan=True, allow_infinity=True, width=64) | st.floats(-1e-3, 1e-3)


@st.composite
def sample_streams(draw):
    """Draw samples in bursts: still, moving, NaN, repeated and backwards stamps, gaps."""
    count = draw(st.integers(0, 400))
    step = draw(st.sampled_from([1_000_000, 10_000_000, 50_000_000]))
    stamps, rows = [], []
    stamp = draw(st.integers(0, 2**61))
    base = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=9, max_size=9)))
    while len(stamps) < count:
        kind = draw(st.sampled_from(['still', 'still', 'move', 'glitch', 'repeat', 'back', 'gap']))
        length = draw(st.integers(1, 80))
        for k in range(length):
            if kind == 'gap':
                stamp += draw(st.integers(1, 10**9))
            elif kind == 'back':
                stamp -= draw(st.integers(0, 10**8))
            elif kind != 'repeat':
                stamp += step
            if kind == 'move':
                base = base + 1e-3
            row = base.copy()
            if kind == 'glitch':
                row[draw(st.integers(0, 8))] = draw(sample_values)
            stamps.append(max(stamp, 0))
            rows.append(row)
    return np.array(stamps[:count], dtype=np.int64), np.array(rows[:count]).reshape(-1, 9)


@pytest.mark.slow
@FAST
@given(sample_streams(), st.integers(1, 64))
def test_posture_detector_never_raises_and_emits_only_finite_postures_from_its_input(data, chunk):
    stamps, rows = data
    detector = DwellDetector(window_s=0.05, capture_s=0.1, max_gap_s=0.02)
    postures = []
    for begin in range(0, len(stamps), chunk):
        part = slice(begin, begin + chunk)
        postures += detector.update(
            {
                'sliders': (stamps[part], rows[part, :6]),
                'inclinometer': (stamps[part], rows[part, 6:8]),
                'encoder': (stamps[part], rows[part, 8:]),
            }
        )
    postures += detector.finish()[0]
    finite = rows[np.all(np.isfinite(rows), axis=1)]
    emitted = [p.stamp_ns for p in postures]
    assert emitted == sorted(set(emitted))  # one posture per stamp, in time order
    for posture in postures:
        assert np.all(np.isfinite(posture.values)) and posture.sample_count >= 1
        assert np.all(posture.values >= finite.min(axis=0) - 1e-9)
        assert np.all(posture.values <= finite.max(axis=0) + 1e-9)


@FAST
@given(
    st.one_of(
        st.lists(scalars, max_size=5), st.just([2**70]), st.just([-1]), st.just([[1, 2], [3]])
    ),
    st.one_of(values, st.just(np.zeros((1, 8)))),
)
def test_posture_detector_refuses_malformed_batches_with_a_named_error(stamps, rows):
    try:
        DwellDetector().add('sliders', stamps, rows)
    except InvalidReadingError:
        pass


@FAST
@given(
    st.lists(
        st.tuples(
            st.sampled_from(['sliders', 'inclinometer', 'encoder']),
            st.integers(0, 2**62),
            st.floats(-1.0, 1.0),
        ),
        max_size=200,
    )
)
def test_synchronizer_pairs_only_within_the_skew_and_stays_bounded(events):
    synchronizer = StreamSynchronizer(max_skew_ns=20_000_000, history=16)
    paired = []
    for stream, stamp, value in events:
        if stream == 'sliders':
            paired += synchronizer.add_actuators(ActuatorReading(stamp, [value] * 6))
        elif stream == 'inclinometer':
            paired += synchronizer.add_inclinometer(InclinometerReading(stamp, value, value))
        else:
            paired += synchronizer.add_encoder(EncoderReading(stamp, value))
        assert synchronizer.pending <= 16
    paired += synchronizer.flush()
    stamps = [p.stamp_ns for p in paired]
    assert stamps == sorted(set(stamps))
    slider_stamps = {stamp for stream, stamp, _ in events if stream == 'sliders'}
    assert set(stamps) <= slider_stamps


# --------------------------------------------------------------------------- bag reader


@st.composite
def joint_state_dicts(draw, stamp_ns: int) -> dict:
    names = draw(st.one_of(st.just(list(POSTURE_NAMES)), st.lists(names_pool, max_size=11)))
    positions = draw(
        st.one_of(
            st.lists(st.floats(-1.0, 1.0), min_size=len(names), max_size=len(names)),
            st.lists(st.floats(width=64), max_size=11),
        )
    )
    return {
        'header': {
            'stamp': {'sec': stamp_ns // 10**9, 'nanosec': stamp_ns % 10**9},
            'frame_id': '',
        },
        'name': names,
        'position': positions,
        'velocity': [],
        'effort': [],
    }


@pytest.mark.slow
@settings(max_examples=30 * SCALE, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_bag_reader_on_malformed_content_raises_only_named_errors(data):
    """Random JointState content, topics, types and raw bytes, through postures_from_bag."""
    directory = Path(tempfile.mkdtemp(prefix='hexacal-fuzz-')) / 'bag'
    topics = data.draw(
        st.lists(
            st.sampled_from(
                [
                    '/hexacal/posture',
                    '/hexacal/sliders',
                    '/hexacal/inclinometer',
                    '/hexacal/encoder',
                    '/left/hexacal/posture',
                    '/other',
                ]
            ),
            min_size=1,
            max_size=4,
            unique=True,
        )
    )
    try:
        _write_fuzzed_bag(data, directory, topics)
        loaded = postures_from_bag(directory)
    except PROJECT_ERRORS:
        return
    for posture in loaded.postures:
        assert all(math.isfinite(v) for v in posture.values())


def _write_fuzzed_bag(data, directory: Path, topics: list[str]) -> None:
    with BagWriter(directory) as writer:
        types = {}
        for topic in topics:
            types[topic] = data.draw(
                st.sampled_from([JOINT_STATE_TYPE, JOINT_STATE_TYPE, 'std_msgs/msg/String'])
            )
            writer.add_topic(topic, types[topic])
        for index in range(data.draw(st.integers(0, 40))):
            topic = data.draw(st.sampled_from(topics))
            stamp = (
                data.draw(st.integers(0, 2**40))
                if data.draw(st.booleans())
                else (index + 1) * 10**7
            )
            if data.draw(st.integers(0, 9)) == 0:
                writer.write_raw(topic, data.draw(st.binary(max_size=64)), stamp)
            elif types[topic] == JOINT_STATE_TYPE:
                writer.write(topic, data.draw(joint_state_dicts(stamp)), stamp)
            else:
                writer.write(topic, {'data': data.draw(st.text(max_size=10))}, stamp)


_DEFINITION = message_definition(JOINT_STATE_TYPE)


@settings(max_examples=30 * SCALE, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_bag_reader_on_mutated_schemas_raises_only_named_errors(data):
    """The posture topic's ros2msg text edited line by line: other versions, garbage."""
    from mcap.writer import Writer as McapWriter

    lines = _DEFINITION.splitlines()
    for _ in range(data.draw(st.integers(1, 4))):
        index = data.draw(st.integers(0, len(lines) - 1))
        action = data.draw(st.sampled_from(['drop', 'duplicate', 'replace', 'insert']))
        if action == 'drop':
            del lines[index]
        elif action == 'duplicate':
            lines.insert(index, lines[index])
        else:
            new = data.draw(
                st.sampled_from(
                    [
                        'float32[] position',
                        'int32 extra',
                        'string name',
                        'float64[3] position',
                        'bogus line here',
                        '',
                        'std_msgs/Nothing header',
                        'uint8 X=3',
                    ]
                )
            )
            if action == 'replace':
                lines[index] = new
            else:
                lines.insert(index, new)
    path = Path(tempfile.mkdtemp(prefix='hexacal-fuzz-')) / 'mutated.mcap'
    with open(path, 'wb') as stream:
        writer = McapWriter(stream)
        writer.start(profile='ros2', library='hexacal fuzz')
        schema_id = writer.register_schema(JOINT_STATE_TYPE, 'ros2msg', '\n'.join(lines).encode())
        channel_id = writer.register_channel('/hexacal/posture', 'cdr', schema_id)
        for index in range(data.draw(st.integers(0, 3))):  # raw CDR bytes under the mutated schema
            writer.add_message(
                channel_id, index + 1, data.draw(st.binary(max_size=120)), index + 1
            )
        writer.finish()
    try:
        loaded = postures_from_bag(path)
    except PROJECT_ERRORS:
        return
    assert all(math.isfinite(v) for p in loaded.postures for v in p.values())


@pytest.mark.slow
@FAST
@given(values)
def test_bag_metadata_yaml_of_any_shape_raises_only_bag_errors(document):
    directory = Path(tempfile.mkdtemp(prefix='hexacal-fuzz-')) / 'bag'
    with BagWriter(directory) as writer:
        writer.add_topic('/hexacal/posture', JOINT_STATE_TYPE)
    try:
        text = yaml.safe_dump({'rosbag2_bagfile_information': document})
    except yaml.YAMLError:
        text = repr(document)
    (directory / 'metadata.yaml').write_text(text)
    try:
        reader = open_bag(directory)
        reader.info()
        list(reader.messages())
    except BagError:
        pass
