"""
The machine models hexacal knows: each one's parameter layout and actuator joint names (ROS-free).

A model (kinematic architecture) is six chains between the base and the
platform.  Its parameter vector is chain-major: chain 1's fields, then chain
2's, ... (SI units).  A parameters YAML names its model with the key
``model`` beside the chain keys; a file without it is a Hexa Slide, so every
file written before other models existed keeps loading.

This module owns the names and layouts only; the kinematics written against a
layout live in ``hexacal_identify.core.architectures``.  Each model is one
declarative ``ModelLayout`` (fields, units, file keys, actuator joints and the
physical checks of its vector, which name fields, never indices); a new model
is one more layout passed to ``register_model``.  The module imports no numpy,
so command-line front ends can list the models without loading it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import Any, Protocol

from hexacal_msgs_py.errors import InvalidParametersError

N_CHAINS = 6
MODEL_KEY = 'model'
DEVICE_MOUNT_KEY = (
    # parameters-file key of the device mount: hanging | standing (core/machine/device.py)
    'device.mount'
)
# The measuring device's defects (core/machine/device.py), SI units: link length offset (m),
# inclinometer zero offsets, axis non-perpendicularity and rotary zero offset (rad).  A calibrated
# parameters file carries those identified with it as `device.defects.<name>` keys (absent: not
# identified).
DEVICE_DEFECT_NAMES: tuple[str, ...] = ('dL', 'alpha0', 'beta0', 'gamma', 'phi0')
DEVICE_DEFECT_UNITS: tuple[str, ...] = ('m', 'rad', 'rad', 'rad', 'rad')
DEVICE_DEFECTS_KEY = 'device.defects'


def device_defect_key(name: str) -> str:
    """Return the parameters-file key of one identified device defect: `device.defects.<name>`."""
    if name not in DEVICE_DEFECT_NAMES:
        raise ValueError(
            f'device defect must be one of {", ".join(DEVICE_DEFECT_NAMES)}, got {name!r}'
        )
    return f'{DEVICE_DEFECTS_KEY}.{name}'


class FloatVector(Protocol):
    """A parameter vector as the checks read it: a numpy array or a sequence of floats."""

    def __getitem__(self, index: int) -> Any:
        """Return entry `index`."""


# SI units an actuator reading can have: a linear actuator's metres, a rotary one's radians.
ACTUATOR_UNITS: tuple[str, ...] = ('m', 'rad')


@dataclass(frozen=True)
class ActuatorQuantities:
    """
    The units of what an actuator reads and carries, by the kind of its motion (SI and display).

    A linear actuator (slider, leg) reads metres and carries a force; a rotary one (a motor
    turning a crank) reads radians and carries a torque.  Every consumer outside a model's
    module (noise models, drives, guards, reports, the CLI) takes its units and words from
    here, so none names a model.  ``display_scale`` converts an SI reading to ``display``
    (mm or deg), ``small_scale`` to ``small`` (um or urad: noise, deviations).
    """

    unit: str  # SI unit of the reading: 'm' or 'rad'
    kind: str  # 'linear' or 'rotary'
    reading: str  # what the reading is, in words
    effort: str  # what a drive carries ('force' or 'torque')
    effort_unit: str  # 'N' or 'N m'
    stiffness_unit: str  # servo stiffness: 'N/m' or 'N m/rad'
    speed_unit: str  # 'm/s' or 'rad/s'
    display: str  # display unit of a reading: 'mm' or 'deg'
    display_scale: float  # SI -> display
    small: str  # display unit of a small difference: 'um' or 'urad'
    small_scale: float  # SI -> small

    def shown(self, value: float, digits: int = 3) -> str:
        """Return an SI reading in the display unit, labelled (e.g. '12.300 mm', '4.500 deg')."""
        return f'{value * self.display_scale:.{digits}f} {self.display}'

    def shown_small(self, value: float, digits: int = 1) -> str:
        """Return a small SI difference in um or urad, labelled."""
        return f'{value * self.small_scale:.{digits}f} {self.small}'


LINEAR_ACTUATOR = ActuatorQuantities(
    'm', 'linear', 'actuator position', 'force', 'N', 'N/m', 'm/s', 'mm', 1e3, 'um', 1e6
)
ROTARY_ACTUATOR = ActuatorQuantities(
    'rad', 'rotary', 'actuator angle', 'torque', 'N m', 'N m/rad', 'rad/s', 'deg',
    180.0 / math.pi, 'urad', 1e6,
)
_ACTUATOR_QUANTITIES = {
    quantities.unit: quantities for quantities in (LINEAR_ACTUATOR, ROTARY_ACTUATOR)
}


def actuator_quantities(unit: str) -> ActuatorQuantities:
    """Return the units of an actuator whose readings are in `unit` ('m' or 'rad')."""
    try:
        return _ACTUATOR_QUANTITIES[unit]
    except KeyError:
        raise ValueError(
            f'actuator unit must be one of {ACTUATOR_UNITS}, got {unit!r}'
        ) from None


HEXA_SLIDE = 'hexa_slide'
GOUGH_STEWART = 'gough_stewart'
ROTARY_HEXAPOD = 'rotary_hexapod'
DEFAULT_MODEL = HEXA_SLIDE


@dataclass(frozen=True)
class ChainKey:
    """One per-chain key of the parameters file: ``chain_N.<name>``."""

    name: str
    offset: int  # first field of this key inside the chain's block
    count: int | None  # number of values; None for a scalar
    description: str

    @property
    def width(self) -> int:
        """Return the number of fields the key covers (1 for a scalar)."""
        return 1 if self.count is None else self.count


@dataclass(frozen=True)
class PositiveField:
    """Physical check: the per-chain field ``field`` must be > 0 (``note`` explains it)."""

    field: str
    note: str = ''

    def problem(self, layout: ModelLayout, chain: int, vector: FloatVector) -> str | None:
        """Return why chain's field is not positive (None: it is)."""
        value = float(vector[layout.parameter_index(chain, self.field)])
        if value <= 0.0:
            unit = layout.field_units[layout.fields.index(self.field)]
            unit_text = '' if unit == '1' else f' {unit}'  # '1': dimensionless
            return f'chain_{chain}.{self.field} must be > 0{unit_text}{self.note}, got {value!r}'
        return None


