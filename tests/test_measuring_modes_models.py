"""
Each measuring mode with real nodes on both machine models (issue #18, Evidence).

Hexa Slide: a short plan from ``hexacal plan --measuring-mode M`` walked by the executor on the
driver in that mode, the collector recording. ``passive_actuator``: the five commanded
actuators stand at their setpoints within the reading noise, the released one where the TRUE
machine puts it (core.passive_actuator.solve_passive on the driver's true parameters from the
five setpoints), millimetres from where the nominal model predicted it. ``lvdt``: six
commanded at their setpoints, the link's extension inside the stroke at every posture and for
the driver all along. ``compliant``: the driver reports the servo forces, below the limit.
A move that would leave the LVDT stroke or carry a servo force beyond the limit is paused
before it is sent (test_executor_modes.py has the Gough-Stewart lvdt case).

Gough-Stewart (test_executor_refine.py covers compliant): ``lvdt`` and ``passive_actuator``
with the identify node, 20 postures: after the intermediate calibration at 17 postures
(``targets_model``) the link's extension, resp. the released actuator's offset from the
targets model's prediction, shrinks from millimetres to micrometres; in ``lvdt`` the
recorded bag's measured link lengths L_m make the calibration: ``hexacal calibrate`` on it
against the same postures calibrated with L in place of L_m.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import json
from pathlib import Path
import subprocess
from typing import Any

from hexacal_identify.core.architectures import architecture, KinematicParameters
from hexacal_identify.core.modes.passive_actuator import solve_passive
from hexacal_identify.core.planning.planner import Plan
import numpy as np
import pytest
from system_support import (
    fast_collector_parameters,
    node_argv,
    STOP_TIMEOUT_S,
    venv_executable,
    write_parameter_files,
)
from system_support import probe  # noqa: F401 - fixture
from test_executor import _driver, _executor, ExecutorWatch

HS, GS = 'hexa_slide', 'gough_stewart'
LINK_M = 0.75  # the driver's link (no dL) and the plan's L
NOISE_M = 1e-6  # the driver's actuator and LVDT noise: uniform +- this
STROKE_M = 5e-3  # the LVDT stroke, the driver's and the executor's default
FORCE_LIMIT_N = 500.0  # max_force_n, the driver's default (the executor's: 0.8 x)
STIFFNESS_N_PER_M = 2e4  # servo_stiffness_n_per_m, the driver's default
SHORT = 6  # postures of the Hexa Slide plans
REFINED = 20  # postures of the Gough-Stewart refinement plans
FIRST = 17  # core/walk_refine/refinement.py's first checkpoint for 42 parameters
MATCH_M = 5e-5  # a posture stands at a command's target: far below the plans' spacing


@dataclass
class Walk:
    """What a walked plan left: the plan, the models, what the probe heard, the files."""

    plan: Plan
    truth: KinematicParameters
    nominal: KinematicParameters
    nominal_path: Path
    finished: dict[str, str]
    postures: list
    commands: list
    drive: list[dict[str, str]]
    models: list[str]
    parameters: list[np.ndarray]
    bag: Path


def _parameters(path: Path) -> KinematicParameters:
    from hexacal_msgs_py.parameters_file import read_parameters_file

    loaded = read_parameters_file(path)
    return architecture(loaded.model).default_parameters().with_vector(loaded.vector)


def _ik(params: KinematicParameters, poses: np.ndarray) -> np.ndarray:
    arch = params.architecture
    return np.array(arch.legs(arch.chains(params), np.atleast_2d(poses)).actuators)


def _plan(tmp_path: Path, nominal: Path, mode: str, postures: int) -> Path:
    # Seed 0, the planner's default: not chosen to dodge anything (see the report of #18).
    out = tmp_path / f'{mode}.yaml'
    result = subprocess.run(
        [
            venv_executable('hexacal'), 'plan', '--postures', str(postures), '--candidates',
            '300', '--seed', '0', '--fixed-fraction', '0', '--measuring-mode', mode,
            '--nominal', str(nominal), '--out', str(out),
        ],
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert result.returncode == 0, result.stderr
    return out


def _walk(ros_processes, probe, tmp_path, model, mode, postures, refine=False):  # noqa: F811
    """Walk a `postures` plan of `model` in `mode` on the true machine; the run's record."""
    truth, nominal = write_parameter_files(tmp_path, model)
    plan_path = _plan(tmp_path, nominal, mode, postures)
    plan = Plan.load(plan_path)
    assert plan.measuring_mode == mode and plan.model == model, plan_path.read_text()[:500]
    probe.subscribe_status()
    probe.subscribe_postures(model=model)
    parameters = probe.subscribe_parameters()
    watch = ExecutorWatch(probe)
    started = []
    if refine:
        started.append(('identify', ros_processes.start(node_argv(
            'identify', {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out')}
        ))))
    started.append(('driver', ros_processes.start(
        _driver(truth, measuring_mode=mode, slider_noise_m=NOISE_M)
    )))
    started.append(('collector', ros_processes.start(node_argv(
        'collector',
        fast_collector_parameters(tmp_path / 'bags', bag_name=mode, parameters_file=str(nominal)),
    ))))
    for name, process in started:
        probe.wait_for_node(name, process=process)
    executor = ros_processes.start(_executor(
        plan_path, nominal, refine_targets=refine, refine_timeout_s=300.0
    ))
    nodes = [process for _, process in started] + [executor]
    models: list[str] = []

    def done(status):
        if not models or models[-1] != status.get('targets_model'):
            models.append(status.get('targets_model', ''))
        return status.get('state') in ('done', 'paused', 'aborted', 'refused') and status

    finished = watch.wait(
        done, 120.0 + 20.0 * postures, f'the {model} plan walked in {mode}', *nodes
    )
    log = executor.log_text()
    assert finished['state'] == 'done', (finished, log[-3000:])
    assert finished['measured'] == str(postures) and finished['skipped'] == '0', finished
    assert finished['measuring_mode'] == mode and 'Traceback' not in log
    drive = probe.spin_until(
        lambda: (s := _driver_statuses(probe)) and s, 10.0, "the driver's status"
    )
    for process in reversed(nodes):  # the collector closes its bag on the way out
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
    return Walk(
        plan, _parameters(truth), _parameters(nominal), nominal, finished,
        list(probe.postures), list(watch.commands), drive, models, list(parameters),
        tmp_path / 'bags' / mode,
    )


def _driver_statuses(probe) -> list[dict[str, str]]:  # noqa: F811 - the fixture
    return [values for _, _, values in probe.statuses if 'max_actuator_deviation_m' in values]


@dataclass
class Stand:
    """A measured plan posture: its index, readings, targets and released chain."""

    index: int
    posture: Any
    readings: np.ndarray  # (6,) the posture's actuator readings
    setpoints: np.ndarray  # (6,) the targets model's inverse kinematics of the planned pose
    released: int | None  # the plan's released chain (passive_actuator), else None

    @property
    def commanded(self) -> np.ndarray:
        """Return the mask of the commanded actuators (6,)."""
        mask = np.ones(6, bool)
        if self.released is not None:
            mask[self.released] = False
        return mask


def _joint_names(model: str | None) -> list[str]:
    return [f'{"leg" if model == GS else "slider"}_{i + 1}' for i in range(6)]


def _targets(walk: Walk) -> np.ndarray:
    """
    Return each plan posture's targets (K, 6): inverse kinematics on the model it walked on.

    The nominal model up to the first calibration, then the parameters identify published
    for it (the only calibration of a walk shorter than the next checkpoint, 34 postures).
    """
    targets = _ik(walk.nominal, walk.plan.poses)
    if walk.parameters:
        refined = walk.nominal.with_vector(walk.parameters[-1])
        targets[FIRST:] = _ik(refined, walk.plan.poses[FIRST:])
    return targets


def _stands(walk: Walk) -> list[Stand]:
    """
    Return each plan posture's measured posture, in plan order.

    That is the last posture whose commanded actuators read its targets within MATCH_M (a
    posture at the start stands at none: left out).

    The commands the probe heard to a plan posture (all but perhaps the first) must end
    at its targets exactly, naming the joints the plan commands there: so the targets are the
    model's of that posture, the one `targets_model` names.
    """
    names = _joint_names(walk.plan.model)
    targets = _targets(walk)
    passive = walk.plan.measuring_mode == 'passive_actuator'
    released = [names.index(r) if passive else None for r in walk.plan.released_actuators or
                [None] * len(targets)]
    masks = np.ones((len(targets), 6), bool)
    for i, chain in enumerate(released):
        if chain is not None:
            masks[i, chain] = False
    found: dict[int, Stand] = {}
    for posture in walk.postures:
        readings = np.array(posture.actuator_positions)
        near = np.where(masks, np.abs(targets - readings), 0.0).max(axis=1)
        index = int(np.argmin(near))
        if near[index] < MATCH_M:
            found[index] = Stand(index, posture, readings, targets[index], released[index])
    assert sorted(found) == list(range(len(targets))), (sorted(found), walk.postures)
    heard = set()
    for command in walk.commands:
        sent = np.full(6, np.nan)
        for name, value in zip(command.joint_names, command.points[-1].positions):
            sent[names.index(name)] = value
        with np.errstate(invalid='ignore'):
            near = np.where(masks, np.abs(targets - sent), 0.0).max(axis=1)
        index = int(np.nanargmin(np.where(np.isnan(near), np.inf, near)))
        if not near[index] < MATCH_M:
            continue  # not a move to a plan posture (the hold at the start, after a release)
        assert near[index] < 1e-7, (near[index], index, sent, targets[index])
        assert np.array_equal(~np.isnan(sent), masks[index]), (command.joint_names, index)
        heard.add(index)
    # The first commands may go out before the probe's subscription is matched (discovery
    # under load); the later ones, those on refined targets among them, are all heard.
    assert set(range(len(targets) // 2, len(targets))) <= heard, (sorted(heard), len(targets))
    return [found[i] for i in sorted(found)]


def _commanded_deviation(stands: list[Stand]) -> float:
    """Return the largest |reading - setpoint| of a commanded actuator (m)."""
    return max(np.max(np.abs(s.readings - s.setpoints)[s.commanded]) for s in stands)


def _released_on_truth(walk: Walk, stands: list[Stand]) -> np.ndarray:
    """Return where the true machine puts each released actuator: the five setpoints + link."""
    solution = solve_passive(
        walk.truth,
        np.array([s.setpoints for s in stands]),
        np.array([s.released for s in stands]),
        walk.plan.poses[[s.index for s in stands]],
        LINK_M,
    )
    solution.raise_if_failed()
    return solution.released_positions


def _check_passive(walk: Walk) -> tuple[list[Stand], np.ndarray, np.ndarray]:
    """Check the passive_actuator walk; return the stands, true error and released offset."""
    stands = _stands(walk)
    assert all(s.released is not None for s in stands)
    assert all(len(c.joint_names) == 5 for c in walk.commands)
    assert all(s['state'] == 'ok' for s in walk.drive), [s['fault'] for s in walk.drive]
    # The five commanded stand at their setpoints: the truth exactly, the readings within noise.
    assert float(walk.drive[-1]['max_actuator_deviation_m']) < 1e-9, walk.drive[-1]
    assert _commanded_deviation(stands) <= 1.5 * NOISE_M
    released = np.array([s.readings[s.released] for s in stands])
    true_error = np.abs(released - _released_on_truth(walk, stands))
    assert np.max(true_error) <= 1.5 * NOISE_M, true_error
    # The targets model predicts it at the planned pose: the offset is what the link did to the
    # released actuator because the model is not the machine.
    offset = np.array([abs(s.readings[s.released] - s.setpoints[s.released]) for s in stands])
    return stands, true_error, offset


def _extensions(walk: Walk, stands: list[Stand]) -> np.ndarray:
    """Return the measured link extension (L_m - L) at each stand (m)."""
    lengths = [s.posture.link_length for s in stands]
    assert all(length is not None for length in lengths), lengths
    return np.array(lengths) - LINK_M


def _check_lvdt(walk: Walk) -> tuple[list[Stand], np.ndarray]:
    """Check the lvdt walk: six at their setpoints, the link inside its stroke; extensions."""
    stands = _stands(walk)
    assert all(s.released is None for s in stands)
    assert all(len(c.joint_names) == 6 for c in walk.commands)
    assert all(s['state'] == 'ok' for s in walk.drive), [s['fault'] for s in walk.drive]
    assert float(walk.drive[-1]['max_actuator_deviation_m']) < 1e-9, walk.drive[-1]
    assert _commanded_deviation(stands) <= 1.5 * NOISE_M
    extensions = _extensions(walk, stands)
    assert np.max(np.abs(extensions)) < STROKE_M, extensions
    # All along every move (the driver's truth), not only at the postures.
    largest = max(float(s['max_link_extension_m']) for s in walk.drive)
    assert largest < STROKE_M, largest
    assert largest >= np.max(np.abs(extensions)) - 1.5 * NOISE_M
    return stands, extensions


@pytest.mark.slow
@pytest.mark.parametrize('mode', ['passive_actuator', 'lvdt', 'compliant'])
def test_a_hexa_slide_plan_walks_in_each_measuring_mode(
    ros_processes, tmp_path, probe, mode  # noqa: F811 - fixture
):
    walk = _walk(ros_processes, probe, tmp_path, HS, mode, SHORT)
    assert walk.models == ['nominal'], walk.models
    deviation = float(walk.drive[-1]['max_actuator_deviation_m'])
    if mode == 'passive_actuator':
        stands, true_error, offset = _check_passive(walk)
        # The check can fail: the nominal model's prediction misses the truth by far more.
        assert np.max(offset) > 100 * 1.5 * NOISE_M, offset
        figure = (
            f'released {[walk.plan.released_actuators[s.index] for s in stands]}; released '
            f'actuator from the truth {np.max(true_error) * 1e6:.3g} um (largest), from the '
            f'nominal prediction {np.max(offset) * 1e6:.4g} um; commanded from their setpoints '
            f'{_commanded_deviation(stands) * 1e6:.3g} um (readings), {deviation * 1e6:.3g} um '
            '(truth)'
        )
    elif mode == 'lvdt':
        stands, extensions = _check_lvdt(walk)
        figure = (
            f'link extension at the postures up to {np.max(np.abs(extensions)) * 1e6:.4g} um, '
            f'all along {float(walk.drive[-1]["max_link_extension_m"]) * 1e6:.4g} um (stroke '
            f'+-{STROKE_M * 1e3:g} mm)'
        )
    else:
        assert all(len(c.joint_names) == 6 for c in walk.commands)
        assert all(s['state'] == 'ok' for s in walk.drive), [s['fault'] for s in walk.drive]
        force = max(float(s['max_force_n']) for s in walk.drive)
        # Reported: the strain of a nominal model's targets (millimetres) x the stiffness.
        assert deviation > 1e-4 and STIFFNESS_N_PER_M * deviation <= force * (1 + 1e-9)
        assert force < FORCE_LIMIT_N
        figure = f'largest servo force {force:.4g} N (limit {FORCE_LIMIT_N:g} N)'
    print(
        f'\n{mode}, Hexa Slide, {SHORT} postures in {walk.finished["elapsed_s"]} s: {figure}; '
        f'largest deviation of a commanded actuator at rest (truth) {deviation * 1e6:.4g} um'
    )


def _refined_walk(ros_processes, probe, tmp_path, mode) -> Walk:  # noqa: F811 - fixture
    walk = _walk(ros_processes, probe, tmp_path, GS, mode, REFINED, refine=True)
    assert walk.models[0] == 'nominal', walk.models
    assert walk.finished['targets_model'] == f'calibration after {FIRST} postures'
    assert walk.parameters, 'no intermediate calibration was published'
    return walk


def _split(values: np.ndarray, stands: list[Stand]) -> tuple[np.ndarray, np.ndarray]:
    """Return |values| on nominal targets (postures 1..17) and on refined ones (18..)."""
    refined = np.array([s.index >= FIRST for s in stands])
    return np.abs(values[~refined]), np.abs(values[refined])


@pytest.mark.slow
def test_refined_targets_shrink_the_lvdt_extension_and_the_bag_calibrates_with_l_m(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    walk = _refined_walk(ros_processes, probe, tmp_path, 'lvdt')
    stands, extensions = _check_lvdt(walk)
    before, after = _split(extensions, stands)
    assert max(after) * 10.0 < max(before), (before, after)
    with_lm, ignored = _calibrations(walk, tmp_path)
    # With L_m micrometres (as test_calibrate_lvdt_bag.py offline); with L the millimetres of
    # extension at the first 17 postures become model error.
    assert with_lm < 20e-6 and with_lm * 5.0 < ignored, (with_lm, ignored)
    print(
        f'\nlvdt, Gough-Stewart, {REFINED} postures in {walk.finished["elapsed_s"]} s: largest '
        f'link extension on nominal targets {max(before) * 1e6:.4g} um, on targets from the '
        f'calibration after {FIRST} postures {max(after) * 1e6:.4g} um; hexacal calibrate on '
        f'the bag: mean pose error {with_lm * 1e6:.3g} um with the measured L_m, '
        f'{ignored * 1e6:.4g} um with L in their place'
    )


def _calibrations(walk: Walk, tmp_path: Path) -> tuple[float, float]:
    """Return the mean pose errors of the bag calibrated with L_m (hexacal calibrate) and L."""
    from hexacal_identify.core.assessment.validation import pose_errors, validation_poses
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
    from hexacal_identify.calibration_steps.calibration_run import calibrate

    output = tmp_path / 'calibrated.yaml'
    completed = subprocess.run(
        [
            venv_executable('hexacal'), 'calibrate', str(walk.bag), '--nominal',
            str(walk.nominal_path), '--output', str(output), '--json',
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert completed.returncode == 0, completed.stderr
    result = json.loads(completed.stdout)
    recorded = postures_from_bag(walk.bag)
    assert result['measuring_mode'] == 'lvdt'
    assert result['bag']['postures_with_link_length'] == len(recorded.postures) >= REFINED
    poses = validation_poses(walk.truth, 50, seed=0)

    def error(params: KinematicParameters) -> float:
        return pose_errors(walk.truth, params, poses).summary()['position_mean_m']

    without = [replace(p, link_length=None) for p in recorded.postures]
    ignored = calibrate(walk.nominal, without, link_length=LINK_M).parameters
    return error(_parameters(output)), error(ignored)


@pytest.mark.slow
def test_refined_targets_shrink_the_released_actuators_offset(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    walk = _refined_walk(ros_processes, probe, tmp_path, 'passive_actuator')
    stands, true_error, offset = _check_passive(walk)
    before, after = _split(offset, stands)
    assert max(after) * 10.0 < max(before), (before, after)
    print(
        f'\npassive_actuator, Gough-Stewart, {REFINED} postures in '
        f'{walk.finished["elapsed_s"]} s: released actuator from the targets model\'s '
        f'prediction on nominal targets up to {max(before) * 1e6:.4g} um, on targets from the '
        f'calibration after {FIRST} postures up to {max(after) * 1e6:.4g} um; from the truth '
        f'{np.max(true_error) * 1e6:.3g} um; commanded from their setpoints '
        f'{_commanded_deviation(stands) * 1e6:.3g} um'
    )


def _crossing_plan(tmp_path: Path, mode: str) -> Path:
    """
    Return two Hexa Slide sphere postures: the driver's start, then 0.25 m aside.

    A one-point move between them leaves the sphere by millimetres on the way (the Hexa
    Slide's joint-space interpolation: more than Gough-Stewart's, so no first move away from
    the start, which would cross the limits already).
    """
    poses = np.array(
        [[x, 0.0, -np.sqrt(LINK_M**2 - x**2), 0.0, 0.0, 0.0] for x in (0.0, 0.25)]
    )
    path = tmp_path / f'crossing-{mode}.yaml'
    Plan(f'crossing-{mode}', LINK_M, poses, ['sphere'] * 2, model=HS, measuring_mode=mode).save(
        path
    )
    return path


@pytest.mark.slow
@pytest.mark.parametrize(
    ('mode', 'limits', 'notice'),
    [
        ('lvdt', {'lvdt_stroke_m': 2e-3, 'lvdt_margin_m': 5e-4},
         'beyond the LVDT stroke +-2 mm less the 0.5 mm margin'),
        ('compliant', {'max_force_n': 50.0}, 'beyond max_force_n'),
    ],
)
def test_a_hexa_slide_move_that_would_cross_a_limit_is_paused_before_it_is_sent(
    ros_processes, tmp_path, probe, mode, limits, notice  # noqa: F811 - fixture
):
    # As test_executor_modes.py's Gough-Stewart lvdt case: the true machine is the nominal one,
    # so the prediction is the truth and the driver's peaks show what was sent. Joint-space
    # interpolation (path_step_m 0) from posture 1 to 2 strains the link by millimetres.
    _, nominal = write_parameter_files(tmp_path, HS)
    plan_path = _crossing_plan(tmp_path, mode)
    probe.subscribe_status()
    watch = ExecutorWatch(probe)
    driver = ros_processes.start(
        _driver(nominal, measuring_mode=mode, slider_noise_m=NOISE_M, **{
            key: value for key, value in limits.items() if key == 'lvdt_stroke_m'
        })
    )
    probe.wait_for_node('driver', process=driver)
    executor = ros_processes.start(
        _executor(plan_path, nominal, path_step_m=0.0, wait_for_posture=False, **limits)
    )
    nodes = (driver, executor)
    paused = watch.wait(
        lambda s: s.get('state') in ('paused', 'done') and s, 90.0, 'the guard pausing', *nodes
    )
    assert paused['state'] == 'paused' and paused['measured'] == '1', paused
    assert paused['measuring_mode'] == mode
    assert paused['notice'].startswith('posture 2 of 2: the move was not sent: '), paused
    assert notice in paused['notice'], paused['notice']
    assert watch.statuses[-1][0] == 1  # WARN
    probe.spin_for(2.0)  # whatever was published before the pause has arrived by now
    assert len(watch.commands) <= 2, watch.commands  # the move to posture 1, perhaps a hold
    drive = probe.spin_until(
        lambda: (s := _driver_statuses(probe)) and s[-1], 10.0, "the driver's status"
    )
    assert drive['state'] == 'ok', drive
    if mode == 'lvdt':
        peak, limit = float(drive['max_link_extension_m']), 2e-3 - 5e-4
    else:
        peak, limit = float(drive['max_force_n']), limits['max_force_n']
    assert peak < limit, drive
    for process in nodes:
        assert ros_processes.stop(process, STOP_TIMEOUT_S) == 0, process.log_path.read_text()
    print(f'\n{mode} guard, Hexa Slide: driver peak {peak:.4g} (SI) < {limit:g}; {paused["notice"]}')
