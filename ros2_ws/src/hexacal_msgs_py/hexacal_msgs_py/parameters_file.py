"""
Kinematic parameters as ROS 2 parameters YAML files and chain dicts (ROS-free).

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

Other machine models (models.py) name themselves with ``model: <name>`` beside
their chain keys, e.g. a Gough-Stewart platform::

    /**:
      ros__parameters:
        model: gough_stewart
        chain_1.A: [x, y, z]
        chain_1.B: [x, y, z]
        chain_1.l0: 0.85
        ...

A file without ``model`` is a Hexa Slide; Hexa Slide files are written without
it.  A ``chain_N.<key>`` that is not a key of the file's
model is an error naming the key.

An optional section carries the axial compliances identified with the geometry
(m/N; ``compliance_extras`` / ``compliances_from_extras``)::

        compliance.chains: 2.0e-08        # or compliance.chain_1 .. chain_6
        compliance.link: 1.0e-07          # the measuring link's (calibration only)
        compliance_std.chains: 1.5e-09    # their standard deviations, where known

A rigid calibration writes none of it (its file is the geometry alone) and a file
without it is a rigid machine.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import json
import math
import numbers
import os
from pathlib import Path
import re
from typing import Any, Union

from hexacal_msgs_py.errors import InvalidParametersError, ParameterFileError
from hexacal_msgs_py.files import atomic_write, load_yaml_text
from hexacal_msgs_py.models import (
    DEFAULT_MODEL,
    HEXA_SLIDE,
    model_for_vector_size,
    MODEL_KEY,
    model_layout,
    ModelLayout,
    MODELS,
)
from hexacal_msgs_py.names import N_CHAINS
import numpy as np
import yaml

PathLike = Union[str, os.PathLike]
ChainDict = dict[str, dict[str, Any]]

# The Hexa Slide's per-chain key -> (offset in the chain's 9 fields, number of
# values); None marks a scalar. Written in this order. (Every model's keys:
# models.MODELS[name].chain_keys.)
CHAIN_KEYS: dict[str, tuple[int, int | None]] = {
    key.name: (key.offset, key.count) for key in MODELS[HEXA_SLIDE].chain_keys
}
_CHAIN_KEY = re.compile(r'^chain_[0-9]+\.')
_PARAMETER_NAME = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$')
_MAX_NAMESPACE_DEPTH = 8

_Fail = Callable[[str], Exception]


class _RosParametersLoader(yaml.SafeLoader):
    """
    SafeLoader that also reads `1e-5` and `1.5e3` as floats, as ROS 2 does.

    YAML 1.1 (PyYAML) needs a dot and a signed exponent; rcl's parser does not.
    """


def _read_exponent_floats(loader: type[yaml.resolver.BaseResolver]) -> None:
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
    _FAST_LOADERS.update(
        {yaml.SafeLoader: yaml.CSafeLoader, _RosParametersLoader: _RosParametersCLoader}
    )


def _layout_of(model: str | ModelLayout | None, size: int | None = None) -> ModelLayout:
    """
    Return the named model's layout.

    The named model's layout; None: the Hexa Slide, or the one model of a vector of `size`.
    """
    if isinstance(model, ModelLayout):
        return model
    if model is None:
        return model_layout(DEFAULT_MODEL) if size is None else model_for_vector_size(size)
    return model_layout(model)


def as_parameter_vector(vector: object, model: str | ModelLayout | None = None) -> np.ndarray:
    """
    Return a float64 copy of `vector`, checked to be the model's number of finite values.

    Without `model`, a vector of 54 values is a Hexa Slide's and one of 42 a
    Gough-Stewart platform's.
    """
    try:
        array = np.array(vector, dtype=np.float64)
    except (TypeError, ValueError) as error:
        expected = _layout_of(model).n_parameters if model is not None else "the model's"
        raise InvalidParametersError(
            f'parameter vector must be {expected} numbers: {error}'
        ) from None
    if model is None:
        sizes = sorted({layout.n_parameters for layout in MODELS.values()})
        if array.ndim != 1 or array.size not in sizes:
            default = MODELS[DEFAULT_MODEL]
            raise InvalidParametersError(
                f'parameter vector must have shape ({default.n_parameters},) (a {default.title}) '
                'or one of '
                f'{[(n,) for n in sizes]} (see models.MODELS), got {array.shape}'
            )
    layout = _layout_of(model, array.size)
    if array.shape != (layout.n_parameters,):
        raise InvalidParametersError(
            f'parameter vector must have shape ({layout.n_parameters},) for a {layout.name}, got '
            f'{array.shape}'
        )
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        index = int(bad[0])
        raise InvalidParametersError(
            f'parameter vector must be finite, got {array[index]!r} at '
            f'{layout.parameter_names[index]} (index {index})'
        )
    return array


def validate_parameters(vector: object, model: str | ModelLayout | None = None) -> np.ndarray:
    """
    Return the parameter vector, physically checked.

    as_parameter_vector() plus the model's physical checks (Hexa Slide: ax^2+ay^2 < 1 and l > 0).
    """
    array = as_parameter_vector(vector, model)
    problem = _layout_of(model, array.size).physical_problem(array)
    if problem:
        raise InvalidParametersError(problem)
    return array


@dataclass(frozen=True)
class ParametersFile:
    """A parameters file's contents: its model, the parameter vector and the other parameters."""

    model: str
    vector: np.ndarray
    extras: dict[str, Any]

    @property
    def layout(self) -> ModelLayout:
        return MODELS[self.model]


