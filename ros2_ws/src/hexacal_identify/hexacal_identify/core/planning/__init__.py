"""
Posture design: the K measuring postures that best determine the model.

Start at ``planner``.

* ``planner``: plan postures for a measuring mode.
* ``candidate_set``: the candidates' identification-Jacobian rows.
* ``selection``: greedy and exchange selection of a design.
* ``observability``: the observability indices of a design.
* ``posture_limits``: candidates within the limits every planned posture respects.
* ``robust_postures``: postures six stiff drives can hold on machines unlike the nominal.
* ``measuring_plan``: what a plan adds for its measuring mode.
* ``plan_check``: checking a plan before anything moves.
"""
