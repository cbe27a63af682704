"""
Check docs/nodes.md against the code, and that every relative link of the docs resolves.

The node reference is checked against the nodes themselves, not against a copy of their
parameter lists: each node is constructed in-process (rclpy, this session's isolated domain,
see conftest.py; no spinning, so nothing is discovered or published) and its declared
parameters are read from it - name, type, default, range and whether it may be set at run
time. The node classes are found by the name each node gives itself, so the test does not
depend on which module or class a node lives in. The executor needs a plan and a nominal
file: they are written with `hexacal params` and `hexacal plan` first.

Each node has a section `## <name>` in docs/nodes.md with a `### Parameters` table
(`| name | type | default | range | run time | description |`) and a `### Topics and
services` table. A parameter declared and not documented, or documented and not declared,
fails; so do a wrong type, default, range or run-time flag, and a topic or service the node
creates that its section does not name with its message type. bringup and replay are
command-line tools: every option their --help lists (and every launch argument of
launch/hexacal.launch.py) must be in their section.
"""

from __future__ import annotations

from dataclasses import dataclass
import importlib
import inspect
import math
from pathlib import Path
import pkgutil
import re
import subprocess
from typing import Any

import pytest
from rosproc import venv_executable
import yaml

REPO = Path(__file__).resolve().parents[1]
NODES_MD = REPO / 'docs' / 'nodes.md'
LAUNCH_FILE = REPO / 'ros2_ws/src/hexacal_identify/launch/hexacal.launch.py'
# Every node executable and the packages its code lives in.
NODE_PACKAGES = ('hexacal_identify.nodes', 'hexacal_driver')
NODES = ('collector', 'identify', 'executor', 'kinematics', 'driver')
TOOLS = ('bringup', 'replay')
# rclpy declares these on every node; docs/nodes.md says so once, not per node.
BUILTIN_PARAMETERS = {'use_sim_time', 'start_type_description_service'}
BUILTIN_TOPICS = {'/rosout', '/parameter_events'}
# Parameters whose default the node computes at start-up (documented in words).
COMPUTED_DEFAULTS = {
    ('identify', 'output_dir'),  # the working directory
    ('executor', 'plan'),
    ('executor', 'nominal'),
    ('executor', 'plan_name'),
    ('executor', 'stroke_limits_m'),
    ('executor', 'actuator_joints'),
    ('driver', 'plan_name'),
    ('collector', 'actuator_joints'),
}
TYPE_NAMES = {
    'PARAMETER_BOOL': 'bool',
    'PARAMETER_INTEGER': 'int',
    'PARAMETER_DOUBLE': 'double',
    'PARAMETER_STRING': 'string',
    'PARAMETER_BOOL_ARRAY': 'bool[]',
    'PARAMETER_INTEGER_ARRAY': 'int[]',
    'PARAMETER_DOUBLE_ARRAY': 'double[]',
    'PARAMETER_STRING_ARRAY': 'string[]',
}
LINKED_DOCS = ('README.md', 'docs/*.md')
_LINK = re.compile(r'(?<!!)\[[^\]]*\]\(([^)\s]+)\)')
_CODE = re.compile(r'`([^`]+)`')


@dataclass(frozen=True)
class Declared:
    """Hold a parameter as the node declares it."""

    type_name: str  # TYPE_NAMES' value, '' when not set, 'dynamic' for dynamic typing
    value: Any
    low: float | None
    high: float | None
    run_time: bool


@dataclass(frozen=True)
class Documented:
    """Hold a parameter row of docs/nodes.md, its cells as written."""

    type_cell: str
    default_cell: str
    range_cell: str
    run_time_cell: str


# ------------------------------------------------------------------------- docs/nodes.md


