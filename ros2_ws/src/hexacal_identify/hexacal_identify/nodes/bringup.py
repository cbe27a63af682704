"""``bringup``: start the hexacal nodes as child processes (no ros2 launch needed).

collector, identify and kinematics always (kinematics unless --no-kinematics),
the simulated driver unless --no-driver (a real machine publishes), and the
executor when --executor-plan names a plan from `hexacal plan`: it walks the
plan through the trajectory controller on --command-topic (with the simulated
driver, the driver then runs in commanded mode on that topic; without an
executor plan the driver walks its own --plan as before). The input remaps
(--sliders-topic, --inclinometer-topic, --encoder-topic) and the joint mapping
(--actuator-joints, --inclinometer-joints, --rotary-joint, --inclinometer-type,
--inclinometer-signs, --inclinometer-offsets-rad) say where a real machine's
readings come from: the remaps go to every node that reads them (collector,
executor, kinematics, and the driver that publishes them), the mapping to the
collector (actuator and inclinometer joints to the executor too).

Each node runs in its own process group with its parameters given as
``--ros-args -p name:=value``. SIGINT and SIGTERM are forwarded to every
child, which then shut down cleanly (the collector closes its bag); a child
that does not exit within the stop timeout is escalated to SIGTERM, then
SIGKILL. If one node exits on its own, the others are stopped too and its exit
code is returned. On Linux the children also receive SIGTERM if bringup
itself dies, so no node outlives it.

The same pieces (`NodeLaunch`, `NodeGroup`) start the nodes of `hexacal demo`.
On a ROS 2 install, launch/hexacal.launch.py starts the same nodes: its launch
arguments go through `launches_from_arguments`, so both build the same nodes.
With --shutdown-when-done the executor stops once the plan is walked (and the
calibration answered): bringup then stops the other nodes and exits 0.
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
    'executor': 'hexacal_identify.nodes.executor',
    'kinematics': 'hexacal_identify.nodes.kinematics',
}
PACKAGES = {
    'driver': 'hexacal_driver',
    'collector': 'hexacal_identify',
    'identify': 'hexacal_identify',
    'executor': 'hexacal_identify',
    'kinematics': 'hexacal_identify',
}
# The contract's names (hexacal_msgs_py.names and .inputs, spelled here: importing them costs
# numpy): the machine's three sensor inputs as the nodes name them, the command topic of
# ros2_control's joint_trajectory_controller, the inclinometer types.
SLIDERS, INCLINOMETER, ENCODER = 'hexacal/sliders', 'hexacal/inclinometer', 'hexacal/encoder'
DEFAULT_COMMAND_TOPIC = '/joint_trajectory_controller/joint_trajectory'
INCLINOMETER_TYPES = ('joint_state', 'imu')
# Stop order: the machine first, so the collector records up to the end and then closes its bag.
STOP_ORDER = ('executor', 'driver', 'collector', 'kinematics', 'identify')
DEFAULT_STOP_TIMEOUT_S = 10.0
_PR_SET_PDEATHSIG = 1


@dataclass
class NodeLaunch:
    """One node to start: its executable, namespace and parameters."""

    executable: str  # a key of EXECUTABLE_MODULES
    parameters: dict[str, object] = field(default_factory=dict)
    namespace: str = ''
    remaps: dict[str, str] = field(default_factory=dict)  # ROS name -> topic (`-r from:=to`)

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
        for source, target in self.remaps.items():
            ros_args += ['-r', f'{source}:={target}']
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
    if isinstance(value, (list, tuple)):  # a YAML flow list: [leg_a, leg_b], [0.0, 0.01]
        return '[' + ', '.join(ros_parameter_text(item) for item in value) + ']'
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

    def start(
        self,
        launch: NodeLaunch,
        env: Mapping[str, str] | None = None,
        log_path: str | os.PathLike[str] | None = None,
    ) -> RunningNode:
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
                launch.command(),
                env=child_env,
                stdin=subprocess.DEVNULL,
                stdout=log_file,
                stderr=subprocess.STDOUT if log_file else None,
                start_new_session=True,
                preexec_fn=self._preexec,
            )
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

    def stop(
        self, timeout: float = DEFAULT_STOP_TIMEOUT_S, order: Sequence[str] | None = None
    ) -> dict[str, int]:
        """SIGINT every node (in `order` of executables first), escalate; name -> exit code."""
        first = list(order or ())
        ranked = sorted(
            self.nodes, key=lambda n: first.index(n.name) if n.name in first else len(first)
        )
        for node in ranked:
            self._stop_one(node, timeout)
        codes = {}
        for node in self.nodes:
            codes[node.name] = node.popen.returncode
            if node.log_file:
                node.log_file.close()
        self.nodes = []
        return codes

    def stop_node(self, node: RunningNode, timeout: float = DEFAULT_STOP_TIMEOUT_S) -> int:
        """Stop one node of the group (SIGINT, escalating), take it out of the group; its exit code."""
        self._stop_one(node, timeout)
        self.nodes.remove(node)
        if node.log_file:
            node.log_file.close()
        return node.popen.returncode

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


@dataclass(frozen=True)
class MachineInputs:
    """Where the machine's readings come from: topic remaps and the collector's joint mapping.

    Empty fields keep the contract's topics (hexacal/sliders, hexacal/inclinometer,
    hexacal/encoder) and the nodes' defaults (hexacal_msgs_py.inputs).
    """

    sliders_topic: str = ''
    inclinometer_topic: str = ''
    encoder_topic: str = ''
    inclinometer_type: str = ''  # joint_state | imu
    actuator_joints: tuple[str, ...] = ()
    inclinometer_joints: tuple[str, ...] = ()
    rotary_joint: str = ''
    inclinometer_signs: tuple[int, ...] = ()
    inclinometer_offsets_rad: tuple[float, ...] = ()

    def remaps(self, *inputs: str) -> dict[str, str]:
        """`-r` remaps of the given inputs (those set and not the contract's name)."""
        topics = {
            SLIDERS: self.sliders_topic,
            INCLINOMETER: self.inclinometer_topic,
            ENCODER: self.encoder_topic,
        }
        return {name: topics[name] for name in inputs if topics[name] and topics[name] != name}

    def collector_parameters(self) -> dict[str, object]:
        values = {
            'actuator_joints': list(self.actuator_joints),
            'inclinometer_joints': list(self.inclinometer_joints),
            'rotary_joint': self.rotary_joint,
            'inclinometer_type': self.inclinometer_type,
            'inclinometer_signs': [int(v) for v in self.inclinometer_signs],
            'inclinometer_offsets_rad': [float(v) for v in self.inclinometer_offsets_rad],
        }
        return {name: value for name, value in values.items() if value}

    @property
    def imu(self) -> bool:
        return self.inclinometer_type == 'imu'


def launches(
    namespace: str = '',
    nominal: str = '',
    output_dir: str = '',
    bag_dir: str = '',
    plan: str = '',
    postures: int | None = None,
    record: bool = True,
    driver: Mapping[str, object] | None = None,
    collector: Mapping[str, object] | None = None,
    identify: Mapping[str, object] | None = None,
    with_driver: bool = True,
    model: str = '',
    *,
    executor_plan: str = '',
    command_topic: str = '',
    calibrate_when_done: bool = False,
    shutdown_when_done: bool = False,
    executor: Mapping[str, object] | None = None,
    with_kinematics: bool = False,
    kinematics_parameters: str = '',
    kinematics: Mapping[str, object] | None = None,
    inputs: MachineInputs | None = None,
) -> list[NodeLaunch]:
    """The NodeLaunch of each node; empty options keep the nodes' defaults.

    `model` (hexa_slide or gough_stewart) goes to the driver and the collector;
    identify and the executor take their model from the nominal file, kinematics from
    its parameters file (or the first calibration it hears). An `executor_plan` adds the
    executor (plan, nominal, command_topic, calibrate_when_done, shutdown_when_done) and
    puts the driver in commanded mode on the same command topic; `with_kinematics` adds
    the kinematics node (its `parameters` file, commands on command_topic). `inputs`
    remaps the sensor topics of every node that reads (or, the driver, publishes) them.
    """
    inputs = inputs or MachineInputs()
    command_topic = command_topic or DEFAULT_COMMAND_TOPIC
    driver_parameters: dict[str, object] = {}
    collector_model: dict[str, object] = {'model': model} if model else {}
    driver_parameters.update(collector_model)
    if plan:
        driver_parameters['plan'] = plan
    if postures is not None:
        driver_parameters['postures'] = int(postures)
    if executor_plan:  # the simulated machine takes the real one's interface
        driver_parameters['command_topic'] = command_topic
    driver_parameters.update(driver or {})
    collector_parameters: dict[str, object] = {'record': bool(record), **collector_model}
    if bag_dir:
        collector_parameters['output_dir'] = str(bag_dir)
    collector_parameters.update(inputs.collector_parameters())
    collector_parameters.update(collector or {})
    identify_parameters: dict[str, object] = {}
    if nominal:
        identify_parameters['nominal'] = str(Path(nominal).resolve())
    if output_dir:
        identify_parameters['output_dir'] = str(Path(output_dir).resolve())
    identify_parameters.update(identify or {})
    nodes = [
        NodeLaunch(
            'collector',
            collector_parameters,
            namespace,
            inputs.remaps(SLIDERS, INCLINOMETER, ENCODER),
        ),
        NodeLaunch('identify', identify_parameters, namespace),
    ]
    if with_kinematics:
        kinematics_parameters_ = {'command_topic': command_topic}
        if kinematics_parameters:
            kinematics_parameters_['parameters'] = str(Path(kinematics_parameters).resolve())
        kinematics_parameters_.update(kinematics or {})
        nodes.append(
            NodeLaunch('kinematics', kinematics_parameters_, namespace, inputs.remaps(SLIDERS))
        )
    if executor_plan:
        executor_parameters: dict[str, object] = {
            'plan': str(Path(executor_plan).resolve()),
            'command_topic': command_topic,
        }
        if nominal:
            executor_parameters['nominal'] = str(Path(nominal).resolve())
        if inputs.actuator_joints:
            executor_parameters['actuator_joints'] = list(inputs.actuator_joints)
        if inputs.inclinometer_joints and not inputs.imu:
            executor_parameters['inclinometer_joints'] = list(inputs.inclinometer_joints)
        if calibrate_when_done:
            executor_parameters['calibrate_when_done'] = True
        if shutdown_when_done:
            executor_parameters['shutdown_when_done'] = True
        executor_parameters.update(executor or {})
        # The executor reads a JointState inclinometer (fixed-position postures); an Imu one
        # stays unmapped for it.
        read = (SLIDERS,) if inputs.imu else (SLIDERS, INCLINOMETER)
        nodes.append(NodeLaunch('executor', executor_parameters, namespace, inputs.remaps(*read)))
    if with_driver:
        nodes.append(
            NodeLaunch(
                'driver',
                driver_parameters,
                namespace,
                inputs.remaps(SLIDERS, INCLINOMETER, ENCODER),
            )
        )
    return nodes


def name_list(text: str | Sequence[str]) -> tuple[str, ...]:
    """'a,b', '[a, b]' or ['a', 'b'] -> ('a', 'b'); '' -> ()."""
    if not isinstance(text, str):
        return tuple(str(item) for item in text)
    text = text.strip()
    if text.startswith('[') and text.endswith(']'):
        text = text[1:-1]
    return tuple(item.strip().strip('\'"') for item in text.split(',') if item.strip())


def number_list(text: str | Sequence[float], kind: type = float) -> tuple:
    """'1,-1' / '[0.0, 0.01]' -> numbers of `kind` (argparse/launch errors name the text)."""
    try:
        return tuple(kind(float(item)) if kind is int else kind(item) for item in name_list(text))
    except ValueError:
        raise ValueError(f'expected a list of numbers, got {text!r}') from None


def _truthy(text: str | bool) -> bool:
    if isinstance(text, bool):
        return text
    value = str(text).strip().lower()
    if value in ('true', '1', 'yes', 'on'):
        return True
    if value in ('false', '0', 'no', 'off', ''):
        return False
    raise ValueError(f'expected true or false, got {text!r}')


def launches_from_arguments(values: Mapping[str, str]) -> list[NodeLaunch]:
    """The nodes of launch/hexacal.launch.py from its launch arguments (strings, as given).

    '' keeps a node's default; the plan walked by the executor is `executor_plan`
    (`plan` stays the simulated driver's own plan when there is none).
    """

    def get(name: str, default: str = '') -> str:
        return str(values.get(name, default) or '').strip()

    inputs = MachineInputs(
        sliders_topic=get('sliders_topic'),
        inclinometer_topic=get('inclinometer_topic'),
        encoder_topic=get('encoder_topic'),
        inclinometer_type=get('inclinometer_type'),
        actuator_joints=name_list(get('actuator_joints')),
        inclinometer_joints=name_list(get('inclinometer_joints')),
        rotary_joint=get('rotary_joint'),
        inclinometer_signs=number_list(get('inclinometer_signs'), int),
        inclinometer_offsets_rad=number_list(get('inclinometer_offsets_rad')),
    )
    nominal, true_params = get('nominal'), get('true_params')
    driver = {'true_params': str(Path(true_params).resolve())} if true_params else {}
    postures = get('postures')
    return launches(
        get('namespace'),
        nominal,
        get('output_dir'),
        get('bag_dir'),
        get('plan'),
        int(postures) if postures else None,
        _truthy(get('record', 'true')),
        driver,
        with_driver=_truthy(get('use_driver', 'true')),
        model=get('model') or _file_model(nominal) or _file_model(true_params),
        executor_plan=get('executor_plan'),
        command_topic=get('command_topic'),
        calibrate_when_done=_truthy(get('calibrate_when_done')),
        shutdown_when_done=_truthy(get('shutdown_when_done')),
        with_kinematics=_truthy(get('use_kinematics', 'true')),
        kinematics_parameters=get('kinematics_parameters'),
        inputs=inputs,
    )


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
    """'driver:settle_s=0.5' -> ('driver', 'settle_s', 0.5) (value read as YAML; a flow list of
    scalars stays a list)."""
    try:
        node, rest = text.split(':', 1)
        name, value = rest.split('=', 1)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f'--param must look like NODE:NAME=VALUE, got {text!r}'
        ) from None
    if node not in EXECUTABLE_MODULES:
        raise argparse.ArgumentTypeError(
            f'--param node must be one of {sorted(EXECUTABLE_MODULES)}, got {node!r}'
        )
    try:
        parsed = yaml.safe_load(value) if value else ''
    except yaml.YAMLError:
        parsed = value
    scalar = (bool, int, float, str)
    if isinstance(parsed, list) and parsed and all(isinstance(v, scalar) for v in parsed):
        return node, name, parsed
    return node, name, parsed if isinstance(parsed, scalar) else value


