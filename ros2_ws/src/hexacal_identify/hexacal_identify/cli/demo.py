"""``hexacal demo``: the whole system on a simulated machine, end to end (what `make demo` runs).

Writes the true machine (Table 1; with ``--model gough_stewart`` the default
Gough-Stewart platform) and the nominal model (set 2, seed 0) as parameters
YAML, starts collector, identify and driver as child processes in a
ROS domain of its own (localhost discovery), follows the postures as they are
collected, calls `hexacal/calibrate`, receives the published parameters and
prints the parameter and pose errors before and after calibration.
"""
from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
import fcntl
import math
import os
from pathlib import Path
import signal
import sys
import tempfile
import time
from typing import IO, TYPE_CHECKING, Callable

if TYPE_CHECKING:  # numpy and the process launcher are imported where the demo runs, not at `hexacal` start-up
    import numpy as np

    from ..nodes.bringup import NodeGroup, RunningNode

DOMAIN_ID_RANGE = range(1, 101)
# Shared with tests/conftest.py: a demo and a test session never pick the same domain.
DOMAIN_LOCK_PATTERN = 'hexacal-test-ros-domain-{}.lock'
GRAPH_TIMEOUT_S = 30.0
CALIBRATE_TIMEOUT_S = 300.0
GROUPS = {'A0': slice(0, 3), 'B': slice(3, 6), 'l': slice(6, 7), 'a': slice(7, 9)}
# Parameter groups of the before/after table, per model (chain-major fields, see models.py).
MODEL_GROUPS = {
    'hexa_slide': GROUPS,
    'gough_stewart': {'A': slice(0, 3), 'B': slice(3, 6), 'l0': slice(6, 7)},
}
MODEL_CHOICES = tuple(MODEL_GROUPS)
EXIT_OK, EXIT_FAILED = 0, 1


class DemoError(RuntimeError):
    """The demo could not complete; the message says which step and why."""


def add_parsers(subparsers) -> None:
    parser = subparsers.add_parser(
        'demo', help='simulate a machine, collect postures over ROS 2, calibrate, print the errors',
        description='Run driver, collector and identify on a simulated Table 1 machine (or, with '
        '--model gough_stewart, the default Gough-Stewart platform), calibrate nominal set 2 from '
        'the collected postures and print parameter and pose errors before and after. Takes '
        'about 1.5 minutes with the defaults.')
    parser.add_argument('--model', choices=MODEL_CHOICES, default='hexa_slide',
                        help='machine model: hexa_slide (Table 1, default) or gough_stewart '
                        '(the default 6-UPS hexapod)')
    parser.add_argument('--postures', type=int, default=50, help='postures to collect (default 50)')
    parser.add_argument('--noise-um', type=float, default=10.0,
                        help='uniform noise half-width: um on sliders, urad on angles (default 10)')
    parser.add_argument('--out', type=Path, default=None,
                        help='work directory for the parameter YAMLs and logs '
                        '(default out/demo_<timestamp>)')
    parser.add_argument('--bag-dir', type=Path, default=Path('bags'),
                        help='the bag is recorded to <bag-dir>/demo_<timestamp> (default bags)')
    parser.add_argument('--plan', choices=('mixed', 'random'), default='mixed',
                        help='mixed: 3 sphere : 1 fixed postures (default); random: sphere only')
    parser.add_argument('--settle-s', type=float, default=0.5, help='move time between postures')
    parser.add_argument('--dwell-s', type=float, default=1.2, help='stationary time per posture')
    parser.add_argument('--rate-hz', type=float, default=100.0, help='sensor rate (default 100)')
    parser.add_argument('--seed', type=int, default=0, help='seed of plan, noise and nominal set')
    parser.add_argument('--validation-postures', type=int, default=50,
                        help='fresh postures for the pose errors (default 50)')
    parser.set_defaults(handler=run)


# --------------------------------------------------------------------------- ROS domain


_domain_lock: IO[str] | None = None


def claim_domain_id() -> int:
    """A ROS domain id no test session or other demo uses (held until this process exits)."""
    global _domain_lock
    if os.environ.get('HEXACAL_DEMO_DOMAIN_ID'):
        return int(os.environ['HEXACAL_DEMO_DOMAIN_ID'])
    start = (os.getpid() * 7) % len(DOMAIN_ID_RANGE)
    for offset in range(len(DOMAIN_ID_RANGE)):
        domain_id = DOMAIN_ID_RANGE[(start + offset) % len(DOMAIN_ID_RANGE)]
        lock = open(Path(tempfile.gettempdir()) / DOMAIN_LOCK_PATTERN.format(domain_id), 'a')
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _domain_lock = lock
        return domain_id
    raise DemoError('every ROS domain id 1..100 is in use; set HEXACAL_DEMO_DOMAIN_ID')


