"""
Targets refined from a first calibration during a walk (ROS-free).

Start at ``refinement`` (the schedule, shared by the measuring-mode study and the
executor); ``refined_targets`` is the executor's side of it.

* ``refinement``: when to re-calibrate during a walk, and the re-targeted postures.
* ``refined_targets``: the executor's targets refined from a first calibration.
* ``refine_answer``: which calibration is the executor's own (the calibrate answer's file).
"""
