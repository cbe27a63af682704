"""The device turned about its link axis, through the driver, the collector and the bag (real nodes).

A simulated driver with a defective device (`device_defects`), turned by pi (`device_turn`)
except where its plan file names another turn per posture, publishes exactly (noise 0) what the
core's defect model (core.device.inclinometer_readings, the rotary wrap(phi - turn + phi0))
gives for the platform on the device's true sphere L + dL, and its inclinometer messages carry
the `device_turn` joint whenever the turn is non-zero. The collector publishes and records
postures carrying the turn; the bag read back gives PostureReadings with it.

A device without the joint (an ideal device in its normal mounting, as a real one that knows
nothing of turns) takes the collector's `device_turn` parameter, set at start and at run time.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from system_support import (
    fast_collector_parameters,
    fast_driver_parameters,
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
)

DEFECTS = 'dL=5e-4,alpha0=2e-4,beta0=-1.5e-4,gamma=1e-4,phi0=3e-4'
LINK_LENGTH_M = 0.75
POSTURES = 6
# Per plan posture: None takes the driver's device_turn parameter (pi); 0.0 is the normal mounting.
PLAN_TURNS = (None, math.pi / 2, None, 0.0, -math.pi / 2, None)
DRIVER_TURN = math.pi


def wrap(angle: np.ndarray) -> np.ndarray:
    return (np.asarray(angle, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def expected_readings(plan, turns: np.ndarray) -> np.ndarray:
    """(N, 9) what the defective, turned device and the actuators read at the plan's postures,
    straight from the core: the platform on the true sphere L + dL (sphere postures radially,
    fixed ones where the turned device reads zero)."""
    from hexacal_identify.core import table1_parameters
    from hexacal_identify.core.machine.device import (
        DeviceDefects,
        fixed_position,
        inclinometer_readings,
    )
    from hexacal_identify.core.machine.kinematics import inverse_kinematics

    defects = DeviceDefects.parse(DEFECTS)
    true_length = LINK_LENGTH_M + defects.dL
    poses = np.array(plan.poses, dtype=float)
    for i, kind in enumerate(plan.kinds):
        if kind == 'fixed':
            poses[i, :3] = fixed_position(LINK_LENGTH_M, defects, 'hanging', turns[i]).position[0]
        else:
            poses[i, :3] *= true_length / np.linalg.norm(poses[i, :3])
    assert np.allclose(np.linalg.norm(poses[:, :3], axis=1), true_length, rtol=0, atol=1e-12)
    alpha, beta = inclinometer_readings(poses[:, :3], defects, 'hanging', turns)
    rotary = wrap(poses[:, 5] - turns + defects.phi0)
    sliders = inverse_kinematics(table1_parameters(), poses)
    return np.column_stack([sliders, alpha, beta, rotary])


def recorded_inclinometer(bag: Path) -> list:
    """(names, positions) of every inclinometer message the collector recorded. The bag, not a
    probe subscription: the driver starts walking once the collector is matched, so a probe
    discovered later (a loaded machine) would miss the first postures' messages."""
    from hexacal_identify.bag import open_bag

    with open_bag(bag) as reader:
        return [
            (tuple(m.decoded.name), tuple(m.decoded.position))
            for m in reader.messages(['hexacal/inclinometer'])
        ]


@pytest.mark.slow
def test_driver_with_defects_and_turns_to_the_collectors_bag(ros_processes, tmp_path, probe):
    from dataclasses import replace

    from hexacal_driver.plan import generated_plan, save_plan
    from hexacal_identify.core import table1_parameters
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
    from hexacal_msgs_py.names import DEVICE_TURN_JOINT, INCLINOMETER_NAMES, POSTURE_NAMES

    plan = replace(
        generated_plan('mixed', table1_parameters(), POSTURES, seed=4),
        name='turns',
        device_turns=PLAN_TURNS,
    )
    assert 'fixed' in plan.kinds
    plan_path = tmp_path / 'turns.yaml'
    save_plan(plan_path, plan)
    turns = np.array([DRIVER_TURN if t is None else t for t in PLAN_TURNS])
    expected = expected_readings(plan, turns)

    bags = tmp_path / 'bags'
    probe.subscribe_postures()
    collector = ros_processes.start(
        node_argv('collector', fast_collector_parameters(bags, bag_name='turned')),
        name='collector',
    )
    probe.wait_for_node('collector', '/', collector)
    # The plan is walked once, so every posture must be captured: a dwell of 1.5 s leaves the
    # collector room to capture again after a stall of the driver's stream (a gap drops a capture).
    driver = ros_processes.start(
        node_argv(
            'driver',
            fast_driver_parameters(
                plan=str(plan_path),
                slider_noise_m=0.0,
                angle_noise_rad=0.0,
                device_defects=DEFECTS,
                device_turn=DRIVER_TURN,
                dwell_s=1.5,
            ),
        ),
        name='driver',
    )
    nodes = (collector, driver)
    probe.spin_until(
        lambda: len(probe.postures) >= POSTURES,
        POSTURES * 1.0 + 60.0,
        f'{POSTURES} postures',
        lambda: '\n'.join(p.describe(20) for p in nodes),
    )
    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0, driver.describe()
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0, collector.describe()
    driver_log = driver.log_path.read_text()
    assert 'device defects dL=0.0005 m, alpha0=0.0002 rad' in driver_log, driver_log
    assert 'device turned 3.14159 rad about its link' in driver_log, driver_log
    assert f'{POSTURES} postures published' in collector.log_path.read_text(), collector.describe()

    # The inclinometer stream as recorded: the joint exactly when the device is turned, with the turn.
    inclinometer = recorded_inclinometer(bags / 'turned')
    turned = [(names, positions) for names, positions in inclinometer if len(names) == 3]
    normal = [(names, positions) for names, positions in inclinometer if len(names) == 2]
    assert turned and normal and len(turned) + len(normal) == len(inclinometer)
    assert all(names == INCLINOMETER_NAMES + (DEVICE_TURN_JOINT,) for names, _ in turned)
    assert all(names == INCLINOMETER_NAMES for names, _ in normal)
    assert {positions[2] for _, positions in turned} == {math.pi, math.pi / 2, -math.pi / 2}

    # The live postures: the core's readings (noise 0: to rounding), each with its turn, the
    # joint only on turned ones.
    live = probe.postures[:POSTURES]
    values = np.array([p.values() for p in live])
    assert np.abs(values - expected).max() < 1e-9, np.abs(values - expected).max(axis=0)
    assert [p.device_turn for p in live] == turns.tolist()
    for names, turn in zip(probe.posture_joint_names, turns):
        assert names == POSTURE_NAMES + ((DEVICE_TURN_JOINT,) if turn else ())
    # Reversed, the inclinometer reads the true angles negated plus the same offsets: the
    # posture readings are not those of the normal mounting.
    normal_readings = expected_readings(plan, np.zeros(POSTURES))
    assert np.abs(values[0, 6:8] - normal_readings[0, 6:8]).min() > 1e-6

    # The bag: its postures read back carry the turn.
    recorded = postures_from_bag(bags / 'turned', source='posture')
    assert recorded.postures == live
    assert [p.device_turn for p in recorded.postures] == turns.tolist()
    # Re-detected from the raw streams, each posture takes the turn of the inclinometer messages around it.
    redetected = postures_from_bag(bags / 'turned', source='raw').postures
    assert len(redetected) >= POSTURES
    by_sliders = {tuple(np.round(p.actuator_positions, 6)): p.device_turn for p in redetected}
    for posture, turn in zip(live, turns):
        assert by_sliders.get(tuple(np.round(posture.actuator_positions, 6)), turn) == turn
    assert sorted(set(p.device_turn for p in redetected)) == sorted(set(turns.tolist()))


