"""
The fit: identification by least squares (eqs. 5-13).

Start at ``identification.identify``; what judges a fit is in ``core.assessment``.

* ``residuals``: the cost functions (eqs. 7, 8, 10, 12, 13) and their Jacobians.
* ``identification``: the solve (its rounds), and the names a caller needs.
* ``solver_options``: what a solve is asked to do (``SolverOptions``).
* ``identification_result``: what it returns (``IdentificationResult``).
* ``fit_problem``: FK, residuals and Jacobian of the postures in use.
* ``row_weights``: whitening by the reading noise and robust weights.
* ``least_squares_run``: one solver run, its normal equations and covariance.
* ``weighting``: what weighs a fit (measured scatter, a noise model, none).
* ``compliance``: axial compliances identified with the geometry.
* ``statics``: loads of the chains and the link from the weights, per measuring mode.
* ``baseline``: the paper-style identification, the baseline to measure against.
"""
