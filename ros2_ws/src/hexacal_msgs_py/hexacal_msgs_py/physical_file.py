"""
Read, write and check physical description files: the one owner of the format (ROS-free).

A physical description says what the kinematic parameters do not: masses,
stiffnesses, servo gains and friction of one machine.  The MuJoCo-simulated
machine (hexacal_driver.physics_machine), the MJCF export
(hexacal_identify.physics.mjcf) and a compliance model read it.  YAML, SI units::

    format: hexacal-physical/1
    model: hexa_slide
    gravity: [0.0, 0.0, -9.81]            # m/s^2, base frame
    platform:                             # the moving platform (platform frame)
      mass: 20.0                          # kg
      com: [0.0, 0.0, 0.0]                # m
      inertia: [0.31, 0.31, 0.63]         # kg m^2, principal moments about the com
    payload: {mass: 0.0, com: [0.0, 0.0, 0.0]}   # a point mass, platform frame
    legs: {mass: 2.0, com_fraction: 0.5}  # per leg (rod); com along the leg from its base side
    actuators: {moving_mass: 3.0}         # per actuator: slider / extending rod, kg
    link: {mass: 1.5, com_fraction: 0.5, axial_stiffness: 1.0e7}  # N/m; null = rigid
    drives:
      kp: 1.0e8                           # N/m, scalar or 6 values (one per actuator)
      kd: 4.0e4                           # N s/m, scalar or 6 values
      following_error_limit: 0.001        # m: a larger servo error is a drive fault
      release_ramp_s: 0.3                 # s: a released drive's force goes to zero this gradually
    structure:
      axial_stiffness: 5.0e7              # N/m between encoder and joint centres; null = rigid
    released_friction: {coulomb: 10.0, viscous: 100.0}   # N and N s/m, the released actuator

The drives' and the released friction's values are in the model's actuator unit (the
contract's ``actuator_unit``): for a machine whose actuators turn (the rotary hexapod's
motors, readings in rad) kp is in N m/rad, kd in N m s/rad, the following-error limit in rad
and the released friction in N m and N m s/rad; ``actuators.moving_mass`` is then the crank's
mass and ``legs`` are the rods.

Every section and key is optional except ``format`` and ``model``; what is
missing takes the shipped default of the model (`default_physical`).  An
unknown section or key, a negative mass or a non-positive stiffness is an error
naming the key.  This module imports nothing of the core.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
import math
import os
from pathlib import Path
from typing import Any, Callable, Union

from hexacal_msgs_py.errors import HexacalContractError
from hexacal_msgs_py.files import atomic_write, load_yaml_text
from hexacal_msgs_py.models import GOUGH_STEWART, HEXA_SLIDE, MODELS, ROTARY_HEXAPOD
from hexacal_msgs_py.names import N_CHAINS

PathLike = Union[str, os.PathLike]

PHYSICAL_FORMAT = 'hexacal-physical/1'
STANDARD_GRAVITY = (0.0, 0.0, -9.81)


class PhysicalFileError(HexacalContractError, ValueError):
    """A physical description that cannot be read or is not physical; names the key."""


Vector3 = tuple[float, float, float]
PerActuator = tuple[float, ...]  # N_CHAINS values


@dataclass(frozen=True)
class PhysicalDescription:
    """
    The physics of one machine (module doc): masses, stiffnesses, gains, friction (SI).

    ``drive_kp``, ``drive_kd`` and ``structure_axial_stiffness`` hold one value per actuator;
    ``None`` stiffness means rigid.
    """

    model: str
    gravity: Vector3 = STANDARD_GRAVITY
    platform_mass: float = 20.0
    platform_com: Vector3 = (0.0, 0.0, 0.0)
    platform_inertia: Vector3 = (0.3, 0.3, 0.6)
    payload_mass: float = 0.0
    payload_com: Vector3 = (0.0, 0.0, 0.0)
    leg_mass: float = 2.0
    leg_com_fraction: float = 0.5
    actuator_moving_mass: float = 3.0
    link_mass: float = 1.5
    link_com_fraction: float = 0.5
    link_axial_stiffness: float | None = 1.0e7
    drive_kp: PerActuator = (1.0e8,) * N_CHAINS
    drive_kd: PerActuator = (4.0e4,) * N_CHAINS
    following_error_limit: float = 1.0e-3
    release_ramp_s: float = 0.3
    structure_axial_stiffness: PerActuator | None = (5.0e7,) * N_CHAINS
    released_coulomb: float = 10.0
    released_viscous: float = 100.0
    source: str = field(default='', compare=False)  # the file it was read from (messages)

    def __post_init__(self) -> None:
        """Normalise numbers to floats and check every value; PhysicalFileError names the key."""
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, (list, tuple)):
                object.__setattr__(self, f.name, tuple(_as_float(v) for v in value))
            elif f.name not in ('model', 'source') and value is not None:
                object.__setattr__(self, f.name, _as_float(value))
        problem = physical_problem(self)
        if problem:
            where = f'{self.source}: ' if self.source else ''
            raise PhysicalFileError(f'{where}{problem}')

    @property
    def rigid(self) -> bool:
        """Return True when neither the structure nor the link has a spring."""
        return self.structure_axial_stiffness is None and self.link_axial_stiffness is None

    def made_rigid(self) -> 'PhysicalDescription':
        """Return the same machine without structural or link compliance."""
        return replace(self, structure_axial_stiffness=None, link_axial_stiffness=None)

    def weightless(self) -> 'PhysicalDescription':
        """Return the same machine with gravity off."""
        return replace(self, gravity=(0.0, 0.0, 0.0))


# Key of each field in the file: (section, key).
_FILE_KEYS: dict[str, tuple[str, str]] = {
    'platform_mass': ('platform', 'mass'),
    'platform_com': ('platform', 'com'),
    'platform_inertia': ('platform', 'inertia'),
    'payload_mass': ('payload', 'mass'),
    'payload_com': ('payload', 'com'),
    'leg_mass': ('legs', 'mass'),
    'leg_com_fraction': ('legs', 'com_fraction'),
    'actuator_moving_mass': ('actuators', 'moving_mass'),
    'link_mass': ('link', 'mass'),
    'link_com_fraction': ('link', 'com_fraction'),
    'link_axial_stiffness': ('link', 'axial_stiffness'),
    'drive_kp': ('drives', 'kp'),
    'drive_kd': ('drives', 'kd'),
    'following_error_limit': ('drives', 'following_error_limit'),
    'release_ramp_s': ('drives', 'release_ramp_s'),
    'structure_axial_stiffness': ('structure', 'axial_stiffness'),
    'released_coulomb': ('released_friction', 'coulomb'),
    'released_viscous': ('released_friction', 'viscous'),
}
_SECTIONS = ('gravity',) + tuple(dict.fromkeys(section for section, _ in _FILE_KEYS.values()))
_VECTORS = {'gravity', 'platform_com', 'platform_inertia', 'payload_com'}
_PER_ACTUATOR = {'drive_kp', 'drive_kd', 'structure_axial_stiffness'}
_NULLABLE = {'link_axial_stiffness', 'structure_axial_stiffness'}
_POSITIVE = {
    'platform_mass', 'link_axial_stiffness', 'drive_kp', 'following_error_limit',
    'structure_axial_stiffness',
}
_NON_NEGATIVE = {
    'payload_mass', 'leg_mass', 'actuator_moving_mass', 'link_mass', 'drive_kd',
    'released_coulomb', 'released_viscous', 'platform_inertia', 'release_ramp_s',
}
_FRACTIONS = {'leg_com_fraction', 'link_com_fraction'}


def key_name(field_name: str) -> str:
    """Return the file key of a PhysicalDescription field ('platform.mass'; 'gravity')."""
    if field_name in _FILE_KEYS:
        section, key = _FILE_KEYS[field_name]
        return f'{section}.{key}'
    return field_name


def physical_problem(description: PhysicalDescription) -> str | None:
    """Return what is wrong with a description, naming the file key (None: nothing)."""
    if description.model not in MODELS:
        return f'model must be one of {", ".join(MODELS)}, got {description.model!r}'
    for f in fields(description):
        if f.name in ('model', 'source'):
            continue
        value = getattr(description, f.name)
        name = key_name(f.name)
        if value is None:
            if f.name not in _NULLABLE:
                return f'{name} must be given (null only for a stiffness)'
            continue
        values = value if isinstance(value, tuple) else (value,)
        expected = 3 if f.name in _VECTORS else N_CHAINS if f.name in _PER_ACTUATOR else 1
        if len(values) != expected:
            return f'{name} must hold {expected} value(s), got {len(values)}'
        if not all(isinstance(v, float) and math.isfinite(v) for v in values):
            return f'{name} must be finite numbers (SI units), got {value!r}'
        if f.name in _POSITIVE and min(values) <= 0.0:
            return f'{name} must be positive, got {value!r}'
        if f.name in _NON_NEGATIVE and min(values) < 0.0:
            return f'{name} must not be negative, got {value!r}'
        if f.name in _FRACTIONS and not 0.0 <= values[0] <= 1.0:
            return f'{name} is a fraction of the length from the base side: 0..1, got {value!r}'
    return None


# Shipped defaults of a realistic machine, per model (unlisted models: the dataclass defaults).
_MODEL_DEFAULTS: dict[str, dict[str, Any]] = {
    # A 20 kg platform about 0.5 m across (a disc: I = m r^2 / 4, m r^2 / 2), 2 kg legs, 3 kg
    # carriages on ball screws with stiff servos (kp 1e8 N/m), a 1.5 kg measuring link.
    HEXA_SLIDE: {'platform_inertia': (0.3125, 0.3125, 0.625)},
    # A 0.4 m platform on electric cylinders: 1.5 kg moving rods, softer servos (kp 1e7 N/m).
    GOUGH_STEWART: {
        'platform_inertia': (0.2, 0.2, 0.4),
        'actuator_moving_mass': 1.5,
        'drive_kp': (1.0e7,) * N_CHAINS,
        'drive_kd': (1.2e4,) * N_CHAINS,
    },
    # A 10 kg platform 0.5 m across, 1 kg cranks of 0.15 m and 0.5 kg rods; geared servo motors
    # of 2e5 N m/rad (8.9e6 N/m at the crank tip; kd with the platform's share of the inertia
    # settles in 0.5 s and lags 2 mrad on a 0.15 s move) with a 5 mrad following-error limit
    # (0.75 mm at the tip), a released motor's gearbox 1 N m and 10 N m s/rad, rods of 2e7 N/m.
    ROTARY_HEXAPOD: {
        'platform_mass': 10.0,
        'platform_inertia': (0.16, 0.16, 0.32),
        'leg_mass': 0.5,
        'actuator_moving_mass': 1.0,
        'drive_kp': (2.0e5,) * N_CHAINS,
        'drive_kd': (300.0,) * N_CHAINS,
        'following_error_limit': 5.0e-3,
        'structure_axial_stiffness': (2.0e7,) * N_CHAINS,
        'released_coulomb': 1.0,
        'released_viscous': 10.0,
    },
}


def default_physical(model: str = HEXA_SLIDE) -> PhysicalDescription:
    """Return the shipped physical description of a realistic machine of ``model``."""
    if model not in MODELS:
        raise PhysicalFileError(f'model must be one of {", ".join(MODELS)}, got {model!r}')
    return PhysicalDescription(model=model, **_MODEL_DEFAULTS.get(model, {}))


def physical_document(description: PhysicalDescription) -> dict[str, Any]:
    """Return the file's document (plain dicts and lists) of a description."""
    document: dict[str, Any] = {
        'format': PHYSICAL_FORMAT,
        'model': description.model,
        'gravity': list(description.gravity),
    }
    for name, (section, key) in _FILE_KEYS.items():
        value = getattr(description, name)
        if isinstance(value, tuple):
            value = value[0] if name in _PER_ACTUATOR and len(set(value)) == 1 else list(value)
        document.setdefault(section, {})[key] = value
    return document


