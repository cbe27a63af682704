"""
Received postures checked and stacked: model checks, sensor ranges, Measurements.

Any machine model: the nominal parameters file names its model (``model:``, none = Hexa
Slide); `check_model` refuses to calibrate the postures of one model with the nominal
parameters of another. `posture_problem` screens a posture against the sensors' ranges (its
reason codes are the node's and the bag reader's), and `measurements_from_postures` stacks
postures into the core's Measurements.
"""

from __future__ import annotations

from typing import Sequence

from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.readings import PostureReading
import numpy as np

from ..core.architectures import KinematicParameters
from ..core.errors import InvalidMeasurementError
from ..core.machine.measurements import FIXED, MeasurementLimits, Measurements, SPHERE


# A posture whose inclinometer reads zero on both axes (within this, rad) was taken at the fixed
# position [0, 0, -L] (section 3.2's second procedure). 5e-5 rad is 37 um at L = 0.75 m: above
# the noise of an averaged reading, far below the spread of sphere postures.
FIXED_POSITION_TOLERANCE_RAD = 5e-5


# Reasons a received posture is rejected before it is stored (posture_problem).
ACTUATOR_BEYOND_STROKE = 'slider-beyond-stroke'  # (any model's actuator: a leg on a Gough-Stewart)
ANGLE_OUT_OF_RANGE = 'angle-out-of-range'
MODEL_MISMATCH = 'model-mismatch'


class ModelMismatchError(InvalidMeasurementError):
    """Postures of one machine model, nominal parameters of another: nothing to calibrate."""

    reason = MODEL_MISMATCH


def joints_text(model: str) -> str:
    names = MODELS[model].actuator_names
    return f'{names[0]}..{names[-1]}'


def check_model(
    postures_model: str | None, nominal: KinematicParameters, what: str, nominal_source: str = ''
) -> None:
    """
    Raise ModelMismatchError if postures of one model meet a nominal of another.

    ModelMismatchError if postures of `postures_model` (None: unknown, not checked) meet a nominal
    of another.
    """
    if postures_model is None or postures_model == nominal.model:
        return
    source = f' {nominal_source}' if nominal_source else ''
    raise ModelMismatchError(
        f'{what} holds {postures_model} postures (actuator joints {joints_text(postures_model)}) '
        'but the nominal '
        f"parameters{source} are a {nominal.model}'s (joints {joints_text(nominal.model)}): give "
        f'a {postures_model} '
        'nominal parameters file'
    )


def posture_problem(
    posture: PostureReading,
    limits: MeasurementLimits = MeasurementLimits(),
    model: str | None = None,
) -> tuple[str, str] | None:
    """
    (reason, description) if a (finite) posture reads beyond a sensor's range, else None.

    The same limits as the core's Measurements.validate: a posture outside them
    would make the whole identification refuse, so the node and the bag reader
    set it aside with this reason and keep every other posture. `model` names
    the actuators in the description (default: the Hexa Slide's sliders).
    """
    layout = MODELS[model or DEFAULT_MODEL]
    unit = layout.actuator_unit
    least, most = limits.actuator_range(unit)
    for name, value in zip(layout.actuator_names, posture.actuator_positions):
        if not least <= value <= most:
            return ACTUATOR_BEYOND_STROKE, (
                f'{name} = {value!r} {unit} is beyond the stroke [{least:g}, {most:g}] {unit}'
            )
    for name, value, limit in (
        ('inclinometer_x (alpha)', posture.alpha, limits.inclinometer_range_rad),
        ('inclinometer_y (beta)', posture.beta, limits.inclinometer_range_rad),
        ('rotary (phi)', posture.phi, limits.rotary_range_rad),
    ):
        if abs(value) > limit:
            return (
                ANGLE_OUT_OF_RANGE,
                f"{name} = {value!r} rad is beyond the sensor's range +-{limit:.4g} rad",
            )
    return None


def measurements_from_postures(
    postures: Sequence[PostureReading],
    fixed_tolerance_rad: float = FIXED_POSITION_TOLERANCE_RAD,
    nominal_link_length: float | None = None,
) -> Measurements:
    """
    Stack posture readings into Measurements; kinds from the inclinometer reading.

    Each posture's ``device_turn`` (rad: the device turned about its link axis, e.g. pi for a
    reversal) goes with it; a turned device reads zero at the same fixed position, so the kinds
    are told apart the same way.  The postures' scatter becomes the measurements'
    ``standard_errors`` when every posture carries it (else none: ``scatter_count`` says how
    many do).  Postures with a measured ``link_length`` (the lvdt measuring mode, m) give the
    measurements' ``link_lengths`` (L_m of eq. 4 per posture); a posture without one then
    stands at ``nominal_link_length`` (ValueError when that is not given).  When no posture has
    one the measurements have none and the device's L holds, as before.
    """
    if not postures:
        return Measurements(np.zeros((0, 6)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, str))
    actuators = np.array([p.actuator_positions for p in postures], dtype=float)
    angles = np.array([[p.alpha, p.beta] for p in postures], dtype=float)
    rotary = np.array([p.phi for p in postures], dtype=float)
    fixed = np.all(np.abs(angles) <= fixed_tolerance_rad, axis=1)
    errors = None
    if scatter_count(postures) == len(postures):
        errors = np.array(
            [p.scatter.standard_errors for p in postures if p.scatter is not None], dtype=float
        )
    return Measurements(
        actuators,
        angles,
        rotary,
        np.where(fixed, FIXED, SPHERE),
        device_turn=np.array([p.device_turn for p in postures], dtype=float),
        standard_errors=errors,
        link_lengths=_link_lengths(postures, nominal_link_length),
    )


def _link_lengths(
    postures: Sequence[PostureReading], nominal: float | None
) -> np.ndarray | None:
    """Return each posture's measured link length (m), the nominal where it has none."""
    measured = [p.link_length for p in postures]
    if all(length is None for length in measured):
        return None
    if nominal is None and any(length is None for length in measured):
        raise ValueError(
            'some postures have a measured link_length and some do not: '
            'give the nominal link length for the others'
        )
    return np.array([nominal if m is None else m for m in measured], dtype=float)


def link_length_count(postures: Sequence[PostureReading]) -> int:
    """Return how many of the postures carry a measured link length (lvdt measuring mode)."""
    return sum(p.link_length is not None for p in postures)


def scatter_count(postures: Sequence[PostureReading]) -> int:
    """Return how many of the postures carry their readings' scatter."""
    return sum(p.scatter is not None for p in postures)
