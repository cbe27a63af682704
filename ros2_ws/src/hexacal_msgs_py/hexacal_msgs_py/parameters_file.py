"""Kinematic parameters as ROS 2 parameters YAML files and chain dicts (ROS-free).

File format (SI units: m; `a` holds the x, y components of the unit rail
direction vector)::

    /**:
      ros__parameters:
        chain_1.A0: [x, y, z]
        chain_1.B: [x, y, z]
        chain_1.a: [ax, ay]
        chain_1.l: 0.9947
        ...
        chain_6.l: 0.9947

Both dotted keys and nested mappings (``chain_1: {A0: [...]}``) load, as in
ROS 2; files are written with dotted keys. The vector form is the 54-vector
in PARAMETER_FIELDS chain-major order.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
import json
import math
import numbers
import os
from pathlib import Path
import re
from typing import Any, Union

import numpy as np
import yaml

from hexacal_msgs_py.errors import InvalidParametersError, ParameterFileError
from hexacal_msgs_py.files import atomic_write, load_yaml_text
from hexacal_msgs_py.names import (
    N_CHAINS,
    N_PARAMETERS,
    N_PARAMETERS_PER_CHAIN,
    PARAMETER_NAMES,
)

PathLike = Union[str, os.PathLike]
ChainDict = dict[str, dict[str, Any]]

# Per-chain key -> (offset in the chain's 9 fields, number of values);
# None marks a scalar. Written in this order.
CHAIN_KEYS: dict[str, tuple[int, int | None]] = {
    'A0': (0, 3),
    'B': (3, 3),
    'a': (7, 2),
    'l': (6, None),
}
_CHAIN_KEY_NAMES = frozenset(
    f'chain_{chain}.{key}' for chain in range(1, N_CHAINS + 1) for key in CHAIN_KEYS)
_PARAMETER_NAME = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$')
_MAX_NAMESPACE_DEPTH = 8

_Fail = Callable[[str], Exception]


class _RosParametersLoader(yaml.SafeLoader):
    """SafeLoader that also reads `1e-5` and `1.5e3` as floats, as ROS 2 does.

    YAML 1.1 (PyYAML) needs a dot and a signed exponent; rcl's parser does not.
    """


def _read_exponent_floats(loader: type) -> None:
    loader.add_implicit_resolver(
        'tag:yaml.org,2002:float',
        re.compile(r'^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$'),
        list('-+0123456789.'),
    )


_read_exponent_floats(_RosParametersLoader)
_FAST_LOADERS: dict[type, type] = {}  # pure-Python loader -> its twin with libyaml's parser
if getattr(yaml, 'CSafeLoader', None) is not None:

    class _RosParametersCLoader(yaml.CSafeLoader):
        """_RosParametersLoader with libyaml's parser (same resolvers and constructors)."""

    _read_exponent_floats(_RosParametersCLoader)
    _FAST_LOADERS.update({yaml.SafeLoader: yaml.CSafeLoader, _RosParametersLoader: _RosParametersCLoader})