def physical_file_text(description: PhysicalDescription) -> str:
    """Return the YAML text of a description (the written bytes)."""
    import yaml

    header = (
        '# hexacal physical description (SI units: kg, m, kg m^2, N/m, N s/m, N, m/s^2);\n'
        '# docs/formats.md "Physical description files".\n'
    )
    return header + yaml.safe_dump(
        physical_document(description), sort_keys=False, default_flow_style=None
    )


def write_physical_file(path: PathLike, description: PhysicalDescription) -> Path:
    """Write a description atomically; return the path."""
    return atomic_write(Path(path), physical_file_text(description))


def read_physical_file(path: PathLike) -> PhysicalDescription:
    """Read and check a physical description file; PhysicalFileError names the file and key."""
    name = os.fspath(path)
    try:
        text = Path(path).read_text(encoding='utf-8')
    except (OSError, UnicodeDecodeError) as error:
        raise PhysicalFileError(f'{name}: cannot read a physical description: {error}') from error
    return physical_from_text(text, name)


def physical_from_text(text: str, source: str = '<text>') -> PhysicalDescription:
    """Parse a physical description from YAML text (``source`` names it in errors)."""
    import yaml

    def fail(message: str) -> PhysicalFileError:
        return PhysicalFileError(f'{source}: {message}')

    # ROS 2's reading of numbers (1e7 is a float), as parameters files are read.
    from hexacal_msgs_py.parameters_file import _FAST_LOADERS, _RosParametersLoader

    try:
        document = load_yaml_text(
            text, _RosParametersLoader, _FAST_LOADERS.get(_RosParametersLoader)
        )
    except (yaml.YAMLError, RecursionError) as error:
        raise fail(f'invalid YAML: {error}') from None
    return physical_from_document(document, source, fail)