@pytest.mark.slow
def test_collector_parameter_turns_postures_without_the_joint(ros_processes, tmp_path, probe):
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
    from hexacal_msgs_py.names import DEVICE_TURN_JOINT, POSTURE_NAMES
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    bags = tmp_path / 'bags'
    probe.subscribe_postures()
    collector = ros_processes.start(
        node_argv(
            'collector', fast_collector_parameters(bags, bag_name='operator', device_turn=3.14159)
        ),
        name='collector',
    )
    probe.wait_for_node('collector', '/', collector)
    driver = ros_processes.start(
        node_argv(
            'driver',
            fast_driver_parameters(
                plan='random', postures=40, slider_noise_m=0.0, angle_noise_rad=0.0
            ),
        ),
        name='driver',
    )
    nodes = (collector, driver)
    details = lambda: '\n'.join(p.describe(20) for p in nodes)  # noqa: E731
    probe.spin_until(lambda: len(probe.postures) >= 2, 60.0, 'two postures', details)

    client = probe.node.create_client(SetParameters, '/collector/set_parameters')
    probe.spin_until(client.service_is_ready, 30.0, 'the collector parameter service')

    def set_turn(value) -> object:
        request = SetParameters.Request(
            parameters=[Parameter('device_turn', value=value).to_parameter_msg()]
        )
        future = client.call_async(request)
        return probe.spin_until(
            lambda: future.result() if future.done() else None, 30.0, 'set_parameters'
        ).results[0]

    for bad in (7.0, float('nan')):
        result = set_turn(bad)
        assert not result.successful and 'device_turn' in result.reason, result
    result = set_turn(-1.5)
    assert result.successful, result
    changed_at = len(probe.postures)
    probe.spin_until(
        lambda: len(probe.postures) >= changed_at + 3,
        60.0,
        'three postures after the change',
        details,
    )
    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0, driver.describe()
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0, collector.describe()
    log = collector.log_path.read_text()
    assert 'device_turn 3.14159 -> -1.5 rad' in log, log

    inclinometer = recorded_inclinometer(bags / 'operator')
    assert inclinometer and all(DEVICE_TURN_JOINT not in names for names, _ in inclinometer)
    live = list(probe.postures)
    turns = [p.device_turn for p in live]
    # The first postures the old value, the last ones the new (the change lands between two).
    assert turns[:2] == [3.14159, 3.14159] and turns[-2:] == [-1.5, -1.5], turns
    assert set(turns) == {3.14159, -1.5}
    assert all(
        names == POSTURE_NAMES + (DEVICE_TURN_JOINT,) for names in probe.posture_joint_names
    )
    recorded = postures_from_bag(bags / 'operator', source='posture').postures
    assert len(recorded) >= len(live)  # recorded before it is published
    assert [p.device_turn for p in recorded[: len(live)]] == turns


@pytest.mark.slow
def test_bad_device_parameters_are_refused(ros_processes, tmp_path, probe):
    for argv, text in (
        (node_argv('driver', fast_driver_parameters(device_defects='dL=oops')), 'device_defects'),
        (
            node_argv('driver', fast_driver_parameters(device_defects='tilt=1e-3')),
            'bad device defect',
        ),
        (
            node_argv('collector', fast_collector_parameters(tmp_path / 'bags', device_turn=9.0)),
            'device_turn',
        ),
    ):
        process = ros_processes.start(argv, name=argv[0].rsplit('/', 1)[-1])
        probe.spin_until(
            lambda: not process.running(), 60.0, f'{argv[0]} to refuse', process.describe
        )
        assert process.popen.returncode == 2, process.describe()
        log = process.log_text()
        assert text in log and 'Traceback' not in log, log
