"""
The kinematics node with real processes (#11 section 4): the calibrated model at work.

The simulated driver walks its plan (noise-free readings) on the true machine;
two kinematics nodes follow it, one (namespace ``true``) with the true
parameters file, one (``nominal``) with nominal set 2:

* the platform pose of each reading: the true node's equals the pose forward
  kinematics with the true parameters gives for the published readings, and
  the plan's pose while the machine stands there, within micrometres; the
  nominal node's is millimetres off;
* machine markers: the architecture's drawing at a published pose, in the base frame;
* a target pose becomes a JointTrajectory with IK(true) or IK(nominal) of it; a
  target no leg reaches and one outside the stroke are refused on the status
  topic and nothing is published;
* a calibration published on the node's hexacal/parameters replaces the
  nominal parameters (the nominal node then tracks the truth); one of the
  other model is refused.

Every wait is on a condition; the probe only spins.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hexacal_driver.plan import resolve_plan
from hexacal_identify.core.architectures import architecture, parameters_for
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.live import home_pose, solve_pose
from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE, MODELS
from hexacal_msgs_py.parameters_file import read_parameters_file
import numpy as np
import pytest
import system_support
from system_support import node_argv, NODE_START_TIMEOUT_S, STOP_TIMEOUT_S, write_parameter_files

probe = system_support.probe  # the probe fixture, for this module's tests

PLAN_POSTURES, SEED = 3, 5
DRIVER = {
    'plan': 'random',
    'postures': PLAN_POSTURES,
    'seed': SEED,
    'rate_hz': 50.0,
    'settle_s': 0.4,
    'dwell_s': 0.6,
    'loop': True,
    'slider_noise_m': 0.0,
    'angle_noise_rad': 0.0,
    'wait_for_subscriber': False,
}
SPEED = 0.05  # max_actuator_speed of the nodes, m/s
MARKERS_RATE_HZ = 10.0  # the nodes' default markers_rate_hz
NAMESPACES = ('true', 'nominal')
STATUS_NAME = 'hexacal kinematics'


@dataclass
class Listener:
    """What the probe received: readings and poses by stamp, markers, commands, statuses by ns."""

    readings: dict = field(default_factory=dict)  # stamp ns -> (6,)
    poses: dict = field(
        default_factory=lambda: {ns: {} for ns in NAMESPACES}
    )  # ns -> stamp -> (6,)
    frames: dict = field(default_factory=lambda: {ns: set() for ns in NAMESPACES})
    markers: list = field(default_factory=list)  # MarkerArray of the true node
    markers_sent: list = field(default_factory=list)  # and when the node published each (s)
    commands: dict = field(default_factory=lambda: {ns: [] for ns in NAMESPACES})
    statuses: dict = field(
        default_factory=lambda: {ns: [] for ns in NAMESPACES}
    )  # (level, message, values)
    status_stamps: dict = field(
        default_factory=lambda: {ns: [] for ns in NAMESPACES}
    )  # the header stamp (ns) of each of statuses


def listen(probe, model: str) -> Listener:
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped
    from hexacal_msgs_py.conversions import (
        joint_state_to_actuator_reading,
        stamp_ns,
        status_values,
    )
    from hexacal_msgs_py.poses import pose_from_message
    from hexacal_msgs_py.qos import COMMAND_QOS, MARKERS_QOS, POSE_QOS, SENSOR_QOS
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory
    from visualization_msgs.msg import MarkerArray

    heard = Listener()
    node = probe.node
    # Deeper than STATUS_QOS's depth 1 (compatible with it): no status is lost between two spins.
    status_qos = QoSProfile(
        depth=100,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )

    def on_readings(message):
        heard.readings[stamp_ns(message.header.stamp)] = np.array(
            joint_state_to_actuator_reading(message, model).actuator_positions
        )

    node.create_subscription(JointState, '/hexacal/sliders', on_readings, SENSOR_QOS)
    for ns in NAMESPACES:

        def on_pose(message, ns=ns):
            heard.poses[ns][stamp_ns(message.header.stamp)] = np.array(pose_from_message(message))
            heard.frames[ns].add(message.header.frame_id)

        def on_command(message, ns=ns):
            heard.commands[ns].append(message)

        def on_status(message, ns=ns):
            for status in message.status:
                if status.name == STATUS_NAME:
                    heard.statuses[ns].append(
                        (
                            status.level[0]
                            if isinstance(status.level, bytes)
                            else int(status.level),
                            status.message,
                            status_values(status),
                        )
                    )
                    heard.status_stamps[ns].append(stamp_ns(message.header.stamp))

        node.create_subscription(PoseStamped, f'/{ns}/hexacal/platform_pose', on_pose, POSE_QOS)
        node.create_subscription(JointTrajectory, f'/{ns}/command', on_command, COMMAND_QOS)
        node.create_subscription(
            DiagnosticArray, f'/{ns}/hexacal/calibration_status', on_status, status_qos
        )

    def on_markers(message, info):
        heard.markers.append(message)
        heard.markers_sent.append(info['source_timestamp'] * 1e-9)

    node.create_subscription(
        MarkerArray, '/true/hexacal/machine_markers', on_markers, MARKERS_QOS
    )
    return heard


def kinematics_argv(namespace: str, parameters_file, **extra) -> list[str]:
    files = {'parameters': str(parameters_file)} if parameters_file else {}
    # follow_calibrations: these nodes take any calibration published on their topic (the
    # pre-store behaviour, set explicitly; tests/test_deploy.py tests the default).
    settings = {'command_topic': 'command', 'max_actuator_speed': SPEED}
    argv = node_argv(
        'kinematics',
        {**files, **settings, 'follow_calibrations': True, **extra},
        namespace,
    )
    return argv + [
        '-r',
        'hexacal/sliders:=/hexacal/sliders',
    ]  # the driver's readings, outside the namespace


def matched_poses(heard: Listener, ns: str) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(stamp, readings, node pose) of every pose whose reading the probe received too."""
    return [
        (stamp, heard.readings[stamp], pose)
        for stamp, pose in sorted(heard.poses[ns].items())
        if stamp in heard.readings
    ]


