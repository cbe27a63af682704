"""
Start the hexacal nodes as child processes: the ``bringup`` executable (no ros2 launch needed).

collector, identify and kinematics always (kinematics unless --no-kinematics),
the simulated driver unless --no-driver (a real machine publishes), and the
executor when --executor-plan names a plan from `hexacal plan`: it walks the
plan through the trajectory controller on --command-topic (with the simulated
driver, the driver then runs in commanded mode on that topic; without an
executor plan the driver walks its own --plan). The input remaps
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

The same pieces (launch_spec.NodeLaunch, supervisor.NodeGroup) start the nodes
of `hexacal demo`. On a ROS 2 install, launch/hexacal.launch.py starts the same
nodes: its launch arguments go through system.launches_from_arguments, so both
build the same nodes.
With --shutdown-when-done the executor stops once the plan is walked (and the
calibration answered): bringup then stops the other nodes and exits 0.
"""


from __future__ import annotations

import argparse
from pathlib import Path
import signal
import sys
import time
from typing import Callable

from hexacal_msgs_py.interface_names import (
    DEFAULT_COMMAND_TOPIC,
    ENCODER_TOPIC as ENCODER,
    INCLINOMETER_TOPIC as INCLINOMETER,
    INCLINOMETER_TYPES,
    SLIDERS_TOPIC as SLIDERS,
)
from hexacal_msgs_py.measuring_modes import MEASURING_MODES
import yaml

from .launch_spec import EXECUTABLE_MODULES, NodeLaunch
from .supervisor import DEFAULT_STOP_TIMEOUT_S, NodeGroup
from .system import file_model, launches, MachineInputs, name_list, number_list

# Stop order: the machine first, so the collector records up to the end and then closes its bag.
STOP_ORDER = ('executor', 'driver', 'collector', 'kinematics', 'identify')


def _parse_param(text: str) -> tuple[str, str, object]:
    """
    Return 'driver:settle_s=0.5' as ('driver', 'settle_s', 0.5).

    The value is read as YAML; a flow list of scalars stays a list.
    """
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


def _argument_list(kind: type | None = None) -> Callable[[str], tuple]:
    """Return the argparse type of a list option: 'a,b' or '[a, b]' (numbers of `kind`)."""

    def parse(text: str) -> tuple:
        try:
            return number_list(text, kind) if kind else name_list(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    parse.__name__ = 'list'
    return parse


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of the bringup options."""
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
        '--bag-name',
        default='',
        help="the bag's directory name under --bag-dir (default: hexacal_<date>_<time>)",
    )
    parser.add_argument(
        '--calibration-store',
        default='',
        help='calibration store directory of identify and kinematics (default: the '
        "machine model's store, as `hexacal history`)",
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
        '--measuring-mode',
        default='',
        choices=('', *MEASURING_MODES),
        help='how the drives meet the measuring link: passive_actuator, lvdt or compliant, '
        "for the simulated driver and an executor that takes it (default '': the driver's "
        "default; the executor follows the plan's mode)",
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
    """Return the nodes of parsed bringup options."""
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
        model=args.model or file_model(args.nominal) or file_model(args.true_params),
        executor_plan=args.executor_plan,
        command_topic=args.command_topic,
        calibrate_when_done=args.calibrate_when_done,
        shutdown_when_done=args.shutdown_when_done,
        executor=extra['executor'],
        with_kinematics=not args.no_kinematics,
        kinematics_parameters=args.kinematics_parameters,
        kinematics=extra['kinematics'],
        inputs=inputs,
        measuring_mode=args.measuring_mode,
        bag_name=args.bag_name,
        calibration_store=args.calibration_store,
    )
    return nodes


def main(argv: list[str] | None = None) -> int:
    """Start the nodes, wait for a signal or a node's exit, stop them all; the exit code."""
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
