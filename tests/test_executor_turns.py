"""The executor walks a turning procedure: it pauses for the operator to turn the device, and the
nodes named in device_turn_nodes (driver, collector) take the new turn on resume (real nodes,
real processes).

A plan of four sphere postures, two in the normal mounting and two with the device reversed
(device_turn pi), as `hexacal plan` orders a turning procedure (one remount per turn). The
collector and the driver start with the turn an earlier plan left them at (STALE_TURN): the
executor sets them to the mounting at the start (`mounted_turn`, 0) before the first move.
"""

from __future__ import annotations

import math
from pathlib import Path

from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
from hexacal_identify.core.planning.planner import Plan
from hexacal_msgs_py.names import DEFAULT_COMMAND_TOPIC, DEVICE_TURN_JOINT
import numpy as np
import pytest
from system_support import (
    fast_collector_parameters,
    node_argv,
    probe,  # noqa: F401 - fixture
    STOP_TIMEOUT_S,
    write_parameter_files,
)
from test_executor import _driver, _executor, ExecutorWatch

L = 0.75
TURNS = [0.0, 0.0, math.pi, math.pi]
STALE_TURN = 1.0  # rad: what an earlier plan left on the nodes
MATCH_M = (
    5e-3  # a posture belongs to the plan posture whose targets its actuators are this close to
)


def _turning_plan(tmp_path: Path) -> tuple[Path, np.ndarray]:
    """Four sphere postures the executor commands (paths included); their nominal targets."""
    nominal = nominal_set(2, seed=0)
    stroke = default_stroke(nominal)
    for seed in range(20):
        poses = sample_poses(
            nominal,
            4,
            np.random.default_rng(seed),
            'sphere',
            nominal.architecture.default_workspace(),
        )
        try:
            targets = check_plan(nominal, poses, ['sphere'] * 4, stroke, L, path_step_m=0.02)
        except ValueError:
            continue
        break
    else:
        raise AssertionError('no commandable four-posture plan in 20 seeds')
    path = tmp_path / 'turning-plan.yaml'
    Plan('turning-test', L, poses, ['sphere'] * 4, device_turns=TURNS).save(path)
    assert Plan.load(path).turns.tolist() == TURNS
    return path, targets


