"""
The executor's pause on the simulated compliant drives, ROS-free (core/walk + drives.py).

A pause in the middle of a move lets the move end at its target and sends nothing.  The hold
it replaced went back to the measured actuators, which arrive late (here 0.1 s, 50 mm behind
the setpoints at 0.5 m/s); the six drives went there in a straight line, off the path the link
allows, and on a busy CI machine loaded the link to 538 N, past its 500 N limit
(tests/test_executor.py, compliant mode).  A hold at the setpoints the executor computes is
late in the same way: the drive is further along when it arrives.
"""

from __future__ import annotations

from hexacal_driver.drives import DriveState
from hexacal_driver.machine import SimulatedMachine
from hexacal_driver.parameters import PARAMETERS
from hexacal_driver.simulation import STILL
from hexacal_identify.core.machine.device import inclinometer_angles
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
from hexacal_identify.core.walk.execution import ExecutionSettings, PlanExecution
from hexacal_identify.core.walk.execution import ExecutionState as State
from hexacal_identify.core.walk.platform_paths import CommandPurpose
import numpy as np

L = 0.75
DT = 0.01
LAG_TICKS = 10  # the readings reach the executor 0.1 s late (a busy machine, a slow network)


class _Walk:
    """The executor's rules on the driver's compliant drives, sampled every DT seconds."""

    def __init__(self, seed: int = 3) -> None:
        values = {name: spec.default for name, spec in PARAMETERS.items()}
        values.update(
            command_topic='/joint_trajectory_controller/joint_trajectory',
            measuring_mode='compliant',
            max_actuator_speed_m_s=1.0,  # as the demo's: faster than the executor's commands
        )
        self.machine = SimulatedMachine(values)
        nominal = nominal_set(2, seed=0)
        workspace = nominal.architecture.default_workspace()
        poses = sample_poses(nominal, 3, np.random.default_rng(seed), 'sphere', workspace)
        stroke = default_stroke(nominal)
        targets = check_plan(nominal, poses, ['sphere'] * 3, stroke, L, path_step_m=0.02)
        self.execution = PlanExecution(
            nominal, poses, ['sphere'] * 3, targets,
            ExecutionSettings(max_actuator_speed_m_s=0.5, settle_s=0.3), stroke, L,
        )
        self.drive = self.machine.require_follower()
        self.t, self.still_since = 0.0, None
        self.commands: list = []
        self.link_forces: list[float] = []
        self.readings: list = []  # what the sensors read, oldest first

    def send(self, commands) -> None:
        for command in commands:
            self.commands.append((self.t, command))
            points = [(list(p), float(s)) for p, s in zip(command.points, command.times)]
            checked, problem = self.machine.check_command(
                list(self.drive.joint_names), points, 0, 0
            )
            assert problem is None, problem
            self.drive.command(self.t, checked)

    def tick(self) -> None:
        execution, drive = self.execution, self.drive
        self.readings.append(drive.sample(self.t))
        self.link_forces.append(abs(drive.link_force_n))
        sample = self.readings[max(len(self.readings) - 1 - LAG_TICKS, 0)]
        execution.on_actuators(self.t, sample.actuators.copy())
        alpha, beta = inclinometer_angles(sample.pose[None, :3])
        execution.on_inclinometer(self.t, float(alpha[0]), float(beta[0]))
        if sample.phase == STILL and execution.state == State.RUNNING:
            self.still_since = self.t if self.still_since is None else self.still_since
            if self.t - self.still_since >= 0.5:
                execution.on_posture(self.t, sample.actuators.copy())
                self.still_since = float('inf')  # one posture per stop
        else:
            self.still_since = None
        if execution.state == State.WAITING:
            self.send(execution.start(self.t))
        else:
            self.send(execution.step(self.t))
        self.t += DT

    def run_until(self, done, limit_s: float = 30.0) -> None:
        end = self.t + limit_s
        while not done() and self.t < end:
            self.tick()
        assert done(), f'not reached in {limit_s} s'


def test_a_pause_mid_move_lets_the_move_end_on_the_compliant_drives():
    walk = _Walk()
    execution, drive = walk.execution, walk.drive
    walk.run_until(lambda: execution.measured == 1)
    moves = len(walk.commands)
    walk.run_until(lambda: len(walk.commands) > moves)  # posture 2's move is sent
    sent_at, move = walk.commands[-1]
    assert move.purpose == CommandPurpose.MOVE and move.duration_s > 0.2
    walk.run_until(lambda: walk.t >= sent_at + 0.25 * move.duration_s)
    behind = np.max(np.abs(execution.actuators.latest - drive.setpoints_at(walk.t)))
    assert behind > 0.02  # the readings the old hold went back to: 0.1 s late
    ok, message, hold = execution.pause(walk.t)
    assert ok and hold == [] and 'the move under way ends at its target' in message
    walk.run_until(lambda: walk.t >= sent_at + move.duration_s + 1.0)
    assert drive.state == DriveState.OK, drive.fault
    assert len(walk.commands) == moves + 1  # nothing was sent while paused
    np.testing.assert_array_equal(drive.setpoints, move.positions)  # it stands at the target
    assert max(walk.link_forces) < 0.5 * 500.0

    ok, _, again = execution.resume(walk.t)
    assert ok
    walk.send(again)
    walk.run_until(lambda: execution.state == State.DONE)
    assert execution.measured == 3 and not execution.skipped
    assert drive.state == DriveState.OK and max(walk.link_forces) < 0.5 * 500.0
