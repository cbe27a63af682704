"""
Validated, immutable sensor readings of the hexacal contract (ROS-free).

Units: slider positions (the articular variables lambda_i: slider positions
along the rails on a Hexa Slide, leg extensions on a Gough-Stewart platform) in
m; inclinometer angles alpha (about X) and beta (about Y) and the rotary angle
phi in rad; stamps in ns.  The readings do not name the model: the six
actuator values are in chain order whatever their joint names (models.py).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
import math
import operator
from typing import cast, SupportsIndex

from hexacal_msgs_py.deprecation import deprecated_attribute, warn_deprecated
from hexacal_msgs_py.errors import InvalidReadingError
from hexacal_msgs_py.names import (
    DEVICE_TURN_JOINT,
    LINK_LENGTH_JOINT,
    MAX_DEVICE_TURN,
    N_CHAINS,
    POSTURE_NAMES,
)

NS_PER_S = 1_000_000_000  # stamps are integer nanoseconds


def _check_stamp(kind: str, stamp_ns: object) -> int:
    if isinstance(stamp_ns, bool):
        raise InvalidReadingError(f'{kind}: stamp_ns must be an integer, got {stamp_ns!r}')
    try:
        # operator.index decides (numpy integers yes, floats no); the cast only tells mypy, and
        # costs no runtime Protocol check per reading (offline re-detection reads millions).
        value = operator.index(cast(SupportsIndex, stamp_ns))
    except TypeError:
        raise InvalidReadingError(
            f'{kind}: stamp_ns must be an integer, got {stamp_ns!r}'
        ) from None
    if value < 0:
        raise InvalidReadingError(f'{kind}: stamp_ns must be >= 0, got {value}')
    return value


def _check_value(kind: str, name: str, value: object) -> float:
    if isinstance(value, (bool, str, bytes)):
        raise InvalidReadingError(f'{kind}: {name} must be a number, got {value!r}')
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidReadingError(f'{kind}: {name} must be a number, got {value!r}') from None
    except OverflowError:  # an integer beyond the float range
        number = math.inf
    if not math.isfinite(number):
        raise InvalidReadingError(f'{kind}: {name} must be finite, got {number!r}')
    return number


def _check_turn(kind: str, value: object) -> float:
    turn = _check_value(kind, DEVICE_TURN_JOINT, value)
    if abs(turn) > MAX_DEVICE_TURN:
        raise InvalidReadingError(
            f'{kind}: {DEVICE_TURN_JOINT} must be within +-2 pi rad, got {turn!r}'
        )
    return turn


def _check_link_length(kind: str, value: object) -> float | None:
    """Return the measured link length (m, finite > 0), or None (the device's nominal L)."""
    if value is None:
        return None
    length = _check_value(kind, LINK_LENGTH_JOINT, value)
    if length <= 0.0:
        raise InvalidReadingError(f'{kind}: {LINK_LENGTH_JOINT} must be > 0 m, got {length!r}')
    return length


def _check_actuators(kind: str, positions: object) -> tuple[float, ...]:
    if isinstance(positions, (str, bytes)) or not isinstance(positions, Iterable):
        raise InvalidReadingError(
            f'{kind}: slider_positions must be a sequence of {N_CHAINS} numbers, got {positions!r}'
        )
    values = tuple(positions)
    if len(values) != N_CHAINS:
        raise InvalidReadingError(
            f'{kind}: slider_positions must have {N_CHAINS} values, got {len(values)}'
        )
    return tuple(
        _check_value(kind, f'slider_{i}', value) for i, value in enumerate(values, start=1)
    )


@dataclass(frozen=True)
class ActuatorReading:
    """The six actuator readings lambda (m): slider positions (Hexa Slide) or leg extensions."""

    stamp_ns: int
    actuator_positions: tuple[float, ...]

    def __post_init__(self) -> None:
        kind = type(self).__name__
        object.__setattr__(self, 'stamp_ns', _check_stamp(kind, self.stamp_ns))
        object.__setattr__(
            self, 'actuator_positions', _check_actuators(kind, self.actuator_positions)
        )

    @property
    def slider_positions(self) -> tuple[float, ...]:
        """Return actuator_positions, warning: the field's deprecated name."""
        warn_deprecated('slider_positions', 'actuator_positions')
        return self.actuator_positions


@dataclass(frozen=True)
class InclinometerReading:
    """
    Biaxial inclinometer angles: alpha about X, beta about Y (rad).

    device_turn: the device's rotation about its link axis from its normal
    mounting (rad; 0 normal, pi reversed, pi/2 quarter turn), |turn| <= 2 pi.
    """

    stamp_ns: int
    alpha: float
    beta: float
    device_turn: float = 0.0

    def __post_init__(self) -> None:
        kind = type(self).__name__
        object.__setattr__(self, 'stamp_ns', _check_stamp(kind, self.stamp_ns))
        object.__setattr__(self, 'alpha', _check_value(kind, 'alpha', self.alpha))
        object.__setattr__(self, 'beta', _check_value(kind, 'beta', self.beta))
        object.__setattr__(self, 'device_turn', _check_turn(kind, self.device_turn))


@dataclass(frozen=True)
class EncoderReading:
    """Rotary sensor angle phi of the calibration device (rad)."""

    stamp_ns: int
    phi: float

    def __post_init__(self) -> None:
        kind = type(self).__name__
        object.__setattr__(self, 'stamp_ns', _check_stamp(kind, self.stamp_ns))
        object.__setattr__(self, 'phi', _check_value(kind, 'phi', self.phi))


@dataclass(frozen=True)
class PostureScatter:
    """
    How well a posture's nine values are known from the samples averaged into them.

    Per channel in POSTURE_NAMES order (six actuators, alpha, beta, phi):
    `standard_errors` is the standard error of the channel's mean (m or rad, the channel's
    unit: its samples' scatter over the square root of their number) and `sample_counts` the
    number of samples averaged (>= 1).  On a posture JointState the standard errors travel in
    `velocity` and the counts in `effort` (docs/formats.md).

    link_length_standard_error / link_length_sample_count: the same for the posture's measured
    link length (lvdt measuring mode, m), None where the posture has no measured length.
    """

    standard_errors: tuple[float, ...]
    sample_counts: tuple[int, ...]
    link_length_standard_error: float | None = None
    link_length_sample_count: int | None = None

    def __post_init__(self) -> None:
        kind = type(self).__name__
        errors = tuple(self.standard_errors)
        counts = tuple(self.sample_counts)
        if len(errors) != len(POSTURE_NAMES) or len(counts) != len(POSTURE_NAMES):
            raise InvalidReadingError(
                f'{kind}: expected {len(POSTURE_NAMES)} standard errors and sample counts, '
                f'got {len(errors)} and {len(counts)}'
            )
        checked = tuple(
            _check_value(kind, f'standard error of {name}', value)
            for name, value in zip(POSTURE_NAMES, errors)
        )
        if min(checked) < 0.0:
            raise InvalidReadingError(f'{kind}: standard errors must be >= 0, got {checked}')
        whole = []
        for name, count in zip(POSTURE_NAMES, counts):
            number = _check_value(kind, f'sample count of {name}', count)
            if number < 1 or number != int(number):
                raise InvalidReadingError(
                    f'{kind}: sample count of {name} must be a whole number >= 1, got {count!r}'
                )
            whole.append(int(number))
        object.__setattr__(self, 'standard_errors', checked)
        object.__setattr__(self, 'sample_counts', tuple(whole))
        self._check_link()

    def _check_link(self) -> None:
        kind = type(self).__name__
        error, count = self.link_length_standard_error, self.link_length_sample_count
        if (error is None) != (count is None):
            raise InvalidReadingError(
                f'{kind}: the link length needs both a standard error and a sample count'
            )
        if error is None or count is None:
            return
        checked = _check_value(kind, f'standard error of {LINK_LENGTH_JOINT}', error)
        number = _check_value(kind, f'sample count of {LINK_LENGTH_JOINT}', count)
        if checked < 0.0 or number < 1 or number != int(number):
            raise InvalidReadingError(
                f'{kind}: {LINK_LENGTH_JOINT} needs a standard error >= 0 and a whole sample '
                f'count >= 1, got {error!r} and {count!r}'
            )
        object.__setattr__(self, 'link_length_standard_error', checked)
        object.__setattr__(self, 'link_length_sample_count', int(number))


@dataclass(frozen=True)
class PostureReading:
    """
    One measured posture.

    The six actuator readings (m) with the device's alpha, beta, phi (rad).

    device_turn: the mounting the posture was measured in, the device's
    rotation about its link axis from its normal mounting (rad; 0 normal, pi
    reversed, pi/2 quarter turn), |turn| <= 2 pi.  It is not one of the nine
    values() (POSTURE_NAMES); on a JointState it is the optional joint
    DEVICE_TURN_JOINT, absent when 0.

    scatter: the readings' scatter behind the nine values (PostureScatter), or None where it is
    not known (a posture given by hand, a bag recorded before it existed).

    link_length: the measuring link's length L_m measured at this posture (m, finite > 0; the
    lvdt measuring mode), which replaces the device's nominal L in eq. 4; None (the default)
    means the nominal L.  Not one of the nine values(); on a JointState it is the optional joint
    LINK_LENGTH_JOINT, absent when None.
    """

    stamp_ns: int
    actuator_positions: tuple[float, ...]
    alpha: float
    beta: float
    phi: float
    device_turn: float = 0.0
    scatter: PostureScatter | None = None
    link_length: float | None = None

    def __post_init__(self) -> None:
        kind = type(self).__name__
        object.__setattr__(self, 'stamp_ns', _check_stamp(kind, self.stamp_ns))
        object.__setattr__(
            self, 'actuator_positions', _check_actuators(kind, self.actuator_positions)
        )
        object.__setattr__(self, 'alpha', _check_value(kind, 'alpha', self.alpha))
        object.__setattr__(self, 'beta', _check_value(kind, 'beta', self.beta))
        object.__setattr__(self, 'phi', _check_value(kind, 'phi', self.phi))
        object.__setattr__(self, 'device_turn', _check_turn(kind, self.device_turn))
        object.__setattr__(self, 'link_length', _check_link_length(kind, self.link_length))

    @property
    def slider_positions(self) -> tuple[float, ...]:
        """Return actuator_positions, warning: the field's deprecated name."""
        warn_deprecated('slider_positions', 'actuator_positions')
        return self.actuator_positions

    @classmethod
    def from_parts(
        cls,
        sliders: ActuatorReading,
        inclinometer: InclinometerReading,
        encoder: EncoderReading,
        stamp_ns: int | None = None,
    ) -> PostureReading:
        """
        Combine synchronised readings; the stamp defaults to the sliders' stamp.

        The device turn is the inclinometer reading's.
        """
        return cls(
            stamp_ns=sliders.stamp_ns if stamp_ns is None else stamp_ns,
            actuator_positions=sliders.actuator_positions,
            alpha=inclinometer.alpha,
            beta=inclinometer.beta,
            phi=encoder.phi,
            device_turn=inclinometer.device_turn,
        )

    def values(self) -> tuple[float, ...]:
        """
        Return the nine values in posture-joint order.

        Six actuators, alpha, beta, phi (POSTURE_NAMES).
        """
        return self.actuator_positions + (self.alpha, self.beta, self.phi)

    @classmethod
    def from_values(
        cls,
        stamp_ns: int,
        values: Iterable[float],
        device_turn: float = 0.0,
        scatter: PostureScatter | None = None,
        link_length: float | None = None,
    ) -> PostureReading:
        """Inverse of values(): nine numbers in POSTURE_NAMES order (turn rad, link length m)."""
        numbers = tuple(values)
        if len(numbers) != len(POSTURE_NAMES):
            raise InvalidReadingError(
                f'{cls.__name__}: expected {len(POSTURE_NAMES)} values '
                f'{POSTURE_NAMES}, got {len(numbers)}'
            )
        alpha, beta, phi = numbers[N_CHAINS:]
        return cls(
            stamp_ns,
            numbers[:N_CHAINS],
            alpha,
            beta,
            phi,
            device_turn=device_turn,
            scatter=scatter,
            link_length=link_length,
        )


# Renamed names: still importable for users' scripts, with a DeprecationWarning.
DEPRECATED_NAMES = {'SliderReading': 'ActuatorReading'}


def __getattr__(name: str) -> object:
    """Return a renamed name's new object, warning (PEP 562); else AttributeError."""
    return deprecated_attribute(__name__, name, DEPRECATED_NAMES, globals())
