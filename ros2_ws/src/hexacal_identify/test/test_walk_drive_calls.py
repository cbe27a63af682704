"""What the executor decides about the drive, without DDS: core/walk/drive_calls.py, session."""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import default_stroke, plan_targets
from hexacal_identify.core.sessions.executor_session import inclinometer_line, start_waits
from hexacal_identify.core.walk.drive_calls import (
    command_text,
    DriveMode,
    lvdt_extension,
    ReleaseCalls,
    trajectory,
)
from hexacal_identify.core.walk.execution import PlanExecution, ReleaseRequest
from hexacal_identify.core.walk.messages import LogLevel
from hexacal_identify.core.walk.mode_driver import walk_mode
from hexacal_identify.core.walk.platform_paths import Command, CommandPurpose
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_msgs_py.inputs import InputMapping
from hexacal_msgs_py.names import LINK_LENGTH_JOINT
import numpy as np

L = 0.75
GS = 'gough_stewart'
NOMINAL = default_parameters(GS)
STROKE = default_stroke(NOMINAL)
POSES = sample_poses(
    NOMINAL, 3, np.random.default_rng(1), 'sphere', NOMINAL.architecture.default_workspace()
)
NAMES = NOMINAL.layout.actuator_names


@dataclass
class _Answer:
    success: bool
    message: str


class _Service:
    """A release service in memory: it appears when told, and answers each call's future."""

    def __init__(self, name: str):
        self.srv_name = name
        self.ready = False
        self.calls: list[tuple[bool, Future]] = []

    def service_is_ready(self) -> bool:
        return self.ready

    def call(self, release: bool) -> Future:
        future: Future = Future()
        self.calls.append((release, future))
        return future


def _calls(wait_s=2.0):
    services = [_Service(f'/hexacal/release/{name}') for name in NAMES]
    return ReleaseCalls(services, NAMES, wait_s), services


def test_a_swap_locks_the_released_chain_then_releases_the_next_one_call_at_a_time():
    calls, services = _calls()
    for service in services:
        service.ready = True
    request = ReleaseRequest(posture=1, lock=2, release=4)
    assert calls.step(0.0, request, lambda: 0.0) is None and calls.active
    (release, future), = services[2].calls
    assert release is False and services[4].calls == []  # the lock comes first
    assert calls.step(0.1, None, lambda: 0.1) is None  # not answered yet
    future.set_result(_Answer(True, 'locked'))
    assert calls.step(0.2, None, lambda: 0.2) is None  # the lock answered: the next step calls
    assert calls.step(0.25, None, lambda: 0.25) is None
    (release, future), = services[4].calls
    assert release is True
    future.set_result(_Answer(True, 'released'))
    assert calls.step(0.3, None, lambda: 0.3) == (4, '') and not calls.active
    assert calls.messages == [
        (LogLevel.INFO, f'lock {NAMES[2]}: locked'),
        (LogLevel.INFO, f'release {NAMES[4]}: released'),
    ]


def test_a_missing_service_a_silent_one_and_a_refusal_each_end_the_request_with_why():
    calls, services = _calls(wait_s=2.0)
    request = ReleaseRequest(posture=0, lock=None, release=1)
    assert calls.step(0.0, request, lambda: 0.0) is None
    assert calls.step(1.9, None, lambda: 1.9) is None  # still within release_wait_s
    released, problem = calls.step(2.1, None, lambda: 2.1)
    assert released is None
    assert problem == f'cannot release {NAMES[1]}: no service /hexacal/release/{NAMES[1]} ' \
        '(waited 2 s)'

    services[1].ready = True
    assert calls.step(10.0, request, lambda: 10.0) is None  # called at 10 s
    released, problem = calls.step(12.5, None, lambda: 12.5)
    assert 'did not answer within 2 s' in problem and released is None

    assert calls.step(20.0, ReleaseRequest(0, 3, 1), lambda: 20.0) is None
    services[3].ready = True
    calls.step(20.1, None, lambda: 20.1)
    services[3].calls[-1][1].set_result(_Answer(True, 'locked'))
    calls.step(20.2, None, lambda: 20.2)
    calls.step(20.25, None, lambda: 20.25)
    services[1].calls[-1][1].set_result(_Answer(False, 'the drive is faulted'))
    assert calls.step(20.3, None, lambda: 20.3) == (
        None,
        f'the drive refused to release {NAMES[1]}: the drive is faulted',
    )  # the lock went through: nothing is released now


def test_a_request_with_nothing_to_do_ends_at_once():
    calls, _ = _calls()
    assert calls.step(0.0, ReleaseRequest(0, None, None), lambda: 0.0) == (None, '')