COMPLIANCE_KEY = 'compliance'
COMPLIANCE_STD_KEY = 'compliance_std'
SHARED_CHAIN_COMPLIANCE = 'chains'
LINK_COMPLIANCE = 'link'
COMPLIANCE_NAMES = (SHARED_CHAIN_COMPLIANCE,) + tuple(
    f'chain_{c}' for c in range(1, N_CHAINS + 1)
) + (LINK_COMPLIANCE,)


def compliance_extras(
    values: Mapping[str, float], std: Mapping[str, float] | None = None
) -> dict[str, float]:
    """Return the parameters-file keys of identified compliances (m/N; module doc); {}: rigid."""
    extras: dict[str, float] = {}
    for key, mapping in ((COMPLIANCE_KEY, values), (COMPLIANCE_STD_KEY, std or {})):
        for name, value in mapping.items():
            if name not in COMPLIANCE_NAMES:
                raise ValueError(
                    f'unknown compliance {name!r}; choose from {", ".join(COMPLIANCE_NAMES)}'
                )
            if value is not None and math.isfinite(float(value)):
                extras[f'{key}.{name}'] = float(value)
    return extras


def compliances_from_extras(extras: Mapping[str, Any]) -> dict[str, float]:
    """
    Return {name: m/N} of a parameters file's compliance section ({} without one: rigid).

    ValueError names a key that is not a compliance, a value that is not a finite number, or a
    section that gives both the shared ``chains`` and per-chain values.
    """
    prefix = f'{COMPLIANCE_KEY}.'
    values: dict[str, float] = {}
    for key, value in extras.items():
        if not key.startswith(prefix):
            continue
        name = key[len(prefix):]
        if name not in COMPLIANCE_NAMES:
            raise ValueError(
                f'{key}: not a compliance; choose from '
                + ', '.join(prefix + n for n in COMPLIANCE_NAMES)
            )
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(
            float(value)
        ):
            raise ValueError(f'{key}: a compliance is a finite number of m/N, got {value!r}')
        values[name] = float(value)
    if SHARED_CHAIN_COMPLIANCE in values and any(n.startswith('chain_') for n in values):
        raise ValueError(
            f'{prefix}{SHARED_CHAIN_COMPLIANCE} and per-chain {prefix}chain_N both given: give one'
        )
    return values


