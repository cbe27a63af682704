"""
The fit: identification by least squares (eqs. 5-13) and what judges it.

Start at ``identification.identify``.

* ``residuals``: the cost functions (eqs. 7, 8, 10, 12, 13) and their Jacobians.
* ``identification``: the solve (its rounds), and the names a caller needs.
* ``solver_options``: what a solve is asked to do (``SolverOptions``).
* ``identification_result``: what it returns (``IdentificationResult``).
* ``fit_problem``: FK, residuals and Jacobian of the postures in use.
* ``row_weights``: whitening by the reading noise and robust weights.
* ``least_squares_run``: one solver run, its normal equations and covariance.
* ``weighting``: what weighs a fit (measured scatter, a noise model, none).
* ``identifiability``: rank and the named unidentifiable combinations.
* ``adequacy``: does the fit explain its residuals by the reading noise.
* ``uncertainty``: predicted pose errors from the covariance.
* ``position_error``: the position error a covariance predicts, mapped over the workspace.
* ``verification``: verification on fresh postures without ground truth.
* ``validation``: pose accuracy against a known true machine (studies, tests).
* ``baseline``: the paper-style identification, the baseline to measure against.
"""
