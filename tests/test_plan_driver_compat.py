"""A plan written by ``hexacal plan`` is what the driver's plan-file mode executes (crosses two packages)."""
import numpy as np

from hexacal_driver.plan import check_reachable, load_plan
from hexacal_identify.core.model import table1_parameters
from hexacal_identify.core.planning import plan_postures

NOMINAL = table1_parameters()


def test_the_driver_reads_a_planned_file_exactly(tmp_path):
    planning = plan_postures(NOMINAL, 16, n_candidates=500, cost="sphere-fixed", seed=7)
    path = planning.plan.save(tmp_path / "plan.yaml")
    driver_plan = load_plan(path)
    assert driver_plan.name == planning.plan.name
    np.testing.assert_array_equal(driver_plan.poses, planning.plan.poses)
    assert list(driver_plan.kinds) == planning.plan.kinds.tolist()
    check_reachable(driver_plan, NOMINAL)  # raises naming the posture if the driver could not go there
