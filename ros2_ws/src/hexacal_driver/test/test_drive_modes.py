"""Unit tests of the drives per measuring mode and their guard (drives.py), without ROS."""

from hexacal_driver.drives import DriveState
from hexacal_driver.machine import SimulatedMachine
from hexacal_driver.parameters import parameter_problem, PARAMETERS
from hexacal_driver.reports import drives_start_text
from hexacal_driver.simulation import CommandFollower
from hexacal_identify.core.modes.compliant import link_tension
from hexacal_identify.core.modes.lvdt import lvdt_extensions
from hexacal_identify.core.modes.passive_actuator import solve_passive
import numpy as np
import pytest

RELEASED = 'slider_3'


def machine(**overrides) -> SimulatedMachine:
    """Return the commanded simulated machine of the node's defaults with `overrides`."""
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values['command_topic'] = '/joint_trajectory_controller/joint_trajectory'
    values.update(overrides)
    return SimulatedMachine(values)


def follow(m: SimulatedMachine, names, target, start_s: float, duration_s: float = 1.0):
    """Command one point and sample the follower at 100 Hz to its end; return the last sample."""
    checked, problem = m.check_command(list(names), [(list(target), duration_s)], 0, 0)
    assert problem is None, problem
    end_s = m.follower.command(start_s, checked)
    sample = None
    for now_s in np.arange(start_s, end_s + 0.05, 0.01):
        sample = m.follower.sample(float(now_s))
    return sample, end_s + 0.05


def five(m: SimulatedMachine, offset: np.ndarray):
    """Return the five commanded joints and their targets: the setpoints + offset."""
    f = m.follower
    mask = f.commanded_mask()
    return list(f.commanded_names()), (f.setpoints + offset)[mask]


def test_passive_five_at_setpoints_and_released_where_the_link_puts_it():
    m = machine(measuring_mode='passive_actuator', device_defects='dL=2e-4')
    f = m.follower
    start_pose = f.pose.copy()
    assert f.release(RELEASED, True, 0.0)[0]
    names, target = five(m, np.array([2e-3, -1e-3, 0.0, 1.5e-3, 0.0, -2e-3]))
    sample, _ = follow(m, names, target, 0.0)
    index = f.joint_names.index(RELEASED)
    commanded = np.delete(sample.actuators, index)
    assert np.max(np.abs(commanded - target)) < 1e-12
    expected = solve_passive(
        m.true_params, f.setpoints[None], index, start_pose[None], m.true_link_length, m.mount
    )
    assert expected.converged[0]
    assert abs(sample.actuators[index] - expected.actuators[0, index]) < 1e-9
    assert abs(np.linalg.norm(sample.pose[:3]) - m.true_link_length) < 1e-12
    assert abs(sample.actuators[index] - f.actuators[index]) == 0.0
    assert f.status_values()['released_joint'] == RELEASED
    assert f.following_error_m < 1e-12


def test_passive_refusals():
    m = machine(measuring_mode='passive_actuator')
    f = m.follower
    six = list(f.joint_names)
    # No joint released: five joints leave one undefined.
    names = [name for name in six if name != RELEASED]
    _, problem = m.check_command(names, [(list(f.setpoints[f.commanded_mask()][:5]), 1.0)], 0, 0)
    assert problem is not None and 'missing' in problem and 'release one first' in problem
    assert f.release(RELEASED, True, 0.0)[0]
    done, message = f.release('slider_1', True, 0.0)
    assert not done and RELEASED in message
    _, problem = m.check_command(six, [(list(f.setpoints), 1.0)], 0, 0)
    assert problem is not None and RELEASED in problem and 'released' in problem
    names, target = five(m, np.full(6, 1e-3))
    checked, problem = m.check_command(names, [(list(target), 1.0)], 0, 0)
    assert problem is None
    f.command(10.0, checked)
    done, message = f.release(RELEASED, False, 10.5)
    assert not done and 'moving' in message
    done, message = f.release(RELEASED, False, 12.0)
    assert done and f.released is None
    # Locked where it stands: six commanded at their true positions, no following error.
    assert f.setpoints[2] == f.actuators[2]
    assert machine(measuring_mode='compliant').follower.release(RELEASED, True, 0.0)[0] is False


def test_lvdt_extension_is_the_forward_kinematics_distance():
    m = machine(measuring_mode='lvdt', device_defects='dL=1e-4')
    f = m.follower
    start = f.pose.copy()
    sample, _ = follow(m, f.joint_names, f.setpoints + np.array([1e-3, 0, -1e-3, 0, 5e-4, 0]), 0.0)
    assert np.array_equal(sample.actuators, f.setpoints)  # stiff: exactly at the setpoints
    expected = lvdt_extensions(m.true_params, f.setpoints[None], start[None], m.true_link_length)
    assert abs(f.link_extension_m) > 1e-5
    assert abs(f.link_extension_m - expected[0]) < 1e-10
    assert abs(np.linalg.norm(sample.pose[:3]) - m.true_link_length - f.link_extension_m) < 1e-12
    assert abs(f.link_reading_m - (m.link_length + f.link_extension_m)) < 1e-15
    assert f.status_values()['link_extension_m'] == f.link_extension_m


