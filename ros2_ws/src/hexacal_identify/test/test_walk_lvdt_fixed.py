"""
The executor's fixed-position postures in the lvdt mode (#18): aim at a zero reading only.

All six actuators are commanded and the telescopic link follows: the corrections (driven by the
inclinometer, core/walk/execution.py) bring the link to the vertical through O, the LVDT extension
is left where the true machine puts it (nothing corrects it), and the guard still predicts every
correction. The posture then lies where eq. 10 puts it with the measured length, (0, 0, -L_m).
"""

from hexacal_identify.core import sample_poses, table1_parameters
from hexacal_identify.core.fit.residuals import ChannelSigma, CostFunction
from hexacal_identify.core.machine.device import DeviceDefects, DeviceModel
from hexacal_identify.core.machine.kinematics import forward_kinematics
from hexacal_identify.core.machine.measurements import FIXED, Measurements
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.core.planning.plan_check import default_stroke, plan_targets
from hexacal_identify.core.walk.execution import PlanExecution
from hexacal_identify.core.walk.guard import GuardSettings, move_guard
from hexacal_identify.core.walk.settings import ExecutionSettings
from hexacal_msgs_py.measuring_modes import MeasuringMode
import numpy as np

L = 0.75
TRUE = table1_parameters()
NOMINAL = nominal_set(2, exact=TRUE)  # millimetres off: the link tilts and extends on TRUE
STROKE = default_stroke(NOMINAL)
POSES = sample_poses(TRUE, 3, np.random.default_rng(3), FIXED)
DEVICE = DeviceModel(L)


def _walk():
    """Return the execution, the guard's calls and the true poses where postures were taken."""
    targets, problems = plan_targets(NOMINAL, POSES, [FIXED] * 3, STROKE, L)
    assert not problems
    asked = []
    guard = move_guard(NOMINAL, MeasuringMode.LVDT, L, STROKE, GuardSettings())

    def counted(current, start, points, released):
        asked.append(points)
        return guard(current, start, points, released)

    settings = ExecutionSettings(
        settle_s=0.2, wait_for_posture=False, path_step_m=0.0, inclinometer_settle_s=0.0
    )
    execution = PlanExecution(
        NOMINAL, POSES, [FIXED] * 3, targets, settings, STROKE, L, guard=counted
    )
    return execution, asked


def test_corrections_aim_at_a_zero_reading_and_leave_the_lvdt_free():
    execution, asked = _walk()
    setpoints = execution.targets[0]
    execution.on_actuators(0.0, setpoints)
    commands = execution.start(0.0)
    pose = POSES[0]
    taken, extensions = [], []
    for now in np.arange(0.02, 60.0, 0.02):
        if commands:
            setpoints = commands[-1].positions  # the six reach their setpoints exactly
            near = POSES[commands[-1].posture]  # the planned pose: the true one is near it
            solved = forward_kinematics(TRUE, setpoints[None], near[None])
            assert solved.converged[0]
            pose = solved.poses[0]
        alpha, beta = DEVICE.readings(pose[None, :3])
        execution.on_actuators(now, setpoints)
        execution.on_inclinometer(now, float(alpha[0]), float(beta[0]))
        measured = execution.measured
        commands = execution.step(now)
        if execution.measured > measured:
            taken.append(pose.copy())
            extensions.append(float(np.linalg.norm(pose[:3])) - L)
        if execution.state.value == 'done':
            break
    assert execution.measured == 3 and execution.total_corrections >= 3
    # Each correction was predicted by the guard (LVDT stroke) before it was sent.
    assert len(asked) == 3 + execution.total_corrections
    taken = np.array(taken)
    alpha, beta = DEVICE.readings(taken[:, :3])
    assert np.max(np.abs([alpha, beta])) <= ExecutionSettings().fixed_tolerance_rad
    # The extension was not corrected: hundreds of um, the model error, inside the stroke.
    assert np.max(np.abs(extensions)) > 1e-4 and np.max(np.abs(extensions)) < 4e-3
    # Eq. 10 with the LVDT's length puts each posture where it stood; with -L it would not.
    lengths = np.linalg.norm(taken[:, :3], axis=1)
    readings = Measurements(
        np.zeros((3, 6)), np.column_stack([alpha, beta]), taken[:, 5], [FIXED] * 3, lengths
    )
    cost = CostFunction('fixed', readings, DEVICE, ChannelSigma())
    fixed, _ = cost.fixed_positions(DeviceDefects(), np.arange(3))
    tolerance = ExecutionSettings().fixed_tolerance_rad * L * 1.5
    assert np.max(np.linalg.norm(fixed - taken[:, :3], axis=1)) < tolerance
    assert np.max(np.abs(lengths - L)) > 10 * tolerance  # (0, 0, -L) is that far off
