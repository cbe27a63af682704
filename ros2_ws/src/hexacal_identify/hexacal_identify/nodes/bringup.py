"""``bringup``: start driver, collector and identify as child processes (no ros2 launch needed).

Each node runs in its own process group with its parameters given as
``--ros-args -p name:=value``. SIGINT and SIGTERM are forwarded to every
child, which then shut down cleanly (the collector closes its bag); a child
that does not exit within the stop timeout is escalated to SIGTERM, then
SIGKILL. If one node exits on its own, the others are stopped too and its exit
code is returned. On Linux the children also receive SIGTERM if bringup
itself dies, so no node outlives it.

The same pieces (`NodeLaunch`, `NodeGroup`) start the nodes of `hexacal demo`.
On a ROS 2 install, launch/hexacal.launch.py starts the same three nodes.
"""
from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time
from typing import IO

import yaml

EXECUTABLE_MODULES = {
    'driver': 'hexacal_driver.driver_node',
    'collector': 'hexacal_identify.nodes.collector',
    'identify': 'hexacal_identify.nodes.identify',
}
DEFAULT_STOP_TIMEOUT_S = 10.0
_PR_SET_PDEATHSIG = 1


@dataclass
class NodeLaunch:
    """One node to start: its executable, namespace and parameters."""

    executable: str  # 'driver', 'collector' or 'identify'
    parameters: dict[str, object] = field(default_factory=dict)
    namespace: str = ''

    def command(self) -> list[str]:
        """argv: the console script next to this interpreter, else `python -m <module>`."""
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
        for name, value in self.parameters.items():
            ros_args += ['-p', f'{name}:={ros_parameter_text(value)}']
        return argv + (['--ros-args', *ros_args] if ros_args else [])


def normalize_namespace(namespace: str) -> str:
    """'left' -> '/left'; '' stays the root namespace."""
    namespace = namespace.strip()
    if not namespace or namespace == '/':
        return ''
    return '/' + namespace.strip('/')


def ros_parameter_text(value: object) -> str:
    """A value as `-p name:=<text>` must spell it to keep its type (rcl reads it as YAML)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in '.eEn') else text + '.0'  # 100 would be an integer
    text = os.fspath(value) if isinstance(value, os.PathLike) else str(value)
    try:
        reads_back = yaml.safe_load(text) == text
    except yaml.YAMLError:
        reads_back = False
    return text if reads_back and text else json.dumps(text)  # quoted: stays a string


def _parent_death_signal():
    """A preexec_fn giving the child SIGTERM when its parent dies (Linux prctl), or None.

    libc is loaded here, in the parent: the child only makes the call, no dlopen after fork.
    """
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None

    def set_parent_death_signal() -> None:
        prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)

    return set_parent_death_signal


@dataclass
class RunningNode:
    launch: NodeLaunch
    popen: subprocess.Popen
    log_file: IO[bytes] | None = None

    @property
    def name(self) -> str:
        return self.launch.executable

    def running(self) -> bool:
        return self.popen.poll() is None


class NodeGroup:
    """Child node processes, each in its own process group; stop() ends them all."""

    def __init__(self, die_with_parent: bool = False) -> None:
        # die_with_parent runs code between fork and exec: only for single-threaded parents.
        self.nodes: list[RunningNode] = []
        self._preexec = _parent_death_signal() if die_with_parent else None

    def start(self, launch: NodeLaunch, env: Mapping[str, str] | None = None,
              log_path: str | os.PathLike[str] | None = None) -> RunningNode:
        """Start a node; its output goes to log_path, else to this process's stdout/stderr."""
        log_file = None
        if log_path is not None:
            Path(log_path).parent.mkdir(parents=True, exist_ok=True)
            log_file = open(log_path, 'wb')  # noqa: SIM115 - closed by stop()
        child_env = dict(os.environ)
        child_env.update(env or {})
        child_env.setdefault('PYTHONUNBUFFERED', '1')
        try:
            popen = subprocess.Popen(
                launch.command(), env=child_env, stdin=subprocess.DEVNULL,
                stdout=log_file, stderr=subprocess.STDOUT if log_file else None,
                start_new_session=True, preexec_fn=self._preexec)
        except BaseException:
            if log_file:
                log_file.close()
            raise
        node = RunningNode(launch, popen, log_file)
        self.nodes.append(node)
        return node

    def signal_all(self, signum: int) -> None:
        for node in self.nodes:
            if node.running():
                try:
                    os.killpg(node.popen.pid, signum)
                except ProcessLookupError:
                    pass

    def exited(self) -> list[RunningNode]:
        return [node for node in self.nodes if not node.running()]

    def stop(self, timeout: float = DEFAULT_STOP_TIMEOUT_S,
             order: Sequence[str] | None = None) -> dict[str, int]:
        """SIGINT every node (in `order` of executables first), escalate; name -> exit code."""
        first = list(order or ())
        ranked = sorted(self.nodes, key=lambda n: first.index(n.name) if n.name in first
                        else len(first))
        for node in ranked:
            self._stop_one(node, timeout)
        codes = {}
        for node in self.nodes:
            codes[node.name] = node.popen.returncode
            if node.log_file:
                node.log_file.close()
        self.nodes = []
        return codes

    @staticmethod
    def _stop_one(node: RunningNode, timeout: float) -> None:
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if not node.running():
                break
            try:
                os.killpg(node.popen.pid, signum)
            except ProcessLookupError:
                break
            try:
                node.popen.wait(timeout if signum != signal.SIGKILL else None)
            except subprocess.TimeoutExpired:
                continue
        node.popen.wait()