def load_parameters(path: PathLike) -> np.ndarray:
    """Load the parameter vector (54 for a Hexa Slide) from a ROS 2 parameters YAML file."""
    return read_parameters_file(path).vector


def load_model(path: PathLike) -> str:
    """
    Return the model a parameters file names.

    The model a parameters file names (``hexa_slide`` when it names none).
    """
    return read_parameters_file(path).model


def read_yaml_document(path: PathLike, fail: _Fail, loader: type = yaml.SafeLoader) -> Any:
    """
    Read a YAML file's document with a safe loader.

    A YAML file's document with a safe loader; every failure becomes fail(message), raised.

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
    """Load the parameter vector and the other parameters (dotted name -> value; not ``model``)."""
    contents = read_parameters_file(path)
    return contents.vector, contents.extras


def read_parameters_file(path: PathLike) -> ParametersFile:
    """Load a parameters file: its model (key ``model``, default hexa_slide), vector and extras."""
    name = os.fspath(path)

    def fail(message: str) -> ParameterFileError:
        return ParameterFileError(f'{name}: {message}')

    document = read_yaml_document(path, fail, _RosParametersLoader)
    flat: dict[str, Any] = {}
    _flatten(_ros_parameters(document, fail), '', flat, fail)
    layout = _model_from_flat(flat, fail)
    vector = _vector_from_flat(flat, fail, layout)
    chain_keys = layout.chain_key_names
    extras = {
        key: value for key, value in flat.items() if key not in chain_keys and key != MODEL_KEY
    }
    return ParametersFile(layout.name, vector, extras)


def _model_from_flat(flat: Mapping[str, Any], fail: _Fail) -> ModelLayout:
    if MODEL_KEY not in flat:
        return MODELS[DEFAULT_MODEL]
    try:
        return model_layout(flat[MODEL_KEY])
    except InvalidParametersError as error:
        raise fail(f'{MODEL_KEY}: {error}') from None


def save_parameters(
    path: PathLike,
    vector: object,
    extras: Mapping[str, Any] | None = None,
    header_comment: str | None = None,
    model: str | None = None,
) -> None:
    """
    Write the parameter vector (and extra parameters) atomically as ROS 2 parameters YAML.

    Floats are written with repr() so that loading gives the same bits back.
    `model` defaults to the one model of the vector's size; a model other than
    the Hexa Slide is written as ``model: <name>`` first.
    """
    name = os.fspath(path)

    def fail(message: str) -> ParameterFileError:
        return ParameterFileError(f'{name}: {message}')

    try:
        array = validate_parameters(vector, model)
    except InvalidParametersError as error:
        raise fail(str(error)) from None
    layout = _layout_of(model, array.size)
    flat_extras: dict[str, Any] = {}
    if extras:
        _flatten(extras, '', flat_extras, fail)
    lines = []
    if header_comment:
        lines += [f'# {line}'.rstrip() for line in header_comment.splitlines()]
    lines += ['/**:', '  ros__parameters:']
    if layout.name != HEXA_SLIDE:
        lines.append(f'    {MODEL_KEY}: {layout.name}')
    for chain, entry in _chain_entries(array, layout):
        for key, value in entry.items():
            if isinstance(value, list):
                text = '[' + ', '.join(_format_float(v) for v in value) + ']'
            else:
                text = _format_float(value)
            lines.append(f'    chain_{chain}.{key}: {text}')
    chain_keys = layout.chain_key_names
    for key, value in flat_extras.items():
        if key == MODEL_KEY:
            if value != layout.name:
                raise fail(
                    f"extra parameter {MODEL_KEY}={value!r} contradicts the vector's model "
                    f'{layout.name}'
                )
            continue
        if key in chain_keys or _CHAIN_KEY.match(key):
            raise fail(f'extra parameter {key} collides with a kinematic parameter')
        if not _PARAMETER_NAME.match(key):
            raise fail(f'extra parameter name {key!r} is not a valid ROS 2 parameter name')
        lines.append(f'    {key}: {_yaml_value(value, key, fail)}')
    _atomic_write(Path(path), '\n'.join(lines) + '\n', fail)


def _chain_entries(array: np.ndarray, layout: ModelLayout):
    """(chain number, {key: value or list}) per chain, keys in the model's file order."""
    width = layout.fields_per_chain
    for chain in range(1, layout.n_chains + 1):
        fields = array[(chain - 1) * width:chain * width]
        entry: dict[str, Any] = {}
        for key in layout.chain_keys:
            if key.count is None:
                entry[key.name] = float(fields[key.offset])
            else:
                entry[key.name] = [float(v) for v in fields[key.offset:key.offset + key.count]]
        yield chain, entry


