"""
The measuring modes: how the platform is held on the link's sphere.

* ``passive_actuator``: five commanded chains plus the link (the paper's section 4).
* ``released_actuator``: which actuator is released at each posture.
* ``release_moves``, ``release_rehearsal``, ``release_plan``: the moves between
  postures, rehearsed on machines unlike the nominal, and the release per move.
* ``link_load``: the measuring link's load with each actuator released, from the weights.
* ``lvdt``: the LVDT link's predicted extension.
* ``compliant``: where equally compliant drives put the platform.
"""
