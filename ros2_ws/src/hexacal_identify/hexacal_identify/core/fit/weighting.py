"""
What weighs a calibration: the postures' measured scatter, a noise model, or nothing.

A posture the collector averaged carries its scatter (``PostureScatter``: the standard error
of each channel's mean).  Where every posture does, the fit weighs each posture's channels by
it (``Weights.SCATTER``): a posture taken while the machine still shook, or a channel that
scattered more, counts less, and the variance factor compares the residuals with what the
postures' own scatter predicts.  Postures without scatter (a bag recorded without it,
postures given by hand) are weighed by the noise model when one is given (``--noise-um``,
the identify node's noise_slider_m / noise_angle_rad; ``Weights.NOISE_MODEL``), else not at
all (``Weights.NONE``).  The modes (``--weights``, the identify node's ``weights``):

* ``auto`` (default): scatter when every posture carries it, else the noise model when one
  is given, else none;
* ``scatter``: the postures' scatter (refused when a posture carries none);
* ``noise-model``: the noise model even where the postures carry scatter (refused without
  one);
* ``none``: unweighted.
"""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_msgs_py.models import actuator_quantities

from ..errors import InvalidMeasurementError
from ..machine.measurements import NoiseModel, ScatterFloor, Weights

AUTO, SCATTER, NOISE_MODEL, NONE = 'auto', 'scatter', 'noise-model', 'none'
WEIGHT_MODES = (AUTO, SCATTER, NOISE_MODEL, NONE)
UM = 1e6  # display only


def weight_mode(text: str) -> str:
    """Return the mode `text` names ('noise_model' is 'noise-model'); ValueError if none."""
    mode = text.strip().lower().replace('_', '-')
    if mode not in WEIGHT_MODES:
        raise ValueError(f'weights must be one of {", ".join(WEIGHT_MODES)}, got {text!r}')
    return mode


@dataclass(frozen=True)
class WeightChoice:
    """What weighs the fit, and the one line that says so (CLI, JSON, status, report)."""

    weights: Weights
    note: str


def choose_weights(
    mode: str,
    with_scatter: int,
    postures: int,
    noise: NoiseModel | None,
    floor: ScatterFloor = ScatterFloor(),
    actuator_unit: str = 'm',
) -> WeightChoice:
    """
    Return what weighs a fit of `postures` postures, `with_scatter` of which carry scatter.

    ``actuator_unit`` (the model's, m or rad) labels the actuators' figures in the note: um for
    sliders and legs, urad for cranks.  Raises InvalidMeasurementError for ``scatter`` when a
    posture carries none, ValueError for ``noise-model`` without a noise model or an unknown
    mode.
    """
    mode = weight_mode(mode)
    small = actuator_quantities(actuator_unit).small  # um, or urad for cranks
    everyone = postures > 0 and with_scatter == postures
    if mode == SCATTER and not everyone:
        raise InvalidMeasurementError(
            f"weights 'scatter': {postures - with_scatter} of {postures} postures carry no "
            "scatter (standard errors of their means); weigh by 'noise-model' or 'auto'"
        )
    if mode == SCATTER or (mode == AUTO and everyone):
        return WeightChoice(
            Weights.SCATTER,
            "each posture's measured scatter (standard errors of its means, at least "
            f'{floor.actuator_m * UM:.3g} {small} / {floor.angle_rad * UM:.3g} urad)',
        )
    # Scatter on some postures only: it cannot weigh them all alike, so it weighs none.
    partial = (
        f'{postures - with_scatter} of {postures} postures carry no scatter; '
        if mode == AUTO and with_scatter
        else ''
    )
    if mode == NOISE_MODEL and noise is None:
        raise ValueError(
            "weights 'noise-model' needs the noise model: give --noise-um (the identify node's "
            'noise_slider_m and noise_angle_rad)'
        )
    if mode in (NOISE_MODEL, AUTO) and noise is not None:
        return WeightChoice(
            Weights.NOISE_MODEL,
            f'{partial}the noise model (uniform +-{noise.actuator_m * UM:.3g} {small} on the '
            f'actuators, +-{noise.angle_rad * UM:.3g} urad on the angles, every posture alike)',
        )
    why = 'asked for' if mode == NONE else 'no noise model and no scatter'
    return WeightChoice(Weights.NONE, f'{partial}unweighted ({why})')


__all__ = ['WEIGHT_MODES', 'WeightChoice', 'choose_weights', 'weight_mode']
