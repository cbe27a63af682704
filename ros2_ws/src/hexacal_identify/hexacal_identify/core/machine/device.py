"""
The measuring device: a link with U joints, a biaxial inclinometer and a rotary sensor.

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

Turning the device about its link axis (``device_turn`` per posture, rad; the
posture message's ``device_turn`` joint).  The whole device - both U-joint
fixtures, the link, the sensors - is remounted turned by ``turn`` about the
base Z axis through O (the link axis at zero reading).  It then reads, in its
own turned frame, exactly what the normal device reads: the readings belong to
``R_z(turn)^T p`` and the position is ``p = R_z(turn) p_device(readings)``.
Turned by pi (the classic reversal of an inclinometer) the sensor reads the
true angles negated plus the same zero offsets, so alpha0 and beta0 change sign
against the geometry and eq. 7 separates them from the machine; turned by pi/2
the axes swap, so the skew gamma acts on the other axis and is separated too.
The rotary sensor turns with the link: it reads ``phi - turn + phi0`` (wrapped
to [-pi, pi)); phi0 keeps its sign (a platform-frame definition whatever the turn).

Mounting (``DeviceModel.mount``, the parameter ``device.mount``):

* ``hanging`` (default): everything above - the device's base joint O at the
  base origin, the platform below it (the Hexa Slide; a ceiling-mounted
  hexapod).  Fixed position [0, 0, -L].
* ``standing``: an upright machine (a Gough-Stewart hexapod on the floor).  The
  device's base joint O is still the base origin, the platform is above it.
  The base frame is the same (Z up, against gravity; X and Y along the
  inclinometer's measuring axes at zero reading, section 2.3), the readings are
  the same (alpha about X, beta about Y, both zero with the link vertical, the
  same defects with the same meaning), and the link points up::

      p = (-L cos(alpha) sin(beta), L sin(alpha), L cos(alpha) cos(beta)) = -p_hanging

  Fixed position [0, 0, +L].  Why this one: an inclinometer senses gravity, so
  on either mount it must sit upright on the link (an upside-down one does not
  read zero with the link vertical).  With the same sensor fixed the same way
  to the link, a reading stands for one orientation R of the rigid link (the U
  joint at O allows the same orientations whichever way the link leaves it),
  and only the link's direction in that body differs: from O to the platform
  it is R (0, 0, -1) hanging and R (0, 0, +1) standing.  The platform end of
  an upright link moves opposite to the lower end of a hanging one (a reading
  that swings a hanging link's end to +x swings a standing link's end to -x),
  so the whole defect model holds with p -> -p, exactly: ``dL``, ``alpha0``,
  ``beta0``, ``gamma`` keep their meaning and every derivative changes sign.
  Turning the hanging formula by 180 deg about X, (L ca sb, L sa, L ca cb), or
  about Y, (-L ca sb, -L sa, L ca cb), is this formula with beta, respectively
  alpha, negated: an inclinometer whose beta (alpha) sign is reversed, not the
  same sensor; the printed eq. 4, (L ca sb, -L sa, L ca cb), is this formula
  with both negated: a sensor turned by 180 deg about the link.  A device
  mounted that way is used by negating the reversed readings before they
  enter hexacal; the mount option does not do it.
  The rotary sensor is unchanged: it reads phi, the rotation of the platform
  about its own z axis (eq. 2), on either mount.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from hexacal_msgs_py.models import DEVICE_DEFECT_NAMES, DEVICE_DEFECT_UNITS
import numpy as np

from ..errors import CalibrationError

DEFAULT_LINK_LENGTH_M = 0.750
HANGING = 'hanging'  # platform below the device's base joint: p_z = -L cos(alpha) cos(beta)
STANDING = 'standing'  # platform above it: p = -p_hanging
MOUNTS = (HANGING, STANDING)
DEFAULT_MOUNT = HANGING
DEVICE_PARAMETER_NAMES = (
    DEVICE_DEFECT_NAMES  # ("dL", "alpha0", "beta0", "gamma", "phi0"): the contract's
)
DEVICE_PARAMETER_UNITS = DEVICE_DEFECT_UNITS
N_DEVICE_PARAMETERS = len(DEVICE_PARAMETER_NAMES)


# Turning procedures: the device turns (rad) a plan's postures are shared out over (module doc,
# studies.device_procedure).  One remount per turn.
TURNING_PROCEDURES: dict[str, tuple[float, ...]] = {
    'none': (0.0,),
    'reversal': (0.0, np.pi),  # 0 / 180 deg: alpha0 and beta0 change sign against the geometry
    'quarter-turns': (
        0.0,
        np.pi / 2,
        np.pi,
        3 * np.pi / 2,
    ),  # also moves the skew gamma to the other axis
}


def procedure_turns(procedure: str) -> tuple[float, ...]:
    """
    Return the device turns of a turning procedure.

    The device turns of a turning procedure; ValueError naming the choices for an unknown one.
    """
    if procedure not in TURNING_PROCEDURES:
        raise ValueError(
            f'unknown procedure {procedure!r}; choose one of {", ".join(TURNING_PROCEDURES)}'
        )
    return TURNING_PROCEDURES[procedure]


class DeviceMountError(CalibrationError, ValueError):
    """A device mount that is neither ``hanging`` nor ``standing``."""

    reason = 'invalid-device-mount'


def check_mount(mount: object) -> str:
    """``mount`` if it is one of MOUNTS, else a DeviceMountError naming the allowed values."""
    if not (isinstance(mount, str) and mount in MOUNTS):
        raise DeviceMountError(
            f'device mount must be one of {", ".join(MOUNTS)} (default {DEFAULT_MOUNT}), '
            f'got {mount!r}'
        )
    return mount


def _standing(mount: str) -> bool:
    """
    Return True for the standing mount.

    True for the standing mount (p = -p_hanging); validates ``mount``.
    """
    return check_mount(mount) == STANDING


@dataclass(frozen=True)
class DeviceModel:
    """
    Geometry of the measuring link as the identification assumes it.

    ``mount``: ``hanging`` (platform below the device's base joint, default) or
    ``standing`` (platform above it); the module doc says what each means.
    """

    link_length: float = DEFAULT_LINK_LENGTH_M
    mount: str = DEFAULT_MOUNT

    def __post_init__(self) -> None:
        if not (np.isfinite(self.link_length) and self.link_length > 0):
            raise ValueError(f'link_length must be a positive length in m, got {self.link_length}')
        check_mount(self.mount)

    def position(
        self,
        alpha: np.ndarray,
        beta: np.ndarray,
        defects: 'DeviceDefects | None' = None,
        link_length: float | np.ndarray | None = None,
        device_turn: np.ndarray | float | None = None,
    ) -> 'DevicePosition':
        """
        Return platform positions (and derivatives) from readings.

        Platform positions (and derivatives) from readings; ``link_length`` per posture for an
        LVDT, ``device_turn`` (rad) per posture for a device turned about its link (module doc).
        """
        length = self.link_length if link_length is None else link_length
        return device_position(
            alpha,
            beta,
            length,
            defects if defects is not None else DeviceDefects(),
            self.mount,
            device_turn,
        )

    def readings(
        self,
        position: np.ndarray,
        defects: 'DeviceDefects | None' = None,
        device_turn: np.ndarray | float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        Return what the inclinometer reads with the platform at ``position`` (N, 3).

        What the (defective, possibly turned) inclinometer reads with the platform at ``position``
        (N, 3).
        """
        return inclinometer_readings(
            position, defects if defects is not None else DeviceDefects(), self.mount, device_turn
        )

    def angles(self, position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(alpha, beta) of an ideal inclinometer with the platform at ``position`` (N, 3)."""
        return inclinometer_angles(position, self.mount)

    def fixed_position(
        self, defects: 'DeviceDefects | None' = None, device_turn: float = 0.0
    ) -> 'DevicePosition':
        """
        Return where the inclinometer reads zero, with its derivatives.

        Where the (defective, possibly turned) inclinometer reads zero, (1, 3), with its
        derivatives.
        """
        return fixed_position(
            self.link_length,
            defects if defects is not None else DeviceDefects(),
            self.mount,
            device_turn,
        )

    @property
    def fixed_point(self) -> np.ndarray:
        """Return the ideal fixed position (eq. 10): [0, 0, -L] hanging, [0, 0, +L] standing."""
        return fixed_point(self.link_length, self.mount)

    def sphere_z(self, xy: np.ndarray, link_length: float | None = None) -> np.ndarray:
        """
        Return z of the sphere postures above (N, 2) ``xy``.

        On the link's side of O.
        """
        return sphere_z(xy, self.link_length if link_length is None else link_length, self.mount)


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
                raise ValueError(f'device defect {f.name} must be finite, got {value}')
        if abs(self.gamma) >= 0.5 or abs(self.alpha0) >= 0.5 or abs(self.beta0) >= 0.5:
            raise ValueError('device angle defects must be small (|value| < 0.5 rad)')

    @property
    def vector(self) -> np.ndarray:
        return np.array([getattr(self, name) for name in DEVICE_PARAMETER_NAMES])

    @classmethod
    def from_vector(cls, vector: np.ndarray) -> 'DeviceDefects':
        return cls(*(float(v) for v in vector))

    @classmethod
    def parse(cls, text: str) -> 'DeviceDefects':
        """
        Parse 'dL=0.0005,alpha0=2e-4,...' (SI units) into DeviceDefects.

        'dL=0.0005,alpha0=2e-4,...' (SI units) -> DeviceDefects; names as DEVICE_PARAMETER_NAMES.
        """
        values: dict[str, float] = {}
        for item in filter(None, (part.strip() for part in text.split(','))):
            name, sep, value = item.partition('=')
            name = name.strip()
            if not sep or name not in DEVICE_PARAMETER_NAMES:
                raise ValueError(
                    f'bad device defect {item!r}: expected NAME=VALUE with NAME one of '
                    f'{", ".join(DEVICE_PARAMETER_NAMES)}'
                )
            try:
                values[name] = float(value)
            except ValueError:
                raise ValueError(
                    f'device defect {name} must be a number in SI units, got {value!r}'
                ) from None
        return cls(**values)

    def describe(self) -> str:
        return ', '.join(
            f'{n}={getattr(self, n):g} {u}'
            for n, u in zip(DEVICE_PARAMETER_NAMES, DEVICE_PARAMETER_UNITS)
        )


@dataclass(frozen=True)
class DevicePrior:
    """
    Prior knowledge of device parameters: a value and a standard deviation (SI) per defect.

    A caliper measurement of the link (dL = 0 +- 10 um), an inclinometer's
    calibration certificate (alpha0 = 0 +- 50 urad): the solver adds one row
    (value - prior) / std per entry (maximum a posteriori with a Gaussian prior,
    the rows whitened like the data), so the covariance includes them.  A
    parameter with a prior is identified.  ``entries``: (name, value, std) with
    names from DEVICE_PARAMETER_NAMES.
    """

    entries: tuple[tuple[str, float, float], ...] = ()

    def __post_init__(self) -> None:
        seen = set()
        for entry in self.entries:
            if len(entry) != 3:
                raise ValueError(f'a device prior is (name, value, std), got {entry!r}')
            name, value, std = entry
            if name not in DEVICE_PARAMETER_NAMES:
                raise ValueError(
                    f'device prior on unknown parameter {name!r}; choose from '
                    f'{", ".join(DEVICE_PARAMETER_NAMES)}'
                )
            if name in seen:
                raise ValueError(f'device prior on {name} given twice')
            seen.add(name)
            if not (np.isfinite(value) and np.isfinite(std) and std > 0):
                raise ValueError(
                    f'device prior on {name}: value must be finite and std positive (SI units), '
                    f'got {value!r} +- {std!r}'
                )

    def __bool__(self) -> bool:
        return bool(self.entries)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _, _ in self.entries)

    @property
    def indices(self) -> np.ndarray:
        """Index of each entry's parameter in DEVICE_PARAMETER_NAMES."""
        return np.array([DEVICE_PARAMETER_NAMES.index(name) for name in self.names], dtype=int)

    @property
    def values(self) -> np.ndarray:
        return np.array([value for _, value, _ in self.entries], dtype=float)

    @property
    def stds(self) -> np.ndarray:
        return np.array([std for _, _, std in self.entries], dtype=float)

    def get(self, name: str) -> tuple[float, float] | None:
        """(value, std) of the prior on ``name``, or None."""
        return next(((value, std) for n, value, std in self.entries if n == name), None)

    @classmethod
    def parse(cls, text: str) -> 'DevicePrior':
        """'dL=0:10e-6,alpha0=0:50e-6' (NAME=VALUE:STD, SI units) -> DevicePrior."""
        entries = []
        for item in filter(None, (part.strip() for part in text.split(','))):
            name, sep, rest = item.partition('=')
            value, colon, std = rest.partition(':')
            name = name.strip()
            if not sep or not colon:
                raise ValueError(
                    f'bad device prior {item!r}: expected NAME=VALUE:STD in SI units, '
                    'e.g. dL=0:10e-6 (link length offset 0 +- 10 um)'
                )
            try:
                entries.append((name, float(value), float(std)))
            except ValueError:
                raise ValueError(
                    f'device prior {item!r}: VALUE and STD must be numbers in SI units'
                ) from None
        return cls(tuple(entries))

    def describe(self) -> str:
        units = dict(zip(DEVICE_PARAMETER_NAMES, DEVICE_PARAMETER_UNITS))
        return ', '.join(
            f'{name}={value:g} +- {std:g} {units[name]}' for name, value, std in self.entries
        )


def measured_position(
    alpha: np.ndarray,
    beta: np.ndarray,
    link_length: float | np.ndarray,
    mount: str = DEFAULT_MOUNT,
) -> np.ndarray:
    """Platform position from the inclinometer (eq. 4, sign of z as in the module doc), (N, 3)."""
    standing = _standing(mount)
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    length = np.asarray(link_length, dtype=float)
    position = np.stack(
        [
            length * np.cos(alpha) * np.sin(beta),
            -length * np.sin(alpha),
            -length * np.cos(alpha) * np.cos(beta),
        ],
        axis=-1,
    )
    return -position if standing else position


def inclinometer_angles(
    position: np.ndarray, mount: str = DEFAULT_MOUNT
) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of eq. 4: (alpha, beta) of the link pointing from O to ``position``."""
    return inclinometer_readings(position, DeviceDefects(), mount)


def turn_rotations(device_turn: np.ndarray | float | None, n: int) -> np.ndarray:
    """
    Return R_z(turn) per posture, (n, 3, 3).

    The frame of a device turned by ``turn`` about its link axis.
    """
    turn = (
        np.zeros(n)
        if device_turn is None
        else np.broadcast_to(np.asarray(device_turn, dtype=float), (n,))
    )
    c, s = np.cos(turn), np.sin(turn)
    rotation = np.zeros((n, 3, 3))
    rotation[:, 0, 0], rotation[:, 0, 1], rotation[:, 1, 0], rotation[:, 1, 1] = c, -s, s, c
    rotation[:, 2, 2] = 1.0
    return rotation


def inclinometer_readings(
    position: np.ndarray,
    defects: DeviceDefects,
    mount: str = DEFAULT_MOUNT,
    device_turn: np.ndarray | float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """
    Return what a defective inclinometer reads for the link pointing at ``position``.

    What a defective inclinometer reads for the link pointing from O to ``position`` (no noise).

    ``device_turn`` (rad, per posture): the device turned about its link axis (module doc).
    """
    position = np.atleast_2d(np.asarray(position, dtype=float))
    if (
        device_turn is not None
    ):  # the turned device reads, in its own (turned) frame, what the normal one reads
        position = np.einsum(
            'nji,nj->ni', turn_rotations(device_turn, len(position)), position
        )  # R_z(turn)^T p
    if _standing(mount):
        position = (
            -position
        )  # the same reading as a hanging link pointing the other way (module doc)
    u = position / np.linalg.norm(position, axis=1, keepdims=True)
    b = np.arctan2(u[:, 0], -u[:, 2])
    sin_s, cos_s = u[:, 1], np.hypot(u[:, 0], u[:, 2])
    sensed = np.cos(defects.gamma) * sin_s - np.sin(defects.gamma) * np.sin(b) * cos_s
    alpha_true = np.arcsin(np.clip(-sensed, -1.0, 1.0))
    return alpha_true + defects.alpha0, b + defects.beta0


def fixed_point(link_length: float, mount: str = DEFAULT_MOUNT) -> np.ndarray:
    """
    Return where an ideal inclinometer reads zero (eq. 10).

    [0, 0, -L] hanging, [0, 0, +L] standing, (3,).
    """
    if _standing(mount):
        return np.array([0.0, 0.0, link_length])
    return np.array([0.0, 0.0, -link_length])


def sphere_z(xy: np.ndarray, link_length: float, mount: str = DEFAULT_MOUNT) -> np.ndarray:
    """
    Return z of the points of the L-sphere about O above (N, 2) ``xy``.

    z of the points of the L-sphere about O above (N, 2) ``xy``, on the platform's side of O.

    Hanging: -sqrt(L^2 - x^2 - y^2) (the sphere postures' z until now); standing: +sqrt(...).
    """
    standing = _standing(mount)
    xy = np.asarray(xy, dtype=float)
    z = np.sqrt(link_length**2 - np.sum(xy**2, axis=1))
    return z if standing else -z


@dataclass
class DevicePosition:
    """Positions from readings, and their derivatives w.r.t. (dL, alpha0, beta0, gamma)."""

    position: np.ndarray  # (N, 3)
    d_defects: np.ndarray  # (N, 3, 4): columns dL, alpha0, beta0, gamma
    d_readings: np.ndarray  # (N, 3, 2): columns alpha, beta (for noise propagation)


def device_position(
    alpha: np.ndarray,
    beta: np.ndarray,
    link_length: float | np.ndarray,
    defects: DeviceDefects = DeviceDefects(),
    mount: str = DEFAULT_MOUNT,
    device_turn: np.ndarray | float | None = None,
) -> DevicePosition:
    """
    Platform position from inclinometer readings through the defect model (module doc).

    Standing: the hanging result negated (position and both derivative arrays). ``device_turn``
    (rad, per posture): the device turned about its link axis, p = R_z(turn) p_device.
    """
    standing = _standing(mount)
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
        big_a * db_g - big_b * da_g
    ) / radius**2
    scale = length[:, None]
    du_dbeta = du_db + du_ds * ds_db[:, None]
    d_defects = np.stack(
        [u, -scale * du_ds * ds_da[:, None], -scale * du_dbeta, scale * du_ds * ds_dg[:, None]],
        axis=-1,
    )
    d_readings = np.stack([scale * du_ds * ds_da[:, None], scale * du_dbeta], axis=-1)
    position = scale * u
    if device_turn is not None:  # the turned device's frame is R_z(turn) of the normal one
        rotation = turn_rotations(device_turn, len(alpha))
        position = np.einsum('nij,nj->ni', rotation, position)
        d_defects = np.einsum('nij,njk->nik', rotation, d_defects)
        d_readings = np.einsum('nij,njk->nik', rotation, d_readings)
    if standing:
        return DevicePosition(-position, -d_defects, -d_readings)
    return DevicePosition(position, d_defects, d_readings)


def fixed_position(
    link_length: float,
    defects: DeviceDefects = DeviceDefects(),
    mount: str = DEFAULT_MOUNT,
    device_turn: float = 0.0,
) -> DevicePosition:
    """
    Return where the inclinometer reads zero, with derivatives.

    Where the (defective, possibly turned) inclinometer reads zero: the fixed position of eq. 10,
    (1, 3), with derivatives.
    """
    return device_position(
        np.zeros(1), np.zeros(1), link_length, defects, mount, np.array([device_turn])
    )