@dataclass(frozen=True)
class UnitVectorXY:
    """Physical check: fields ``x``, ``y`` (file key ``key``) are the x, y of a unit vector."""

    key: str
    x: str
    y: str

    def problem(self, layout: ModelLayout, chain: int, vector: FloatVector) -> str | None:
        """Return why chain's (x, y) is not inside the unit circle (None: it is)."""
        x = float(vector[layout.parameter_index(chain, self.x)])
        y = float(vector[layout.parameter_index(chain, self.y)])
        norm_xy = x * x + y * y
        if norm_xy >= 1.0:
            return (
                f'chain_{chain}.{self.key} = [{x!r}, {y!r}] is not the x, y components of a '
                f'unit vector ({self.x}^2 + {self.y}^2 = {norm_xy!r} >= 1)'
            )
        return None


@dataclass(frozen=True)
class FieldBelow:
    """Physical check: the per-chain field ``field`` must satisfy |value| < ``limit``."""

    field: str
    limit: float
    note: str = ''

    def problem(self, layout: ModelLayout, chain: int, vector: FloatVector) -> str | None:
        """Return why chain's field is not inside (-limit, limit) (None: it is)."""
        value = float(vector[layout.parameter_index(chain, self.field)])
        if not abs(value) < self.limit:
            unit = layout.field_units[layout.fields.index(self.field)]
            unit_text = '' if unit == '1' else f' {unit}'  # '1': dimensionless
            return (
                f'chain_{chain}.{self.field} must be within +-{self.limit!r}{unit_text}'
                f'{self.note}, got {value!r}'
            )
        return None


PhysicalCheck = PositiveField | UnitVectorXY | FieldBelow


