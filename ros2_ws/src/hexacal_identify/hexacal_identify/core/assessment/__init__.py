"""
Judging a fit: what it determines, how well it explains its data, what it predicts.

Start at ``adequacy.assess`` (is a fit explained by the reading noise) and
``verification`` (a calibration checked on fresh postures); the fit itself is in
``core.fit``.

* ``identifiability``: rank and the named unidentifiable combinations.
* ``adequacy``: does the fit explain its residuals by the reading noise.
* ``uncertainty``: predicted pose errors from the covariance.
* ``position_error``: the position error a covariance predicts, mapped over the workspace.
* ``verification``: verification on fresh postures without ground truth.
* ``validation``: pose accuracy against a known true machine (studies, tests).
"""
