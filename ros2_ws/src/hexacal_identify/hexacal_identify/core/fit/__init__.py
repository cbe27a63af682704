"""
The fit: identification by least squares (eqs. 5-13) and what judges it.

Start at ``identification.identify``.

* ``residuals``: the cost functions (eqs. 7, 8, 10, 12, 13) and their Jacobians.
* ``identification``: the solver and its result.
* ``weighting``: what weighs a fit (measured scatter, a noise model, none).
* ``identifiability``: rank and the named unidentifiable combinations.
* ``adequacy``: does the fit explain its residuals by the reading noise.
* ``uncertainty``: predicted pose errors from the covariance.
* ``verification``: verification on fresh postures without ground truth.
* ``validation``: pose accuracy against a known true machine (studies, tests).
* ``baseline``: the paper-style identification, the baseline to measure against.
"""
