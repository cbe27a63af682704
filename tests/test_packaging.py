"""Packaging of the ament_python packages: colcon build and test, package.xml, venv install."""

from __future__ import annotations

import ast
import configparser
from contextlib import chdir
from importlib import metadata
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys

from catkin_pkg.package import parse_package
import pytest

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / 'ros2_ws' / 'src'
PACKAGES = ('hexacal_msgs_py', 'hexacal_identify', 'hexacal_driver')
EXECUTABLES = {
    'hexacal_driver': ('driver',),
    'hexacal_identify': (
        'collector',
        'identify',
        'executor',
        'kinematics',
        'replay',
        'hexacal',
        'bringup',
    ),
}
# ROS packages that, when imported, must be declared in package.xml.
ROS_PACKAGES = frozenset(
    {
        'rclpy',
        'sensor_msgs',
        'std_msgs',
        'std_srvs',
        'diagnostic_msgs',
        'ament_index_python',
        'builtin_interfaces',
        'geometry_msgs',
        'rcl_interfaces',
        'launch',
        'launch_ros',
        'rosidl_runtime_py',
        'rosbag2_py',
        *PACKAGES,
    }
)
# Python modules from system packages: import name -> (rosdep key, pip requirement).
PYTHON_PACKAGES = {
    'numpy': ('python3-numpy', 'numpy'),
    'scipy': ('python3-scipy', 'scipy'),
    'yaml': ('python3-yaml', 'pyyaml'),
    'matplotlib': ('python3-matplotlib', 'matplotlib'),
    'tqdm': ('python3-tqdm', 'tqdm'),
    'threadpoolctl': ('python3-threadpoolctl', 'threadpoolctl'),
    'lz4': ('python3-lz4', 'lz4'),
    'zstandard': ('python3-zstandard', 'zstandard'),
    'mcap': (None, 'mcap'),  # no rosdep key: pip only
    'mcap_ros2': (None, 'mcap-ros2-support'),
    # Imported by the tests only: test dependencies (rosdep key, the setup.py test extra).
    'pytest': ('python3-pytest', 'pytest'),
    'hypothesis': ('python3-hypothesis', 'hypothesis'),
}
COLCON = Path(sys.executable).parent / 'colcon'
NO_COLCON = 'colcon is not installed here (`make setup` installs it from requirements-dev.txt)'
BUILD_ARTIFACTS = shutil.ignore_patterns(
    'build', 'install', 'log', '__pycache__', '*.egg-info', '.pytest_cache', '.hypothesis'
)


def imported_modules(paths: list[Path]) -> dict[str, Path]:
    """Top-level absolute imports of the given Python files -> first file importing it."""
    found: dict[str, Path] = {}
    for path in paths:
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                found.setdefault(name.split('.')[0], path)
    return found


def package_sources(package: str) -> tuple[list[Path], list[Path]]:
    """(runtime Python files: the package and launch files, test Python files)."""
    root = SRC / package
    runtime = sorted((root / package).rglob('*.py')) + sorted(root.glob('launch/*.py'))
    tests = sorted((root / 'test').rglob('*.py')) if (root / 'test').is_dir() else []
    return runtime, tests


def setup_py_data(package: str):
    """The Distribution that setup.py describes, without building anything."""
    from distutils.core import run_setup

    with chdir(SRC / package):
        return run_setup('setup.py', stop_after='init')


@pytest.mark.parametrize('package', PACKAGES)
def test_package_xml_is_format3_ament_python(package):
    manifest = parse_package(SRC / package / 'package.xml')  # validates format 3
    assert manifest.name == package
    assert manifest.package_format == 3
    assert manifest.get_build_type() == 'ament_python'
    assert 'python3-pytest' in {d.name for d in manifest.test_depends}
    assert (SRC / package / 'resource' / package).is_file()


@pytest.mark.parametrize('package', PACKAGES)
def test_package_xml_declares_every_imported_package(package):
    manifest = parse_package(SRC / package / 'package.xml')
    runtime_deps = {d.name for d in manifest.exec_depends}  # includes <depend>
    test_deps = runtime_deps | {d.name for d in manifest.test_depends}
    runtime, tests = package_sources(package)
    for files, declared, kind in (
        (runtime, runtime_deps, 'exec_depend'),
        (tests, test_deps, 'exec_depend/test_depend'),
    ):
        for module, path in imported_modules(files).items():
            if module in ROS_PACKAGES and module != package:
                assert module in declared, (
                    f'{path.relative_to(REPO)} imports {module}: add <{kind}>{module}'
                    f'</...> to {package}/package.xml'
                )
            if module in PYTHON_PACKAGES and PYTHON_PACKAGES[module][0]:
                key = PYTHON_PACKAGES[module][0]
                assert key in declared, (
                    f'{path.relative_to(REPO)} imports {module}: add <{kind}>{key}'
                    f'</...> to {package}/package.xml'
                )


