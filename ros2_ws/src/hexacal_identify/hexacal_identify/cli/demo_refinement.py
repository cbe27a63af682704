"""
The demo's drive figures split before / after target refinement, ROS-free.

The executor walks the calibration plan on nominal targets until the postures measured allow a
calibration of full rank, then on targets from intermediate calibrations (status
``targets_model``: ``nominal`` | ``calibration after N postures``,
core/walk_refine/refined_targets.py);
with refinement the demo walks the verification plan on the calibration's targets. The simulated
driver publishes its status ``hexacal driver`` at every rest (key ``rests``) with the TRUE
deviation of the commanded actuators from their setpoints there (``actuator_deviation_m``), the
force and link extension there (``force_n``, ``link_extension_m``) and the peaks of the motion
that ended there (``move_max_force_n``, ``move_max_link_extension_m``). `RestLog` hears those
statuses, each tagged with the targets' model in force when it came, and `refinement_summary`
gives summary.json's ``refinement`` object (docs/formats.md). A rest and the motion into it
count with the model of the targets that motion went to: the first motion on refined targets
starts from the last strained standing on nominal ones, so its peaks carry some of that strain;
the figures at rest do not.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import re
from typing import Any, Mapping

from hexacal_msgs_py.measuring_modes import MeasuringMode
from hexacal_msgs_py.models import ActuatorQuantities, LINEAR_ACTUATOR

from .demo_summary import status_number

NOMINAL = 'nominal'
CALIBRATION_TARGETS = 'calibration'  # the verification plan walked on the calibration's targets
_POSTURES = re.compile(r'calibration after (\d+) postures')


def refined_at(targets_model: str) -> int | None:
    """Return N of ``calibration after N postures`` (None: nominal, empty or unknown)."""
    match = _POSTURES.fullmatch(targets_model.strip())
    return int(match.group(1)) if match else None


@dataclass(frozen=True)
class Rest:
    """One rest of the machine: on refined targets or not, and the drives' figures there (SI)."""

    refined: bool
    deviation_m: float | None
    force_n: float | None
    extension_m: float | None
    move_force_n: float | None = None
    move_extension_m: float | None = None


@dataclass
class RestLog:
    """The rests heard from the driver's statuses, in order; ``missed`` those never heard."""

    rests: list[Rest] = field(default_factory=list)
    missed: int = 0
    _count: int = 0

    def hear(self, values: Mapping[str, str], refined: bool) -> bool:
        """Record the status's rest when its ``rests`` count is new; return whether it was."""
        count = status_number(values, 'rests')
        if count is None or int(count) <= self._count:
            return False
        self.missed += int(count) - self._count - 1  # replaced before it was delivered
        self._count = int(count)
        self.rests.append(
            Rest(
                refined,
                status_number(values, 'actuator_deviation_m'),
                status_number(values, 'force_n'),
                _magnitude(status_number(values, 'link_extension_m')),
                status_number(values, 'move_max_force_n'),
                status_number(values, 'move_max_link_extension_m'),
            )
        )
        return True


def _magnitude(value: float | None) -> float | None:
    return None if value is None else abs(value)


def _largest(values: list[float | None]) -> float | None:
    known = [value for value in values if value is not None]
    return max(known) if known else None


def phase_figures(rests: list[Rest], mode: str) -> dict[str, Any]:
    """
    Return the largest deviation, force (compliant) and extension (lvdt) over `rests` (SI).

    At rest, and (``max_move_*``) over the motions into those rests as well.
    """
    compliant, lvdt = mode == MeasuringMode.COMPLIANT, mode == MeasuringMode.LVDT

    def largest(name: str, applies: bool) -> float | None:
        return _largest([getattr(rest, name) for rest in rests]) if applies else None

    return {
        'rests': len(rests),
        'max_actuator_deviation_m': largest('deviation_m', True),
        'max_force_n': largest('force_n', compliant),
        'max_link_extension_m': largest('extension_m', lvdt),
        'max_move_force_n': largest('move_force_n', compliant),
        'max_move_link_extension_m': largest('move_extension_m', lvdt),
    }


def refinement_summary(
    log: RestLog,
    mode: str,
    *,
    refine: bool,
    targets_models: list[str],
    calibration_postures: int,
    verification_postures: int,
) -> dict[str, Any]:
    """
    Return summary.json's ``refinement`` object.

    ``targets_models``: the calibration walk's ``targets_model`` values in the order heard;
    the postures before the first ``calibration after N postures`` were walked on nominal
    targets, the rest of the calibration plan on refined ones, and the verification plan on
    the calibration's targets when `refine` (else on nominal ones).
    """
    counts = [n for n in (refined_at(model) for model in targets_models) if n is not None]
    refined_models = list(dict.fromkeys(m for m in targets_models if refined_at(m) is not None))
    first = min(counts[0], calibration_postures) if counts else calibration_postures
    on_refined = calibration_postures - first + (verification_postures if refine else 0)
    on_nominal = first + (0 if refine else verification_postures)
    return {
        'refine_targets': bool(refine),
        'targets_models': refined_models,
        'verification_targets': (
            None if not verification_postures else CALIBRATION_TARGETS if refine else NOMINAL
        ),
        'postures_on_nominal': on_nominal,
        'postures_on_refined': on_refined,
        'rests_missed': log.missed,
        'before': phase_figures([rest for rest in log.rests if not rest.refined], mode),
        'after': phase_figures([rest for rest in log.rests if rest.refined], mode),
    }


def refinement_lines(
    refinement: Mapping[str, Any] | None, units: ActuatorQuantities = LINEAR_ACTUATOR
) -> list[str]:
    """
    Return the before -> after lines the demo prints.

    Deviations in um and forces in N for linear actuators, urad and N m for ``units`` of
    actuators that turn; the link's extension in um.
    """
    if not refinement:
        return []
    before, after = refinement['before'], refinement['after']

    def pair(key: str, scale: float, unit: str) -> str:
        def show(value: float | None) -> str:
            return '-' if value is None else f'{value * scale:.1f}'

        return f'{show(before[key])} -> {show(after[key])} {unit}'

    lines = [
        f'before -> after refinement ({refinement["postures_on_nominal"]} postures on nominal '
        f'targets -> {refinement["postures_on_refined"]} on refined ones): deviation '
        + pair('max_actuator_deviation_m', units.small_scale, units.small)
    ]
    if before['max_force_n'] is not None or after['max_force_n'] is not None:
        lines.append(
            f'  {units.effort} at rest {pair("max_force_n", 1.0, units.effort_unit)}, moves '
            f'included {pair("max_move_force_n", 1.0, units.effort_unit)}'
        )
    if before['max_link_extension_m'] is not None or after['max_link_extension_m'] is not None:
        lines.append(
            f'  link extension at rest {pair("max_link_extension_m", 1e6, "um")}, moves '
            f'included {pair("max_move_link_extension_m", 1e6, "um")}'
        )
    if refinement.get('rests_missed'):
        lines.append(f'  ({refinement["rests_missed"]} rests not heard from the driver)')
    return lines