def launches(namespace: str = '', nominal: str = '', output_dir: str = '', bag_dir: str = '',
             plan: str = '', postures: int | None = None, record: bool = True,
             driver: Mapping[str, object] | None = None,
             collector: Mapping[str, object] | None = None,
             identify: Mapping[str, object] | None = None,
             with_driver: bool = True, model: str = '') -> list[NodeLaunch]:
    """The NodeLaunch of each node; empty options keep the nodes' defaults.

    `model` (hexa_slide or gough_stewart) goes to the driver and the collector;
    identify takes its model from the nominal file.
    """
    driver_parameters: dict[str, object] = {}
    collector_model: dict[str, object] = {'model': model} if model else {}
    driver_parameters.update(collector_model)
    if plan:
        driver_parameters['plan'] = plan
    if postures is not None:
        driver_parameters['postures'] = int(postures)
    driver_parameters.update(driver or {})
    collector_parameters: dict[str, object] = {'record': bool(record), **collector_model}
    if bag_dir:
        collector_parameters['output_dir'] = str(bag_dir)
    collector_parameters.update(collector or {})
    identify_parameters: dict[str, object] = {}
    if nominal:
        identify_parameters['nominal'] = str(Path(nominal).resolve())
    if output_dir:
        identify_parameters['output_dir'] = str(Path(output_dir).resolve())
    identify_parameters.update(identify or {})
    nodes = [NodeLaunch('collector', collector_parameters, namespace),
             NodeLaunch('identify', identify_parameters, namespace)]
    if with_driver:
        nodes.append(NodeLaunch('driver', driver_parameters, namespace))
    return nodes


def _file_model(path: str) -> str:
    """The model a parameters file names if it is not the default Hexa Slide; '' otherwise.

    '' also for a file that cannot be read: the node that reads it names the problem.
    """
    if not path:
        return ''
    from hexacal_msgs_py.errors import HexacalContractError
    from hexacal_msgs_py.models import DEFAULT_MODEL
    from hexacal_msgs_py.parameters_file import read_parameters_file

    try:
        model = read_parameters_file(path).model
    except (HexacalContractError, OSError, ValueError):
        return ''
    return '' if model == DEFAULT_MODEL else model