@pytest.mark.parametrize('package', PACKAGES)
def test_setup_py_requires_every_imported_python_package(package):
    dist = setup_py_data(package)
    assert dist.get_name() == package
    required = {
        r.split('=')[0].split('<')[0].split('>')[0].strip().lower()
        for r in dist.install_requires or []
    }
    runtime, _ = package_sources(package)
    for module, path in imported_modules(runtime).items():
        if module in PYTHON_PACKAGES:
            requirement = PYTHON_PACKAGES[module][1]
            assert requirement in required, (
                f'{path.relative_to(REPO)} imports {module}: add {requirement!r} to '
                f'install_requires in {package}/setup.py'
            )


@pytest.mark.parametrize('package', PACKAGES)
def test_setup_py_declares_pytest_and_every_test_import_as_colcon_reads_it(package):
    # colcon test runs pytest only for a package whose setup.py names it a test dependency.
    pytest.importorskip('colcon_python_setup_py', reason=NO_COLCON)
    from colcon_core.package_augmentation.python import extract_dependencies
    from colcon_core.task.python.test import has_test_dependency
    from colcon_python_setup_py.package_identification.python_setup_py import (
        get_setup_information,
    )

    data = get_setup_information(SRC / package / 'setup.py')
    assert has_test_dependency(data, 'pytest'), (
        f"{package}/setup.py: colcon test falls back to unittest: add extras_require={{'test': "
        "['pytest']}"
    )
    dependencies = extract_dependencies(data)
    declared = {d.name.lower() for kind in ('run', 'test') for d in dependencies[kind]}
    _, tests = package_sources(package)
    for module, path in imported_modules(tests).items():
        if module in PYTHON_PACKAGES:
            requirement = PYTHON_PACKAGES[module][1]
            assert requirement in declared, (
                f'{path.relative_to(REPO)} imports {module}: add {requirement!r} to '
                f"extras_require['test'] in {package}/setup.py"
            )


def _pytest_options(path: Path) -> dict[str, str]:
    parser = configparser.ConfigParser(interpolation=None)
    parser.read(path)
    return {name: parser['pytest'][name] for name in ('addopts', 'markers')}


@pytest.mark.parametrize('package', PACKAGES)
def test_a_package_runs_its_tests_with_the_repository_options(package):
    # colcon test runs pytest in the package directory, where the package's pytest.ini rules.
    assert _pytest_options(SRC / package / 'pytest.ini') == _pytest_options(REPO / 'pytest.ini')


def test_identify_requires_its_python_dependencies():
    required = {r.lower() for r in setup_py_data('hexacal_identify').install_requires}
    assert {
        'numpy',
        'scipy',
        'pyyaml',
        'mcap',
        'mcap-ros2-support',
        'matplotlib',
        'tqdm',
    } <= required
    assert not any(r.startswith('ros-') for r in required), 'ROS wheels belong in requirements.txt'


