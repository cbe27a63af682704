"""The identify node's parameters as one snapshot, and why a value is refused when set."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
import math
from typing import Any

from .paths import DEFAULT_OUTPUT, output_path
from .prior import LINK_LENGTH_PRIOR, prior_parameter_problem, PRIOR_PARAMETERS
from ..core.fit.compliance import COMPLIANCE_MODES
from ..core.fit.residuals import COSTS
from ..core.fit.weighting import weight_mode
from ..core.machine.device import DEVICE_PARAMETER_NAMES
from ..core.machine.measurements import NoiseModel, ScatterFloor


def names(text: str) -> tuple[str, ...]:
    """Return the names of a comma-separated list ('' = none)."""
    return tuple(name.strip() for name in text.split(',') if name.strip())


@dataclass(frozen=True)
class Settings:
    """What a calibration or verification reads of the node's parameters (same names, SI)."""

    nominal: str = ''
    output: str = DEFAULT_OUTPUT
    output_dir: str = ''
    cost: str = 'absolute'
    bag: str = ''
    link_length: float = 0.75
    identify_device: str = ''
    noise_slider_m: float = 0.0
    noise_angle_rad: float = 0.0
    robust_loss: str = ''
    verify_threshold_m: float = 0.0
    report_dir: str = 'report'
    calibration_store: str = ''  # '' = the machine model's default store (store.default_store_dir)
    weights: str = 'auto'  # core.weighting: auto, scatter, noise-model, none
    scatter_floor_actuator_m: float = ScatterFloor().actuator_m
    scatter_floor_angle_rad: float = ScatterFloor().angle_rad
    # Axial compliances identified with the geometry (core/fit/compliance.py): the choice, the
    # physical description whose weights load them ('' = the model's shipped one) and datasheet
    # priors NAME=VALUE:STD,... (m/N; '' = none), as `hexacal calibrate --compliance` takes them.
    compliance: str = 'none'
    physical_file: str = ''
    compliance_prior: str = ''
    # With compliance none: the rigid fit's deflection check (core/assessment/deflection.py)
    # with physical_file's stiffnesses, as `hexacal calibrate --physical` runs it.
    deflection_check: bool = False
    # device.* parameters by name (prior.PRIOR_PARAMETERS); missing = 0 (no prior)
    device_prior: Mapping[str, float] = field(default_factory=dict)

    def noise(self) -> NoiseModel | None:
        """Return the reading noise when both half-widths are set (> 0), else None."""
        if self.noise_slider_m > 0 and self.noise_angle_rad > 0:
            return NoiseModel(self.noise_slider_m, self.noise_angle_rad)
        return None

    def scatter_floor(self) -> ScatterFloor:
        """Return the smallest standard errors a posture is credited with (ScatterFloor)."""
        return ScatterFloor(self.scatter_floor_actuator_m, self.scatter_floor_angle_rad)


# The parameters a Settings holds one field each of (device_prior holds PRIOR_PARAMETERS).
SETTINGS_PARAMETERS = tuple(
    name for name in Settings.__dataclass_fields__ if name != 'device_prior'
)


def parameter_problem(name: str, value: Any, current: Callable[[str, Any], Any]) -> str | None:
    """
    Return why setting parameter `name` to `value` is refused, or None to accept it.

    `current(name, fallback)` is a parameter's value with the change applied (fallback when not
    declared yet): output and output_dir are checked together, and so are the link prior's two.
    """
    if name == 'identify_device':
        unknown = sorted(set(names(value)) - set(DEVICE_PARAMETER_NAMES))
        if unknown:
            return (
                f'identify_device: unknown {unknown}; choose from '
                f'{", ".join(DEVICE_PARAMETER_NAMES)}'
            )
    if name == 'robust_loss' and value != '':  # '' (the default): no import of the solver
        from ..core.fit.identification import ROBUST_LOSSES

        if value not in ROBUST_LOSSES:
            return f"robust_loss must be '', {', '.join(ROBUST_LOSSES)}; got {value!r}"
    if name == 'report_dir' and value:  # '' = no report
        try:
            output_path(value, current('output_dir', ''))
        except ValueError as error:
            return f'report_dir: {error}'
    if name == 'weights':
        try:
            weight_mode(value)
        except ValueError as error:
            return str(error)
    if name in ('scatter_floor_actuator_m', 'scatter_floor_angle_rad') and not (
        math.isfinite(value) and value > 0
    ):
        return f'{name} must be a positive standard deviation (SI), got {value!r}'
    if name == 'compliance' and value not in COMPLIANCE_MODES:
        return f'compliance must be one of {", ".join(COMPLIANCE_MODES)}, got {value!r}'
    if name == 'compliance_prior' and value:
        from ..calibration_steps.calibration_run import parse_compliance_prior

        try:
            parse_compliance_prior(value)
        except ValueError as error:
            return f'compliance_prior: {error}'
    if name == 'physical_file' and value:
        from ..core.fit.statics import MassModel

        try:
            MassModel.load(value)
        except ValueError as error:  # unreadable, or not a physical description
            return f'physical_file: {error}'
    if name == 'cost' and value not in COSTS:
        return f'cost must be one of {", ".join(COSTS)}, got {value!r}'
    if name == 'link_length' and not math.isfinite(value):
        return 'link_length must be finite'
    if name in PRIOR_PARAMETERS:
        link = (current(LINK_LENGTH_PRIOR, 0.0), current(f'{LINK_LENGTH_PRIOR}_std', 0.0))
        problem = prior_parameter_problem(name, value, link)
        if problem is not None:
            return problem
    if name in ('output', 'output_dir'):
        try:
            output_path(current('output', DEFAULT_OUTPUT), current('output_dir', ''))
        except ValueError as error:
            return str(error)
    return None
