"""The machine models hexacal knows: each one's parameter layout and actuator joint names (ROS-free).

A model (kinematic architecture) is six chains between the base and the
platform.  Its parameter vector is chain-major: chain 1's fields, then chain
2's, ... (SI units).  A parameters YAML names its model with the key
``model`` beside the chain keys; a file without it is a Hexa Slide, so every
file written before other models existed keeps loading.

This module owns the names and layouts only; the kinematics written against a
layout live in ``hexacal_identify.core.architectures``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import math

from hexacal_msgs_py.errors import InvalidParametersError
import numpy as np

N_CHAINS = 6
MODEL_KEY = 'model'
DEVICE_MOUNT_KEY = (
    'device.mount'  # parameters-file key of the device mount: hanging | standing (core/device.py)
)
# The measuring device's defects (core/device.py), SI units: link length offset (m), inclinometer
# zero offsets, axis non-perpendicularity and rotary zero offset (rad).  A calibrated parameters
# file carries those identified with it as `device.defects.<name>` keys (absent: not identified).
DEVICE_DEFECT_NAMES: tuple[str, ...] = ('dL', 'alpha0', 'beta0', 'gamma', 'phi0')
DEVICE_DEFECT_UNITS: tuple[str, ...] = ('m', 'rad', 'rad', 'rad', 'rad')
DEVICE_DEFECTS_KEY = 'device.defects'


def device_defect_key(name: str) -> str:
    """The parameters-file key of one identified device defect: `device.defects.<name>`."""
    if name not in DEVICE_DEFECT_NAMES:
        raise ValueError(
            f'device defect must be one of {", ".join(DEVICE_DEFECT_NAMES)}, got {name!r}'
        )
    return f'{DEVICE_DEFECTS_KEY}.{name}'


HEXA_SLIDE = 'hexa_slide'
GOUGH_STEWART = 'gough_stewart'
DEFAULT_MODEL = HEXA_SLIDE


@dataclass(frozen=True)
class ChainKey:
    """One per-chain key of the parameters file: ``chain_N.<name>``."""

    name: str
    offset: int  # first field of this key inside the chain's block
    count: int | None  # number of values; None for a scalar
    description: str


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
    physical_problem: Callable[
        [np.ndarray], str | None
    ]  # the vector's physical checks (None: fine)
    n_chains: int = N_CHAINS

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


def _hexa_slide_problem(vector: np.ndarray) -> str | None:
    for chain in range(1, N_CHAINS + 1):
        base = (chain - 1) * 9
        ax, ay = float(vector[base + 7]), float(vector[base + 8])
        norm_xy = ax * ax + ay * ay
        if norm_xy >= 1.0:
            return (
                f'chain_{chain}.a = [{ax!r}, {ay!r}] is not the x, y components of a '
                f'unit vector (ax^2 + ay^2 = {norm_xy!r} >= 1)'
            )
        length = float(vector[base + 6])
        if length <= 0.0:
            return f'chain_{chain}.l must be > 0 m, got {length!r}'
    return None


def _gough_stewart_problem(vector: np.ndarray) -> str | None:
    for chain in range(1, N_CHAINS + 1):
        offset = float(vector[(chain - 1) * 7 + 6])
        if offset <= 0.0:
            return f'chain_{chain}.l0 must be > 0 m (the leg length at actuator reading zero), got {offset!r}'
    return None


MODELS: dict[str, ModelLayout] = {
    HEXA_SLIDE: ModelLayout(
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
        physical_problem=_hexa_slide_problem,
    ),
    GOUGH_STEWART: ModelLayout(
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
        physical_problem=_gough_stewart_problem,
    ),
}


def model_layout(name: object) -> ModelLayout:
    """The layout of model `name`; an unknown name is an InvalidParametersError listing the known ones."""
    if not isinstance(name, str) or name not in MODELS:
        raise InvalidParametersError(
            f'unknown model {name!r}; hexacal knows {", ".join(sorted(MODELS))}'
        )
    return MODELS[name]


def model_for_vector_size(size: int) -> ModelLayout:
    """The one model whose vector has `size` entries (files and messages without a model name)."""
    matches = [layout for layout in MODELS.values() if layout.n_parameters == size]
    if len(matches) != 1:
        sizes = ', '.join(f'{layout.name} {layout.n_parameters}' for layout in MODELS.values())
        raise InvalidParametersError(
            f'a parameter vector of {size} values names no single model ({sizes}); give the model'
        )
    return matches[0]


def model_for_actuator_names(names: Sequence[str]) -> ModelLayout | None:
    """The model whose six actuator joints all appear in `names` (None if none does)."""
    present = set(names)
    for layout in MODELS.values():
        if present.issuperset(layout.actuator_names):
            return layout
    return None