def ramp_until_fault(m: SimulatedMachine, offset: np.ndarray, names=None):
    """Command setpoints + offset over 10 s; return the samples up to a fault and one after."""
    f = m.follower
    names = list(names or f.joint_names)
    checked, problem = m.check_command(names, [(list(f.setpoints + offset), 10.0)], 0, 0)
    assert problem is None, problem
    f.command(0.0, checked)
    samples = []
    for now_s in np.arange(0.0, 10.0, 0.01):
        samples.append(f.sample(float(now_s)))
        if f.fault is not None:
            break
    assert f.state == DriveState.FAULT
    samples.append(f.sample(20.0))  # long after: still held
    return samples


def test_lvdt_end_stop_faults_before_the_stroke_is_passed_and_holds():
    m = machine(measuring_mode='lvdt', lvdt_stroke_m=1e-3)
    f = m.follower
    samples = ramp_until_fault(m, np.array([0.03, 0.03, 0.03, 0.03, 0.03, 0.03]))
    held = samples[-1]
    assert np.array_equal(held.actuators, samples[-2].actuators)
    assert np.array_equal(held.pose, samples[-2].pose)
    assert abs(np.linalg.norm(held.pose[:3]) - m.true_link_length) <= 1e-3 + 1e-12
    assert f.following_error_m <= f.settings.max_following_error_m
    assert f.fault.value > f.fault.limit == f.settings.max_following_error_m
    assert 'end stop' in f.fault.text
    _, problem = m.check_command(list(f.joint_names), [(list(f.setpoints), 1.0)], 0, 0)
    assert problem is not None and 'fault' in problem
    assert f.reset()[0] and f.state == DriveState.OK and f.following_error_m == 0.0


@pytest.mark.slow
def test_over_constrained_passive_faults_before_the_limit_and_holds():
    m = machine(measuring_mode='passive_actuator')
    f = m.follower
    samples = ramp_until_fault(m, np.array([5e-3, 0, 0, 0, 0, 0]))
    limit = f.settings.max_following_error_m
    assert 0.5 * limit < f.following_error_m <= limit
    assert f.fault.joint in f.joint_names and f.fault.value > limit
    assert np.array_equal(samples[-1].actuators, samples[-2].actuators)
    values = f.status_values()
    assert values['state'] == 'fault' and 'over-constrained' in values['fault']
    assert values['fault_limit'] == limit
    assert f.release(RELEASED, True, 30.0)[0] is False  # reset first


def test_compliant_force_is_stiffness_times_deviation_and_faults_at_the_limit():
    m = machine(
        measuring_mode='compliant', servo_stiffness_n_per_m=1e6, max_force_n=1e3,
        max_link_force_n=1e9,
    )
    f = m.follower
    samples = ramp_until_fault(m, np.full(6, 5e-3))
    forces = f.forces()
    assert np.allclose(forces, 1e6 * (f.actuators - f.setpoints), rtol=0, atol=1e-12)
    assert 0 < np.max(np.abs(forces)) <= 1e3
    assert f.fault.value > 1e3 and 'force' in f.fault.text
    assert np.array_equal(samples[-1].actuators, samples[-2].actuators)
    assert f.status_values()['force_n'] == pytest.approx(np.max(np.abs(forces)))


def test_compliant_servos_fault_before_they_overload_the_measuring_link():
    m = machine(measuring_mode='compliant', servo_stiffness_n_per_m=1e6, max_force_n=1e9)
    f = m.follower
    samples = ramp_until_fault(m, np.full(6, 5e-3))
    # The default link limit: what a measuring link of the documented kind bears.
    assert f.settings.max_link_force_n == 500.0
    assert f.fault.joint == 'link' and f.fault.value > 500.0 == f.fault.limit, f.fault
    assert 'measuring link' in f.fault.text and 'beyond the limit 500 N' in f.fault.text
    # The standing held is the last one inside the limit.
    assert np.array_equal(samples[-1].actuators, samples[-2].actuators)
    held = link_tension(f.params, f.pose, f.actuators, f.setpoints, 1e6)[0]
    assert 0 < abs(held) <= 500.0
    values = f.status_values()
    assert values['link_force_n'] == pytest.approx(held)
    assert abs(held) <= values['max_link_force_n'] <= 500.0