def physical_from_document(
    document: object,
    source: str = '<document>',
    fail: Callable[[str], PhysicalFileError] | None = None,
) -> PhysicalDescription:
    """Build a description from a parsed document; missing keys take the model's defaults."""
    if fail is None:
        def fail(message: str) -> PhysicalFileError:
            return PhysicalFileError(f'{source}: {message}')
    if not isinstance(document, dict):
        raise fail('a physical description is a mapping with format, model and sections')
    if document.get('format') != PHYSICAL_FORMAT:
        raise fail(f'format must be {PHYSICAL_FORMAT!r}, got {document.get("format")!r}')
    model = document.get('model')
    if not isinstance(model, str) or model not in MODELS:
        raise fail(f'model must be one of {", ".join(MODELS)}, got {model!r}')
    unknown = sorted(set(map(str, document)) - {'format', 'model', *_SECTIONS})
    if unknown:
        raise fail(f'unknown key {unknown[0]!r}; the sections are {", ".join(_SECTIONS)}')
    values: dict[str, Any] = {}
    if 'gravity' in document:
        values['gravity'] = _vector(document['gravity'], 'gravity', 3, fail)
    by_section: dict[str, dict[str, str]] = {}
    for name, (section, key) in _FILE_KEYS.items():
        by_section.setdefault(section, {})[key] = name
    for section, keys in by_section.items():
        if section not in document:
            continue
        entries = document[section]
        if not isinstance(entries, dict):
            raise fail(f'{section} must be a mapping of {", ".join(keys)}, got {entries!r}')
        for key, value in entries.items():
            if key not in keys:
                raise fail(
                    f'unknown key {section}.{key}; {section} holds {", ".join(keys)}'
                )
            name = keys[key]
            if value is None and name in _NULLABLE:
                values[name] = None
            elif name in _VECTORS:
                values[name] = _vector(value, f'{section}.{key}', 3, fail)
            elif name in _PER_ACTUATOR:
                if isinstance(value, list):
                    values[name] = _vector(value, f'{section}.{key}', N_CHAINS, fail)
                else:
                    values[name] = (_number(value, f'{section}.{key}', fail),) * N_CHAINS
            else:
                values[name] = _number(value, f'{section}.{key}', fail)
    base = default_physical(model)
    try:
        return replace(base, source=source, **values)
    except PhysicalFileError as error:
        raise PhysicalFileError(str(error)) from None


def _as_float(value: object) -> object:
    """Return a real number as float (others unchanged: the check names them)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    return value


def _number(value: object, name: str, fail: Callable[[str], PhysicalFileError]) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise fail(f'{name} must be a number (SI units), got {value!r}')
    return float(value)


def _vector(
    value: object, name: str, size: int, fail: Callable[[str], PhysicalFileError]
) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != size:
        raise fail(f'{name} must be a list of {size} numbers (SI units), got {value!r}')
    return tuple(_number(v, f'{name}[{i}]', fail) for i, v in enumerate(value))