# --------------------------------------------------------------------------- the run


@dataclass
class DemoPaths:
    work: Path
    bag: Path
    true_params: Path
    nominal: Path
    calibration: Path
    logs: Path


def _model(args) -> str:
    return getattr(args, 'model', None) or 'hexa_slide'


def _paths(args) -> DemoPaths:
    stamp = datetime.now().strftime('%Y%m%d_%H%M%S')
    work = (args.out or Path('out') / f'demo_{stamp}').resolve()
    truth = 'true_table1.yaml' if _model(args) == 'hexa_slide' else f'true_{_model(args)}.yaml'
    return DemoPaths(work, (args.bag_dir / f'demo_{stamp}').resolve(), work / truth,
                     work / 'nominal_set2.yaml', work / 'calibration.yaml', work / 'logs')


def _check_args(args) -> None:
    from hexacal_msgs_py.models import model_layout

    count = model_layout(_model(args)).n_parameters
    minimum = math.ceil(count / 4)
    if args.postures < minimum:
        raise ValueError(f'--postures must be at least {minimum} ({count} parameters, 4 residuals '
                         f'per posture), got {args.postures}')
    for name in ('noise_um', 'settle_s', 'dwell_s', 'rate_hz'):
        value = getattr(args, name)
        if not math.isfinite(value) or value < 0 or (name != 'noise_um' and value == 0):
            raise ValueError(f"--{name.replace('_', '-')} must be positive, got {value}")
    if args.dwell_s < 1.0:
        raise ValueError(f'--dwell-s must be at least 1.0 s: the collector needs 0.8 s of '
                         f'stillness per posture, got {args.dwell_s}')


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # SIGTERM too ends the demo through its cleanup (children stopped)


