"""The executor drives the measuring modes on the real driver (issue #18; real nodes, processes).

passive_actuator: a small Gough-Stewart plan from `hexacal plan --measuring-mode
passive_actuator` walked on the driver in that mode: each posture's actuator released at rest
through hexacal/release/<joint>, the five others commanded; every posture is measured, the drive
never faults and the commanded actuators stand at their setpoints.
"""

from __future__ import annotations

from pathlib import Path

from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.planning.planner import Plan
from hexacal_msgs_py.parameters_file import save_parameters
import numpy as np
import pytest
from system_support import hexacal_plan, STOP_TIMEOUT_S, write_parameter_files
from system_support import probe  # noqa: F401 - fixture
from test_executor import _driver, _executor, _machine_and_collector, ExecutorWatch

GS = 'gough_stewart'
POSTURES = 6


def _passive_plan(tmp_path: Path, nominal: Path, seed: int = 1) -> Path:
    # Seed 1: with seed 0 the planner's release of posture 4 jams the passive system at the
    # start of its move (test_a_drive_that_jams_pauses_the_plan_with_the_drives_fault).
    return hexacal_plan(
        tmp_path / f'passive-{seed}.yaml', nominal, '--postures', POSTURES, '--candidates', 200,
        '--seed', seed, '--fixed-fraction', 0, '--measuring-mode', 'passive_actuator',
    )


def _worst_released(plan_path: Path, nominal: Path) -> Path:
    """Rewrite the plan to release, after its first posture, the worst-conditioned actuator."""
    from hexacal_identify.core.modes.passive_actuator import release_conditions
    from hexacal_identify.calibration_steps.machine_files import load_machine

    plan = Plan.load(plan_path)
    params = load_machine(nominal)
    conditions = release_conditions(params, plan.poses, plan.link_length)
    worst = np.argmax(np.where(np.isfinite(conditions), conditions, -np.inf), axis=1)
    names = params.layout.actuator_names
    plan.released_actuators = plan.released_actuators[:1] + tuple(
        names[int(chain)] for chain in worst[1:]
    )
    return plan.save(plan_path.with_name('worst-released.yaml'))


def _driver_statuses(probe) -> list[dict[str, str]]:  # noqa: F811 - the fixture
    return [values for _, _, values in probe.statuses if 'max_actuator_deviation_m' in values]


