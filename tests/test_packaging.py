"""Packaging of the ament_python packages: colcon build, package.xml, venv install."""

from __future__ import annotations

import ast
from contextlib import chdir
from importlib import metadata
import os
from pathlib import Path
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
}
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


@pytest.mark.slow
def test_colcon_build_installs_executables_and_markers(tmp_path):
    workspace = tmp_path / 'ws'
    shutil.copytree(SRC, workspace / 'src', ignore=BUILD_ARTIFACTS)
    # A launch file proves that launch/*.launch.py is installed (the repo may have none yet).
    launch_dir = workspace / 'src' / 'hexacal_identify' / 'launch'
    launch_dir.mkdir(exist_ok=True)
    (launch_dir / 'packaging_probe.launch.py').write_text(
        'def generate_launch_description():\n    raise NotImplementedError\n'
    )
    install = tmp_path / 'install'
    colcon = Path(sys.executable).parent / 'colcon'
    result = subprocess.run(
        [
            str(colcon),
            '--log-base',
            str(tmp_path / 'log'),
            'build',
            '--base-paths',
            str(workspace / 'src'),
            '--build-base',
            str(tmp_path / 'build'),
            '--install-base',
            str(install),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, f'colcon build failed:\n{result.stdout}\n{result.stderr}'

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