def sections(text: str, level: str = '## ') -> dict[str, str]:
    """Split markdown at headings of `level`: first word of the heading (no backticks) -> body."""
    found: dict[str, str] = {}
    name = None
    lines: list[str] = []
    for line in text.splitlines():
        if line.startswith(level):
            if name is not None:
                found[name] = '\n'.join(lines)
            name = line.removeprefix(level).split()[0].strip('`')
            lines = []
        elif name is not None:
            lines.append(line)
    if name is not None:
        found[name] = '\n'.join(lines)
    return found


def table_rows(text: str) -> list[list[str]]:
    """Return the body rows of the markdown tables in `text`, as lists of stripped cells."""
    rows = []
    for line in text.splitlines():
        line = line.strip()
        if not line.startswith('|') or set(line) <= set('|-: '):
            continue
        cells = [cell.strip() for cell in re.split(r'(?<!\\)\|', line.strip('|'))]
        rows.append(cells)
    return [row for row in rows if row and row[0].lower() not in ('name', 'parameter', 'option')]


def documented_parameters(section: str) -> dict[str, Documented]:
    """Return the rows of the section's `### Parameters` table: name -> its cells."""
    table = sections(section, '### ').get('Parameters', '')
    documented = {}
    for row in table_rows(table):
        names = _CODE.findall(row[0])
        assert len(names) == 1 and len(row) >= 6, f'malformed parameter row {row}'
        documented[names[0]] = Documented(row[1], row[2], row[3], row[4])
    return documented


def node_sections() -> dict[str, str]:
    return sections(NODES_MD.read_text())


# ------------------------------------------------------------------------- the nodes


def _node_classes() -> list[type]:
    """Return every rclpy Node subclass of the node packages built without arguments."""
    from rclpy.node import Node

    classes = {}
    for package_name in NODE_PACKAGES:
        package = importlib.import_module(package_name)
        modules = [package] + [
            importlib.import_module(info.name)
            for info in pkgutil.walk_packages(package.__path__, package_name + '.')
            if not info.name.endswith('__main__')  # importing it would run it
        ]
        for module in modules:
            for value in vars(module).values():
                if (
                    inspect.isclass(value)
                    and issubclass(value, Node)
                    and value.__module__.startswith(package_name.split('.')[0])
                ):
                    required = [
                        p
                        for p in inspect.signature(value.__init__).parameters.values()
                        if p.name != 'self'
                        and p.default is p.empty
                        and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
                    ]
                    if not required:
                        classes[f'{value.__module__}.{value.__qualname__}'] = value
    return list(classes.values())


def _endpoint_type(message_class: Any) -> str:
    """Return the type name of a message or service class: 'sensor_msgs/msg/JointState'."""
    module = message_class.__module__.split('.')  # sensor_msgs.msg._joint_state
    return f'{module[0]}/{module[1]}/{message_class.__name__}'


def _declared(node: Any) -> dict[str, Declared]:
    from rcl_interfaces.msg import ParameterType

    type_names = {
        getattr(ParameterType, name): TYPE_NAMES.get(name, '')
        for name in dir(ParameterType)
        if name.startswith('PARAMETER_')
    }
    declared = {}
    for name, parameter in node._parameters.items():
        if name in BUILTIN_PARAMETERS:
            continue
        descriptor = node.describe_parameter(name)
        ranges = [*descriptor.floating_point_range, *descriptor.integer_range]
        value = parameter.value
        declared[name] = Declared(
            type_name='dynamic'
            if descriptor.dynamic_typing
            else type_names.get(parameter.type_.value, ''),
            value=list(value) if isinstance(value, (list, tuple)) or hasattr(value, 'tolist')
            else value,
            low=ranges[0].from_value if ranges else None,
            high=ranges[0].to_value if ranges else None,
            run_time=not descriptor.read_only,
        )
    return declared


def _endpoints(node: Any) -> set[tuple[str, str, str]]:
    """Return (kind, name, type) of every topic and service the node made but rclpy's own."""
    own = node.get_fully_qualified_name() + '/'
    found = set()
    for publisher in node.publishers:
        found.add(('published', publisher.topic_name, _endpoint_type(publisher.msg_type)))
    for subscription in node.subscriptions:
        found.add(('subscribed', subscription.topic_name, _endpoint_type(subscription.msg_type)))
    for service in node.services:
        found.add(('service', service.service_name, _endpoint_type(service.srv_type)))
    return {
        endpoint
        for endpoint in found
        if endpoint[1] not in BUILTIN_TOPICS and not endpoint[1].startswith(own)
    }