def _argument_list(kind: type | None = None):
    """argparse type of a list option: 'a,b' or '[a, b]' (numbers of `kind` when given)."""

    def parse(text: str) -> tuple:
        try:
            return number_list(text, kind) if kind else name_list(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    parse.__name__ = 'list'
    return parse


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='bringup',
        description='Start the hexacal nodes (collector, identify, kinematics; '
        'the simulated driver unless --no-driver; the executor with --executor-plan) as child '
        'processes; Ctrl-C (or SIGTERM) stops them all cleanly.',
    )
    parser.add_argument('--namespace', default='', help='ROS namespace of all nodes (e.g. left)')
    parser.add_argument(
        '--nominal', default='', help='nominal parameters YAML for identify and the executor'
    )
    parser.add_argument(
        '--output-dir',
        default='',
        help='directory identify writes its '
        'calibration YAML under (default: the current directory)',
    )
    parser.add_argument(
        '--bag-dir', default='', help='directory the collector records bags into (default: bags)'
    )
    parser.add_argument(
        '--no-record',
        action='store_true',
        help='do not record until hexacal/start_recording is called',
    )
    parser.add_argument(
        '--plan',
        default='',
        help='driver plan: random, fixed, mixed or a plan '
        "YAML (default: the driver's); the driver walks it when there is no "
        '--executor-plan',
    )
    parser.add_argument('--postures', type=int, default=None, help='postures of a generated plan')
    parser.add_argument(
        '--true-params',
        default='',
        help='parameters YAML of the simulated '
        'machine, of either model (default: the default machine of --model)',
    )
    parser.add_argument(
        '--model',
        default='',
        choices=('', 'hexa_slide', 'gough_stewart'),
        help='machine model of the driver and the collector (default: the model '
        '--nominal, else --true-params names, else hexa_slide)',
    )
    parser.add_argument(
        '--no-driver',
        action='store_true',
        help='no simulated driver: a real machine publishes (use_driver:=false)',
    )
    machine = parser.add_argument_group(
        'plan execution and the calibrated model',
        'the executor walks a plan through the trajectory controller; kinematics publishes '
        'hexacal/platform_pose and turns hexacal/target_pose into compensated commands',
    )
    machine.add_argument(
        '--executor-plan',
        default='',
        metavar='PLAN',
        help='plan YAML from `hexacal plan`: start the executor walking it (with '
        '--nominal); the simulated driver then follows --command-topic',
    )
    machine.add_argument(
        '--command-topic',
        default='',
        help='JointTrajectory command topic of '
        f'the executor and kinematics (default {DEFAULT_COMMAND_TOPIC})',
    )
    machine.add_argument(
        '--calibrate-when-done',
        action='store_true',
        help='the executor calls hexacal/calibrate when the plan is walked',
    )
    machine.add_argument(
        '--shutdown-when-done',
        action='store_true',
        help='stop everything (exit 0) once the executor is done (and the calibration answered)',
    )
    machine.add_argument(
        '--kinematics-parameters',
        default='',
        metavar='FILE',
        help='calibrated parameters YAML kinematics starts from (default: it '
        'waits for hexacal/parameters)',
    )
    machine.add_argument(
        '--no-kinematics', action='store_true', help='do not start the kinematics node'
    )
    inputs = parser.add_argument_group(
        'machine inputs',
        "where a real machine's readings come from (default: the contract's "
        'topics and joints); e.g. all three topics /joint_states for ros2_control',
    )
    inputs.add_argument('--sliders-topic', default='', help=f'actuator readings ({SLIDERS})')
    inputs.add_argument(
        '--inclinometer-topic', default='', help=f'inclinometer readings ({INCLINOMETER})'
    )
    inputs.add_argument('--encoder-topic', default='', help=f'rotary readings ({ENCODER})')
    inputs.add_argument(
        '--inclinometer-type',
        default='',
        choices=('', *INCLINOMETER_TYPES),
        help='joint_state (default) or imu (sensor_msgs/Imu)',
    )
    inputs.add_argument(
        '--actuator-joints',
        type=_argument_list(),
        default=(),
        metavar='A,B,C,D,E,F',
        help="the six actuator joints in chain order (default: the model's)",
    )
    inputs.add_argument(
        '--inclinometer-joints',
        type=_argument_list(),
        default=(),
        metavar='X,Y',
        help='the inclinometer joints alpha, beta',
    )
    inputs.add_argument('--rotary-joint', default='', help='the rotary sensor joint (phi)')
    inputs.add_argument(
        '--inclinometer-signs',
        type=_argument_list(int),
        default=(),
        metavar='SX,SY',
        help='per channel 1 or -1',
    )
    inputs.add_argument(
        '--inclinometer-offsets-rad',
        type=_argument_list(float),
        default=(),
        metavar='OX,OY',
        help='per channel, the raw reading with the link level',
    )
    parser.add_argument(
        '--param',
        action='append',
        type=_parse_param,
        default=[],
        metavar='NODE:NAME=VALUE',
        help='any other node parameter, e.g. driver:settle_s=0.5 (repeatable; '
        f'NODE one of {", ".join(EXECUTABLE_MODULES)})',
    )
    parser.add_argument(
        '--stop-timeout',
        type=float,
        default=DEFAULT_STOP_TIMEOUT_S,
        help='seconds a node gets to exit after SIGINT before escalation',
    )
    return parser


