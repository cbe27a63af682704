"""
Walking a plan on the machine through its trajectory controller (the executor's core).

Start at ``execution.PlanExecution`` (the state machine).

* ``settings``: the walk's states, settings and outcomes.
* ``messages``: what the executor hears and says.
* ``mode_driver``: how the executor drives a plan's measuring mode.
* ``guard``: predict a move on the model before it is sent.
* ``platform_paths``: platform paths and actuator commands along the link's sphere.
* ``inclinometer``: settled inclinometer readings for fixed-position corrections.
* ``refinement``, ``refined_targets``, ``refine_answer``: targets refined from a first
  calibration, and which calibration is the executor's own.
* ``turns``: turning the device about its link axis during a plan.
"""