@pytest.mark.slow
def test_a_passive_actuator_plan_releases_one_joint_per_posture_and_commands_five(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    truth, nominal = write_parameter_files(tmp_path, GS)
    plan_path = _passive_plan(tmp_path, nominal)
    plan = Plan.load(plan_path)
    assert plan.measuring_mode == 'passive_actuator' and all(plan.released_actuators)
    probe.subscribe_status()
    watch = ExecutorWatch(probe)
    driver, collector = _machine_and_collector(
        ros_processes, probe, tmp_path, truth, nominal, {'measuring_mode': 'passive_actuator'},
        bag_name='passive',
    )
    executor = ros_processes.start(_executor(plan_path, nominal))
    nodes = (driver, collector, executor)
    released_seen: set[str] = set()

    def done(status):
        released_seen.add(status.get('released_joint', ''))
        return status.get('state') in ('done', 'paused', 'aborted') and status

    finished = watch.wait(done, 60.0 + 15.0 * POSTURES, 'the passive plan walked', *nodes)
    assert finished['state'] == 'done', (finished, executor.log_text()[-3000:])
    assert finished['measured'] == str(POSTURES) and finished['skipped'] == '0', finished
    assert finished['measuring_mode'] == 'passive_actuator'
    assert released_seen - {''} <= set(plan.released_actuators)
    assert plan.released_actuators[-1] in released_seen
    assert finished['released_joint'] == ''  # done: the last one locked again, all six held
    # Every command names five joints, never the released one at the time.
    assert watch.commands and all(len(c.joint_names) == 5 for c in watch.commands)
    drive = probe.spin_until(
        lambda: (s := _driver_statuses(probe)) and s[-1], 10.0, "the driver's status"
    )
    statuses = _driver_statuses(probe)
    assert all(s['state'] == 'ok' for s in statuses), [s['fault'] for s in statuses]
    deviation = float(drive['max_actuator_deviation_m'])
    # The five commanded stand at their setpoints: the link moves only the released one.
    assert deviation < 1e-6, drive
    log = executor.log_text()
    assert 'measuring_mode passive_actuator (plan)' in log and 'Traceback' not in log
    for process in (executor, collector, driver):
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
    print(
        f'\npassive_actuator, Gough-Stewart, {POSTURES} postures in {finished["elapsed_s"]} s: '
        f'largest commanded actuator deviation from its setpoint at rest {deviation * 1e6:.3g} '
        f'um; releases {sorted(released_seen - {""})}'
    )


def _lvdt_crossing_plan(tmp_path: Path) -> Path:
    """Two sphere postures 0.5 m apart: a one-point move between them leaves the sphere."""
    import math

    import numpy as np

    length = 0.75
    poses = np.array(
        [[x, 0.0, -math.sqrt(length**2 - x**2), 0.0, 0.0, 0.0] for x in (0.25, -0.25)]
    )
    path = tmp_path / 'lvdt-crossing.yaml'
    Plan('lvdt-crossing', length, poses, ['sphere'] * 2, model=GS, measuring_mode='lvdt').save(
        path
    )
    return path


@pytest.mark.slow
def test_a_move_that_would_cross_the_lvdt_stroke_is_paused_before_it_is_sent(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    # The driver's true machine is the nominal one: the prediction is the truth, so the
    # driver's peak extension shows what was sent. Joint-space interpolation (path_step_m 0)
    # from posture 1 to 2 pulls the platform 2.95 mm inside the sphere: beyond +-2 mm less 0.5.
    _, nominal = write_parameter_files(tmp_path, GS)
    plan_path = _lvdt_crossing_plan(tmp_path)
    probe.subscribe_status()
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(
        _driver(nominal, measuring_mode='lvdt', lvdt_stroke_m=2e-3, slider_noise_m=1e-6)
    )
    probe.wait_for_node('driver', process=driver)
    executor = ros_processes.start(
        _executor(
            plan_path, nominal, path_step_m=0.0, wait_for_posture=False, lvdt_stroke_m=2e-3,
            lvdt_margin_m=5e-4,
        )
    )
    nodes = (driver, executor)
    paused = watch.wait(
        lambda s: s.get('state') in ('paused', 'done') and s, 90.0, 'the guard pausing', *nodes
    )
    assert paused['state'] == 'paused' and paused['measured'] == '1', paused
    assert paused['measuring_mode'] == 'lvdt'
    notice = paused['notice']
    assert notice.startswith('posture 2 of 2: the move was not sent: the link would be ')
    assert 'beyond the LVDT stroke +-2 mm less the 0.5 mm margin' in notice, notice
    assert watch.statuses[-1][0] == 1  # WARN
    assert all(  # path_step_m 0
        _straight_in_joint_space([p.positions for p in c.points]) for c in watch.commands
    )
    # Whatever was published before the pause has arrived by now (late under load), and the
    # crossing move would be a third command: the move to posture 1, perhaps the hold.
    probe.spin_for(2.0)
    assert len(watch.commands) <= 2, watch.commands
    drive = probe.spin_until(
        lambda: (s := _driver_statuses(probe)) and s[-1], 10.0, "the driver's status"
    )
    assert drive['state'] == 'ok', drive
    extension = float(drive['max_link_extension_m'])
    assert extension < 1.5e-3, drive
    for process in nodes:
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
    print(
        "\nlvdt guard: paused before posture 2; the driver's largest link extension "
        f'{extension * 1e6:.1f} um (stroke +-2 mm); {notice}'
    )


def _straight_in_joint_space(points: np.ndarray) -> bool:
    """Return True when a command's points lie on one line in joint space (an eased move)."""
    points = np.asarray(points, dtype=float)
    along = points[-1] - points[0]
    if len(points) < 3 or not np.any(along):
        return True
    offsets = points - points[0]
    fractions = offsets @ along / (along @ along)
    return bool(np.max(np.abs(offsets - fractions[:, None] * along)) < 1e-9)


@pytest.mark.slow
def test_a_drive_that_jams_pauses_the_plan_with_the_drives_fault(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    # The planner's postures with, after the first, the worst-conditioned actuator released at
    # each (the planner rehearses its releases so that they do not jam), on a machine further
    # from its nominal (set 3, ~5 mm) than the planner's rehearsal assumes: on the true machine
    # the five commanded plus the link jam on the way (the prediction on the nominal model, from
    # the planned pose, misses it): the drive faults and holds, and the executor pauses with the
    # drive's fault and what to do, sending nothing more.
    truth, nominal = write_parameter_files(tmp_path, GS)
    save_parameters(nominal, nominal_set(3, seed=0, model=GS).vector, model=GS)
    plan_path = _worst_released(_passive_plan(tmp_path, nominal, seed=0), nominal)
    probe.subscribe_status()
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(_driver(truth, measuring_mode='passive_actuator'))
    probe.wait_for_node('driver', process=driver)
    # Walked as planned: rehearsed again at rest, the executor would release other chains.
    executor = ros_processes.start(
        _executor(plan_path, nominal, wait_for_posture=False, check_releases_at_rest=False)
    )
    nodes = (driver, executor)
    paused = watch.wait(
        lambda s: s.get('state') in ('paused', 'done') and s, 90.0, 'the pause', *nodes
    )
    assert paused['state'] == 'paused' and int(paused['measured']) < POSTURES, paused
    notice = paused['notice']
    assert notice.startswith(
        'the drive faulted: the five commanded actuators and the link jam (released '
        f'{paused["released_joint"]}'
    ), notice
    assert 'reset the drive (hexacal/driver/reset) and resume' in notice
    assert watch.statuses[-1][0] == 1  # WARN
    probe.spin_for(2.0)  # what was published before the pause has arrived
    sent = len(watch.commands)
    probe.spin_for(1.0)
    assert len(watch.commands) == sent  # the drive holds itself: nothing more is sent
    for process in nodes:
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