def test_compliant_default_follows_as_before():
    """The default (compliant, 500 N at 2e4 N/m) moves exactly as the plain CommandFollower."""
    m = machine()
    f = m.follower
    plain = CommandFollower(m.true_params, f.pose, f.max_speed_m_s, m.true_link_length, m.mount)
    checked, _ = m.check_command(
        list(f.joint_names), [(list(f.setpoints + np.array([3e-3, 0, -2e-3, 0, 1e-3, 0])), 1.0)],
        0, 0,
    )
    f.command(0.0, checked)
    plain.command(0.0, checked)
    for now_s in np.arange(0.0, 1.5, 0.01):
        ours, theirs = f.sample(float(now_s)), plain.sample(float(now_s))
        assert np.array_equal(ours.actuators, theirs.actuators)
        assert np.array_equal(ours.pose, theirs.pose)
    assert f.state == DriveState.OK and f.strain_m == plain.strain_m > 1e-4


def test_measuring_mode_parameter_is_checked():
    assert parameter_problem('measuring_mode', 'passive_actuator') is None
    assert 'lvdt' in parameter_problem('measuring_mode', 'rigid')
    assert PARAMETERS['measuring_mode'].default == 'compliant'


def test_the_start_line_names_the_mode_and_its_guard():
    assert 'fault above 500 N on a servo or 500 N on the link' in drives_start_text(
        machine().follower
    )
    text = drives_start_text(machine(measuring_mode='lvdt', lvdt_stroke_m=0.002).follower)
    assert 'lvdt' in text and '+-0.002 m' in text and '0.0005 m following error' in text


def test_each_rest_keeps_the_peaks_of_the_motion_into_it():
    """rest_reached counts the rest and keeps the largest force of the motion that ended there."""
    m = machine(measuring_mode='compliant')
    f = m.follower
    names = list(f.joint_names)
    away = f.setpoints + np.array([3e-3, 0, -2e-3, 0, 1e-3, 0])
    _, now_s = follow(m, names, away, 0.0)
    f.rest_reached()
    strained = f.status_values()
    assert strained['rests'] == 1
    assert strained['move_max_force_n'] >= strained['force_n'] > 0
    assert strained['move_max_link_extension_m'] == ''  # no LVDT link in compliant mode
    # Back to where it started: a smaller strain, and the motion's own peak, not the first one.
    follow(m, names, f.setpoints - np.array([3e-3, 0, -2e-3, 0, 1e-3, 0]) * 0.9, now_s)
    f.rest_reached()
    values = f.status_values()
    assert values['rests'] == 2
    assert values['move_max_force_n'] < strained['move_max_force_n']
    assert values['move_max_force_n'] >= values['force_n']
    assert values['max_force_n'] == strained['max_force_n']  # the run's peak stays


def test_the_drives_status_is_due_on_a_change_when_forced_and_every_period():
    from hexacal_driver.reports import DriveStatusReport

    m = machine(measuring_mode='passive_actuator')
    report = DriveStatusReport(period_s=1.0)
    level, message, values, new_fault = report.report(m.follower, 0)
    assert (level, message, new_fault) == ('OK', 'passive_actuator', '')
    assert values == m.follower.status_values()
    assert report.report(m.follower, 500_000_000) is None  # unchanged, within the period
    assert report.report(m.follower, 500_000_000, force=True) is not None
    assert report.report(m.follower, 1_600_000_000) is not None  # the period has passed
    assert m.follower.release(RELEASED, True, 0.0)[0]
    level, message, _, _ = report.report(m.follower, 1_700_000_000)  # a change: at once
    assert (level, message) == ('OK', f'passive_actuator, {RELEASED} released')


def test_a_late_tick_moves_the_machine_as_the_ticks_it_missed_would_have():
    # A loaded computer wakes the node late: one sample then covers a whole move. The machine
    # still moves continuously, so it ends where the 100 Hz samples take it, with no jam.
    offset = np.array([40e-3, -30e-3, 0.0, 35e-3, -25e-3, 30e-3])
    ends = []
    for late in (False, True):
        m = machine(measuring_mode='passive_actuator')
        f = m.follower
        assert f.release(RELEASED, True, 0.0)[0]
        names, target = five(m, offset)
        if late:
            checked, problem = m.check_command(names, [(list(target), 1.0)], 0, 0)
            assert problem is None, problem
            end_s = f.command(0.0, checked)
            f.sample(0.0)
            sample = f.sample(end_s + 0.05)
        else:
            sample, _ = follow(m, names, target, 0.0)
        assert f.fault is None, f.fault
        ends.append(sample)
    np.testing.assert_allclose(ends[1].pose, ends[0].pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ends[1].actuators, ends[0].actuators, rtol=0, atol=1e-9)