def test_venv_has_entry_points_and_ament_index_entries():
    """What `make setup` promises: console scripts and ament index entries in .venv."""
    scripts = {ep.name: ep.value for ep in metadata.entry_points(group='console_scripts')}
    for package, names in EXECUTABLES.items():
        for name in names:
            assert name in scripts, f'{name} is not a console script of {package}'
            assert (Path(sys.executable).parent / name).is_file()
    env = dict(os.environ, AMENT_PREFIX_PATH=sys.prefix)
    code = (
        'import sys\nfrom ament_index_python.packages import get_package_share_directory\n'
        'for p in sys.argv[1:]: print(get_package_share_directory(p))'
    )
    result = subprocess.run(
        [sys.executable, '-c', code, *PACKAGES], env=env, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    for package, share in zip(PACKAGES, result.stdout.split()):
        assert (Path(share) / 'package.xml').read_bytes() == (
            SRC / package / 'package.xml'
        ).read_bytes()


def _colcon(root: Path, *arguments: str, timeout: float) -> subprocess.CompletedProcess:
    """Run colcon with its logs, build and install spaces under `root`."""
    verb, *rest = arguments
    spaces = ['--build-base', str(root / 'build'), '--install-base', str(root / 'install')]
    if verb == 'test-result':
        spaces = []
    return subprocess.run(
        [str(COLCON), '--log-base', str(root / 'log'), verb, *spaces, *rest],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.fixture(scope='module')
def colcon_workspace(tmp_path_factory) -> Path:
    """Return a scratch workspace (its root) with the three packages built by `colcon build`."""
    if not COLCON.is_file():
        pytest.skip(NO_COLCON)
    root = tmp_path_factory.mktemp('colcon')
    workspace = root / 'ws'
    shutil.copytree(SRC, workspace / 'src', ignore=BUILD_ARTIFACTS)
    # A launch file proves that launch/*.launch.py is installed (the repo may have none yet).
    launch_dir = workspace / 'src' / 'hexacal_identify' / 'launch'
    launch_dir.mkdir(exist_ok=True)
    (launch_dir / 'packaging_probe.launch.py').write_text(
        'def generate_launch_description():\n    raise NotImplementedError\n'
    )
    result = _colcon(root, 'build', '--base-paths', str(workspace / 'src'), timeout=600)
    assert result.returncode == 0, f'colcon build failed:\n{result.stdout}\n{result.stderr}'
    return root


@pytest.mark.slow
def test_colcon_build_installs_executables_and_markers(colcon_workspace):
    install = colcon_workspace / 'install'
    for package, names in EXECUTABLES.items():
        for name in names:
            executable = install / package / 'lib' / package / name
            assert executable.is_file() and os.access(executable, os.X_OK), executable
    for package in PACKAGES:
        prefix = install / package
        assert (prefix / 'share' / package / 'package.xml').read_bytes() == (
            SRC / package / 'package.xml'
        ).read_bytes()
        assert (prefix / 'share/ament_index/resource_index/packages' / package).is_file()
        site = next(prefix.glob('lib/python3*/site-packages'))
        for init in (SRC / package / package).rglob('__init__.py'):
            installed = site / init.relative_to(SRC / package)
            assert installed.is_file(), f'{installed} missing: find_packages() lost a package'
    assert (
        install / 'hexacal_identify/share/hexacal_identify/launch/packaging_probe.launch.py'
    ).is_file()

    env = dict(
        os.environ,
        AMENT_PREFIX_PATH=os.pathsep.join(str(install / package) for package in PACKAGES),
    )
    code = (
        'from ament_index_python.packages import get_package_share_directory\n'
        'print(get_package_share_directory("hexacal_driver"))'
    )
    found = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True)
    assert found.returncode == 0, found.stderr
    assert Path(found.stdout.strip()) == install / 'hexacal_driver/share/hexacal_driver'


def _pytest_count(package: str) -> int:
    """Return the number of tests pytest collects in the package's directory."""
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '--collect-only', '-q', '-p', 'no:cacheprovider'],
        cwd=SRC / package,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr
    return int(re.search(r'^(\d+) tests? collected', result.stdout, re.M).group(1))


@pytest.mark.slow  # the package's whole suite, its slow tests and lint included
def test_colcon_test_runs_the_package_suite_as_pytest_does(colcon_workspace):
    package = 'hexacal_msgs_py'  # the smallest suite
    source = colcon_workspace / 'ws' / 'src' / package
    result = _colcon(
        colcon_workspace,
        'test',
        '--base-paths',
        str(source),
        '--event-handlers',
        'console_direct-',
        timeout=1800,
    )
    assert result.returncode == 0, f'colcon test failed:\n{result.stdout}\n{result.stderr}'
    results = colcon_workspace / 'build' / package
    summary = _colcon(
        colcon_workspace, 'test-result', '--test-result-base', str(results), '--verbose', timeout=60
    )
    found = re.search(
        r'^Summary: (\d+) tests, (\d+) errors, (\d+) failures, (\d+) skipped$',
        summary.stdout,
        re.M,
    )
    assert found, summary.stdout + summary.stderr
    tests, errors, failures, _ = map(int, found.groups())
    assert (errors, failures) == (0, 0) and summary.returncode == 0, summary.stdout
    assert tests == _pytest_count(package), summary.stdout
    # pytest ran them (colcon's unittest fallback finds none): its JUnit file, its lint tests.
    junit = (results / 'pytest.xml').read_text()
    assert f'classname="{package}.test.test_flake8_msgs"' in junit
    assert f'classname="{package}.test.test_pep257_msgs"' in junit