def as_parameter_vector(vector: object) -> np.ndarray:
    """Return a float64 copy of `vector`, checked to be 54 finite numbers."""
    try:
        array = np.array(vector, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InvalidParametersError(
            f'parameter vector must be {N_PARAMETERS} numbers: {error}') from None
    if array.shape != (N_PARAMETERS,):
        raise InvalidParametersError(
            f'parameter vector must have shape ({N_PARAMETERS},), got {array.shape}')
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        index = int(bad[0])
        raise InvalidParametersError(
            f'parameter vector must be finite, got {array[index]!r} at '
            f'{PARAMETER_NAMES[index]} (index {index})')
    return array


def validate_parameters(vector: object) -> np.ndarray:
    """as_parameter_vector() plus physical checks: ax^2+ay^2 < 1 and l > 0."""
    array = as_parameter_vector(vector)
    problem = _physical_problem(array)
    if problem:
        raise InvalidParametersError(problem)
    return array


def load_parameters(path: PathLike) -> np.ndarray:
    """Load the 54-vector from a ROS 2 parameters YAML file."""
    return load_parameters_file(path)[0]


def read_yaml_document(path: PathLike, fail: _Fail,
                       loader: type = yaml.SafeLoader) -> Any:
    """A YAML file's document with a safe loader; every failure becomes fail(message), raised.

    Shared by the loaders of YAML files (parameters here, posture plans in the
    driver) so a missing file, bad encoding, bad YAML or absurd nesting is always
    a named error of the caller's kind.  SafeLoader and the parameters loader
    parse with libyaml when PyYAML has it (files.load_yaml_text).
    """
    try:
        text = Path(path).read_text(encoding='utf-8')
    except OSError as error:
        raise fail(f'cannot read: {error.strerror or error}') from error
    except UnicodeDecodeError as error:
        raise fail(f'not UTF-8 text: {error}') from error
    try:
        return load_yaml_text(text, loader, _FAST_LOADERS.get(loader))
    except yaml.YAMLError as error:
        raise fail(f'invalid YAML: {error}') from error
    except RecursionError:  # PyYAML composes recursively: '[[[[...' thousands deep
        raise fail('invalid YAML: nested too deeply') from None


def load_parameters_file(path: PathLike) -> tuple[np.ndarray, dict[str, Any]]:
    """Load the 54-vector and the other parameters (dotted name -> value)."""
    name = os.fspath(path)

    def fail(message: str) -> ParameterFileError:
        return ParameterFileError(f'{name}: {message}')

    document = read_yaml_document(path, fail, _RosParametersLoader)
    flat: dict[str, Any] = {}
    _flatten(_ros_parameters(document, fail), '', flat, fail)
    vector = _vector_from_flat(flat, fail)
    extras = {key: value for key, value in flat.items() if key not in _CHAIN_KEY_NAMES}
    return vector, extras


def save_parameters(
    path: PathLike,
    vector: object,
    extras: Mapping[str, Any] | None = None,
    header_comment: str | None = None,
) -> None:
    """Write the 54-vector (and extra parameters) atomically as ROS 2 parameters YAML.

    Floats are written with repr() so that loading gives the same bits back.
    """
    name = os.fspath(path)

    def fail(message: str) -> ParameterFileError:
        return ParameterFileError(f'{name}: {message}')

    try:
        array = validate_parameters(vector)
    except InvalidParametersError as error:
        raise fail(str(error)) from None
    flat_extras: dict[str, Any] = {}
    if extras:
        _flatten(extras, '', flat_extras, fail)
    lines = []
    if header_comment:
        lines += [f'# {line}'.rstrip() for line in header_comment.splitlines()]
    lines += ['/**:', '  ros__parameters:']
    for chain in range(1, N_CHAINS + 1):
        fields = array[(chain - 1) * N_PARAMETERS_PER_CHAIN:chain * N_PARAMETERS_PER_CHAIN]
        for key, (offset, count) in CHAIN_KEYS.items():
            if count is None:
                text = _format_float(fields[offset])
            else:
                text = '[' + ', '.join(_format_float(v) for v in fields[offset:offset + count]) + ']'
            lines.append(f'    chain_{chain}.{key}: {text}')
    for key, value in flat_extras.items():
        if key in _CHAIN_KEY_NAMES:
            raise fail(f'extra parameter {key} collides with a kinematic parameter')
        if not _PARAMETER_NAME.match(key):
            raise fail(f'extra parameter name {key!r} is not a valid ROS 2 parameter name')
        lines.append(f'    {key}: {_yaml_value(value, key, fail)}')
    _atomic_write(Path(path), '\n'.join(lines) + '\n', fail)


def parameters_to_chain_dict(vector: object) -> ChainDict:
    """{'chain_1': {'A0': [3], 'B': [3], 'a': [ax, ay], 'l': l}, ...} (the CLI's JSON shape)."""
    array = as_parameter_vector(vector)
    result: ChainDict = {}
    for chain in range(1, N_CHAINS + 1):
        fields = array[(chain - 1) * N_PARAMETERS_PER_CHAIN:chain * N_PARAMETERS_PER_CHAIN]
        entry: dict[str, Any] = {}
        for key, (offset, count) in CHAIN_KEYS.items():
            if count is None:
                entry[key] = float(fields[offset])
            else:
                entry[key] = [float(v) for v in fields[offset:offset + count]]
        result[f'chain_{chain}'] = entry
    return result


def chain_dict_to_parameters(chains: Mapping[str, Any]) -> np.ndarray:
    """Inverse of parameters_to_chain_dict(), with the same checks as load_parameters()."""
    def fail(message: str) -> InvalidParametersError:
        return InvalidParametersError(message)

    if not isinstance(chains, Mapping):
        raise fail(f'expected a mapping chain_1..chain_{N_CHAINS}, got {type(chains).__name__}')
    flat: dict[str, Any] = {}
    _flatten(chains, '', flat, fail)
    return _vector_from_flat(flat, fail)


def _ros_parameters(document: object, fail: _Fail) -> Mapping[str, Any]:
    """The first node's ros__parameters, descending through namespaces."""
    node = document
    for _ in range(_MAX_NAMESPACE_DEPTH):
        if not isinstance(node, dict) or not node:
            raise fail('expected a mapping "/**:" (or a node name) -> ros__parameters')
        node_name, body = next(iter(node.items()))
        if not isinstance(body, dict):
            raise fail(f'node {node_name!r} must be a mapping containing ros__parameters')
        if 'ros__parameters' in body:
            parameters = body['ros__parameters']
            if not isinstance(parameters, dict):
                raise fail(f'ros__parameters of node {node_name!r} must be a mapping')
            return parameters
        node = body  # a namespace: its first entry is the node
    raise fail('no ros__parameters found')


def _flatten(mapping: Mapping[Any, Any], prefix: str, out: dict[str, Any], fail: _Fail) -> None:
    """Nested mappings -> dotted names, as ROS 2 reads parameter files."""
    for key, value in mapping.items():
        if not isinstance(key, str):
            raise fail(f'parameter name {prefix}{key!r} must be a string')
        name = prefix + key
        if isinstance(value, Mapping):
            _flatten(value, name + '.', out, fail)
        elif name in out:
            raise fail(f'{name} is given twice (dotted and nested)')
        else:
            out[name] = value


def _number(value: object, name: str, fail: _Fail) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise fail(f'{name} must be numeric, got {value!r}')
    try:
        number = float(value)
    except OverflowError:  # an integer beyond the float range
        number = math.inf
    if not math.isfinite(number):
        raise fail(f'{name} must be finite, got {number!r}')
    return number


def _vector_from_flat(flat: Mapping[str, Any], fail: _Fail) -> np.ndarray:
    vector = np.empty(N_PARAMETERS, dtype=np.float64)
    for chain in range(1, N_CHAINS + 1):
        base = (chain - 1) * N_PARAMETERS_PER_CHAIN
        for key, (offset, count) in CHAIN_KEYS.items():
            name = f'chain_{chain}.{key}'
            if name not in flat:
                raise fail(f'missing key {name}')
            value = flat[name]
            if count is None:
                vector[base + offset] = _number(value, name, fail)
                continue
            if not isinstance(value, (list, tuple, np.ndarray)):
                raise fail(f'{name} must be a list of {count} values, got {value!r}')
            if len(value) != count:
                raise fail(f'{name} must have {count} values, got {len(value)}')
            for i, item in enumerate(value):
                vector[base + offset + i] = _number(item, name, fail)
    problem = _physical_problem(vector)
    if problem:
        raise fail(problem)
    return vector


def _physical_problem(vector: np.ndarray) -> str | None:
    for chain in range(1, N_CHAINS + 1):
        base = (chain - 1) * N_PARAMETERS_PER_CHAIN
        ax, ay = float(vector[base + 7]), float(vector[base + 8])
        norm_xy = ax * ax + ay * ay
        if norm_xy >= 1.0:
            return (f'chain_{chain}.a = [{ax!r}, {ay!r}] is not the x, y components of a '
                    f'unit vector (ax^2 + ay^2 = {norm_xy!r} >= 1)')
        length = float(vector[base + 6])
        if length <= 0.0:
            return f'chain_{chain}.l must be > 0 m, got {length!r}'
    return None


def _format_float(value: float) -> str:
    """repr() that YAML 1.1 reads back as the same float ('1e-05' would be a string)."""
    number = float(value)
    if math.isnan(number):
        return '.nan'
    if math.isinf(number):
        return '.inf' if number > 0 else '-.inf'
    text = repr(number)
    if 'e' in text and '.' not in text:
        mantissa, exponent = text.split('e')
        text = f'{mantissa}.0e{exponent}'
    return text


def _yaml_value(value: object, name: str, fail: _Fail) -> str:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return _format_float(float(value))
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a JSON string is a YAML double-quoted scalar
    if isinstance(value, (list, tuple)):
        items = []
        for item in value:
            if isinstance(item, (list, tuple, Mapping, np.ndarray)):
                raise fail(f'extra parameter {name} must be a flat list, got {value!r}')
            items.append(_yaml_value(item, name, fail))
        return '[' + ', '.join(items) + ']'
    raise fail(f'extra parameter {name} has unsupported type {type(value).__name__}')


def _atomic_write(target: Path, text: str, fail: _Fail) -> None:
    """files.atomic_write, with a failure named as this file's ParameterFileError."""
    try:
        atomic_write(target, text)
    except OSError as error:
        raise fail(f'cannot write: {error.strerror or error}') from error
