"""The measuring device: a link with U joints, a biaxial inclinometer and a rotary sensor.

Eq. 4 as printed gives ``z = +L cos(alpha) cos(beta)``, but the text fixes the
inclinometer-zero position at ``[0, 0, -L]`` and the platform hangs below the
base joint O; the sign of z used here is therefore negative:

    p = (L cos(alpha) sin(beta), -L sin(alpha), -L cos(alpha) cos(beta))

alpha is the inclinometer angle about X, beta about Y.  The rotary sensor sits
on the platform and reads phi, the rotation about the platform's local z axis
(section 3.1), i.e. the third Euler angle of eq. 2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_LINK_LENGTH_M = 0.750


@dataclass(frozen=True)
class DeviceModel:
    """Geometry of the measuring link as the identification assumes it."""

    link_length: float = DEFAULT_LINK_LENGTH_M

    def __post_init__(self) -> None:
        if not (np.isfinite(self.link_length) and self.link_length > 0):
            raise ValueError(f"link_length must be a positive length in m, got {self.link_length}")


def measured_position(alpha: np.ndarray, beta: np.ndarray, link_length: float | np.ndarray) -> np.ndarray:
    """Platform position from the inclinometer (eq. 4, sign of z as in the module doc), (N, 3)."""
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    length = np.asarray(link_length, dtype=float)
    return np.stack(
        [length * np.cos(alpha) * np.sin(beta), -length * np.sin(alpha), -length * np.cos(alpha) * np.cos(beta)],
        axis=-1,
    )


def inclinometer_angles(position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of eq. 4: (alpha, beta) of the link pointing from O to ``position``."""
    position = np.atleast_2d(np.asarray(position, dtype=float))
    length = np.linalg.norm(position, axis=1)
    alpha = np.arcsin(np.clip(-position[:, 1] / length, -1.0, 1.0))
    beta = np.arctan2(position[:, 0], -position[:, 2])
    return alpha, beta