@pytest.fixture(scope='module')
def built_nodes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict]:
    """Build each node once with its defaults: name -> {'parameters', 'endpoints'}."""
    import os

    import rclpy

    work = tmp_path_factory.mktemp('nodes')
    hexacal = venv_executable('hexacal')
    nominal, plan = work / 'nominal.yaml', work / 'plan.yaml'
    for argv in (
        [hexacal, 'params', 'table1', '--out', str(nominal)],
        [hexacal, 'plan', '--postures', '6', '--candidates', '200', '--nominal', str(nominal)]
        + ['--out', str(plan)],
    ):
        subprocess.run(argv, check=True, capture_output=True, timeout=120)
    overrides = work / 'overrides.yaml'
    overrides.write_text(
        yaml.safe_dump(
            {'executor': {'ros__parameters': {'plan': str(plan), 'nominal': str(nominal)}}}
        )
    )
    built: dict[str, dict] = {}
    failed: list[str] = []  # classes that could not be built (the nodes' own must be)
    cwd = os.getcwd()
    os.chdir(work)  # the collector records under bags/, identify writes under its directory
    rclpy.init(args=['test', '--ros-args', '--params-file', str(overrides)])
    try:
        for cls in _node_classes():
            try:
                node = cls()
            except Exception as error:  # noqa: B902 - reported below if a node is missing
                failed.append(f'{cls.__qualname__}: {error}')
                continue
            try:
                if node.get_name() in NODES:
                    built[node.get_name()] = {
                        'parameters': _declared(node),
                        'endpoints': _endpoints(node),
                    }
            finally:
                node.destroy_node()
    finally:
        rclpy.shutdown()
        os.chdir(cwd)
    assert sorted(built) == sorted(NODES), f'nodes built: {sorted(built)}; failed: {failed}'
    return built


# ------------------------------------------------------------------------- the checks


def test_every_node_and_tool_has_a_section():
    assert set(NODES) | set(TOOLS) <= set(node_sections())


@pytest.mark.slow  # builds every node (about 3 s)
@pytest.mark.parametrize('name', NODES)
def test_every_declared_parameter_is_documented_and_every_documented_one_declared(
    built_nodes, name
):
    declared = set(built_nodes[name]['parameters'])
    documented = set(documented_parameters(node_sections()[name]))
    assert declared - documented == set(), f'{name}: declared, not in docs/nodes.md'
    assert documented - declared == set(), f'{name}: in docs/nodes.md, not declared'


def _default(cell: str) -> Any:
    spans = _CODE.findall(cell)
    return yaml.safe_load(spans[0]) if len(spans) == 1 and cell.startswith('`') else None


def _range(cell: str) -> tuple[float, float]:
    """Read '1e-07 .. 0.1' or '-2 pi .. 2 pi' as two numbers."""

    def number(text: str) -> float:
        text = text.strip()
        if text.endswith('pi'):
            factor = text[:-2].strip()
            return (float(factor) if factor not in ('', '-') else float(factor + '1')) * math.pi
        return float(text)

    low, high = cell.split('..')
    return number(low), number(high)


