"""The executor's moves start where the drive stands (core/walk/execution.py, blend_command)."""

from __future__ import annotations

from hexacal_identify.core.machine.device import fixed_point
from hexacal_identify.core.machine.kinematics import inverse_kinematics
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_identify.core.planning.plan_check import default_stroke, plan_targets
from hexacal_identify.core.walk.execution import PlanExecution
from hexacal_identify.core.walk.platform_paths import (
    blend_command,
    Command,
    CommandPurpose,
    MIN_SEGMENT_S,
)
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.settings import ExecutionState as State
import numpy as np
import pytest

L = 0.75
NOMINAL = nominal_set(2, seed=0)  # millimetres from the truth, as a real machine's drawing
TRUTH = table1_parameters()
STROKE = default_stroke(NOMINAL)
HOME = np.concatenate([fixed_point(L), np.zeros(3)])
SPEED = 0.5  # the executor's m/s
DRIVE_SPEED = 1.0  # the simulated drive's m/s (hexacal demo)
TICK = 0.01  # the simulated drive's sample period (s)


def _poses(seed: int, pick: list[int]) -> np.ndarray:
    workspace = NOMINAL.architecture.default_workspace()
    return sample_poses(NOMINAL, 6, np.random.default_rng(seed), 'sphere', workspace)[pick]


def _execution(poses, settings=None, **kwargs) -> PlanExecution:
    kinds = ['sphere'] * len(poses)
    targets, problems = plan_targets(NOMINAL, poses, kinds, STROKE, L)
    assert not problems
    settings = settings or ExecutionSettings(
        max_actuator_speed_m_s=SPEED, settle_s=0.2, wait_for_posture=False
    )
    return PlanExecution(NOMINAL, poses, kinds, targets, settings, STROKE, L, **kwargs)


class PassiveDrive:
    """
    The simulated drive in passive_actuator mode on the true machine, as hexacal_driver does.

    A trajectory starts from the current setpoints and goes linearly through its points, each
    segment taking its time or its largest move at DRIVE_SPEED; the machine is solved every TICK
    from its previous pose (solve_passive: five stiff drives and the link); a lock makes the
    released chain's setpoint its true position.
    """

    def __init__(self):
        self.pose = HOME.copy()
        self.setpoints = inverse_kinematics(TRUTH, HOME[None])[0]
        self.actuators = self.setpoints.copy()
        self.released: int | None = None
        self.segments: list[tuple[float, float, np.ndarray, np.ndarray]] = []

    def setpoints_at(self, now: float) -> np.ndarray:
        for start, end, begin, finish in self.segments:
            if now < end:
                return begin + max(now - start, 0.0) / (end - start) * (finish - begin)
        return self.segments[-1][3].copy() if self.segments else self.setpoints.copy()

    def command(self, now: float, command: Command) -> None:
        previous = self.setpoints = self.setpoints_at(now)
        self.segments, elapsed, start = [], 0.0, now
        for point, time in zip(command.points, command.times):
            point = point.copy()
            if self.released is not None:  # not commanded: the executor leaves it out
                point[self.released] = previous[self.released]
            duration = max(time - elapsed, float(np.max(np.abs(point - previous))) / DRIVE_SPEED)
            self.segments.append((start, start + duration, previous, point))
            previous, elapsed, start = point, time, start + duration

    def swap(self, lock: int | None, release: int | None) -> None:
        if lock is not None:
            self.setpoints[lock] = self.actuators[lock]
        self.released, self.segments = release, []

    def reset(self) -> None:
        """Clear a fault: hold where the machine stands (the released chain stays free)."""
        self.setpoints, self.segments = self.actuators.copy(), []

    def sample(self, now: float) -> bool:
        """Move to the setpoints at `now`; False: the passive system jams (no pose near)."""
        setpoints = self.setpoints_at(now)
        if self.released is None:
            self.setpoints = self.actuators = setpoints
            return True
        solved = solve_passive(TRUTH, setpoints[None], self.released, self.pose[None], L)
        if not bool(solved.converged[0]):
            return False
        self.setpoints, self.pose, self.actuators = setpoints, solved.poses[0], solved.actuators[0]
        return True


