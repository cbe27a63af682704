"""
What each node decides, without ROS: one module per node, named after it.

* ``executor_session``: the executor node (besides the walk, ``core.walk``).
* ``kinematics_session``: the kinematics node (the calibrated model at work).
* ``collector_session``: the collector node (counters, stopped streams, status).

The identify node's session is ``hexacal_identify.session``.
"""