def node_launches(args: argparse.Namespace) -> list[NodeLaunch]:
    """The nodes of parsed bringup options."""
    extra: dict[str, dict[str, object]] = {name: {} for name in EXECUTABLE_MODULES}
    for node, name, value in args.param:
        extra[node][name] = value
    if args.true_params:
        extra['driver'].setdefault('true_params', str(Path(args.true_params).resolve()))
    inputs = MachineInputs(
        args.sliders_topic,
        args.inclinometer_topic,
        args.encoder_topic,
        args.inclinometer_type,
        args.actuator_joints,
        args.inclinometer_joints,
        args.rotary_joint,
        args.inclinometer_signs,
        args.inclinometer_offsets_rad,
    )
    nodes = launches(
        args.namespace,
        args.nominal,
        args.output_dir,
        args.bag_dir,
        args.plan,
        args.postures,
        not args.no_record,
        extra['driver'],
        extra['collector'],
        extra['identify'],
        with_driver=not args.no_driver,
        model=args.model or _file_model(args.nominal) or _file_model(args.true_params),
        executor_plan=args.executor_plan,
        command_topic=args.command_topic,
        calibrate_when_done=args.calibrate_when_done,
        shutdown_when_done=args.shutdown_when_done,
        executor=extra['executor'],
        with_kinematics=not args.no_kinematics,
        kinematics_parameters=args.kinematics_parameters,
        kinematics=extra['kinematics'],
        inputs=inputs,
    )
    return nodes


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.executor_plan and not args.nominal:
        parser.error('--executor-plan needs --nominal (the executor plans with it)')
    if args.shutdown_when_done and not args.executor_plan:
        parser.error('--shutdown-when-done needs --executor-plan')
    nodes = node_launches(args)
    group = NodeGroup(die_with_parent=True)
    received: list[int] = []

    def forward(signum: int, frame: object) -> None:
        received.append(signum)

    previous = {
        signum: signal.signal(signum, forward) for signum in (signal.SIGINT, signal.SIGTERM)
    }
    exit_code = 0
    done = False  # the executor finished its plan (shutdown_when_done) and exited 0
    try:
        for launch in nodes:
            node = group.start(launch)
            print(
                f'bringup: started {launch.executable} (pid {node.popen.pid}): '
                f'{" ".join(launch.command())}',
                file=sys.stderr,
                flush=True,
            )
        while not received:
            finished = group.exited()
            if finished:
                node = finished[0]
                if (
                    node.name == 'executor'
                    and args.shutdown_when_done
                    and node.popen.returncode == 0
                ):
                    done = True
                    print(
                        'bringup: the executor is done; stopping the others',
                        file=sys.stderr,
                        flush=True,
                    )
                    break
                exit_code = node.popen.returncode or 1
                print(
                    f'bringup: {node.name} exited with {node.popen.returncode}; stopping the '
                    'others',
                    file=sys.stderr,
                    flush=True,
                )
                break
            time.sleep(0.1)
    finally:
        codes = group.stop(args.stop_timeout, order=STOP_ORDER)
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    failed = {name: code for name, code in codes.items() if code not in (0, None)}
    if (received or done) and not failed:
        print('bringup: all nodes stopped cleanly', file=sys.stderr, flush=True)
    elif failed:
        print(f'bringup: exit codes {failed}', file=sys.stderr, flush=True)
        exit_code = exit_code or 1
    return exit_code


if __name__ == '__main__':
    sys.exit(main())