def _walk_passive(
    execution: PlanExecution, drive: PassiveDrive, until: float = 30.0, operator: bool = False
):
    """
    Walk on the drive; return (jammed at posture index or None, the commands sent).

    With an `operator`, a jam faults the drive, which is reset, and the plan resumed.
    """
    sent, now = [], 0.0
    while now < until and execution.state in (State.WAITING, State.RUNNING):
        if not drive.sample(now):
            if not operator:
                return execution.index, sent
            execution.on_drive_fault(now, 'the five commanded actuators and the link jam')
            assert execution.state == State.PAUSED
            drive.reset()
            execution.resume(now)
        execution.on_actuators(now, drive.actuators)
        if execution.state == State.WAITING:
            commands = execution.start(now)
        else:
            commands = execution.step(now)
        request = execution.release_request
        if request is not None:
            drive.swap(request.lock, request.release)
            commands += execution.on_release(now, request.release, '')
        for command in commands:
            drive.command(now, command)
            sent.append((command, drive.setpoints.copy(), drive.released))
        now += TICK
    return None, sent


@pytest.mark.parametrize('seed, pick, released', [(6, [3, 4], [5, 2]), (9, [1, 2], [3, 4])])
def test_the_passive_system_no_longer_jams_on_the_locked_chains_jump(seed, pick, released):
    # Before: the chain locked where the true link put it (up to ~11 mm off the nominal model)
    # was commanded to the model's path at once: the first ticks jammed the passive system.
    execution = _execution(_poses(seed, pick), released=released)
    drive = PassiveDrive()
    jammed, sent = _walk_passive(execution, drive)
    assert jammed is None and execution.state == State.DONE and execution.measured == 2
    assert drive.released is None and execution.released_now is None  # all six held at the end
    command, setpoints, _ = sent[-1]  # the move after the swap
    np.testing.assert_allclose(command.positions, execution.targets[1], rtol=0, atol=1e-12)


def test_a_move_after_a_swap_starts_where_the_locked_chain_stands():
    settings = ExecutionSettings(
        max_actuator_speed_m_s=SPEED, settle_s=0.2, wait_for_posture=False, path_step_m=1e-3
    )
    execution = _execution(_poses(6, [3, 4]), settings, released=[5, 2])
    jammed, sent = _walk_passive(execution, PassiveDrive())
    assert jammed is None and execution.measured == 2
    command, setpoints, released = sent[-1]  # chain 6 locked where the link put it, 3 released
    assert released == 2 and len(sent) == 2
    offset = setpoints[5] - execution.targets[0, 5]
    assert abs(offset) > 3e-3  # the true machine stands millimetres off the model
    # Its first segment is about the path's own step (1 mm), not the offset.
    first = np.abs(command.points[0] - setpoints)
    assert first[5] < 0.2 * abs(offset) and np.delete(first, 2).max() < 2e-3
    np.testing.assert_allclose(command.positions, execution.targets[1], rtol=0, atol=1e-12)


def test_a_move_after_a_new_model_starts_from_the_old_targets():
    poses = _poses(3, [0, 1, 2])
    settings = ExecutionSettings(
        max_actuator_speed_m_s=SPEED, settle_s=0.2, wait_for_posture=False, path_step_m=1e-3
    )
    execution = _execution(poses, settings, refine_at=(1,))
    now, position = 0.0, inverse_kinematics(NOMINAL, HOME[None])[0]
    while execution.refine_request is None and now < 30.0:
        execution.on_actuators(now, position)
        commands = execution.start(now) if now == 0.0 else execution.step(now)
        for command in commands:
            position = command.positions  # a machine without strain reaches it
        now += 0.05
    assert execution.refine_request == 1
    old = execution.targets[0].copy()  # the drive's setpoints: the old model's at posture 1
    np.testing.assert_array_equal(position, old)
    (command,) = execution.on_refined(now, TRUTH, 'calibrated')
    np.testing.assert_allclose(
        command.positions, inverse_kinematics(TRUTH, poses[1:2])[0], rtol=0, atol=1e-12
    )
    jump = np.max(np.abs(inverse_kinematics(TRUTH, poses[:1])[0] - old))
    assert jump > 5e-3  # the new model's start is millimetres from the setpoints
    first = np.max(np.abs(command.points[0] - old))
    assert first < 0.2 * jump  # the first segment: the path's step, no jump to the new model
    assert command.times[0] >= first / SPEED - 1e-12


