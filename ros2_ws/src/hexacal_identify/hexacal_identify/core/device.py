"""The measuring device: a link with U joints, a biaxial inclinometer and a rotary sensor.

Eq. 4 as printed gives ``z = +L cos(alpha) cos(beta)``, but the text fixes the
inclinometer-zero position at ``[0, 0, -L]`` and the platform hangs below the
base joint O; the sign of z used here is therefore negative:

    p = (L cos(alpha) sin(beta), -L sin(alpha), -L cos(alpha) cos(beta))

alpha is the inclinometer angle about X, beta about Y.  The rotary sensor sits
on the platform and reads phi, the rotation about the platform's local z axis
(section 3.1), i.e. the third Euler angle of eq. 2.

Device defects (section 4 names them; hexacal identifies them):

* ``dL``      link-length offset, m: the true length is L + dL.
* ``alpha0``  inclinometer zero offset about X, rad: alpha_read = alpha_true + alpha0.
* ``beta0``   inclinometer zero offset about Y, rad: beta_read = beta_true + beta0.
* ``gamma``   non-perpendicularity of the inclinometer axes, rad: the alpha axis
              is turned by gamma about Z, so it senses u_y cos(gamma) - u_x sin(gamma)
              of the link direction u instead of u_y alone.
* ``phi0``    rotary-sensor zero offset, rad: phi_read = phi_true + phi0.

Reading -> link direction, with a' = alpha - alpha0 and b = beta - beta0: u lies
in the plane containing Y and the beta-tilted down axis, u = (cos s sin b,
sin s, -cos s cos b), and the alpha axis fixes s through
``cos(gamma) sin s - sin(gamma) sin b cos s = -sin a'``, i.e.
``s = asin(C / R) - delta`` with C = -sin a', R = hypot(A, B), delta = atan2(B, A),
A = cos(gamma), B = -sin(gamma) sin b.  With no defects s = -alpha: eq. 4.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

DEFAULT_LINK_LENGTH_M = 0.750
DEVICE_PARAMETER_NAMES = ("dL", "alpha0", "beta0", "gamma", "phi0")
DEVICE_PARAMETER_UNITS = ("m", "rad", "rad", "rad", "rad")
N_DEVICE_PARAMETERS = len(DEVICE_PARAMETER_NAMES)


@dataclass(frozen=True)
class DeviceModel:
    """Geometry of the measuring link as the identification assumes it."""

    link_length: float = DEFAULT_LINK_LENGTH_M

    def __post_init__(self) -> None:
        if not (np.isfinite(self.link_length) and self.link_length > 0):
            raise ValueError(f"link_length must be a positive length in m, got {self.link_length}")


@dataclass(frozen=True)
class DeviceDefects:
    """The device's intrinsic errors (SI units); zero for an ideal device."""

    dL: float = 0.0
    alpha0: float = 0.0
    beta0: float = 0.0
    gamma: float = 0.0
    phi0: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not np.isfinite(value):
                raise ValueError(f"device defect {f.name} must be finite, got {value}")
        if abs(self.gamma) >= 0.5 or abs(self.alpha0) >= 0.5 or abs(self.beta0) >= 0.5:
            raise ValueError("device angle defects must be small (|value| < 0.5 rad)")

    @property
    def vector(self) -> np.ndarray:
        return np.array([getattr(self, name) for name in DEVICE_PARAMETER_NAMES])

    @classmethod
    def from_vector(cls, vector: np.ndarray) -> "DeviceDefects":
        return cls(*(float(v) for v in vector))

    @classmethod
    def parse(cls, text: str) -> "DeviceDefects":
        """'dL=0.0005,alpha0=2e-4,...' (SI units) -> DeviceDefects; names as DEVICE_PARAMETER_NAMES."""
        values: dict[str, float] = {}
        for item in filter(None, (part.strip() for part in text.split(","))):
            name, sep, value = item.partition("=")
            name = name.strip()
            if not sep or name not in DEVICE_PARAMETER_NAMES:
                raise ValueError(
                    f"bad device defect {item!r}: expected NAME=VALUE with NAME one of {', '.join(DEVICE_PARAMETER_NAMES)}"
                )
            try:
                values[name] = float(value)
            except ValueError:
                raise ValueError(f"device defect {name} must be a number in SI units, got {value!r}") from None
        return cls(**values)

    def describe(self) -> str:
        return ", ".join(f"{n}={getattr(self, n):g} {u}" for n, u in zip(DEVICE_PARAMETER_NAMES, DEVICE_PARAMETER_UNITS))


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
    return inclinometer_readings(position, DeviceDefects())