@dataclass(frozen=True)
class ModelLayout:
    """Parameter layout and joint names of one machine model."""

    name: str
    title: str
    fields: tuple[str, ...]  # per-chain vector fields, in order
    field_units: tuple[str, ...]
    chain_keys: tuple[ChainKey, ...]  # file keys, in the order files are written
    actuator_prefix: str  # joint names are <prefix>_1 .. <prefix>_6
    actuator_description: str
    # Checked per chain, chain 1 first, each chain's checks in this order; the first failure is
    # the problem reported.
    physical_checks: tuple[PhysicalCheck, ...] = ()
    n_chains: int = N_CHAINS
    # SI unit of the actuator readings lambda: 'm' (sliders, legs) or 'rad' (motors with cranks).
    actuator_unit: str = 'm'

    def physical_problem(self, vector: FloatVector) -> str | None:
        """Return why `vector` is not a physical machine of this model (None: it is)."""
        for chain in range(1, self.n_chains + 1):
            for check in self.physical_checks:
                problem = check.problem(self, chain, vector)
                if problem:
                    return problem
        return None

    @property
    def actuator_quantities(self) -> ActuatorQuantities:
        """Return the units of this model's actuators (readings, efforts, display)."""
        return actuator_quantities(self.actuator_unit)

    @property
    def fields_per_chain(self) -> int:
        return len(self.fields)

    @property
    def n_parameters(self) -> int:
        return self.n_chains * len(self.fields)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Name of every vector entry, e.g. 'chain_3.ax'."""
        return tuple(f'chain_{c}.{f}' for c in range(1, self.n_chains + 1) for f in self.fields)

    @property
    def parameter_units(self) -> tuple[str, ...]:
        return tuple(self.field_units) * self.n_chains

    @property
    def chain_key_names(self) -> frozenset[str]:
        return frozenset(
            f'chain_{c}.{k.name}' for c in range(1, self.n_chains + 1) for k in self.chain_keys
        )

    @property
    def key_slices(self) -> dict[str, slice]:
        """Return each file key's fields inside a chain's block, in field order (A0, B, l, a)."""
        keys = sorted(self.chain_keys, key=lambda key: key.offset)
        return {key.name: slice(key.offset, key.offset + key.width) for key in keys}

    @property
    def actuator_names(self) -> tuple[str, ...]:
        return tuple(f'{self.actuator_prefix}_{i}' for i in range(1, self.n_chains + 1))

    @property
    def posture_names(self) -> tuple[str, ...]:
        """Joint names of the posture message: the actuators, then the device's three readings."""
        return self.actuator_names + DEVICE_JOINT_NAMES

    def parameter_index(self, chain: int, field: str) -> int:
        """Index into the vector of `field` of `chain` (1-based, as in chain_1)."""
        if not 1 <= chain <= self.n_chains:
            raise ValueError(f'chain must be in 1..{self.n_chains}, got {chain}')
        if field not in self.fields:
            raise ValueError(
                f'field of a {self.name} chain must be one of {self.fields}, got {field!r}'
            )
        return (chain - 1) * len(self.fields) + self.fields.index(field)


DEVICE_JOINT_NAMES: tuple[str, ...] = ('inclinometer_x', 'inclinometer_y', 'rotary')

# Optional extra joint of a posture JointState and of an inclinometer
# JointState: the measuring device's rotation about its link axis from its
# normal mounting, rad (0 normal, pi reversed, pi/2 a quarter turn).  Absent
# means 0, so every message and bag without it keeps its meaning.
DEVICE_TURN_JOINT = 'device_turn'
# |device_turn| may not exceed one full turn.
MAX_DEVICE_TURN = 2.0 * math.pi
# The fourth device reading, reserved for the ``lvdt`` measuring mode (measuring_modes.py): the
# measured length L_m of a telescopic link, m, which replaces L in eq. 4 for that posture.  Not one
# of DEVICE_JOINT_NAMES (every posture would change): an optional joint where the mode has it.
LINK_LENGTH_JOINT = 'link_length'

# --- the models: one declarative layout each ----------------------------------------------------

HEXA_SLIDE_LAYOUT = ModelLayout(
    name=HEXA_SLIDE,
    title='Hexa Slide (6-PRRS)',
    # A0 rail start (base frame), B spherical joint (platform frame), l leg length,
    # ax, ay: x, y components of the unit rail direction a (a_z < 0).
    fields=('A0x', 'A0y', 'A0z', 'Bx', 'By', 'Bz', 'l', 'ax', 'ay'),
    field_units=('m', 'm', 'm', 'm', 'm', 'm', 'm', '1', '1'),
    chain_keys=(
        ChainKey('A0', 0, 3, 'rail start point, base frame (m)'),
        ChainKey('B', 3, 3, 'spherical joint centre, platform frame (m)'),
        ChainKey('a', 7, 2, 'x, y components of the unit rail direction'),
        ChainKey('l', 6, None, 'leg length (m)'),
    ),
    actuator_prefix='slider',
    actuator_description='slider position lambda along the rail (m)',
    physical_checks=(UnitVectorXY('a', 'ax', 'ay'), PositiveField('l')),
)

GOUGH_STEWART_LAYOUT = ModelLayout(
    name=GOUGH_STEWART,
    title='Gough-Stewart platform (6-UPS)',
    # A base joint (base frame), B platform joint (platform frame), l0 leg length
    # at actuator reading zero: |p + R B - A| = lambda + l0.
    fields=('Ax', 'Ay', 'Az', 'Bx', 'By', 'Bz', 'l0'),
    field_units=('m',) * 7,
    chain_keys=(
        ChainKey('A', 0, 3, 'base joint centre, base frame (m)'),
        ChainKey('B', 3, 3, 'platform joint centre, platform frame (m)'),
        ChainKey('l0', 6, None, 'leg length at actuator reading zero (m)'),
    ),
    actuator_prefix='leg',
    actuator_description='leg extension lambda = leg length - l0 (m)',
    physical_checks=(PositiveField('l0', ' (the leg length at actuator reading zero)'),),
)

