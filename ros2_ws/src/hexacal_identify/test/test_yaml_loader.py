"""
Test the one YAML text loader (hexacal_msgs_py.files.load_yaml_text) (#12 item 2).

libyaml's parser, the same documents.

Parameters files, posture plans and bag metadata parse with yaml.CSafeLoader
(or the parameters loader's libyaml twin) when PyYAML has libyaml: the same
documents as the pure-Python loaders, the same named errors, and no crash
on absurd nesting (libyaml's parser recurses in C: such text goes to the
pure-Python parser, which raises RecursionError, reported as before).
"""

from __future__ import annotations

from pathlib import Path

from hexacal_identify.bag import BagMetadataError, open_bag
from hexacal_identify.bag.reader import load_metadata_yaml
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_msgs_py import files, parameters_file
from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.parameters_file import load_parameters_file, save_parameters
import pytest
import yaml

BAGS = Path(__file__).resolve().parents[4] / 'bags'  # the repository's sample bags
needs_libyaml = pytest.mark.skipif(
    getattr(yaml, 'CSafeLoader', None) is None, reason='PyYAML without libyaml'
)


@needs_libyaml
def test_libyaml_is_used_for_ordinary_text(monkeypatch):
    used = []
    original = yaml.load

    def recording(text, Loader):  # noqa: N803 - yaml.load's keyword
        used.append(Loader)
        return original(text, Loader=Loader)

    monkeypatch.setattr(yaml, 'load', recording)
    load_metadata_yaml(BAGS / 'sphere50_noise10' / 'metadata.yaml')
    assert used == [yaml.CSafeLoader]
    assert files.load_yaml_text('a: [1, -2]\nb: {c: d}\n') == {'a': [1, -2], 'b': {'c': 'd'}}
    assert used[-1] is yaml.CSafeLoader


@needs_libyaml
@pytest.mark.parametrize(
    'bag', ['sphere30_nonoise', 'sphere50_noise10', 'sphere60_fixed20_noise10']
)
def test_bag_metadata_same_as_pure_python(bag):
    text = (BAGS / bag / 'metadata.yaml').read_text(encoding='utf-8')
    assert (
        load_metadata_yaml(BAGS / bag / 'metadata.yaml')
        == yaml.load(text, Loader=yaml.SafeLoader)['rosbag2_bagfile_information']
    )


@needs_libyaml
def test_parameters_files_same_as_pure_python(tmp_path):
    loaders = parameters_file._FAST_LOADERS
    python_loader = parameters_file._RosParametersLoader
    assert loaders[python_loader] is not python_loader
    texts = []
    for index, params in enumerate(
        [
            table1_parameters(),
            nominal_set(1, seed=0),
            nominal_set(2, seed=0),
            nominal_set(3, seed=5),
        ]
    ):
        path = tmp_path / f'p{index}.yaml'
        save_parameters(path, params.vector)
        texts.append(path.read_text())
    # ROS-style exponents without a dot or a signed exponent, which plain YAML 1.1 reads as
    # strings.
    texts.append(
        '/**:\n  ros__parameters:\n    x: 1e-5\n    y: 1.5e3\n    z: -2E+2\n    w: .5e1\n'
        '    s: "1e-5"\n    n: [1, 2.0, -3e2, ~, true, 0x10, 1_000]\n'
    )
    for text in texts:
        expected = yaml.load(text, Loader=python_loader)
        assert files.load_yaml_text(text, python_loader, loaders[python_loader]) == expected
    assert (
        yaml.load(texts[-1], Loader=loaders[python_loader])['/**']['ros__parameters']['x'] == 1e-5
    )
    vector, extras = load_parameters_file(tmp_path / 'p2.yaml')
    assert (vector == nominal_set(2, seed=0).vector).all() and extras == {}


@pytest.mark.slow
@pytest.mark.parametrize(
    'text', ['[' * 60_000, '[' * 60_000 + ']' * 60_000, '{a: ' * 60_000, '- ' * 60_000 + 'x']
)
def test_absurd_nesting_is_a_named_error_not_a_crash(tmp_path, text):
    """Would crash libyaml's composer: goes to the pure-Python parser."""
    path = tmp_path / 'deep.yaml'
    path.write_text('/**:\n  ros__parameters:\n    x: ' + text + '\n')
    with pytest.raises(ParameterFileError, match=f'{path}: invalid YAML'):
        load_parameters_file(path)
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: ' + text + '\n')
    with pytest.raises(
        BagMetadataError, match='metadata.yaml is not a readable rosbag2 metadata file'
    ):
        open_bag(bag)


@pytest.mark.parametrize(
    'text, problem',
    [
        ('/**:\n  ros__parameters: {chain_1.A0: [1, 2\n', 'invalid YAML'),
        ('/**:\n  ros__parameters:\n    x: !!python/object:os.system {}\n', 'invalid YAML'),
        ('a: b: c\n', 'invalid YAML'),
        ('\t- x\n', 'invalid YAML'),
    ],
)
def test_bad_yaml_names_the_file_and_the_problem(tmp_path, text, problem):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(ParameterFileError) as raised:
        load_parameters_file(path)
    message = str(raised.value)
    assert message.startswith(f'{path}: {problem}')
    assert 'line' in message  # where in the file