def parameters_to_chain_dict(vector: object, model: str | None = None) -> ChainDict:
    """
    {'chain_1': {'A0': [3], 'B': [3], 'a': [ax, ay], 'l': l}, ...} (the CLI's JSON shape).

    Keys are the model's (Gough-Stewart: A, B, l0); `model` defaults to the
    one model of the vector's size.
    """
    array = as_parameter_vector(vector, model)
    layout = _layout_of(model, array.size)
    return {f'chain_{chain}': entry for chain, entry in _chain_entries(array, layout)}


def chain_dict_to_parameters(chains: Mapping[str, Any], model: str | None = None) -> np.ndarray:
    """
    Inverse of parameters_to_chain_dict(), with the same checks as load_parameters().

    `model` defaults to the Hexa Slide.
    """

    def fail(message: str) -> InvalidParametersError:
        return InvalidParametersError(message)

    layout = _layout_of(model)
    if not isinstance(chains, Mapping):
        raise fail(f'expected a mapping chain_1..chain_{N_CHAINS}, got {type(chains).__name__}')
    flat: dict[str, Any] = {}
    _flatten(chains, '', flat, fail)
    return _vector_from_flat(flat, fail, layout)


def _ros_parameters(document: object, fail: _Fail) -> Mapping[str, Any]:
    """
    Return the first node's ros__parameters.

    The first node's ros__parameters, descending through namespaces.
    """
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


def _vector_from_flat(flat: Mapping[str, Any], fail: _Fail, layout: ModelLayout) -> np.ndarray:
    known = layout.chain_key_names
    for name in flat:
        if _CHAIN_KEY.match(name) and name not in known:
            keys = ', '.join(key.name for key in layout.chain_keys)
            raise fail(f'{name} is not a {layout.name} parameter (its chain keys are {keys})')
    vector = np.empty(layout.n_parameters, dtype=np.float64)
    for chain in range(1, layout.n_chains + 1):
        base = (chain - 1) * layout.fields_per_chain
        for key in layout.chain_keys:
            name, offset, count = f'chain_{chain}.{key.name}', key.offset, key.count
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
    problem = layout.physical_problem(vector)
    if problem:
        raise fail(problem)
    return vector


def _format_float(value: float) -> str:
    """Repr() that YAML 1.1 reads back as the same float ('1e-05' would be a string)."""
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
        return json.dumps(
            value, ensure_ascii=False
        )  # a JSON string is a YAML double-quoted scalar
    if isinstance(value, (list, tuple)):
        items = []
        for item in value:
            if isinstance(item, (list, tuple, Mapping, np.ndarray)):
                raise fail(f'extra parameter {name} must be a flat list, got {value!r}')
            items.append(_yaml_value(item, name, fail))
        return '[' + ', '.join(items) + ']'
    raise fail(f'extra parameter {name} has unsupported type {type(value).__name__}')


def _atomic_write(target: Path, text: str, fail: _Fail) -> None:
    """Files.atomic_write, with a failure named as this file's ParameterFileError."""
    try:
        atomic_write(target, text)
    except OSError as error:
        raise fail(f'cannot write: {error.strerror or error}') from error