ROTARY_HEXAPOD_LAYOUT = ModelLayout(
    name=ROTARY_HEXAPOD,
    title='Rotary hexapod (6-RUS)',
    # A centre of the crank-tip circle on the motor axis (base frame), B platform joint (platform
    # frame), l rod length, r crank length, axis_az, axis_el: azimuth and elevation of the unit
    # motor axis n, alpha0: crank angle at reading zero about n from h = (-sin az, cos az, 0).
    fields=('Ax', 'Ay', 'Az', 'Bx', 'By', 'Bz', 'l', 'r', 'axis_az', 'axis_el', 'alpha0'),
    field_units=('m',) * 8 + ('rad',) * 3,
    chain_keys=(
        ChainKey('A', 0, 3, 'centre of the crank-tip circle on the motor axis, base frame (m)'),
        ChainKey('B', 3, 3, 'platform joint centre, platform frame (m)'),
        ChainKey('axis', 8, 2, 'azimuth and elevation of the unit motor axis direction (rad)'),
        ChainKey('r', 7, None, 'crank length, motor axis to crank-tip joint centre (m)'),
        ChainKey('l', 6, None, 'rod length, crank-tip joint centre to platform joint centre (m)'),
        ChainKey('alpha0', 10, None, 'crank angle at reading zero, about the motor axis (rad)'),
    ),
    actuator_prefix='crank',
    actuator_description='crank angle lambda about the motor axis from its zero (rad)',
    actuator_unit='rad',
    physical_checks=(
        PositiveField('l', ' (the rod length)'),
        PositiveField('r', ' (the crank length)'),
        FieldBelow('axis_el', math.pi / 2, ' (a vertical motor axis has no azimuth)'),
    ),
)

# Every model hexacal knows, by name (register_model adds one).
MODELS: dict[str, ModelLayout] = {}


def register_model(layout: ModelLayout) -> ModelLayout:
    """
    Add a model's layout to MODELS (a new architecture's contract half); return it.

    The layout must be consistent (one unit per field, file keys that cover every
    field once, checks that name its fields) and its name and actuator joints new.
    """
    if layout.name in MODELS:
        raise ValueError(f'model {layout.name!r} is already registered')
    if len(layout.field_units) != len(layout.fields):
        raise ValueError(f'{layout.name}: one unit per field, got {layout.field_units}')
    covered = sorted(
        i for key in layout.chain_keys for i in range(key.offset, key.offset + key.width)
    )
    if covered != list(range(len(layout.fields))):
        raise ValueError(f'{layout.name}: the chain keys must cover every field once')
    for check in layout.physical_checks:
        named = (check.x, check.y) if isinstance(check, UnitVectorXY) else (check.field,)
        unknown = [field for field in named if field not in layout.fields]
        if unknown:
            raise ValueError(f'{layout.name}: a physical check names unknown field(s) {unknown}')
    if layout.actuator_unit not in ACTUATOR_UNITS:
        raise ValueError(
            f'{layout.name}: actuator_unit must be one of {ACTUATOR_UNITS}, got '
            f'{layout.actuator_unit!r}'
        )
    for other in MODELS.values():
        if other.actuator_prefix == layout.actuator_prefix:
            raise ValueError(
                f"{layout.name}: actuator joints {layout.actuator_prefix}_N are {other.name}'s"
            )
    MODELS[layout.name] = layout
    return layout


register_model(HEXA_SLIDE_LAYOUT)
register_model(GOUGH_STEWART_LAYOUT)
register_model(ROTARY_HEXAPOD_LAYOUT)


def model_layout(name: object) -> ModelLayout:
    """Return the layout of model `name` (unknown: InvalidParametersError listing the known)."""
    if not isinstance(name, str) or name not in MODELS:
        raise InvalidParametersError(
            f'unknown model {name!r}; hexacal knows {", ".join(sorted(MODELS))}'
        )
    return MODELS[name]


def model_for_vector_size(size: int) -> ModelLayout:
    """Return the one model whose vector has `size` entries (files, messages without a model)."""
    matches = [layout for layout in MODELS.values() if layout.n_parameters == size]
    if len(matches) != 1:
        sizes = ', '.join(f'{layout.name} {layout.n_parameters}' for layout in MODELS.values())
        raise InvalidParametersError(
            f'a parameter vector of {size} values names no single model ({sizes}); give the model'
        )
    return matches[0]


def model_for_actuator_names(names: Sequence[str]) -> ModelLayout | None:
    """Return the model whose six actuator joints all appear in `names` (None if none does)."""
    present = set(names)
    for layout in MODELS.values():
        if present.issuperset(layout.actuator_names):
            return layout
    return None