def inclinometer_readings(position: np.ndarray, defects: DeviceDefects) -> tuple[np.ndarray, np.ndarray]:
    """What a defective inclinometer reads for the link pointing from O to ``position`` (no noise)."""
    position = np.atleast_2d(np.asarray(position, dtype=float))
    u = position / np.linalg.norm(position, axis=1, keepdims=True)
    b = np.arctan2(u[:, 0], -u[:, 2])
    sin_s, cos_s = u[:, 1], np.hypot(u[:, 0], u[:, 2])
    sensed = np.cos(defects.gamma) * sin_s - np.sin(defects.gamma) * np.sin(b) * cos_s
    alpha_true = np.arcsin(np.clip(-sensed, -1.0, 1.0))
    return alpha_true + defects.alpha0, b + defects.beta0


@dataclass
class DevicePosition:
    """Positions from readings, and their derivatives w.r.t. (dL, alpha0, beta0, gamma)."""

    position: np.ndarray  # (N, 3)
    d_defects: np.ndarray  # (N, 3, 4): columns dL, alpha0, beta0, gamma
    d_readings: np.ndarray  # (N, 3, 2): columns alpha, beta (for noise propagation)


def device_position(alpha: np.ndarray, beta: np.ndarray, link_length: float | np.ndarray,
                    defects: DeviceDefects = DeviceDefects()) -> DevicePosition:
    """Platform position from inclinometer readings through the defect model (module doc)."""
    alpha = np.atleast_1d(np.asarray(alpha, dtype=float))
    beta = np.atleast_1d(np.asarray(beta, dtype=float))
    length = np.broadcast_to(np.asarray(link_length, dtype=float) + defects.dL, alpha.shape)
    a_true, b = alpha - defects.alpha0, beta - defects.beta0
    cg, sg = np.cos(defects.gamma), np.sin(defects.gamma)
    big_a, big_b, big_c = cg, -sg * np.sin(b), -np.sin(a_true)
    radius = np.hypot(big_a, big_b)
    delta = np.arctan2(big_b, big_a)
    s = np.arcsin(np.clip(big_c / radius, -1.0, 1.0)) - delta
    cos_sd = np.cos(s + delta)  # sqrt(1 - (C/R)^2) on the principal branch
    u = np.stack([np.cos(s) * np.sin(b), np.sin(s), -np.cos(s) * np.cos(b)], axis=-1)
    du_ds = np.stack([-np.sin(s) * np.sin(b), np.cos(s), np.sin(s) * np.cos(b)], axis=-1)
    du_db = np.stack([np.cos(s) * np.cos(b), np.zeros_like(s), np.cos(s) * np.sin(b)], axis=-1)
    # s = asin(C/R) - delta: ds = (dC / R - C dR / R^2) / cos(s + delta) - d delta.
    ds_da = -np.cos(a_true) / (radius * cos_sd)
    db_b = -sg * np.cos(b)  # dB/db
    ds_db = (-big_c * (big_b * db_b / radius) / radius**2) / cos_sd - big_a * db_b / radius**2
    da_g, db_g = -sg, -cg * np.sin(b)  # dA/dgamma, dB/dgamma
    ds_dg = (-big_c * ((big_a * da_g + big_b * db_g) / radius) / radius**2) / cos_sd - (
        big_a * db_g - big_b * da_g) / radius**2
    scale = length[:, None]
    du_dbeta = du_db + du_ds * ds_db[:, None]
    d_defects = np.stack([u, -scale * du_ds * ds_da[:, None], -scale * du_dbeta, scale * du_ds * ds_dg[:, None]],
                         axis=-1)
    d_readings = np.stack([scale * du_ds * ds_da[:, None], scale * du_dbeta], axis=-1)
    return DevicePosition(scale * u, d_defects, d_readings)