@pytest.mark.slow  # builds every node (about 3 s)
@pytest.mark.parametrize('name', NODES)
def test_documented_types_defaults_ranges_and_run_time_flags_are_the_declared_ones(
    built_nodes, name
):
    documented = documented_parameters(node_sections()[name])
    for parameter, declared in built_nodes[name]['parameters'].items():
        row = documented[parameter]
        where = f'{name}.{parameter}'
        if declared.type_name not in ('', 'dynamic'):
            assert row.type_cell.strip('`') == declared.type_name, where
        assert (row.run_time_cell == 'yes') == declared.run_time, f'{where}: run time'
        if declared.low is not None:
            low, high = _range(row.range_cell)
            assert math.isclose(low, declared.low) and math.isclose(high, declared.high), where
        else:
            assert row.range_cell in ('', '-'), f'{where}: no range is declared'
        if (name, parameter) in COMPUTED_DEFAULTS or declared.type_name == '':
            continue
        expected = declared.value
        written = _default(row.default_cell)
        if isinstance(expected, float):  # YAML 1.1 reads 1e-05 as a string
            assert math.isclose(float(written), expected), f'{where}: {row.default_cell}'
        elif isinstance(expected, list) and expected and isinstance(expected[0], float):
            assert [float(x) for x in written] == expected, where
        else:
            assert written == expected, f'{where}: default {row.default_cell} != {expected!r}'


@pytest.mark.slow  # builds every node (about 3 s)
@pytest.mark.parametrize('name', NODES)
def test_every_topic_and_service_a_node_creates_is_documented_with_its_type(built_nodes, name):
    section = sections(node_sections()[name], '### ').get('Topics', '')
    rows = table_rows(section)
    for kind, resolved, type_name in sorted(built_nodes[name]['endpoints']):
        documented = [
            row
            for row in rows
            if resolved.lstrip('/') in [span.lstrip('/') for span in _CODE.findall(row[1])]
        ]
        assert documented, f'{name}: {kind} {resolved} is not in its section'
        assert any(row[0] == kind and type_name in row[2] for row in documented), (
            f'{name}: {resolved} documented as {documented}, expected {kind} {type_name}'
        )


def _help_options(executable: str) -> set[str]:
    result = subprocess.run(
        [venv_executable(executable), '--help'], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    return set(re.findall(r'(?<![\w-])(--[a-z][a-z0-9-]*)', result.stdout)) - {'--help'}


@pytest.mark.parametrize('tool', TOOLS)
def test_every_option_of_a_tool_is_documented(tool):
    section = node_sections()[tool]
    missing = sorted(o for o in _help_options(tool) if f'`{o}' not in section)
    assert not missing, f'{tool}: options not in docs/nodes.md: {missing}'


def test_every_launch_argument_is_documented():
    spec = importlib.util.spec_from_file_location('hexacal_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    section = node_sections()['bringup']
    missing = sorted(a for a in module.ARGUMENTS if f'`{a}' not in section)
    assert not missing, f'launch arguments not in docs/nodes.md: {missing}'


# ------------------------------------------------------------------------- links


def _documents() -> list[Path]:
    return sorted({p for pattern in LINKED_DOCS for p in REPO.glob(pattern)})


def _anchors(path: Path) -> set[str]:
    """Return the heading anchors GitHub gives a markdown file."""
    anchors = set()
    for line in path.read_text().splitlines():
        if line.startswith('#'):
            title = line.lstrip('#').strip().lower()
            title = re.sub(r'[^\w\- ]', '', title)
            anchors.add(title.replace(' ', '-'))
    return anchors


def test_the_docs_exist():
    names = {p.relative_to(REPO).as_posix() for p in _documents()}
    for name in (
        'README.md',
        'docs/user-guide.md',
        'docs/nodes.md',
        'docs/formats.md',
        'docs/design.md',
        'docs/results.md',
        'docs/testing.md',
    ):
        assert name in names


@pytest.mark.parametrize('document', _documents(), ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_relative_link_resolves(document):
    broken = []
    for target in _LINK.findall(document.read_text()):
        if re.match(r'^[a-z][a-z0-9+.-]*:', target):  # https:, mailto:
            continue
        path_part, _, anchor = target.partition('#')
        path = (document.parent / path_part).resolve() if path_part else document
        if not path.exists():
            broken.append(target)
        elif anchor and path.suffix == '.md' and anchor not in _anchors(path):
            broken.append(target)
    assert not broken, f'{document.relative_to(REPO)}: broken links {broken}'
