"""
Walking a plan on the machine through its trajectory controller (the executor's core).

Start at ``execution.PlanExecution`` (the state machine).  What the walk does with
the measuring device is in ``core.walk_device``; targets refined from a first
calibration in ``core.walk_refine``.

* ``settings``: the walk's states, phases, settings and outcomes.
* ``arrival``: when a commanded posture is reached; fixed-position corrections; timeouts.
* ``standing``: where the machine stands; a move blended from the drive's setpoints.
* ``release_choice``: which chain is released, and when the walk asks the drive to swap.
* ``drive_calls``: what the executor asks of the drive (release calls, its mode, trajectories).
* ``progress``: the walk's status fields, ETA and summary.
* ``messages``: what the executor hears and says.
* ``mode_driver``: how the executor drives a plan's measuring mode.
* ``guard``: predict a move on the model before it is sent.
* ``platform_paths``: platform paths and actuator commands along the link's sphere.
"""
