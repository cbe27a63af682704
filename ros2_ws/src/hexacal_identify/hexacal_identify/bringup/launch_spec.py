"""
Describe one node to start: `NodeLaunch` and how its ROS arguments are spelled.

The same description starts a child process (`NodeLaunch.command`, bringup and
``hexacal demo``) and a launch_ros Node (launch/hexacal.launch.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import shutil
import sys
from typing import Any

import yaml

# Executable -> the module `python -m` runs when the console script is not installed.
EXECUTABLE_MODULES = {
    'driver': 'hexacal_driver.driver_node',
    'collector': 'hexacal_identify.nodes.collector',
    'identify': 'hexacal_identify.nodes.identify',
    'executor': 'hexacal_identify.nodes.executor',
    'kinematics': 'hexacal_identify.nodes.kinematics_node',
}
# Executable -> its ROS package (launch_ros finds the executable through it).
PACKAGES = {
    'driver': 'hexacal_driver',
    'collector': 'hexacal_identify',
    'identify': 'hexacal_identify',
    'executor': 'hexacal_identify',
    'kinematics': 'hexacal_identify',
}


@dataclass
class NodeLaunch:
    """One node to start: its executable, namespace and parameters."""

    executable: str  # a key of EXECUTABLE_MODULES
    parameters: dict[str, Any] = field(default_factory=dict)  # ROS parameter values
    namespace: str = ''
    remaps: dict[str, str] = field(default_factory=dict)  # ROS name -> topic (`-r from:=to`)

    def command(self) -> list[str]:
        """Return argv: the console script next to this interpreter, else `python -m <module>`."""
        script = Path(sys.executable).parent / self.executable
        if script.exists():
            argv = [str(script)]
        elif shutil.which(self.executable):
            argv = [str(shutil.which(self.executable))]
        else:
            argv = [sys.executable, '-m', EXECUTABLE_MODULES[self.executable]]
        ros_args = []
        if self.namespace:
            ros_args += ['-r', f'__ns:={normalize_namespace(self.namespace)}']
        for source, target in self.remaps.items():
            ros_args += ['-r', f'{source}:={target}']
        for name, value in self.parameters.items():
            ros_args += ['-p', f'{name}:={ros_parameter_text(value)}']
        return argv + (['--ros-args', *ros_args] if ros_args else [])


def normalize_namespace(namespace: str) -> str:
    """Return 'left' as '/left'; '' (and '/') stay the root namespace ''."""
    namespace = namespace.strip()
    if not namespace or namespace == '/':
        return ''
    return '/' + namespace.strip('/')


def ros_parameter_text(value: object) -> str:
    """Spell a value as `-p name:=<text>` must to keep its type (rcl reads it as YAML)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in '.eEn') else text + '.0'  # 100 would be an integer
    if isinstance(value, (list, tuple)):  # a YAML flow list: [leg_a, leg_b], [0.0, 0.01]
        return '[' + ', '.join(ros_parameter_text(item) for item in value) + ']'
    text = os.fspath(value) if isinstance(value, os.PathLike) else str(value)
    try:
        reads_back = yaml.safe_load(text) == text
    except yaml.YAMLError:
        reads_back = False
    return text if reads_back and text else json.dumps(text)  # quoted: stays a string