def run(args) -> int:
    _check_args(args)
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        return _run(args)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(args) -> int:
    started = time.monotonic()
    paths = _paths(args)
    from hexacal_msgs_py.parameters_file import save_parameters

    from ..nodes.bringup import NodeGroup, NodeLaunch
    from ..core.architectures import architecture
    from ..core.model import nominal_set

    model = _model(args)
    true_params, nominal = architecture(model).default_parameters(), nominal_set(2, seed=args.seed,
                                                                                 model=model)
    if model == 'hexa_slide':
        truth_text, nominal_text = 'Table 1', 'Table 1 + Table 2 errors'
    else:
        truth_text = f'the default {model} machine'
        nominal_text = f'the default {model} machine + errors with Table 2-like statistics'
    save_parameters(paths.true_params, true_params.vector, model=model,
                    header_comment=f'hexacal demo: the simulated true machine ({truth_text}), SI units')
    save_parameters(paths.nominal, nominal.vector, model=model, header_comment=(
        f'hexacal demo: nominal set 2 ({nominal_text}, seed {args.seed}), SI units'))
    collector_model = {} if model == 'hexa_slide' else {'model': model}
    domain_id = claim_domain_id()
    env = {'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    os.environ.update(env)  # the in-process node below joins the same domain
    os.environ.pop('ROS_STATIC_PEERS', None)
    print(f'hexacal demo: work directory {paths.work}, ROS domain {domain_id}', flush=True)

    group = NodeGroup()
    session = None
    try:
        collector = group.start(NodeLaunch('collector', {
            'output_dir': str(paths.bag.parent), 'bag_name': paths.bag.name, **collector_model}),
            env, paths.logs / 'collector.log')
        identify = group.start(NodeLaunch('identify', {
            'nominal': str(paths.nominal), 'output_dir': str(paths.work),
            'output': paths.calibration.name}), env, paths.logs / 'identify.log')
        session = _RosSession()
        session.wait('the collector and identify nodes to come up', GRAPH_TIMEOUT_S, group,
                     session.graph_ready)
        driver = group.start(NodeLaunch('driver', {
            'true_params': str(paths.true_params), 'plan': args.plan,
            'postures': args.postures, 'seed': args.seed, 'rate_hz': float(args.rate_hz),
            'settle_s': float(args.settle_s), 'dwell_s': float(args.dwell_s),
            'slider_noise_m': args.noise_um * 1e-6, 'angle_noise_rad': args.noise_um * 1e-6}),
            env, paths.logs / 'driver.log')
        expected_s = args.postures * (args.settle_s + args.dwell_s)
        machine = '' if model == 'hexa_slide' else f' on a {model}'
        print(f'hexacal demo: driver walks a {args.plan} plan of {args.postures} postures{machine}, '
              f'+-{args.noise_um:g} um / +-{args.noise_um:g} urad noise, {args.rate_hz:g} Hz '
              f'(about {expected_s:.0f} s)', flush=True)
        _follow_postures(session, group, args.postures, 2.0 * expected_s + 60.0)
        session.wait(f'identify to hold all {args.postures} postures', 30.0, group,
                     lambda: session.identify_postures >= args.postures)
        calibrate_started = time.monotonic()
        success, message = session.calibrate(group)
        if not success:
            raise DemoError(f'hexacal/calibrate refused: {message}')
        calibrated = session.wait('the published parameters', 30.0, group,
                                  lambda: session.parameters)
        calibrate_s = time.monotonic() - calibrate_started
        print(f'hexacal demo: calibrated in {calibrate_s:.1f} s: {message}', flush=True)
    except DemoError as error:
        print(f'hexacal demo: error: {error}', file=sys.stderr, flush=True)
        for node in group.nodes:
            print(_log_tail(node), file=sys.stderr)
        return EXIT_FAILED
    finally:
        if session is not None:
            session.close()
        codes = group.stop(order=('driver', 'collector', 'identify'))
    unclean = {name: code for name, code in codes.items() if code != 0}
    if unclean:
        print(f'hexacal demo: warning: nodes exited with {unclean} (logs in {paths.logs})',
              file=sys.stderr)
    print(report(true_params, nominal, true_params.with_vector(calibrated), args, paths,
                 time.monotonic() - started))
    if not (paths.bag / 'metadata.yaml').exists():
        print(f'hexacal demo: error: the bag {paths.bag} was not closed (no metadata.yaml)',
              file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def _log_tail(node: RunningNode, lines: int = 15) -> str:
    if node.log_file is None:
        return ''
    path = Path(node.log_file.name)
    node.log_file.flush()
    text = path.read_text(errors='replace').splitlines()[-lines:]
    return f'--- {node.name} ({path}) ---\n' + '\n'.join(text)


def _follow_postures(session: '_RosSession', group: NodeGroup, total: int,
                     timeout_s: float) -> None:
    from tqdm import tqdm

    interactive = sys.stderr.isatty()
    bar = tqdm(total=total, desc='postures collected', unit='posture', file=sys.stderr,
               disable=not interactive)
    shown = 0
    try:
        def progress() -> bool:
            nonlocal shown
            count = min(session.postures, total)
            if count > shown:
                bar.update(count - shown)
                if not interactive and (count % 10 == 0 or count == total):
                    print(f'postures collected: {count}/{total}', flush=True)
                shown = count
            return session.postures >= total

        session.wait(f'{total} postures', timeout_s, group, progress)
    finally:
        bar.close()


class _RosSession:
    """An in-process node that watches postures, calls the service and receives the result."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        from std_srvs.srv import Trigger

        from diagnostic_msgs.msg import DiagnosticArray

        from hexacal_msgs_py.names import (
            CALIBRATE_SERVICE,
            CALIBRATION_STATUS_TOPIC,
            PARAMETERS_TOPIC,
            POSTURE_TOPIC,
        )
        from hexacal_msgs_py.qos import PARAMETERS_QOS, POSTURE_QOS, STATUS_QOS

        self.context = Context()
        # Python keeps SIGINT: Ctrl-C raises KeyboardInterrupt and the children are stopped.
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node('hexacal_demo', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.postures = 0  # seen here
        self.identify_postures = 0  # received by identify, from its status
        self.parameters: np.ndarray | None = None
        self._trigger = Trigger
        self.node.create_subscription(JointState, POSTURE_TOPIC, self._on_posture, POSTURE_QOS)
        self.node.create_subscription(Float64MultiArray, PARAMETERS_TOPIC, self._on_parameters,
                                      PARAMETERS_QOS)
        self.node.create_subscription(DiagnosticArray, CALIBRATION_STATUS_TOPIC, self._on_status,
                                      STATUS_QOS)
        self.client = self.node.create_client(Trigger, CALIBRATE_SERVICE)
        self.posture_topic = self.node.resolve_topic_name(POSTURE_TOPIC)

    def _on_posture(self, message) -> None:
        self.postures += 1

    def _on_status(self, message) -> None:
        from hexacal_msgs_py.conversions import status_values

        for status in message.status:
            values = status_values(status)
            if values.get('outcome') == 'collecting':
                self.identify_postures = int(values.get('postures_received', 0))

    def _on_parameters(self, message) -> None:
        from hexacal_msgs_py.conversions import multiarray_to_parameters

        self.parameters = multiarray_to_parameters(message)

    def graph_ready(self) -> bool:
        # The collector publishes postures and identify receives them (as this node does).
        return (self.node.count_publishers(self.posture_topic) >= 1
                and self.node.count_subscribers(self.posture_topic) >= 2
                and self.client.service_is_ready())

    def wait(self, what: str, timeout_s: float, group: NodeGroup, condition: Callable[[], object]):
        deadline = time.monotonic() + timeout_s
        while True:
            result = condition()
            if result is not None and result is not False:
                return result
            exited = group.exited()
            if exited:
                node = exited[0]
                raise DemoError(f'{node.name} exited with {node.popen.returncode} while waiting '
                                f'for {what}\n{_log_tail(node)}')
            if time.monotonic() > deadline:
                raise DemoError(f'timed out after {timeout_s:.0f} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.1)

    def calibrate(self, group: NodeGroup) -> tuple[bool, str]:
        future = self.client.call_async(self._trigger.Request())
        response = self.wait('the hexacal/calibrate response', CALIBRATE_TIMEOUT_S, group,
                             lambda: future.result() if future.done() else None)
        return bool(response.success), str(response.message)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# --------------------------------------------------------------------------- the report


def parameter_error_rows(true_vector: np.ndarray, vector: np.ndarray,
                         model: str = 'hexa_slide') -> dict[str, tuple[float, float]]:
    """Per group (Hexa Slide: A0, B, l, a; Gough-Stewart: A, B, l0): (max, mean) |error| in mm
    (a: unit-vector components x 1000)."""
    import numpy as np

    groups = MODEL_GROUPS[model]
    fields = max(columns.stop for columns in groups.values())
    errors = np.abs(np.asarray(vector) - np.asarray(true_vector)).reshape(6, fields) * 1e3
    return {name: (float(errors[:, columns].max()), float(errors[:, columns].mean()))
            for name, columns in groups.items()}


def report(true_params, nominal, calibrated, args, paths: DemoPaths, wall_s: float) -> str:
    from ..bag import open_bag
    from ..core.validation import pose_errors, validation_poses

    model = true_params.model
    groups = MODEL_GROUPS[model]
    before = parameter_error_rows(true_params.vector, nominal.vector, model)
    after = parameter_error_rows(true_params.vector, calibrated.vector, model)
    if model == 'hexa_slide':
        title = ('Parameter errors vs the simulated truth (Table 1), |error| in mm '
                 '(a: unit-vector components x 1000, as in Table 1)')
    else:
        title = (f'Parameter errors vs the simulated truth (the default {model} machine), '
                 '|error| in mm')
    lines = ['', title,
             f"{'group':<6}{'count':>6}{'before max':>13}{'before mean':>13}"
             f"{'after max':>12}{'after mean':>12}"]
    for name, columns in groups.items():
        count = 6 * (columns.stop - columns.start)
        lines.append(f'{name:<6}{count:>6}{before[name][0]:>13.3f}{before[name][1]:>13.3f}'
                     f'{after[name][0]:>12.4f}{after[name][1]:>12.4f}')
    poses = validation_poses(true_params, args.validation_postures, args.seed,
                             true_params.architecture.default_workspace())
    lines += ['', f'Pose errors over {len(poses)} validation postures',
              f"{'':<20}{'position mean':>15}{'position max':>14}{'orientation mean':>18}"
              f"{'orientation max':>17}",
              f"{'':<20}{'(um)':>15}{'(um)':>14}{'(deg)':>18}{'(deg)':>17}"]
    for label, model in (('before (nominal)', nominal), ('after (calibrated)', calibrated)):
        summary = pose_errors(true_params, model, poses).summary()
        lines.append(f"{label:<20}{summary['position_mean_m'] * 1e6:>15.1f}"
                     f"{summary['position_max_m'] * 1e6:>14.1f}"
                     f"{math.degrees(summary['orientation_mean_rad']):>18.5f}"
                     f"{math.degrees(summary['orientation_max_rad']):>17.5f}"
                     + (f"  ({summary['failed_postures']} FK failures)"
                        if summary['failed_postures'] else ''))
    bag_text = str(paths.bag)
    try:
        info = open_bag(paths.bag).info()
        postures = sum(t.count for name, t in info.topics.items() if name.endswith('/posture'))
        bag_text += f'  ({info.message_count} messages, {postures} postures)'
    except Exception as error:  # noqa: BLE001 - the report still prints, with the path
        bag_text += f'  (unreadable: {error})'
    lines += ['', f'bag:        {bag_text}', f'calibrated: {paths.calibration}',
              f'nominal:    {paths.nominal}', f'truth:      {paths.true_params}',
              f'logs:       {paths.logs}', f'wall time:  {wall_s:.0f} s']
    return '\n'.join(lines)