def _execution(mode):
    targets, problems = plan_targets(NOMINAL, POSES, ['sphere'] * 3, STROKE, L)
    assert not problems
    settings = ExecutionSettings(settle_s=0.2, wait_for_posture=False, path_step_m=0.0)
    return PlanExecution(
        NOMINAL, POSES, ['sphere'] * 3, targets, settings, STROKE, L, released=mode.released,
        guard=lambda *args: '',
    )


def test_a_passive_actuator_plan_is_confirmed_by_the_drive_or_walks_all_six_with_a_warning():
    plan_mode = walk_mode('', 'passive_actuator', [NAMES[2]] * 3, NOMINAL, POSES, L, STROKE)
    drive = DriveMode(discovery_s=3.0)
    execution = _execution(plan_mode)
    mode, waiting = drive.confirm(plan_mode, execution, 0.0, services_ready=False)
    assert mode == plan_mode and waiting and 'release services' in waiting[0]
    mode, waiting = drive.confirm(plan_mode, execution, 1.0, services_ready=True)
    assert (mode.source, waiting) == ('plan, confirmed', [])

    # No service within discovery_s: all six commanded, unguarded, and the log says what to do.
    drive = DriveMode(discovery_s=3.0)
    drive.confirm(plan_mode, execution, 0.0, services_ready=False)
    mode, waiting = drive.confirm(plan_mode, execution, 3.5, services_ready=False)
    assert waiting == [] and mode.mode == 'compliant'
    assert execution.released == [None] * 3 and execution.guard is None
    ((level, text),) = drive.messages
    assert level == LogLevel.WARN and 'within 3 s' in text
    assert 'hexacal plan --measuring-mode compliant' in text


def test_the_drives_status_names_its_mode_its_released_joint_and_a_fault():
    plan_mode = walk_mode('', 'passive_actuator', [NAMES[2]] * 3, NOMINAL, POSES, L, STROKE)
    drive = DriveMode()
    execution = _execution(plan_mode)
    assert drive.hear({'measuring_mode': 'lvdt', 'released_joint': NAMES[5]}, execution,
                      NAMES, 0.0) is None
    assert drive.mode == 'lvdt' and execution.released_now == 5
    # The drive's mode decides at once: no waiting for discovery_s.
    mode, waiting = drive.confirm(plan_mode, execution, 0.0, services_ready=False)
    assert waiting == [] and mode.mode == 'compliant' and 'measuring_mode is lvdt' in \
        drive.messages[0][1]
    assert drive.hear({'state': 'fault', 'fault': 'jam'}, execution, NAMES, 1.0) == []


def test_the_trajectory_leaves_the_released_chain_out_and_the_lvdt_extension_is_its_length():
    points = np.arange(12, dtype=float).reshape(2, 6) * 1e-3
    command = Command(points, np.array([0.5, 1.0]), CommandPurpose.MOVE, 0)
    joints, sent = trajectory(command, NAMES, 3)
    assert joints == [n for i, n in enumerate(NAMES) if i != 3]
    assert sent == [
        ([0.0, 0.001, 0.002, 0.004, 0.005], 0.5),
        ([0.006, 0.007, 0.008, 0.01, 0.011], 1.0),
    ]
    assert trajectory(command, NAMES, None)[0] == list(NAMES)
    assert command_text(command, 7).startswith('move (posture 1 of 7): 2 points to')
    assert lvdt_extension(['x', LINK_LENGTH_JOINT], [0.0, 0.7512], L) == 0.7512 - L
    assert lvdt_extension(['x'], [0.0], L) is None
    assert lvdt_extension([LINK_LENGTH_JOINT], [], L) is None


def test_the_start_waits_for_readings_a_controller_and_a_collector():
    assert start_waits(True, '/s', 1, '/c', False, '/p') == []
    assert start_waits(False, '/s', 0, '/c', True, '/p') == [
        'actuator readings on /s',
        'a controller on /c',
        'a collector on /p',
    ]


def test_the_inclinometer_line_says_how_fixed_positions_are_judged():
    mapping = InputMapping(
        actuator_joints=NAMES,
        inclinometer_joints=('alpha', 'beta'),
        inclinometer_type='imu',
        inclinometer_signs=(1, -1),
        inclinometer_offsets_rad=(0.0, 0.0),
        topics=('/s', '/i', ''),
    )
    line = inclinometer_line(mapping, ExecutionSettings(inclinometer_settle_s=0.0))
    assert 'sensor_msgs/Imu orientation' in line and 'signs [1.0, -1.0]' in line
    assert line.endswith('judged on the mean over settle_s (0.5 s)')