def test_the_blend_fades_the_offset_over_the_moves_time_and_keeps_its_speed():
    # The fraction counts from the path's first point: the whole offset is there (the first
    # point is the setpoints plus the path's own step), none of it in one straight segment
    # from the setpoints (a chain locked centimetres from the model took a share of its offset
    # alone there, a path the release's rehearsal never walked: the drive jammed).
    points = np.linspace(0.1, 0.2, 5)[:, None] * np.ones(6)
    times = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    command = Command(points, times, CommandPurpose.MOVE, 3)
    offset = np.array([8e-3, 0, 0, -4e-3, 0, 0])
    setpoints = np.full(6, 0.075) + offset
    blended = blend_command(command, setpoints, offset, SPEED)
    fraction = (times - 0.1) / 0.4
    np.testing.assert_allclose(blended.points[:-1], points[:-1] + (1 - fraction[:-1, None])
                               * offset)
    np.testing.assert_allclose(blended.points[0] - setpoints, points[0] - 0.075)
    np.testing.assert_array_equal(blended.points[-1], points[-1])
    moves = np.abs(np.diff(np.vstack([setpoints, blended.points]), axis=0)).max(axis=1)
    segments = np.diff(np.concatenate([[0.0], blended.times]))
    assert np.all(segments >= np.maximum(moves / SPEED, MIN_SEGMENT_S) - 1e-12)
    assert (blended.purpose, blended.posture) == (CommandPurpose.MOVE, 3)
    assert blend_command(command, setpoints, np.zeros(6), SPEED) is command
    inside = blend_command(command, setpoints, offset, SPEED, (0.1, 1.0))  # near a stroke's end
    assert inside.points.min() >= 0.1 and inside.points[0, 3] == 0.1


def test_a_fresh_walk_knows_where_a_tilted_machine_stands():
    # Where another plan left the machine (phi beyond the branch tolerance of the guesses):
    # nominal forward kinematics by continuation from the centre, not a one-point command
    # that cuts through joint space off the link sphere (the demo's 29 kN).
    tilted = np.array([0.0, 0.0, -L, -0.46, 0.6, -0.37])
    poses = _poses(0, [0, 1])
    execution = _execution(poses)
    execution.on_actuators(0.0, inverse_kinematics(NOMINAL, tilted[None])[0])
    (command,) = execution.start(0.0)
    assert len(command.points) > 1  # along the link sphere
    assert not [text for _, text in execution.messages if 'cannot tell' in text]
    np.testing.assert_allclose(command.positions, execution.targets[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize('seed, pick, released', [(1, [0, 1], [2, 5]), (2, [3, 4], [0, 1])])
def test_after_a_jam_the_move_goes_on_with_another_chain_released(seed, pick, released):
    # Releases chosen at the postures alone (before #18's rehearsal): on the true machine the
    # move to the second posture meets a fold of the passive system. Rehearsed again at rest
    # from where the machine stands, the release is changed before the move: nothing jams.
    execution = _execution(_poses(seed, pick), released=list(released))
    jammed, _ = _walk_passive(execution, PassiveDrive())
    assert jammed is None and execution.state == State.DONE and execution.measured == 2
    assert execution.released[1] != released[1]
    assert any('may jam with' in text for _, text in execution.messages), execution.messages
    # Walked as planned, the drive faults on that move ...
    unchecked = ExecutionSettings(
        max_actuator_speed_m_s=SPEED, settle_s=0.2, wait_for_posture=False,
        check_releases_at_rest=False,
    )
    jammed, _ = _walk_passive(
        _execution(_poses(seed, pick), unchecked, released=list(released)), PassiveDrive()
    )
    assert jammed == 1
    # ... and the executor's recovery after a fault takes over.
    execution = _execution(_poses(seed, pick), unchecked, released=list(released))
    drive = PassiveDrive()
    jammed, sent = _walk_passive(execution, drive, operator=True)
    # Reset and resumed each time, the executor released another chain at rest (never one that
    # jammed on this move again) until the move went through.
    assert jammed is None and execution.state == State.DONE and execution.measured == 2
    assert execution.released[1] != released[1] and drive.released is None
    swaps = [chain for command, _, chain in sent if command.posture == 1]
    tried = [swaps[0]] + [b for a, b in zip(swaps, swaps[1:]) if b != a]
    assert len(tried) == len(set(tried)) and released[1] in tried
    assert any('faulted with' in text for _, text in execution.messages)


def test_a_chain_left_released_by_an_earlier_plan_is_locked_before_another_is_released():
    poses = _poses(2, [3, 4])
    execution = _execution(poses, released=[0, 5])
    drive = PassiveDrive()
    drive.released = 3  # as an interrupted earlier plan left it
    execution.on_drive_released(3)
    execution.on_actuators(0.0, drive.actuators)
    execution.start(0.0)
    request = execution.release_request
    assert request is not None and request.lock == 3 and request.release == 0
