"""Planned files on the driver's machines: model refusals, reach, the executor's stroke."""

from hexacal_driver.plan import check_reachable, load_plan, PlanError, resolve_plan, save_plan
from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.model import nominal_set, table1_parameters
from hexacal_identify.core.planning.planner import plan_postures
import numpy as np
import pytest

NOMINAL = table1_parameters()
GS = 'gough_stewart'


def test_a_gough_stewart_plan_names_its_model_and_the_driver_walks_only_that_machine(tmp_path):
    planning = plan_postures(nominal_set(2, model=GS), 16, n_candidates=500, seed=7)
    path = planning.plan.save(tmp_path / 'gs_plan.yaml')
    driver_plan = load_plan(path)
    assert driver_plan.model == GS and driver_plan.mount == 'hanging'
    np.testing.assert_array_equal(driver_plan.poses, planning.plan.poses)
    truth = default_parameters(GS)
    legs = check_reachable(driver_plan, truth)  # within the legs' stroke of the GS workspace
    assert legs.min() >= 0.0 and legs.max() <= 0.5
    assert resolve_plan(str(path), truth, 0, 0).model == GS
    with pytest.raises(PlanError, match='made for a gough_stewart .* machine is a hexa_slide'):
        resolve_plan(str(path), NOMINAL, 0, 0)
    # A generated Gough-Stewart plan is drawn in its workspace and written with its model.
    generated = resolve_plan('mixed', truth, 12, 3)
    save_plan(tmp_path / 'generated.yaml', generated)
    assert '  model: gough_stewart\n' in (tmp_path / 'generated.yaml').read_text()
    reloaded = load_plan(tmp_path / 'generated.yaml')
    assert reloaded.model == GS and reloaded.kinds == generated.kinds
    np.testing.assert_array_equal(reloaded.poses, generated.poses)
    # A Hexa Slide plan (no model key) is not walked by the hexapod.
    hexa = tmp_path / 'hexa.yaml'
    save_plan(hexa, resolve_plan('random', NOMINAL, 5, 0))
    assert 'model' not in hexa.read_text()
    with pytest.raises(PlanError, match='made for a hexa_slide'):
        resolve_plan(str(hexa), truth, 0, 0)


@pytest.mark.parametrize('model', [None, GS])
def test_a_planned_file_is_what_the_executor_commands_within_the_commanded_drivers_stroke(
    tmp_path, model
):
    from hexacal_driver.plan import machine_workspace
    from hexacal_identify.core.planning.plan_check import check_plan, default_stroke
    from hexacal_identify.core.machine.kinematics import inverse_kinematics
    from hexacal_identify.core.planning.planner import Plan

    nominal = nominal_set(2, model=model)
    planning = plan_postures(nominal, 16, n_candidates=500, cost='sphere-fixed', seed=7)
    plan = Plan.load(planning.plan.save(tmp_path / 'plan.yaml'))  # what the executor reads
    driver_plan = load_plan(tmp_path / 'plan.yaml')  # what the plan-walking driver reads
    np.testing.assert_array_equal(plan.poses, driver_plan.poses)
    # Every target and every path between postures (along the link sphere) can be commanded.
    targets = check_plan(
        nominal,
        plan.poses,
        plan.kinds,
        default_stroke(nominal),
        plan.link_length,
        plan.mount,
        path_step_m=0.02,
    )
    np.testing.assert_array_equal(targets, inverse_kinematics(nominal, plan.poses))
    # The stroke the executor checks is the one the commanded driver enforces.
    truth = default_parameters(model)
    assert default_stroke(nominal) == tuple(
        machine_workspace(truth, plan.link_length).actuator_stroke_m
    )