@pytest.mark.slow
def test_the_executor_pauses_for_a_device_turn_and_the_nodes_take_it(
    ros_processes, tmp_path, probe
):  # noqa: F811
    from hexacal_identify.core.walk.messages import joint_positions
    from hexacal_msgs_py.qos import POSTURE_QOS
    from sensor_msgs.msg import JointState

    truth, nominal = write_parameter_files(tmp_path)
    plan, targets = _turning_plan(tmp_path)
    postures: list[tuple[np.ndarray, float]] = []  # (actuators, device_turn) as published

    def on_posture(message: JointState) -> None:
        actuators = joint_positions(
            message.name, message.position, [f'slider_{i}' for i in range(1, 7)]
        )
        names = list(message.name)
        turn = (
            float(message.position[names.index(DEVICE_TURN_JOINT)])
            if DEVICE_TURN_JOINT in names
            else 0.0
        )
        postures.append((actuators, turn))

    probe.node.create_subscription(JointState, 'hexacal/posture', on_posture, POSTURE_QOS)
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(_driver(truth, device_turn=STALE_TURN))
    collector = ros_processes.start(
        node_argv(
            'collector',
            fast_collector_parameters(
                tmp_path / 'bags',
                bag_name='turns',
                parameters_file=str(nominal),
                device_turn=STALE_TURN,
            ),
        )
    )
    probe.wait_for_node('driver', process=driver)
    probe.wait_for_node('collector', process=collector)
    executor = ros_processes.start(
        _executor(plan, nominal, 'device_turn_nodes:=[collector, driver]', start_paused=True)
    )
    nodes = (driver, collector, executor)
    # Started paused, so the probe hears every command (the hold of the turn among them).
    watch.wait(lambda s: s.get('state') == 'paused', 60.0, 'the executor ready, paused', *nodes)
    probe.spin_until(
        lambda: probe.node.count_publishers(DEFAULT_COMMAND_TOPIC) >= 1,
        10.0,
        "the executor's command publisher",
    )
    assert (
        'device_turn_needed_rad' not in watch.latest
    )  # the first posture is in the normal mounting
    # Ready only once the nodes have left the stale turn for the mounting at the start.
    assert watch.latest.get('device_turn_set') == 'done', watch.latest
    assert (
        'the mounting at the start: setting device_turn 0 rad on collector, driver'
        in executor.log_text()
    )
    response = probe.call_trigger('hexacal/executor/resume')
    assert response.success and 'resumed at posture 1' in response.message, response.message

    # Both postures of the normal mounting, then the executor waits for the operator.
    paused = watch.wait(
        lambda s: s.get('state') == 'paused' and 'device_turn_needed_rad' in s and s,
        90.0,
        'the pause for the device turn',
        *nodes,
    )
    assert paused['measured'] == '2' and paused['posture'] == '3' and paused['skipped'] == '0'
    assert float(paused['device_turn_needed_rad']) == math.pi
    assert float(paused['device_turn_rad']) == math.pi
    notice = paused['notice']
    assert notice.startswith('posture 3 of 4 needs the device turned to 180 deg (3.14159 rad)')
    assert (
        'turn the device to 180 deg about its link axis, then call hexacal/executor/resume'
        in notice
    )
    assert notice in watch.statuses[-1][1]  # the status message shows it too
    probe.spin_until(
        lambda: watch.commands and len(watch.commands[-1].points) == 1,
        10.0,
        'the hold command',
        lambda: f'{[len(c.points) for c in watch.commands]}\n{executor.log_text()}',
    )
    assert len(watch.commands) == 3  # two moves and the hold: nothing else while waiting
    assert len(postures) >= 2  # (one taken standing before the start may carry the stale turn)

    response = probe.call_trigger('hexacal/executor/resume')
    assert response.success, response.message
    assert 'setting device_turn 3.14159 rad on collector, driver' in response.message
    done = watch.wait(
        lambda s: s.get('state') in ('done', 'aborted') and s,
        90.0,
        'the plan walked to the end',
        *nodes,
    )
    assert done['state'] == 'done' and done['measured'] == '4' and done['skipped'] == '0', done
    assert done['device_turn_set'] == 'done', done
    assert watch.statuses[-1][0] == 0  # OK
    # The collector publishes the fourth posture before the executor counts it as measured.
    matched: dict[int, list[float]] = {}
    for actuators, turn in postures:
        if actuators is None:
            continue
        distances = np.max(np.abs(targets - actuators), axis=1)
        if distances.min() <= MATCH_M:
            matched.setdefault(int(np.argmin(distances)), []).append(turn)
    assert sorted(matched) == [0, 1, 2, 3], (matched, postures)
    # The normal mounting's postures were recorded before the turn, with the mounting at the start,
    # not the stale turn (a still machine may be recorded again after it, rightly turned); every
    # one of the turned postures carries pi.
    assert matched[0][0] == 0.0 and matched[1][0] == 0.0, matched
    assert all(turn == math.pi for turn in matched[2] + matched[3]), matched

    log = executor.log_text()
    assert 'WARN' in log and 'turn the device to 180 deg about its link axis' in log, log
    assert 'device_turn 3.14159 rad set on collector, driver' in log
    assert 'Traceback' not in log
    assert ros_processes.stop(executor, STOP_TIMEOUT_S) == 0, executor.log_text()

    # Walked again with the device still reversed (mounted_turn pi): the nodes are set to pi, and
    # the first posture, in the normal mounting, waits for the operator to turn it back.
    again = ExecutorWatch(probe)
    second = ros_processes.start(
        _executor(plan, nominal, 'device_turn_nodes:=[collector, driver]', mounted_turn=math.pi),
        name='executor-again',
    )
    waiting = again.wait(
        lambda s: s.get('state') == 'paused' and 'device_turn_needed_rad' in s and s,
        60.0,
        'the pause before the first posture',
        driver,
        collector,
        second,
    )
    assert waiting['posture'] == '1' and waiting['measured'] == '0', waiting
    assert float(waiting['device_turn_needed_rad']) == 0.0 and waiting['device_turn_set'] == 'done'
    assert 'needs the device turned to 0 deg' in waiting['notice'], waiting['notice']
    assert 'device_turn 3.14159 rad set on collector, driver' in second.log_text()
    assert not again.commands or all(len(c.points) == 1 for c in again.commands)  # holds, no move
    for process in (second, driver, collector):
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_text()
