"""core/walk_device/inclinometer.py and the fixed-position loop with a lagging, noisy sensor."""

from __future__ import annotations

import math
import re

from hexacal_identify.core.machine.device import inclinometer_angles
from hexacal_identify.core.machine.kinematics import forward_kinematics, inverse_kinematics
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
from hexacal_identify.core.walk.execution import PlanExecution
from hexacal_identify.core.walk.platform_paths import CommandPurpose as Purpose
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_identify.core.walk.settings import ExecutionState as State
from hexacal_identify.core.walk_device.inclinometer import (
    InclinometerState,
    judge_inclinometer,
    robust_noise,
    SETTLE_FRACTION,
    trimmed_mean,
)
import numpy as np
import pytest

L = 0.75
TOLERANCE = 2e-5  # fixed_tolerance_rad's default
TAU_S = 0.2  # the inclinometer's filter
DT_S = 0.01  # 100 Hz readings
NOISE_RAD = 1e-5  # half-width of the uniform reading noise


def _lagged(step: float, seconds: float, noise: float = 0.0, seed: int = 0):
    """Return (times, readings (n, 2)) of a first-order lag settling from `step` to 0."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, seconds, DT_S)
    truth = step * np.exp(-times / TAU_S)
    readings = np.stack([truth, -0.5 * truth], axis=1)
    return times, readings + rng.uniform(-noise, noise, readings.shape)


# --------------------------------------------------------------------------- the judgement


def test_a_steady_inclinometer_is_settled_at_once_and_averaged():
    times = np.arange(0.0, 0.5, DT_S)
    readings = np.tile([3e-5, -4e-5], (len(times), 1))
    judged = judge_inclinometer(times, readings, 0.5, 0.0, 0.25, TOLERANCE)
    assert judged.state == InclinometerState.SETTLED and judged.settled
    assert judged.angles == pytest.approx((3e-5, -4e-5), abs=1e-15)
    assert judged.trend_rad == 0.0 and judged.noise_rad == 0.0
    assert judged.limit_rad == pytest.approx(SETTLE_FRACTION * TOLERANCE)


def test_windows_before_the_move_ended_or_without_readings_are_not_judged():
    times, readings = _lagged(0.0, 1.0)
    waiting = judge_inclinometer(times, readings, 0.6, 0.2, 0.25, TOLERANCE)
    assert waiting.state == InclinometerState.WAITING and waiting.angles is None
    sparse = judge_inclinometer(times[::30], readings[::30], 1.0, 0.0, 0.25, TOLERANCE)
    assert sparse.state == InclinometerState.NO_READINGS and sparse.angles is None
    assert 'fewer than 3 inclinometer readings' in sparse.describe(0.25)


def test_a_lagging_inclinometer_settles_only_once_its_trend_is_below_the_noise():
    step = 5e-3  # what a correction of a few millimetres leaves behind the filter
    times, readings = _lagged(step, 3.0, NOISE_RAD)
    settled_at = None
    for now in np.arange(0.5, 3.0, 0.05):
        judged = judge_inclinometer(times, readings, now, 0.0, 0.25, TOLERANCE)
        if judged.settled:
            settled_at = now
            break
        assert judged.state == InclinometerState.SETTLING
        assert judged.trend_rad > judged.limit_rad
        assert 'inclinometer moved' in judged.describe(0.25)
    assert settled_at is not None
    # Settled only where the lag left a fraction of the tolerance, far below the step, and
    # not much later (with windows of 0.25 s: 0.5 s after the move at the earliest).
    left = step * math.exp(-settled_at / TAU_S)
    assert left < 0.5 * TOLERANCE
    assert settled_at < 2.5
    assert np.abs(judged.angles).max() < TOLERANCE
    # The noise estimate from the successive differences: uniform noise, sigma = w / sqrt(3).
    assert judged.noise_rad == pytest.approx(NOISE_RAD / math.sqrt(3.0), rel=0.5)


def test_spikes_neither_keep_it_settling_nor_bias_the_average():
    times = np.arange(0.0, 0.5, DT_S)
    rng = np.random.default_rng(3)
    readings = np.tile([1e-5, 2e-5], (len(times), 1)) + rng.uniform(-1e-6, 1e-6, (50, 2))
    readings[[7, 31]] += 5e-3  # vibration: two samples far off
    judged = judge_inclinometer(times, readings, 0.5, 0.0, 0.25, TOLERANCE)
    assert judged.settled
    assert judged.angles == pytest.approx((1e-5, 2e-5), abs=1e-6)
    assert readings.mean(axis=0)[0] > 1e-4  # the plain mean would be far off
    assert robust_noise(readings).max() < 2e-6
    np.testing.assert_allclose(trimmed_mean(np.arange(10.0)[:, None]), [4.5])


def test_settings_refuse_a_negative_settle_window():
    with pytest.raises(ValueError, match='inclinometer_settle_s must be a finite number >= 0'):
        ExecutionSettings(inclinometer_settle_s=-0.1)
    assert ExecutionSettings().inclinometer_settle_s == 0.25


# --------------------------------------------------------------------------- the closed loop


class _LaggingMachine:
    """
    A machine that reaches each command after its time, read by a real inclinometer.

    The inclinometer reads the true platform position through a first-order filter (time
    constant TAU_S) plus uniform noise, 100 readings a second, also while moving; a collector
    measures after 0.4 s of stillness (with `collector_motion_m`, as the real one: only if the
    actuators moved more than that since its last posture, one posture per stationary period).
    Before each correction the true angles are kept, with what the execution judged (its log
    line), to compare.
    """

    def __init__(
        self,
        truth,
        execution: PlanExecution,
        seed: int = 0,
        drift_rad_s: float = 0.0,
        silent: bool = False,
        collector_motion_m: float = 0.0,
    ):
        self.collector_motion_m = collector_motion_m
        self.last_posture = None  # the actuators of the collector's last posture
        self.moved = True  # since that posture
        self.truth = truth
        self.drift_rad_s = drift_rad_s  # added to both angles' readings, per second
        self.silent = silent  # no inclinometer readings at all
        self.states = set()  # the status field 'inclinometer' as it went
        self.execution = execution
        self.rng = np.random.default_rng(seed)
        self.points = inverse_kinematics(truth, np.array([[0, 0, -L, 0, 0, 0.0]]))
        self.times, self.t1 = np.zeros(1), 0.0
        self.pose = np.array([0, 0, -L, 0, 0, 0.0])
        self.filtered = np.zeros(2)
        self.commands = []
        self.measured_at = None
        self.t = 0.0
        self.corrections = []  # (posture, true angles, judged angles) at each correction
        self.postures = []  # (time, true angles) of the collector's postures

    def command(self, commands):
        for command in commands:
            if command.purpose == Purpose.CORRECT:
                self.corrections.append(
                    (command.posture, self.true_angles(self.at(self.t)), self._judged())
                )
            self.commands.append(command)
            # Through the command's points (along the link sphere), each at its time.
            self.points = np.vstack([self.at(self.t)[None], command.points])
            self.times = self.t + np.concatenate([[0.0], command.times])
            self.t1 = self.times[-1]

    def _judged(self):
        text = self.execution.messages[-1][1]
        found = re.search(r'inclinometer (\S+), (\S+) rad', text)
        return np.array([float(found.group(1)), float(found.group(2))])

    def at(self, t):
        if t >= self.t1:
            return self.points[-1]
        return np.array([np.interp(t, self.times, column) for column in self.points.T])

    def true_angles(self, q):
        # Mid-move, the nominal path's actuators may not assemble on the true machine (no
        # forward kinematics): the platform is taken where it last was.
        found = forward_kinematics(self.truth, q[None], self.pose[None])
        if found.converged[0]:
            self.pose = found.poses[0]
        alpha, beta = inclinometer_angles(self.pose[None, :3])
        return np.array([float(alpha[0]), float(beta[0])])

    def run(self, until):
        execution = self.execution
        gain = 1.0 - math.exp(-DT_S / TAU_S)
        while self.t < until and execution.state not in (State.DONE, State.ABORTED):
            q = self.at(self.t)
            execution.on_actuators(self.t, q)
            if self.last_posture is not None:
                self.moved |= np.abs(q - self.last_posture).max() > self.collector_motion_m
            self.filtered += gain * (self.true_angles(q) - self.filtered)
            noisy = self.filtered + self.rng.uniform(-NOISE_RAD, NOISE_RAD, 2)
            noisy += self.drift_rad_s * self.t
            if not self.silent:
                execution.on_inclinometer(self.t, float(noisy[0]), float(noisy[1]))
            self.states.add(execution.progress(self.t).get('inclinometer'))
            if self.t >= self.t1:
                if self.measured_at is None:
                    self.measured_at = self.t + 0.4
                if self.t >= self.measured_at and self.moved:
                    execution.on_posture(self.t, q)
                    self.measured_at = math.inf
                    self.last_posture, self.moved = q.copy(), False
                    self.postures.append((self.t, self.true_angles(q)))
            else:
                self.measured_at = None
            self.command(
                execution.start(self.t)
                if execution.state == State.WAITING
                else execution.step(self.t)
            )
            self.t += DT_S


def _walk(
    inclinometer_settle_s: float, timeout_s: float = 30.0, nudge_m: float = 1e-3, **machine
) -> tuple[PlanExecution, _LaggingMachine]:
    """Walk a sphere posture then two fixed-position ones on the Table 1 machine."""
    nominal = nominal_set(2, seed=0)
    rng = np.random.default_rng(1)
    workspace = nominal.architecture.default_workspace()
    poses = np.concatenate(
        [sample_poses(nominal, 1, rng, 'sphere', workspace)]
        + [sample_poses(nominal, 2, rng, 'fixed', workspace)]
    )
    kinds = ['sphere', 'fixed', 'fixed']
    stroke = default_stroke(nominal)
    settings = ExecutionSettings(
        max_actuator_speed_m_s=0.5,
        settle_s=0.2,
        timeout_s=timeout_s,
        max_corrections=5,
        inclinometer_settle_s=inclinometer_settle_s,
        correction_nudge_m=nudge_m,
    )
    execution = PlanExecution(
        nominal, poses, kinds, check_plan(nominal, poses, kinds, stroke, L), settings, stroke, L
    )
    machine = _LaggingMachine(table1_parameters(), execution, **machine)
    machine.run(120.0)
    return execution, machine


def test_settled_readings_reach_the_fixed_position_in_few_corrections_without_overcorrecting():
    execution, machine = _walk(0.25)
    assert execution.state == State.DONE and execution.measured == 3, execution.summary()
    fixed = [outcome for outcome in execution.outcomes if outcome.kind == 'fixed']
    assert all(1 <= outcome.corrections <= 2 for outcome in fixed), fixed
    # Each correction was judged on what the platform's angles were, not on a lagging reading
    # (the log line's 3 significant digits aside).
    for posture, true, judged in machine.corrections:
        assert np.abs(judged - true).max() < max(TOLERANCE, 0.005 * np.abs(true).max()), (
            posture,
            true,
            judged,
        )
    # ... so it never overshot: the next correction of a posture starts from a smaller angle
    # of the same sense, not from the other side.
    for (p1, before, _), (p2, after, _) in zip(machine.corrections, machine.corrections[1:]):
        if p1 == p2:
            assert np.abs(after).max() < 0.1 * np.abs(before).max(), (before, after)
    final = machine.true_angles(machine.at(machine.t))
    assert np.abs(final).max() <= TOLERANCE
    assert 'settling' in machine.states  # the status said what it waited for
    assert any('settled' in text and 'correction 1' in text for _, text in execution.messages)


def test_judging_unsettled_readings_overcorrects_the_same_walk():
    # The old rule: the mean over settle_s as soon as the actuators are still.
    execution, machine = _walk(0.0)
    overshoots = [
        (true, judged)
        for _, true, judged in machine.corrections
        if np.abs(judged - true).max() > 10 * TOLERANCE
    ]
    # It corrected for angles the platform no longer had, and needed more corrections (or gave
    # up on a posture) than the settled loop.
    assert overshoots, machine.corrections
    fixed = [outcome for outcome in execution.outcomes if outcome.kind == 'fixed']
    assert any(o.corrections > 3 or not o.measured for o in fixed), fixed


@pytest.mark.slow
def test_an_inclinometer_that_never_settles_or_is_silent_skips_the_posture_saying_so():
    execution, machine = _walk(0.25, timeout_s=4.0, drift_rad_s=2e-4)
    assert execution.measured == 1, execution.summary()
    reason = execution.skipped[0].reason
    assert reason.startswith('the inclinometer did not settle (inclinometer moved'), reason
    assert 'between two 0.25 s windows' in reason and reason.endswith('within 4 s')
    execution, machine = _walk(0.25, timeout_s=4.0, silent=True)
    assert execution.measured == 1, execution.summary()
    assert execution.skipped[0].reason.startswith('no inclinometer readings (fewer than 3')
    assert 'no-readings' in machine.states


@pytest.mark.slow
def test_a_small_correction_nudges_so_a_one_posture_per_stop_collector_measures_it():
    # A collector that takes one posture per stationary period (0.2 mm: the detector's
    # default tolerance) measured each stop before the settled inclinometer asked for the
    # last, small correction: without the nudge no posture follows it.
    execution, machine = _walk(0.25, timeout_s=6.0, nudge_m=0.0, collector_motion_m=2e-4)
    assert execution.measured < 3 and execution.skipped, execution.summary()
    assert 'came before the last correction' in execution.skipped[0].reason
    # With it, the collector sees a move after every correction and measures the position
    # reached: every fixed posture is measured at the fixed position.
    execution, machine = _walk(0.25, collector_motion_m=2e-4)
    assert execution.state == State.DONE and execution.measured == 3, execution.summary()
    corrections = [c for c in machine.commands if c.purpose == Purpose.CORRECT]
    # An eased correction comes ever closer to its target; a nudge passes it and comes back.
    away = [np.abs(c.points - c.points[-1]).max(axis=1) for c in corrections]
    nudged = [d for d in away if np.any(np.diff(d) > 1e-12)]
    assert nudged and len(nudged) < len(corrections), away
    for distance in nudged:  # 1 mm beyond along the sphere, then the target
        turn = int(np.argmax(np.diff(distance) > 1e-12))  # where it passes the target
        assert 2e-4 < distance[turn:].max() < 5e-3, distance
    at_fixed = [angles for _, angles in machine.postures if np.abs(angles).max() <= TOLERANCE]
    assert len(at_fixed) >= 2, machine.postures
    assert np.abs(machine.postures[-1][1]).max() <= TOLERANCE  # the last, a fixed posture's
    assert any('nudge beyond it' in text for _, text in execution.messages)