def _parse_param(text: str) -> tuple[str, str, object]:
    """'driver:settle_s=0.5' -> ('driver', 'settle_s', 0.5) (value read as YAML)."""
    try:
        node, rest = text.split(':', 1)
        name, value = rest.split('=', 1)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f'--param must look like NODE:NAME=VALUE, got {text!r}') from None
    if node not in EXECUTABLE_MODULES:
        raise argparse.ArgumentTypeError(
            f'--param node must be one of {sorted(EXECUTABLE_MODULES)}, got {node!r}')
    try:
        parsed = yaml.safe_load(value) if value else ''
    except yaml.YAMLError:
        parsed = value
    return node, name, parsed if isinstance(parsed, (bool, int, float, str)) else value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='bringup', description='Start the hexacal driver, collector and identify nodes as '
        'child processes; Ctrl-C (or SIGTERM) stops them all cleanly.')
    parser.add_argument('--namespace', default='', help='ROS namespace of all nodes (e.g. left)')
    parser.add_argument('--nominal', default='', help='nominal parameters YAML for identify')
    parser.add_argument('--output-dir', default='', help='directory identify writes its '
                        'calibration YAML under (default: the current directory)')
    parser.add_argument('--bag-dir', default='', help='directory the collector records bags '
                        'into (default: bags)')
    parser.add_argument('--no-record', action='store_true',
                        help='do not record until hexacal/start_recording is called')
    parser.add_argument('--plan', default='', help="driver plan: random, fixed, mixed or a plan "
                        "YAML (default: the driver's)")
    parser.add_argument('--postures', type=int, default=None, help='postures of a generated plan')
    parser.add_argument('--true-params', default='', help='parameters YAML of the simulated '
                        'machine, of either model (default: the default machine of --model)')
    parser.add_argument('--model', default='', choices=('', 'hexa_slide', 'gough_stewart'),
                        help='machine model of the driver and the collector (default: the model '
                        '--nominal, else --true-params names, else hexa_slide)')
    parser.add_argument('--no-driver', action='store_true',
                        help='start only collector and identify (a real machine publishes)')
    parser.add_argument('--param', action='append', type=_parse_param, default=[],
                        metavar='NODE:NAME=VALUE',
                        help='any other node parameter, e.g. driver:settle_s=0.5 (repeatable)')
    parser.add_argument('--stop-timeout', type=float, default=DEFAULT_STOP_TIMEOUT_S,
                        help='seconds a node gets to exit after SIGINT before escalation')
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    extra: dict[str, dict[str, object]] = {name: {} for name in EXECUTABLE_MODULES}
    for node, name, value in args.param:
        extra[node][name] = value
    if args.true_params:
        extra['driver'].setdefault('true_params', str(Path(args.true_params).resolve()))
    nodes = launches(args.namespace, args.nominal, args.output_dir, args.bag_dir, args.plan,
                     args.postures, not args.no_record, extra['driver'], extra['collector'],
                     extra['identify'], with_driver=not args.no_driver,
                     model=args.model or _file_model(args.nominal) or _file_model(args.true_params))
    group = NodeGroup(die_with_parent=True)
    received: list[int] = []

    def forward(signum: int, frame: object) -> None:
        received.append(signum)

    previous = {signum: signal.signal(signum, forward) for signum in (signal.SIGINT,
                                                                       signal.SIGTERM)}
    exit_code = 0
    try:
        for launch in nodes:
            node = group.start(launch)
            print(f'bringup: started {launch.executable} (pid {node.popen.pid}): '
                  f"{' '.join(launch.command())}", file=sys.stderr, flush=True)
        while not received:
            finished = group.exited()
            if finished:
                node = finished[0]
                exit_code = node.popen.returncode or 1
                print(f'bringup: {node.name} exited with {node.popen.returncode}; stopping the '
                      'others', file=sys.stderr, flush=True)
                break
            time.sleep(0.1)
    finally:
        # The driver first, so the collector records up to the end and then closes its bag.
        codes = group.stop(args.stop_timeout, order=('driver', 'collector', 'identify'))
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    failed = {name: code for name, code in codes.items() if code not in (0, None)}
    if received and not failed:
        print('bringup: all nodes stopped cleanly', file=sys.stderr, flush=True)
    elif failed:
        print(f'bringup: exit codes {failed}', file=sys.stderr, flush=True)
        exit_code = exit_code or 1
    return exit_code


if __name__ == '__main__':
    sys.exit(main())
