"""
The driver's commanded mode on the MuJoCo machine (``physics: mujoco``), through SimulatedMachine.

The same trajectories, release and lock, status and guards as the kinematic follower; the
standing is simulated.  Gravity off and a rigid structure: the released actuator ends where the
closure says, as on the kinematic machine.
"""

from __future__ import annotations

from dataclasses import replace

from hexacal_driver.machine import DriverConfigurationError, SimulatedMachine
from hexacal_driver.parameters import parameter_problem, PARAMETERS
from hexacal_driver.physics_follower import MAX_SETTLE_S
from hexacal_driver.reports import link_overload_warning
from hexacal_driver.simulation import STILL
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_msgs_py.physical_file import default_physical, write_physical_file
import numpy as np
import pytest

pytest.importorskip('mujoco')

RELEASED = 'slider_3'


def machine(**overrides) -> SimulatedMachine:
    values = {name: spec.default for name, spec in PARAMETERS.items()}
    values['command_topic'] = '/joint_trajectory_controller/joint_trajectory'
    values['physics'] = 'mujoco'
    values.update(overrides)
    return SimulatedMachine(values)


def follow(m: SimulatedMachine, names, target, start_s: float, duration_s: float = 0.3):
    """
    Command one point, sample at 100 Hz until STILL after its end; return the last sample.

    STILL is the machine's own rest, not the follower's MAX_SETTLE_S fallback: the setpoints it
    re-commands every tick are no move.
    """
    checked, problem = m.check_command(list(names), [(list(target), duration_s)], 0, 0)
    assert problem is None, problem
    end_s = m.follower.command(start_s, checked)
    now_s, sample = start_s, None
    while sample is None or now_s <= end_s or sample.phase != STILL:
        sample = m.follower.sample(now_s)
        now_s += 0.01
        assert now_s < end_s + MAX_SETTLE_S
    assert m.follower.machine.at_rest()
    return sample, now_s


def test_physics_parameters_are_checked():
    assert PARAMETERS['physics'].default == 'kinematic'
    assert parameter_problem('physics', 'mujoco') is None
    assert 'physics must be one of' in parameter_problem('physics', 'bullet')
    assert 'physical' in parameter_problem('physical', '/nonexistent/physical.yaml')
    with pytest.raises(DriverConfigurationError, match='commanded mode only'):
        machine(command_topic='')


def test_passive_actuator_on_the_mujoco_machine(tmp_path):
    physical = tmp_path / 'physical.yaml'
    rigid = replace(default_physical().weightless().made_rigid(), released_coulomb=0.0)
    write_physical_file(physical, rigid)
    m = machine(measuring_mode='passive_actuator', physical=str(physical))
    f = m.follower
    start_pose = f.pose.copy()
    assert f.release(RELEASED, True, 0.0)[0]
    mask = f.commanded_mask()
    target = (f.setpoints + np.array([2e-3, -1e-3, 0.0, 1.5e-3, 0.0, -2e-3]))[mask]
    sample, now_s = follow(m, f.commanded_names(), target, 0.0)
    index = f.joint_names.index(RELEASED)
    assert np.max(np.abs(np.delete(sample.actuators, index) - target)) < 1e-8
    expected = solve_passive(
        m.true_params, f.setpoints[None], index, start_pose[None], m.true_link_length, m.mount
    )
    assert abs(sample.actuators[index] - expected.actuators[0, index]) < 1e-8
    status = f.status_values()
    assert status['physics'] == 'mujoco' and status['released_joint'] == RELEASED
    assert status['max_joint_gap_m'] < 1e-8 and status['state'] == 'ok'
    # The simulated link's force is on the status in this mode too: weightless, none at rest
    # (the peak holds the move's inertial forces).
    assert status['link_force_n'] == pytest.approx(m.follower.machine.link_force(), abs=1e-9)
    assert abs(status['link_force_n']) < 1e-3 < status['max_link_force_n']
    # At this rest the driver hears whether the move loaded the link past its limit.
    assert link_overload_warning(f) is None  # the default 500 N
    f.settings = replace(f.settings, max_link_force_n=1e-3)
    warning = link_overload_warning(f)
    assert warning is not None and 'beyond its 0.001 N limit' in warning, warning
    assert ', on a move,' in warning, warning  # weightless: the release itself loads nothing
    f.rest_reached()
    assert f.status_values()['move_max_link_force_n'] > 1e-3 and link_overload_warning(f) is None
    assert f.status_values()['move_max_link_force_after'] == 'move'
    # Locked where it stands: no jump; what the link bears next comes after the lock.
    before = f.actuators[index]
    assert f.release(RELEASED, False, now_s)[0]
    assert abs(f.sample(now_s + 0.1).actuators[index] - before) < 1e-8
    f.rest_reached()
    assert f.status_values()['move_max_link_force_after'] == 'lock'


def test_a_following_error_faults_and_reset_holds(tmp_path):
    # A 10 um following-error limit: the servos' lag at 1 m/s (v kd / kp = 0.4 mm) passes it.
    physical = tmp_path / 'physical.yaml'
    write_physical_file(physical, replace(default_physical(), following_error_limit=1e-5))
    m = machine(measuring_mode='lvdt', physical=str(physical), max_actuator_speed_m_s=1.0)
    f = m.follower
    f.sample(0.0)
    checked, problem = m.check_command(
        list(f.commanded_names()), [(list(f.setpoints + 0.02), 0.01)], 0, 0
    )
    assert problem is None
    f.command(0.0, checked)
    for now_s in np.arange(0.01, 0.2, 0.01):
        f.sample(float(now_s))
    assert f.fault is not None and 'following error' in f.fault.text
    assert f.status_values()['state'] == 'fault'
    assert f.reset()[0] and f.fault is None
    f.sample(0.3)
    assert f.fault is None