def pose_error(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(position distance m, largest angle difference rad)."""
    return float(np.linalg.norm(a[:3] - b[:3])), float(np.abs(a[3:] - b[3:]).max())


@pytest.mark.parametrize(
    'parameters, words',
    [
        ({'parameters': 'missing.yaml'}, 'parameters: missing.yaml'),
        (['stroke_limits:=[0.5, 0.1]'], 'stroke_limits must be [low, high]'),
        (['stroke_limits:=0.5'], "expecting type 'DOUBLE_ARRAY'"),
        ({'mount': 'sideways'}, "mount must be '' or one of hanging, standing"),
        ({'max_actuator_speed': -1.0}, 'max_actuator_speed'),
        ({'physical_file': 'missing.yaml'}, 'physical_file: missing.yaml'),
    ],
)
def test_bad_configuration_stops_the_node_with_exit_2(ros_processes, tmp_path, parameters, words):
    from rosproc import venv_executable, wait_for

    if isinstance(parameters, dict):
        argv = node_argv('kinematics', parameters)
    else:  # written out: node_argv quotes lists as strings
        argv = [
            venv_executable('kinematics'),
            '--ros-args',
            *(a for p in parameters for a in ('-p', p)),
        ]
    process = ros_processes.start(argv)
    wait_for(
        lambda: not process.running(),
        NODE_START_TIMEOUT_S,
        what='the node to exit',
        details=process.describe,
    )
    assert process.popen.returncode == 2, process.describe()
    log = process.log_text()
    assert words in log and 'Traceback' not in log, log


@pytest.mark.slow
@pytest.mark.parametrize('model', [HEXA_SLIDE, GOUGH_STEWART])
def test_kinematics_node_tracks_commands_and_draws(ros_processes, tmp_path, probe, model):
    truth_path, nominal_path = write_parameter_files(tmp_path, model)
    arch = architecture(model)
    truth = parameters_for(model, read_parameters_file(truth_path).vector)
    nominal = parameters_for(model, read_parameters_file(nominal_path).vector)
    plan = resolve_plan('random', truth, PLAN_POSTURES, SEED)
    plan_readings = inverse_kinematics(truth, plan.poses)
    heard = listen(probe, model)

    # The true node has no parameters file: it takes the calibration latched on its
    # hexacal/parameters (published before it starts, as identify's result is).
    from hexacal_msgs_py.conversions import parameters_to_multiarray
    from hexacal_msgs_py.qos import PARAMETERS_QOS
    from std_msgs.msg import Float64MultiArray

    latched = probe.node.create_publisher(
        Float64MultiArray, '/true/hexacal/parameters', PARAMETERS_QOS
    )
    latched.publish(parameters_to_multiarray(truth.vector, model))
    nodes = {
        'true': ros_processes.start(kinematics_argv('true', ''), name='kinematics-true'),
        'nominal': ros_processes.start(
            kinematics_argv('nominal', nominal_path), name='kinematics-nominal'
        ),
    }
    for ns, process in nodes.items():
        probe.wait_for_node('kinematics', f'/{ns}', process)
    driver = ros_processes.start(node_argv('driver', {**DRIVER, 'true_params': str(truth_path)}))
    processes = [driver, *nodes.values()]

    def details() -> str:
        return '\n'.join(p.describe(15) for p in processes)

    def alive():
        for process in processes:
            if not process.running():
                raise AssertionError(f'a node exited early\n{process.describe()}')

    # Readings of every plan posture (while the machine stands there), posed by both nodes.
    def standing_indices(ns: str) -> set[int]:
        alive()
        found = set()
        for _, readings, _ in matched_poses(heard, ns):
            close = np.abs(plan_readings - readings).max(axis=1) < 1e-12
            found.update(np.flatnonzero(close).tolist())
        return found

    probe.spin_until(
        lambda: all(len(standing_indices(ns)) == PLAN_POSTURES for ns in NAMESPACES),
        60.0,
        'platform poses of every plan posture from both nodes',
        details,
    )
    assert heard.frames == {'true': {'hexacal_base'}, 'nominal': {'hexacal_base'}}

    # True parameters: the published readings' pose (FK in the test, from the workspace centre)
    # within micrometres, and the plan's pose while the machine stands at a posture.
    guess = home_pose()
    worst_fk = worst_plan = (0.0, 0.0)
    nominal_standing = []
    for stamp, readings, pose in matched_poses(heard, 'true'):
        guess = solve_pose(truth, readings, guess)
        worst_fk = max(worst_fk, pose_error(pose, guess))
        close = np.flatnonzero(np.abs(plan_readings - readings).max(axis=1) < 1e-12)
        if close.size:
            worst_plan = max(worst_plan, pose_error(pose, plan.poses[close[0]]))
            if stamp in heard.poses['nominal']:
                nominal_standing.append(
                    pose_error(heard.poses['nominal'][stamp], plan.poses[close[0]])
                )
    assert worst_fk[0] < 1e-6 and worst_fk[1] < 1e-6, worst_fk
    assert worst_plan[0] < 1e-6 and worst_plan[1] < 1e-6, worst_plan
    # Nominal parameters: millimetres off the true pose.
    nominal_position = np.array([e[0] for e in nominal_standing])
    assert (
        nominal_position.size and nominal_position.min() > 5e-4 and nominal_position.max() < 0.05
    ), nominal_position

    # Markers: the drawing of the machine at one of the published poses, in the base frame.
    def drawn() -> tuple | None:
        for array in reversed(heard.markers):
            stamp = array.markers[0].header.stamp
            pose = heard.poses['true'].get(stamp.sec * 1_000_000_000 + stamp.nanosec)
            if pose is not None:
                return array, pose
        return None

    marker_array, drawn_pose = probe.spin_until(
        drawn, 10.0, 'machine markers of a received pose', details
    )
    markers = {m.ns: m for m in marker_array.markers}
    # At most markers_rate_hz (10 Hz) while the readings come at 50 Hz, each of a newer pose.
    # The node draws on a timer, which keeps its grid: a late tick shortens the next interval
    # (down to 0.06 s seen with both cores busy). What holds is the count over time, by the
    # node's publish times: no minimum spacing, and none in the poses' stamps, which lag by a
    # varying delay.
    stamps = np.array(
        [
            a.markers[0].header.stamp.sec + a.markers[0].header.stamp.nanosec * 1e-9
            for a in heard.markers
        ]
    )
    assert len(stamps) >= 2 and np.all(np.diff(stamps) > 0), np.diff(stamps)
    sent = np.array(heard.markers_sent)
    assert len(sent) <= (sent[-1] - sent[0]) * MARKERS_RATE_HZ + 2, np.diff(sent)
    drawing = arch.drawing(truth, drawn_pose)
    assert (
        set(markers)
        == set(drawing)
        >= {
            'base_joints',
            'platform_joints',
            'platform',
            'device_link',
            'rails' if model == HEXA_SLIDE else 'legs',
        }
    )
    for name, marker in markers.items():
        assert marker.header.frame_id == 'hexacal_base'
        points = np.array([[p.x, p.y, p.z] for p in marker.points])
        assert np.allclose(points, drawing[name].reshape(-1, 3), atol=1e-9), name
        assert marker.type == (marker.SPHERE_LIST if drawing[name].ndim == 2 else marker.LINE_LIST)
    assert np.allclose(
        np.array([[p.x, p.y, p.z] for p in markers['device_link'].points]),
        [[0, 0, 0], drawn_pose[:3]],
        atol=1e-12,
    )

    # Commands: a target pose -> the actuator targets of each node's parameters.
    from geometry_msgs.msg import PoseStamped
    from hexacal_msgs_py.poses import fill_pose_message
    from hexacal_msgs_py.qos import COMMAND_QOS

    publishers = {
        ns: probe.node.create_publisher(PoseStamped, f'/{ns}/hexacal/target_pose', COMMAND_QOS)
        for ns in NAMESPACES
    }
    for publisher in publishers.values():
        probe.spin_until(
            lambda p=publisher: p.get_subscription_count() >= 1,
            NODE_START_TIMEOUT_S,
            f'a subscriber on {publisher.topic_name}',
        )

    def send(ns: str, pose, frame: str = 'hexacal_base', zero_quaternion: bool = False) -> None:
        message = fill_pose_message(PoseStamped(), pose)
        if zero_quaternion:
            orientation = message.pose.orientation
            orientation.x = orientation.y = orientation.z = orientation.w = 0.0
        message.header.frame_id = frame
        message.header.stamp = probe.node.get_clock().now().to_msg()
        publishers[ns].publish(message)

    def refusals(ns: str) -> list[dict]:
        return [
            values for _, _, values in heard.statuses[ns] if values.get('outcome') == 'refused'
        ]

    target = plan.poses[1] + np.array([0.004, -0.003, 0.002, 0.01, -0.01, 0.02])
    # First the refused ones: a pose no leg configuration reaches, one outside the stroke, a wrong
    # frame.
    low, high = arch.default_workspace().actuator_stroke_m
    outside = np.array(
        [0.0, 0.0, home_pose()[2] - 0.5, 0.0, 0.0, 0.0]
    )  # half a metre below the centre
    assert np.any(inverse_kinematics(truth, outside[None])[0] > high) or np.any(
        inverse_kinematics(truth, outside[None])[0] < low
    )
    # IK fails: a Hexa Slide leg shorter than its distance to the rail (a Gough-Stewart leg fails
    # only at zero length); a zero quaternion is no orientation.
    expected = ['unreachable-pose'] if model == HEXA_SLIDE else []
    expected += ['outside-stroke', 'wrong-frame', 'invalid-target']
    for ns in NAMESPACES:
        if model == HEXA_SLIDE:
            send(ns, [3.0, 0.0, -0.7, 0.0, 0.0, 0.0])
        send(ns, outside)
        send(ns, target, frame='world')
        send(ns, target, zero_quaternion=True)
    for ns in NAMESPACES:
        probe.spin_until(
            lambda ns=ns: len(refusals(ns)) >= len(expected),
            15.0,
            f'the refusals of {ns}',
            details,
        )
    for ns in NAMESPACES:
        reasons = [values['reason'] for values in refusals(ns)]
        assert reasons == expected, heard.statuses[ns]
        level = [
            level for level, _, values in heard.statuses[ns] if values.get('outcome') == 'refused'
        ]
        assert level == [1] * len(expected)  # WARN
        assert (
            'nothing sent'
            in [m for _, m, v in heard.statuses[ns] if v.get('outcome') == 'refused'][0]
        )
        send(ns, target)
    for ns in NAMESPACES:
        probe.spin_until(
            lambda ns=ns: (
                heard.commands[ns]
                and [v for _, _, v in heard.statuses[ns] if v.get('outcome') == 'sent']
            ),
            15.0,
            f'a command and its status from {ns}',
            details,
        )
    for ns, params in (('true', truth), ('nominal', nominal)):
        assert (
            len(heard.commands[ns]) == 1
        )  # nothing was sent for the refused targets (commands keep order)
        command = heard.commands[ns][0]
        assert list(command.joint_names) == list(MODELS[model].actuator_names)
        assert len(command.points) == 1
        positions = np.array(command.points[0].positions)
        assert np.allclose(
            positions, inverse_kinematics(params, target[None])[0], atol=1e-12, rtol=0
        )
        duration = (
            command.points[0].time_from_start.sec
            + command.points[0].time_from_start.nanosec * 1e-9
        )
        assert 0.1 <= duration < (high - low) / SPEED + 0.2
        sent = [values for _, _, values in heard.statuses[ns] if values.get('outcome') == 'sent'][
            -1
        ]
        assert float(sent['move_time_s']) == pytest.approx(duration, abs=1e-9)
    # The two models of the machine ask for different readings (mm apart): the compensation.
    difference = np.abs(
        np.array(heard.commands['true'][0].points[0].positions)
        - np.array(heard.commands['nominal'][0].points[0].positions)
    ).max()
    assert 1e-4 < difference < 2e-2, difference

    # A calibration of the other model is refused; the true parameters published on the nominal
    # node's hexacal/parameters replace its nominal ones: it then tracks the truth.
    from hexacal_msgs_py.conversions import parameters_to_multiarray
    from hexacal_msgs_py.qos import PARAMETERS_QOS
    from std_msgs.msg import Float64MultiArray

    other = next(m for m in MODELS if m != model)
    calibrations = probe.node.create_publisher(
        Float64MultiArray, '/nominal/hexacal/parameters', PARAMETERS_QOS
    )
    probe.spin_until(
        lambda: calibrations.get_subscription_count() >= 1,
        NODE_START_TIMEOUT_S,
        'the nominal node on hexacal/parameters',
    )
    calibrations.publish(
        parameters_to_multiarray(architecture(other).default_parameters().vector, other)
    )
    probe.spin_until(
        lambda: [
            v for _, _, v in heard.statuses['nominal'] if v.get('outcome') == 'model-mismatch'
        ],
        15.0,
        'the model-mismatch status',
        details,
    )
    calibrations.publish(parameters_to_multiarray(truth.vector, model))
    index = probe.spin_until(
        lambda: [
            i
            for i, (_, _, v) in enumerate(heard.statuses['nominal'])
            if v.get('outcome') == 'parameters'
            and v.get('parameters_source') == '/nominal/hexacal/parameters'
        ],
        15.0,
        'the calibration taken',
        details,
    )[-1]
    update = heard.statuses['nominal'][index]
    assert (
        update[0] == 0
        and 'new calibration' in update[1]
        and float(update[2]['largest_change_m']) > 1e-4
    )
    # Readings stamped after the node's status of the update were published after it (the driver
    # stamps a sample at or before publishing it), so the node posed them with the new parameters.
    # Not the latest reading the probe has: one in flight to the probe may be posed already.
    taken = heard.status_stamps['nominal'][index]

    def tracks_the_truth() -> bool:
        alive()
        later = [
            (readings, pose)
            for stamp, readings, pose in matched_poses(heard, 'nominal')
            if stamp > taken
        ]
        return len(later) >= 20 and later

    later = probe.spin_until(tracks_the_truth, 30.0, 'poses with the new calibration', details)
    guess = later[0][1]
    for readings, pose in later:
        guess = solve_pose(truth, readings, guess)
        assert pose_error(pose, guess)[0] < 1e-6

    for process in processes:
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
    log = nodes['true'].log_path.read_text()
    assert 'waiting for calibrated parameters on /true/hexacal/parameters' in log
    assert f'calibrated {model} parameters received on /true/hexacal/parameters' in log
    log = nodes['nominal'].log_path.read_text()
    assert 'new calibration on /nominal/hexacal/parameters' in log
    assert f'a {other} calibration on hexacal/parameters does not fit this {model} machine' in log
    assert (
        f'1 commands sent, {len(expected)} refused, 1 calibrations taken' in log
    )  # the summary at shutdown


# --------------------------------------------------------------------------- compensation


COMMAND_SPEED = 0.2  # m/s, the drivers' max_actuator_speed_m_s and the nodes' max_actuator_speed
TARGETS = 3
MACHINES = ('calibrated', 'nominal')


def calibrate_a_recording(tmp_path, truth, nominal_path, model: str):
    """
    Calibrate a simulated recording of the true machine with `hexacal calibrate`.

    40 sphere postures, +-1 um / urad noise, from nominal set 2: the calibrated parameters file.
    """
    from hexacal_identify import cli
    from hexacal_identify.core.machine.measurements import NoiseModel, simulate_measurements
    from hexacal_identify.core.machine.postures import sample_poses
    from synthetic_recording import write_recording

    rng = np.random.default_rng(17)
    poses = sample_poses(truth, 40, rng, 'sphere', architecture(model).default_workspace())
    exact = simulate_measurements(truth, poses, 'sphere', noise=NoiseModel(0.0, 0.0))
    bag = write_recording(
        tmp_path / 'recording',
        exact,
        noise_m=1e-6,
        noise_rad=1e-6,
        raw=False,
        seed=2,
        model=model,
        record_model=model,
    )
    calibrated = tmp_path / 'calibrated.yaml'
    assert (
        cli.main(
            ['calibrate', str(bag), '--nominal', str(nominal_path), '--output', str(calibrated)]
        )
        == 0
    )
    return calibrated


@pytest.mark.slow
@pytest.mark.parametrize('model', [HEXA_SLIDE, GOUGH_STEWART])
def test_compensation_reaches_the_true_pose(ros_processes, tmp_path, probe, model, capsys):
    """
    Check the issue's evidence: compensated targets reach the true pose after calibration.

    A target pose sent through the kinematics node reaches the true pose within a few micrometres
    after calibration and misses it by millimetres with the nominal parameters.

    Two simulated machines (the same truth) in commanded mode, each driven by a kinematics node:
    one with the parameters `hexacal calibrate` identified from a recording, one with nominal set
    2.  The pose each machine reaches is forward kinematics with the TRUE parameters of its
    published (noise-free) actuator readings; the machines hold the platform on the measuring
    link's sphere, so targets lie on it.
    """
    from geometry_msgs.msg import PoseStamped
    from hexacal_identify.core.machine.postures import sample_poses
    from hexacal_msgs_py.conversions import joint_state_to_actuator_reading
    from hexacal_msgs_py.poses import fill_pose_message
    from hexacal_msgs_py.qos import COMMAND_QOS, POSE_QOS, SENSOR_QOS
    from sensor_msgs.msg import JointState

    truth_path, nominal_path = write_parameter_files(tmp_path, model)
    arch = architecture(model)
    truth = parameters_for(model, read_parameters_file(truth_path).vector)
    nominal = parameters_for(model, read_parameters_file(nominal_path).vector)
    calibrated_path = calibrate_a_recording(tmp_path, truth, nominal_path, model)
    calibrated = parameters_for(model, read_parameters_file(calibrated_path).vector)
    files = {'calibrated': calibrated_path, 'nominal': nominal_path}
    models = {'calibrated': calibrated, 'nominal': nominal}
    # Sphere targets every model of the machine can command inside the stroke.
    low, high = arch.default_workspace().actuator_stroke_m
    candidates = sample_poses(
        truth, 20, np.random.default_rng(23), 'sphere', arch.default_workspace()
    )
    inside = np.ones(len(candidates), bool)
    for params in (truth, *models.values()):
        readings = inverse_kinematics(params, candidates)
        inside &= np.all((readings > low + 0.01) & (readings < high - 0.01), axis=1)
    targets = candidates[inside][:TARGETS]
    assert len(targets) == TARGETS

    readings: dict[str, list[np.ndarray]] = {ns: [] for ns in MACHINES}
    for ns in MACHINES:
        probe.node.create_subscription(
            JointState,
            f'/{ns}/hexacal/sliders',
            lambda message, ns=ns: readings[ns].append(
                np.array(joint_state_to_actuator_reading(message, model).actuator_positions)
            ),
            SENSOR_QOS,
        )
    processes = []
    for ns in MACHINES:
        processes.append(
            ros_processes.start(
                node_argv(
                    'driver',
                    {
                        'true_params': str(truth_path),
                        'command_topic': 'command',
                        'rate_hz': 50.0,
                        'max_actuator_speed_m_s': COMMAND_SPEED,
                        'slider_noise_m': 0.0,
                        'angle_noise_rad': 0.0,
                    },
                    ns,
                ),
                name=f'driver-{ns}',
            )
        )
        processes.append(
            ros_processes.start(
                node_argv(
                    'kinematics',
                    {
                        'parameters': str(files[ns]),
                        'command_topic': 'command',
                        'max_actuator_speed': COMMAND_SPEED,
                    },
                    ns,
                ),
                name=f'kinematics-{ns}',
            )
        )

    def details() -> str:
        return '\n'.join(p.describe(15) for p in processes)

    publishers = {
        ns: probe.node.create_publisher(PoseStamped, f'/{ns}/hexacal/target_pose', COMMAND_QOS)
        for ns in MACHINES
    }
    # A kinematics node refuses a target until it has an actuator reading of its own (the move
    # time needs the current position): its first platform pose says it has one.
    tracked: dict[str, int] = {ns: 0 for ns in MACHINES}
    for ns in MACHINES:
        probe.node.create_subscription(
            PoseStamped,
            f'/{ns}/hexacal/platform_pose',
            lambda message, ns=ns: tracked.__setitem__(ns, tracked[ns] + 1),
            POSE_QOS,
        )
    for ns in MACHINES:
        probe.spin_until(
            lambda ns=ns: (
                publishers[ns].get_subscription_count() >= 1
                and probe.node.count_subscribers(f'/{ns}/command') >= 1
                and probe.node.count_publishers(f'/{ns}/command') >= 1
                and len(readings[ns]) > 5
                and tracked[ns] > 0
            ),
            NODE_START_TIMEOUT_S,
            f'the {ns} machine and its kinematics node',
            details,
        )

    def settled(ns: str, before: np.ndarray, count: int = 15):
        """Return the latest readings once the machine left `before`, still for `count` samples."""
        for process in processes:
            if not process.running():
                raise AssertionError(f'a node exited early\n{process.describe()}')
        latest = readings[ns][-count:]
        if len(latest) < count or np.abs(latest[-1] - before).max() < 1e-4:
            return None
        return (latest[-1],) if all(np.array_equal(r, latest[-1]) for r in latest) else None

    errors = {ns: [] for ns in MACHINES}
    for target in targets:
        before = {ns: readings[ns][-1] for ns in MACHINES}
        for ns in MACHINES:
            message = fill_pose_message(PoseStamped(), target)
            message.header.frame_id = 'hexacal_base'
            publishers[ns].publish(message)
        for ns in MACHINES:
            (final,) = probe.spin_until(
                lambda ns=ns: settled(ns, before[ns]),
                30.0,
                f'the {ns} machine standing at its target',
                details,
            )
            reached = solve_pose(truth, final, target)  # the true pose the machine stands at
            errors[ns].append(pose_error(reached, target))
    calibrated_m = max(e[0] for e in errors['calibrated'])
    calibrated_rad = max(e[1] for e in errors['calibrated'])
    nominal_m = [e[0] for e in errors['nominal']]
    calibrated_text = ', '.join(
        f'{m * 1e6:.2f} um / {r * 1e6:.2f} urad' for m, r in errors['calibrated']
    )
    nominal_text = ', '.join(
        f'{m * 1e6:.0f} um / {np.degrees(r):.3f} deg' for m, r in errors['nominal']
    )
    with capsys.disabled():
        print(
            f'\n{model}: true pose error of {TARGETS} commanded poses: calibrated '
            f'{calibrated_text}; nominal {nominal_text}'
        )
    assert calibrated_m < 5e-6 and calibrated_rad < 2e-5, (
        errors
    )  # a few micrometres after calibration
    assert min(nominal_m) > 5e-4, errors  # millimetres with the nominal parameters
    for process in processes:
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()


@pytest.mark.slow
def test_compliance_section_compensates_the_commands(ros_processes, tmp_path, probe):
    """A calibration with chain compliances: commands past the rigid ones by the deflection."""
    from dataclasses import replace

    from geometry_msgs.msg import PoseStamped
    from hexacal_identify.core.fit.statics import MassModel
    from hexacal_identify.core.machine.live import LoadedChains
    from hexacal_msgs_py.conversions import actuator_reading_to_joint_state
    from hexacal_msgs_py.parameters_file import compliance_extras, save_parameters
    from hexacal_msgs_py.physical_file import default_physical, write_physical_file
    from hexacal_msgs_py.poses import fill_pose_message
    from hexacal_msgs_py.qos import COMMAND_QOS, SENSOR_QOS
    from hexacal_msgs_py.readings import ActuatorReading
    from sensor_msgs.msg import JointState

    truth_path, _ = write_parameter_files(tmp_path, HEXA_SLIDE)
    truth = parameters_for(HEXA_SLIDE, read_parameters_file(truth_path).vector)
    compliances = {'chains': 2e-8, 'link': 1e-7}
    compliant_path = tmp_path / 'compliant.yaml'
    save_parameters(compliant_path, truth.vector, compliance_extras(compliances))
    physical = replace(default_physical(HEXA_SLIDE), payload_mass=30.0)
    physical_path = write_physical_file(tmp_path / 'physical.yaml', physical)
    heard = listen(probe, HEXA_SLIDE)
    nodes = [
        ros_processes.start(
            kinematics_argv('true', compliant_path, physical_file=str(physical_path)),
            name='kinematics-compliant',
        ),
        ros_processes.start(kinematics_argv('nominal', truth_path), name='kinematics-rigid'),
    ]
    for ns, process in zip(NAMESPACES, nodes):
        probe.wait_for_node('kinematics', f'/{ns}', process)

    def details() -> str:
        return '\n'.join(p.describe(15) for p in nodes)

    # One reading for the move time, then a target pose to each node.
    pose = home_pose() + np.array([0.01, -0.02, 0.005, 0.02, -0.01, 0.05])
    readings = inverse_kinematics(truth, pose[None])[0]
    sliders = probe.node.create_publisher(JointState, '/hexacal/sliders', SENSOR_QOS)
    targets = {
        ns: probe.node.create_publisher(PoseStamped, f'/{ns}/hexacal/target_pose', COMMAND_QOS)
        for ns in NAMESPACES
    }

    def publish_reading() -> bool:
        stamp = probe.node.get_clock().now().nanoseconds
        sliders.publish(
            actuator_reading_to_joint_state(ActuatorReading(stamp, tuple(readings)))
        )
        return all(heard.poses[ns] for ns in NAMESPACES)

    probe.spin_until(publish_reading, NODE_START_TIMEOUT_S, 'a pose from both nodes', details)

    def send_targets() -> bool:
        for ns, publisher in targets.items():
            if not heard.commands[ns]:
                message = fill_pose_message(PoseStamped(), pose)
                message.header.frame_id = 'hexacal_base'
                publisher.publish(message)
        return all(heard.commands[ns] for ns in NAMESPACES)

    probe.spin_until(send_targets, 15.0, 'a command from both nodes', details)
    compensated = np.array(heard.commands['true'][0].points[0].positions)
    rigid = np.array(heard.commands['nominal'][0].points[0].positions)
    np.testing.assert_allclose(rigid, readings, atol=1e-12)
    # The deflection of six chains of 2e-8 m/N under the weights of the physical file.
    loaded = LoadedChains((2e-8,) * 6, MassModel.from_physical(physical))
    predicted = loaded.shifts(truth, pose[None])[0]
    assert np.abs(predicted).max() > 1e-6
    np.testing.assert_allclose(compensated - rigid, predicted, atol=1e-12)
    # The compliant node's pose of the rigid readings is off by what the deflection moves it.
    compliant_pose = next(iter(heard.poses['true'].values()))
    rigid_pose = next(iter(heard.poses['nominal'].values()))
    np.testing.assert_allclose(rigid_pose, pose, atol=1e-9)
    assert pose_error(compliant_pose, pose)[0] > 1e-7
    statuses = [values for _, _, values in heard.statuses['true']]
    assert any(str(physical_path) in str(v.get('compliance', '')) for v in statuses), statuses
