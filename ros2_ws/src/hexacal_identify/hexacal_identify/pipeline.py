"""
The calibration call shared by the identify node and ``hexacal calibrate``, and bag -> postures.

The node and the CLI both go through :func:`calibrate`, so a bag calibrated
offline gives the same parameters as the node that received the same postures.
No rclpy here: the message objects from a bag are decoded by mcap_ros2 and read
through the contract's name-based conversions.

Any machine model: the nominal parameters file names its model (``model:``,
none = Hexa Slide), and a bag's actuator joint names tell which model recorded
it (slider_1..6: Hexa Slide, leg_1..6: Gough-Stewart; the collector also
stores it in the bag's ``hexacal.collector`` metadata). `check_model` refuses to
calibrate the postures of one model with the nominal parameters of another.

Inputs from a user's own drivers: when the collector recorded an input mapping
(hexacal_msgs_py.inputs, in ``hexacal.collector``), the raw inputs are the
recorded topics (e.g. one /joint_states for all three, an Imu inclinometer)
read by that mapping, through the same contract conversions the collector uses;
a bag without one is read by the contract's topics and joints, as always.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from math import isfinite as _isfinite
from pathlib import Path
from typing import Sequence

from hexacal_msgs_py.inputs import IMU_INCLINOMETER, INPUT_NAMES, InputMapping, InputMappingError
from hexacal_msgs_py.models import DEFAULT_MODEL, device_defect_key, DEVICE_DEFECTS_KEY, MODELS
from hexacal_msgs_py.models import DEVICE_MOUNT_KEY as MOUNT_PARAMETER
from hexacal_msgs_py.names import (
    ENCODER_TOPIC,
    IMU_TYPE,
    INCLINOMETER_TOPIC,
    JOINT_STATE_TYPE,
    LINK_LENGTH_JOINT,
    LINK_TOPIC,
    POSTURE_TOPIC,
    SLIDERS_TOPIC,
)
from hexacal_msgs_py.readings import PostureReading
import numpy as np

from .bag.measuring import MEASURING_METADATA, MeasuringRecord
from .bag.naming import COLLECTOR_METADATA  # the collector's record: model, detector, mapping
from .core.architectures import KinematicParameters, parameters_for
from .core.detection.vocabulary import detector_problem
from .core.errors import InvalidMeasurementError
from .core.fit.compliance import ComplianceModel
from .core.fit.identification import IdentificationResult, identify, SolverOptions
from .core.fit.weighting import AUTO, choose_weights, WeightChoice
from .core.machine.device import (
    check_mount,
    DEFAULT_MOUNT,
    DEVICE_PARAMETER_NAMES,
    DeviceDefects,
    DeviceModel,
    DevicePrior,
)
from .core.machine.measurements import (
    FIXED,
    MeasurementLimits,
    Measurements,
    NoiseModel,
    ScatterFloor,
    SPHERE,
    Weights,
)
from .core.machine.model import parameter_names

# A posture whose inclinometer reads zero on both axes (within this, rad) was taken at the fixed
# position [0, 0, -L] (section 3.2's second procedure). 5e-5 rad is 37 um at L = 0.75 m: above
# the noise of an averaged reading, far below the spread of sphere postures.
FIXED_POSITION_TOLERANCE_RAD = 5e-5
RAW_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)
TABLE1_FILE = Path(__file__).parent / 'data' / 'table1_exact.yaml'  # the default "exact" machine
# Reasons a received posture is rejected before it is stored (posture_problem).
ACTUATOR_BEYOND_STROKE = 'slider-beyond-stroke'  # (any model's actuator: a leg on a Gough-Stewart)
ANGLE_OUT_OF_RANGE = 'angle-out-of-range'
MODEL_MISMATCH = 'model-mismatch'


class ModelMismatchError(InvalidMeasurementError):
    """Postures of one machine model, nominal parameters of another: nothing to calibrate."""

    reason = MODEL_MISMATCH


def load_machine(path: Path | str) -> KinematicParameters:
    """
    Load the parameters of a parameters YAML, of the model it names.

    The parameters of a parameters YAML, of the model it names (ParameterFileError names the file
    and key).
    """
    return load_machine_and_mount(path)[0]


def load_machine_and_mount(path: Path | str) -> tuple[KinematicParameters, str]:
    """
    Load (parameters, device mount) of a parameters YAML.

    Its model's parameters and its ``device.mount`` (default hanging; another value is a
    DeviceMountError naming the file).
    """
    from hexacal_msgs_py.parameters_file import read_parameters_file

    from .core.machine.device import DeviceMountError

    loaded = read_parameters_file(path)
    try:
        mount = check_mount(loaded.extras.get(MOUNT_PARAMETER, DEFAULT_MOUNT))
    except DeviceMountError as error:
        raise DeviceMountError(f'{path}: {MOUNT_PARAMETER}: {error}') from None
    return parameters_for(loaded.model, loaded.vector), mount


def device_defects_extras(result: IdentificationResult) -> dict[str, float]:
    """
    Return the parameters-file keys of the device defects identified with `result`.

    The parameters-file keys (`device.defects.<name>`, SI) of the device defects identified with
    `result`; none identified: {} (the file is exactly as without the device).
    """
    return {
        device_defect_key(name): float(getattr(result.device, name)) for name in result.free_device
    }


def compliance_file_extras(result: IdentificationResult) -> dict[str, float]:
    """Return the parameters-file keys of the compliances identified with `result` ({}: rigid)."""
    from hexacal_msgs_py.parameters_file import compliance_extras

    return compliance_extras(result.compliance, result.compliance_std)


def load_device_defects(path: Path | str) -> tuple[DeviceDefects, tuple[str, ...]]:
    """
    Load the device defects a calibrated parameters file was calibrated with.

    (defects, names given) of a calibrated parameters file's `device.defects.<name>` keys: the
    device it was calibrated with (device_defects_from_extras).
    """
    from hexacal_msgs_py.parameters_file import read_parameters_file

    return device_defects_from_extras(read_parameters_file(path).extras, path)


def device_defects_from_extras(
    extras: dict, path: Path | str
) -> tuple[DeviceDefects, tuple[str, ...]]:
    """
    Return (defects, names given) of a parameters file's extras.

    (defects, names given) of a parameters file's extras (read_parameters_file). Absent keys are 0
    (the ideal device); a key naming no defect or a value that is not a small finite number is a
    ParameterFileError naming the file (`path`) and the key.
    """
    from hexacal_msgs_py.errors import ParameterFileError

    prefix = DEVICE_DEFECTS_KEY + '.'
    values: dict[str, float] = {}
    for key, value in extras.items():
        if not key.startswith(prefix):
            continue
        name = key[len(prefix):]
        if name not in DEVICE_PARAMETER_NAMES:
            raise ParameterFileError(
                f'{path}: {key}: not a device defect (one of {", ".join(DEVICE_PARAMETER_NAMES)})'
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterFileError(f'{path}: {key}: must be a number in SI units, got {value!r}')
        values[name] = float(value)
    try:
        return DeviceDefects(**values), tuple(values)
    except ValueError as error:
        raise ParameterFileError(f'{path}: {DEVICE_DEFECTS_KEY}: {error}') from None


def _joints_text(model: str) -> str:
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
        f'{what} holds {postures_model} postures (actuator joints {_joints_text(postures_model)}) '
        'but the nominal '
        f"parameters{source} are a {nominal.model}'s (joints {_joints_text(nominal.model)}): give "
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
        device_turn=[p.device_turn for p in postures],
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


def weight_choice(
    postures: Sequence[PostureReading],
    weights: str = AUTO,
    noise: NoiseModel | None = None,
    scatter_floor: ScatterFloor = ScatterFloor(),
) -> WeightChoice:
    """Return what weighs a calibration of `postures` (core.weighting.choose_weights)."""
    return choose_weights(weights, scatter_count(postures), len(postures), noise, scatter_floor)


def calibrate(
    nominal: KinematicParameters,
    postures: Sequence[PostureReading],
    *,
    cost: str = 'absolute',
    link_length: float = DeviceModel().link_length,
    allow_rank_deficient: bool = False,
    identify_device: Sequence[str] = (),
    noise: NoiseModel | None = None,
    robust_loss: str | None = None,
    mount: str = DEFAULT_MOUNT,
    device_prior: DevicePrior | None = None,
    weights: str = AUTO,
    scatter_floor: ScatterFloor = ScatterFloor(),
    compliance: ComplianceModel | None = None,
) -> IdentificationResult:
    """
    Identify the parameters from received postures: the one call behind the node and the CLI.

    ``nominal`` is the starting parameter set of any architecture (its model is the
    result's). ``identify_device`` names device defects to identify jointly (e.g. dL,
    alpha0, gamma).  ``weights`` (core.weighting: auto, scatter, noise-model, none) says what
    weighs the residuals: by default the postures' scatter where every posture carries it
    (each standard error raised to ``scatter_floor``), else ``noise`` (reading noise
    half-widths) when given; the result's ``weights`` / ``weights_note`` say which.
    ``mount`` is the device's (hanging, or standing for an upright machine).
    ``device_prior``: prior knowledge of device parameters (a caliper's dL = 0 +- 10 um, a
    certificate's alpha0 = 0 +- 50 urad; SI units): each such parameter is identified, its prior
    weighed against the data by ``noise``, which it therefore requires (ValueError naming both).
    A problem the postures do not determine raises RankDeficientError (never a
    number that means nothing) unless ``allow_rank_deficient``.  ``compliance``: axial
    compliances identified with the geometry from the postures' static loads
    (core/fit/compliance.py; None: the rigid model).
    """
    choice = weight_choice(postures, weights, noise, scatter_floor)
    options = SolverOptions(
        cost=cost,
        device=DeviceModel(link_length=link_length, mount=mount),
        allow_rank_deficient=allow_rank_deficient,
        free_device=tuple(identify_device),
        noise=noise if choice.weights == Weights.NOISE_MODEL else None,
        robust_loss=robust_loss,
        device_prior=device_prior if device_prior is not None else DevicePrior(),
        scatter_weights=choice.weights == Weights.SCATTER,
        scatter_floor=scatter_floor,
        compliance=compliance if compliance is not None else ComplianceModel(),
    )
    measurements = measurements_from_postures(postures, nominal_link_length=link_length)
    result = identify(nominal, measurements, options)
    result.weights_note = choice.note
    return result


def device_prior_json(prior: DevicePrior | None) -> dict[str, dict[str, float]]:
    """
    Return {name: {"value", "std"}} (SI units) of a device prior.

    {"value", "std"}} (SI units) of a device prior: what ``calibrate --json`` and the report carry.
    """
    if prior is None:
        return {}
    return {name: {'value': float(value), 'std': float(std)} for name, value, std in prior.entries}


def status_fields(
    result: IdentificationResult, device_prior: DevicePrior | None = None
) -> dict[str, str]:
    """
    Key/values for /hexacal/calibration_status (SI units, machine-readable).

    Identified device parameters: posterior ``device.<name>`` / ``std.device.<name>``; with a prior
    on
    one, also ``prior.device.<name>`` / ``prior_std.device.<name>``. The fit's adequacy
    (core.adequacy): ``adequacy.verdict`` / ``adequacy.reason`` always, the figures
    (``adequacy.variance_factor``, ``adequacy.expected_low`` / ``_high``, ``adequacy.dof``) and
    the worst ``adequacy.worst_postures`` / ``adequacy.worst_channels`` with a noise model.
    ``weights`` (scatter, noise_model, none) and ``weights_note``: what weighed the fit.
    """
    model = result.parameters.model
    fields = {
        'outcome': result.reason,
        'model': model,
        'cost': result.cost,
        'rank': str(result.rank),
        'condition_number': f'{result.condition_number:.6g}',
        'iterations': str(result.iterations),
        'postures_used': str(len(result.used_postures)),
        'postures_rejected': str(len(result.rejected_postures)),
        'solve_seconds': f'{result.solve_seconds:.6f}',
        'identifiable': str(result.identifiability.identifiable).lower(),
    }
    fields['identifiability'] = result.identifiability.verdict().replace('\n', ' ')
    fields.update({f'rms_residual.{k}': f'{v:.6g}' for k, v in result.rms_residual.items()})
    for index, name in enumerate(DEVICE_PARAMETER_NAMES):
        if name in result.free_device:
            fields[f'device.{name}'] = f'{result.device.vector[index]:.6g}'
            fields[f'std.device.{name}'] = f'{result.device_std[index]:.6g}'
        prior = device_prior.get(name) if device_prior is not None else None
        if prior is not None:
            fields[f'prior.device.{name}'] = f'{prior[0]:.6g}'
            fields[f'prior_std.device.{name}'] = f'{prior[1]:.6g}'
    fields.update(
        {f'std.{name}': f'{s:.6g}' for name, s in zip(parameter_names(model), result.std)}
    )
    for index, why in sorted(result.rejected_postures.items())[:20]:
        fields[f'rejected.{index}'] = why
    # The fit against its noise model (adequacy.verdict unknown without one).
    fields.update(result.adequacy.status_fields())
    fields['weights'] = result.weights
    if result.weights_note:
        fields['weights_note'] = result.weights_note
    return fields


@dataclass
class BagPostures:
    postures: list[PostureReading]
    source: str  # "posture topic" or "raw streams (re-detected)"
    plan: dict[str, str] = field(default_factory=dict)  # recorded posture plan metadata, if any
    ignored_topics: list[str] = field(default_factory=list)
    invalid_messages: int = 0  # readings of hexacal's inputs that were not valid (skipped)
    # Postures set aside (posture_problem): (index among the bag's postures, reason, description).
    rejected: list[tuple[int, str, str]] = field(default_factory=list)
    # The machine model that recorded the bag: its actuator joint names (else the collector's
    # metadata); None when the bag holds neither.
    model: str | None = None
    # The input mapping the collector recorded (topics and joints of the raw inputs); None: a bag
    # without one, whose raw inputs are the contract's topics and joints.
    mapping: InputMapping | None = None
    # The measuring mode and released actuators the collector recorded (bag.measuring); an empty
    # record (mode None) for a bag without one.
    measuring: MeasuringRecord = field(default_factory=MeasuringRecord)
    # What re-detection noticed in words, e.g. still periods a lagging stream never settled in.
    notes: list[str] = field(default_factory=list)

    @property
    def measuring_mode(self) -> str | None:
        """Return the measuring mode the bag was recorded in, None when it does not say."""
        return self.measuring.mode


def _screened(
    postures: list[PostureReading], model: str | None = None
) -> tuple[list[PostureReading], list[tuple[int, str, str]]]:
    kept, rejected = [], []
    for index, posture in enumerate(postures):
        problem = posture_problem(posture, model=model)
        if problem is None:
            kept.append(posture)
        else:
            rejected.append((index, *problem))
    return kept, rejected


def _topic_key(topic: str) -> str:
    """'hexacal/posture' for '/hexacal/posture' and for a namespaced '/left/hexacal/posture'."""
    parts = topic.strip('/').split('/')
    return (
        '/'.join(parts[-2:]) if len(parts) >= 2 and parts[-2] == 'hexacal' else topic.lstrip('/')
    )


# Where postures come from: the posture topic if the bag has one, else the raw inputs ("auto");
# only the posture topic; or always re-detected from the raw inputs.
POSTURE_SOURCES = ('auto', 'posture', 'raw')
# The collector's detector settings in its metadata record: re-detection uses them.
_DETECTOR_SETTINGS = (
    'window_s',
    'capture_s',
    'slider_tolerance_m',
    'angle_tolerance_rad',
    'max_gap_s',
    'max_skew_s',
)

CLOCK_OFFSET_SETTINGS = ('inclinometer_clock_offset_s', 'encoder_clock_offset_s')


def postures_from_bag(
    path: Path | str, *, source: str = 'auto', **detector_options
) -> BagPostures:
    """
    Postures of a bag: its posture topic, else re-detected from the raw inputs.

    ``source``: "auto" (the posture topic if there is one, else the raw inputs), "posture"
    (the posture topic only) or "raw" (re-detect even when there is a posture topic).
    Re-detection uses the detector settings the collector recorded (``hexacal.collector``;
    the detector's defaults where none), ``detector_options`` override them (window_s,
    capture_s, slider_tolerance_m, angle_tolerance_rad, max_gap_s, max_skew_s; ``detector``
    'settled', the only one, ``inclinometer_clock_offset_s``/``encoder_clock_offset_s``
    (s; None: estimated, or the collector's when it was told them), see `_redetect`).

    The raw inputs are the contract's topics (hexacal/sliders, hexacal/inclinometer,
    hexacal/encoder, any namespace) and joints, or, when the collector recorded an input
    mapping (hexacal_msgs_py.inputs: ``actuator_joints``, ``inclinometer_type``, the topic of
    each input, ...), the recorded topics read by that mapping: e.g. all three from one
    /joint_states with custom joint names, the inclinometer from a sensor_msgs/Imu, with
    signs and offsets applied. The posture topic has the contract's names either way.

    Either machine model: the actuator joints of the posture (or sliders) messages
    tell which (``model``), else the model the collector recorded; a bag mixing the
    joints of two models, or whose joints contradict the model its collector recorded,
    raises InvalidMeasurementError.

    Other topics are ignored; a bag with neither a posture topic nor all three raw
    inputs raises InvalidMeasurementError naming what is missing.  Bag-format
    problems raise the bag layer's BagError subclasses, also an input topic whose
    definition is another message version.  Messages that do not decode or are not
    valid readings are skipped and counted (``invalid_messages``, per reading);
    postures beyond a sensor's range are set aside with the reason (``rejected``).
    """
    from .bag import open_bag

    if source not in POSTURE_SOURCES:
        raise ValueError(f'source must be one of {", ".join(POSTURE_SOURCES)}, got {source!r}')
    reader = open_bag(path)
    topics: dict[str, str] = {}
    for topic in reader.topics():
        key = _topic_key(topic)
        if key in topics and key in (POSTURE_TOPIC, *RAW_TOPICS):
            raise InvalidMeasurementError(
                f'bag {path} holds {key} from several namespaces ({topics[key]}, {topic}): '
                'calibrate one machine at a time'
            )
        topics[key] = topic
    plan: dict[str, str] = {}
    collector: dict[str, str] = {}
    measuring = MeasuringRecord()
    for record in reader.metadata():
        if record.name.startswith('hexacal'):
            plan.update({f'{record.name}.{k}': v for k, v in record.data.items()})
        if record.name == COLLECTOR_METADATA:
            collector.update(record.data)
        if record.name == MEASURING_METADATA:  # rewritten as it changes: the last one holds
            measuring = MeasuringRecord.from_metadata(record.data)
    recorded_model = plan.get(RECORDED_MODEL_KEY) or None
    if recorded_model is not None and recorded_model not in MODELS:
        raise InvalidMeasurementError(
            f'bag {path}: its metadata names an unknown model {recorded_model!r} '
            f'({RECORDED_MODEL_KEY}); hexacal knows {", ".join(MODELS)}'
        )
    try:
        mapping = InputMapping.from_metadata(collector, recorded_model)
    except InputMappingError as error:
        raise InvalidMeasurementError(
            f'bag {path}: the input mapping its collector recorded '
            f'({COLLECTOR_METADATA}) is invalid: {error}'
        ) from None
    raw = _raw_topics(reader.topics(), topics, mapping)
    ours = {topics[POSTURE_TOPIC]} if POSTURE_TOPIC in topics else set()
    ours.update(raw.values())
    link_topic = topics.get(LINK_TOPIC)  # the lvdt's link length, when the machine has one
    if link_topic is not None:
        ours.add(link_topic)
    ignored = sorted(t for t in reader.topics() if t not in ours)
    expected = _expected_types(topics, raw, mapping)
    if link_topic is not None:
        expected[link_topic] = JOINT_STATE_TYPE
    _check_types(reader, expected)
    if POSTURE_TOPIC in topics and source != 'raw':
        models: set[str] = set()
        postures, invalid = _valid(
            reader.messages([topics[POSTURE_TOPIC]]), lambda m: _posture(m, models, recorded_model)
        )
        model = _bag_model(path, models, recorded_model)
        kept, rejected = _screened(postures, model)
        return BagPostures(
            kept, 'posture topic', plan, ignored, invalid, rejected, model, mapping, measuring
        )
    if source == 'posture':
        raise InvalidMeasurementError(f'bag {path} has no {POSTURE_TOPIC} topic')
    missing = [_input_text(t, mapping) for t in RAW_TOPICS if t not in raw]
    if missing:
        raise InvalidMeasurementError(
            f'bag {path} has no {POSTURE_TOPIC} topic and lacks the raw stream(s) '
            f'{", ".join(missing)} needed to re-detect postures'
            if POSTURE_TOPIC not in topics
            else f'bag {path} lacks the raw stream(s) {", ".join(missing)} needed to re-detect '
            'postures'
        )
    options = {
        name: float(collector[name])
        for name in _DETECTOR_SETTINGS
        if _is_number(collector.get(name))
    }
    if collector.get('estimate_clock_offsets') == 'False':  # offsets the collector was told
        for name in CLOCK_OFFSET_SETTINGS:
            if _is_number(collector.get(name)):
                options[name] = float(collector[name])
    options.update(detector_options)
    models = set()
    if link_topic is not None:
        options['link_topic'] = link_topic
    notes: list[str] = []
    postures, invalid = _redetect(
        reader, raw, mapping, models, recorded_model, notes=notes, **options
    )
    model = _bag_model(path, models, recorded_model)
    kept, rejected = _screened(postures, model)
    return BagPostures(
        kept,
        'raw streams (re-detected)',
        plan,
        ignored,
        invalid,
        rejected,
        model,
        mapping,
        measuring,
        notes,
    )


def _is_number(text: str | None) -> bool:
    try:
        return text is not None and np.isfinite(float(text))
    except ValueError:
        return False


def _input_text(input_topic: str, mapping: InputMapping | None) -> str:
    recorded = mapping.input_topic(input_topic) if mapping is not None else ''
    if recorded and recorded.lstrip('/') != input_topic:
        return f'{recorded} (the {INPUT_NAMES[input_topic]} input)'
    return '/' + input_topic


def _raw_topics(infos, topics: dict[str, str], mapping: InputMapping | None) -> dict[str, str]:
    """
    Return the bag topic of each raw input that the bag has.

    The recorded mapping's, else the contract's.
    """
    raw: dict[str, str] = {}
    by_name = {name.lstrip('/'): name for name in infos}
    for input_topic in RAW_TOPICS:
        recorded = mapping.input_topic(input_topic) if mapping is not None else ''
        if recorded:
            if recorded.lstrip('/') in by_name:
                raw[input_topic] = by_name[recorded.lstrip('/')]
        elif input_topic in topics:
            raw[input_topic] = topics[input_topic]
    return raw


def _expected_types(
    topics: dict[str, str], raw: dict[str, str], mapping: InputMapping | None
) -> dict[str, str]:
    """Return the message type each of the bag's posture and input topics must have."""
    expected = {topics[POSTURE_TOPIC]: JOINT_STATE_TYPE} if POSTURE_TOPIC in topics else {}
    for input_topic, name in raw.items():
        imu = (
            input_topic == INCLINOMETER_TOPIC
            and mapping is not None
            and mapping.inclinometer_type == IMU_INCLINOMETER
        )
        expected[name] = IMU_TYPE if imu else JOINT_STATE_TYPE
    return expected


RECORDED_MODEL_KEY = 'hexacal.collector.model'  # the collector's metadata record, key 'model'


def _bag_model(path, models: set[str], recorded_model: str | None) -> str | None:
    """
    Return the one model of a bag's actuator joints.

    The one model of a bag's actuator joints (else the recorded one); two models or a contradiction
    raise.
    """
    if len(models) > 1:
        raise InvalidMeasurementError(
            f'bag {path} holds the actuator joints of several models '
            f'({", ".join(sorted(models))}): calibrate one machine at a time'
        )
    if models:
        (model,) = models
        if recorded_model is not None and recorded_model != model:
            raise InvalidMeasurementError(
                f'bag {path}: its messages carry {model} joints ({_joints_text(model)}) but its '
                f'collector recorded a {recorded_model} ({RECORDED_MODEL_KEY})'
            )
        return model
    return recorded_model


def _model_of(decoded, models: set[str], recorded_model: str | None) -> str:
    """
    Return the model whose actuator joints a message carries.

    The model whose actuator joints a message carries (noted in `models`); else the expected one,
    whose conversion then names the missing joints.
    """
    from hexacal_msgs_py.conversions import actuator_model

    carried = actuator_model(decoded.name)
    if carried is None:
        return recorded_model or DEFAULT_MODEL
    models.add(carried.name)
    return carried.name


def _valid(messages, convert) -> tuple[list, int]:
    """Convert every message that is a valid reading; count (and skip) the others."""
    from hexacal_msgs_py.errors import InvalidReadingError

    from .bag import BagDecodeError

    converted, invalid, checked = [], 0, set()
    for message in messages:
        try:
            converted.append(convert(_joint_state(message, checked)))
        except (InvalidReadingError, BagDecodeError):
            # NaN, missing joint, mismatched lengths, bytes that are no JointState (the collector
            # records what arrived): not used, counted.
            invalid += 1
    return converted, invalid


def _check_types(reader, expected: dict[str, str]) -> None:
    """Each topic of `expected` (bag topic -> type) has that type, in the installed version."""
    from .bag import BagSchemaError, message_definition, MessageDefinitionNotFoundError
    from .bag.schemas import field_signature, SCHEMA_ENCODING

    infos = reader.topics()
    installed: dict[str, object] = {}
    for topic, type_name in expected.items():
        if infos[topic].type_name != type_name:
            shown = (
                _topic_key(topic)
                if _topic_key(topic).startswith('hexacal/')
                else topic.lstrip('/')
            )
            raise BagSchemaError(
                f'topic /{shown} has type {infos[topic].type_name}, expected {type_name}',
                topic=topic,
                expected=type_name,
                found=infos[topic].type_name,
            )
        if type_name not in installed:
            try:
                installed[type_name] = field_signature(message_definition(type_name))
            except MessageDefinitionNotFoundError:
                installed[type_name] = (
                    None  # no .msg files to compare with: the bag's own schema decodes it
                )
        signature = installed[type_name]
        for encoding, text in reader.schemas(topic) if signature is not None else ():
            found = field_signature(text) if encoding == SCHEMA_ENCODING else signature
            if found != signature:
                raise BagSchemaError(
                    f'topic {topic} was recorded with another version of {type_name}: '
                    f'{_signature_difference(found, signature)}',
                    topic=topic,
                    expected=type_name,
                    found=infos[topic].type_name,
                )


def _signature_difference(found, installed) -> str:
    found_fields, installed_fields = (
        {n: t for t, n in found},
        {n: t for t, n in installed},
    )
    parts = [f'no field {name!r}' for name in installed_fields if name not in found_fields]
    parts += [
        f'extra field {found_fields[name]} {name}'
        for name in found_fields
        if name not in installed_fields
    ]
    parts += [
        f'field {name!r} is {found_fields[name]}, not {installed_fields[name]}'
        for name in installed_fields
        if name in found_fields and found_fields[name] != installed_fields[name]
    ]
    if not parts:
        parts = [f'fields in another order ({", ".join(found_fields)})']
    return '; '.join(parts) + ' (installed: ' + ', '.join(f'{t} {n}' for t, n in installed) + ')'


def _joint_state(message, checked: set[str]):
    """
    Message.decoded, checked once per topic to have JointState's fields and types.

    The schema check (_check_types) compares the definition text; this catches a
    text the decoder reads differently (e.g. a malformed dependency section).
    """
    decoded = message.decoded
    if message.topic not in checked:
        try:
            stamp = decoded.header.stamp
            usable = (
                isinstance(stamp.sec, int)
                and isinstance(stamp.nanosec, int)
                and all(isinstance(name, str) for name in decoded.name)
                and all(isinstance(value, float) for value in decoded.position)
            )
        except (AttributeError, TypeError):
            usable = False
        if not usable:
            from .bag import BagSchemaError

            raise BagSchemaError(
                f'topic {message.topic}: its schema does not decode to a {JOINT_STATE_TYPE} '
                f'(header.stamp, name: string[], position: float64[]); got {decoded!r:.200}',
                topic=message.topic,
                expected=JOINT_STATE_TYPE,
                found=message.type_name,
            )
        checked.add(message.topic)
    return decoded


def _posture(message, models: set[str], recorded_model: str | None) -> PostureReading:
    from hexacal_msgs_py.conversions import joint_state_to_posture_reading

    return joint_state_to_posture_reading(message, _model_of(message, models, recorded_model))


def _imu(message, checked: set[str]):
    """
    Return Message.decoded of an Imu topic, checked once per topic.

    Message.decoded of an Imu topic, checked once per topic to have the fields the inclinometer
    reads.
    """
    decoded = message.decoded
    if message.topic not in checked:
        try:
            stamp, orientation = decoded.header.stamp, decoded.orientation
            usable = (
                isinstance(stamp.sec, int)
                and isinstance(stamp.nanosec, int)
                and all(isinstance(getattr(orientation, axis), float) for axis in 'xyzw')
                and len(decoded.orientation_covariance) == 9
            )
        except (AttributeError, TypeError):
            usable = False
        if not usable:
            from .bag import BagSchemaError

            raise BagSchemaError(
                f'topic {message.topic}: its schema does not decode to a {IMU_TYPE} '
                f'(header.stamp, orientation, orientation_covariance); got {decoded!r:.200}',
                topic=message.topic,
                expected=IMU_TYPE,
                found=message.type_name,
            )
        checked.add(message.topic)
    return decoded


def _redetect(
    reader,
    topics: dict[str, str],
    mapping: InputMapping | None,
    models: set[str],
    recorded_model: str | None,
    max_skew_s: float | None = None,
    detector: str = 'settled',
    inclinometer_clock_offset_s: float | None = None,
    encoder_clock_offset_s: float | None = None,
    link_topic: str | None = None,
    notes: list[str] | None = None,
    **detector_options,
) -> tuple[list[PostureReading], int]:
    """
    Re-detect the postures of the raw inputs (`topics`: input -> bag topic), read by `mapping`.

    `notes` receives what the settled detector noticed in words (unsettled_notes).

    Inputs that share a topic (one /joint_states) are read from each of its messages once;
    a reading that is not valid counts once in the returned number of invalid readings.
    ``detector``: 'settled' (core.dwell_detector, each stream judged on its own readings,
    postures with their scatter; a clock offset given is used, None: estimated), the only one
    (ValueError naming it for another, e.g. the removed 'window'). ``max_skew_s``: the
    collector's pairing setting, recorded with the others; the detector does not pair.
    ``link_topic``: the recorded lvdt link length stream (hexacal/link), one more stream of the
    detector (the postures get their link_length).
    """
    problem = detector_problem(detector)
    if problem is not None:
        raise ValueError(problem)
    from hexacal_msgs_py.conversions import (
        imu_to_inclinometer_reading,
        joint_state_to_actuator_reading,
        joint_state_to_encoder_reading,
        joint_state_to_inclinometer_reading,
    )
    from hexacal_msgs_py.errors import InvalidReadingError

    from .bag import BagDecodeError
    from .core.detection.dwell_detector import detect_dwell_postures, LINK_STREAM

    imu = mapping is not None and mapping.inclinometer_type == IMU_INCLINOMETER
    streams: dict[str, tuple[list[int], list]] = {t: ([], []) for t in RAW_TOPICS}
    convert = {
        SLIDERS_TOPIC: lambda m: (
            joint_state_to_actuator_reading(
                m, _model_of(m, models, recorded_model), mapping
            ).actuator_positions
        ),
        INCLINOMETER_TOPIC: lambda m: (lambda r: (r.alpha, r.beta, r.device_turn))(
            imu_to_inclinometer_reading(m, mapping)
            if imu
            else joint_state_to_inclinometer_reading(m, mapping)
        ),
        ENCODER_TOPIC: lambda m: (joint_state_to_encoder_reading(m, mapping).phi,),
    }
    # Without a mapping, the joints' places are learnt from the first message of each name list
    # the full conversion reads: the messages after it with that name list are read in place.
    known = _KnownJoints() if mapping is None else None
    inputs_of: dict[str, list[str]] = {}
    for input_topic in RAW_TOPICS:
        inputs_of.setdefault(topics[input_topic], []).append(input_topic)
    imu_topic = topics[INCLINOMETER_TOPIC] if imu else None
    invalid, checked = 0, set()
    for message in reader.messages(list(inputs_of)):
        inputs = inputs_of[message.topic]
        try:
            decoded = (
                _imu(message, checked)
                if message.topic == imu_topic
                else _joint_state(message, checked)
            )
        except BagDecodeError:
            invalid += len(inputs)  # bytes that are no message: not used, counted
            continue
        stamp = None
        for key in inputs:
            value = None if known is None or imu else known.values(key, decoded)
            if value is None:
                try:
                    value = convert[key](decoded)
                except InvalidReadingError:
                    invalid += 1  # a bad reading is skipped; the synchroniser pairs around the gap
                    continue
                if known is not None and not imu:
                    known.learn(key, decoded, models)
            if stamp is None:
                stamp = decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec
            stamps, values = streams[key]
            stamps.append(stamp)
            values.append(value)
    arrays = [
        (np.array(streams[t][0], dtype=np.int64), np.array(streams[t][1], dtype=float))
        for t in RAW_TOPICS
    ]
    # The inclinometer's device_turn joint (the mounting) rides beside alpha, beta: not a channel
    # to synchronise.
    inclinometer_stamps, inclinometer = arrays[1]
    inclinometer = inclinometer.reshape(-1, 3)
    given = {'inclinometer': inclinometer_clock_offset_s, 'encoder': encoder_clock_offset_s}
    streams_in = {
        'sliders': arrays[0],
        'inclinometer': (inclinometer_stamps, inclinometer[:, :2]),
        'encoder': arrays[2],
    }
    if link_topic is not None:
        link, bad = _link_stream(reader, link_topic)
        invalid += bad
        if len(link[0]):
            streams_in[LINK_STREAM] = link
    found, dwell = detect_dwell_postures(
        streams_in,
        clock_offsets_s={k: v for k, v in given.items() if v is not None},
        estimate_offsets=tuple(k for k, v in given.items() if v is None),
        **detector_options,
    )
    if notes is not None:
        notes.extend(unsettled_notes(dwell.unsettled))
    # The turn of the inclinometer message at the posture's time, in the inclinometer's clock.
    shift = int(round(dwell.offsets_s['inclinometer'] * 1_000_000_000))
    readings = [d.reading for d in found]
    return _with_turns(readings, inclinometer_stamps - shift, inclinometer[:, 2]), invalid


class _KnownJoints:
    """
    Read the raw inputs' joints in place from messages whose name list was converted before.

    The same values as the contract's conversions (hexacal_msgs_py.conversions, no input
    mapping) for a message whose joint names equal those of one they converted: the positions at
    the same places, finite (and a device turn within its range), else None and the conversion
    decides (and names the problem).
    """

    def __init__(self) -> None:
        from hexacal_msgs_py.names import MAX_DEVICE_TURN

        self._max_turn = MAX_DEVICE_TURN
        self._places: dict[str, tuple[list[str], tuple[int, ...], int | None]] = {}

    def learn(self, key: str, decoded, models: set[str]) -> None:
        from hexacal_msgs_py.models import MODELS as LAYOUTS
        from hexacal_msgs_py.names import DEVICE_TURN_JOINT, ENCODER_NAMES, INCLINOMETER_NAMES

        names = list(decoded.name)
        if key == SLIDERS_TOPIC:
            carried = [m for m in models if all(n in names for n in LAYOUTS[m].actuator_names)]
            if len(carried) != 1:
                return
            joints = LAYOUTS[carried[0]].actuator_names
        else:
            joints = INCLINOMETER_NAMES if key == INCLINOMETER_TOPIC else ENCODER_NAMES
        turn = None
        if key == INCLINOMETER_TOPIC and DEVICE_TURN_JOINT in names:
            turn = names.index(DEVICE_TURN_JOINT)
        self._places[key] = (names, tuple(names.index(n) for n in joints), turn)

    def values(self, key: str, decoded) -> tuple[float, ...] | None:
        places = self._places.get(key)
        if places is None:
            return None
        names, indexes, turn = places
        position = decoded.position
        if len(position) != len(names) or decoded.name != names:
            return None
        values = tuple([float(position[i]) for i in indexes])
        if not all(map(_isfinite, values)):
            return None
        if key != INCLINOMETER_TOPIC:
            return values
        device_turn = 0.0 if turn is None else float(position[turn])
        if not abs(device_turn) <= self._max_turn:
            return None
        return (*values, device_turn)


def _link_stream(reader, topic: str) -> tuple[tuple[np.ndarray, np.ndarray], int]:
    """Return the recorded link lengths ((stamps ns, values (N, 1) m)) and the invalid count."""
    from .bag import BagDecodeError

    stamps: list[int] = []
    values: list[float] = []
    invalid, checked = 0, set()
    for message in reader.messages([topic]):
        try:
            decoded = _joint_state(message, checked)
            names = list(decoded.name)
            value = float(decoded.position[names.index(LINK_LENGTH_JOINT)])
        except (BagDecodeError, ValueError, IndexError):
            invalid += 1  # not a message, or without the link_length joint: not used, counted
            continue
        if not np.isfinite(value) or value <= 0.0:
            invalid += 1
            continue
        stamps.append(decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec)
        values.append(value)
    arrays = (np.array(stamps, dtype=np.int64), np.array(values, dtype=float).reshape(-1, 1))
    return arrays, invalid


def unsettled_notes(unsettled: dict[str, int]) -> list[str]:
    """
    Say in words which still periods gave no posture because a stream never settled in them.

    `unsettled` is the settled detector's count per stream (DwellDetector.unsettled).
    """
    return [
        f'{count} still period(s) ended before the {stream} readings settled, so no posture was '
        'taken there (readings still creeping towards their level, e.g. an inclinometer lagging '
        'through its own filter for longer than the machine stands still): hold each posture '
        'longer'
        for stream, count in sorted(unsettled.items())
        if count
    ]


def _with_turns(
    readings: list[PostureReading], stamps: np.ndarray, turns: np.ndarray
) -> list[PostureReading]:
    """
    Return each reading with the device turn of the nearest inclinometer message.

    Each reading with the device turn of the inclinometer message nearest its stamp (the mounting
    it was in).
    """
    if not len(turns) or not np.any(turns):
        return readings
    order = np.argsort(stamps, kind='stable')
    stamps, turns = stamps[order], turns[order]
    out = []
    for reading in readings:
        index = int(np.clip(np.searchsorted(stamps, reading.stamp_ns), 0, len(stamps) - 1))
        around = np.arange(max(index - 1, 0), index + 1)
        nearest = around[np.argmin(np.abs(stamps[around] - reading.stamp_ns))]
        out.append(
            replace(reading, device_turn=float(turns[nearest])) if turns[nearest] else reading
        )
    return out
