"""Named errors of the calibration core: each says what is wrong and with what."""

from __future__ import annotations

from typing import Iterable


class CalibrationError(Exception):
    """Base class of every error the core raises on bad input or a failed solve."""

    reason = 'error'


class InvalidMeasurementError(CalibrationError, ValueError):
    """A reading is NaN/inf, out of range, or arrays have inconsistent shapes."""

    reason = 'invalid-measurement'

    def __init__(self, message: str, indices: Iterable[int] = ()):
        super().__init__(message)
        self.indices = list(indices)


class UnreachablePoseError(CalibrationError, ValueError):
    """Inverse kinematics has no real solution (a leg cannot reach its joint)."""

    reason = 'unreachable-pose'

    def __init__(self, message: str, indices: Iterable[int] = ()):
        super().__init__(message)
        self.indices = list(indices)


class ForwardKinematicsError(CalibrationError):
    """Forward kinematics did not converge, or converged to another branch."""

    reason = 'forward-kinematics-failed'

    def __init__(self, message: str, indices: Iterable[int] = ()):
        super().__init__(message)
        self.indices = list(indices)


class TooFewPosturesError(CalibrationError, ValueError):
    """Fewer residuals than parameters to identify."""

    reason = 'too-few-postures'


class RankDeficientError(CalibrationError):
    """The identification Jacobian does not determine every requested parameter."""

    reason = 'rank-deficient'

    def __init__(self, message: str, report=None):
        super().__init__(message)
        self.report = report
