"""The calibration call shared by the identify node and ``hexacal calibrate``, and bag -> postures.

The node and the CLI both go through :func:`calibrate`, so a bag calibrated
offline gives the same parameters as the node that received the same postures.
No rclpy here: the message objects from a bag are decoded by mcap_ros2 and read
through the contract's name-based conversions.

Any machine model: the nominal parameters file names its model (``model:``,
none = Hexa Slide), and a bag's actuator joint names tell which model recorded
it (slider_1..6: Hexa Slide, leg_1..6: Gough-Stewart; the collector also
stores it in the bag's ``hexacal.collector`` metadata). `check_model` refuses to
calibrate the postures of one model with the nominal parameters of another.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
from hexacal_msgs_py.models import DEFAULT_MODEL, MODELS
from hexacal_msgs_py.names import ENCODER_TOPIC, INCLINOMETER_TOPIC, JOINT_STATE_TYPE, POSTURE_TOPIC, SLIDERS_TOPIC
from hexacal_msgs_py.readings import PostureReading

from .core.architectures import KinematicParameters, parameters_for
from .core.device import DEFAULT_MOUNT, DEVICE_PARAMETER_NAMES, DeviceModel, check_mount
from .core.errors import InvalidMeasurementError
from .core.identification import IdentificationResult, SolverOptions, identify
from .core.measurements import FIXED, SPHERE, MeasurementLimits, Measurements, NoiseModel
from .core.model import parameter_names

# A posture whose inclinometer reads zero on both axes (within this, rad) was taken at the fixed
# position [0, 0, -L] (section 3.2's second procedure). 5e-5 rad is 37 um at L = 0.75 m: above
# the noise of an averaged reading, far below the spread of sphere postures.
FIXED_POSITION_TOLERANCE_RAD = 5e-5
RAW_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)
TABLE1_FILE = Path(__file__).parent / "data" / "table1_exact.yaml"  # the default "exact" machine
# Reasons a received posture is rejected before it is stored (posture_problem).
SLIDER_BEYOND_STROKE = "slider-beyond-stroke"  # (any model's actuator: a leg on a Gough-Stewart)
ANGLE_OUT_OF_RANGE = "angle-out-of-range"
MODEL_MISMATCH = "model-mismatch"


class ModelMismatchError(InvalidMeasurementError):
    """Postures of one machine model, nominal parameters of another: nothing to calibrate."""

    reason = MODEL_MISMATCH


MOUNT_PARAMETER = "device.mount"  # parameters-file key of the device mount (core/device.py)


def load_machine(path: Path | str) -> KinematicParameters:
    """The parameters of a parameters YAML, of the model it names (ParameterFileError names the file and key)."""
    return load_machine_and_mount(path)[0]


def load_machine_and_mount(path: Path | str) -> tuple[KinematicParameters, str]:
    """(parameters, device mount) of a parameters YAML: its model's parameters and its ``device.mount``
    (default hanging; another value is a DeviceMountError naming the file)."""
    from hexacal_msgs_py.parameters_file import read_parameters_file

    from .core.device import DeviceMountError

    loaded = read_parameters_file(path)
    try:
        mount = check_mount(loaded.extras.get(MOUNT_PARAMETER, DEFAULT_MOUNT))
    except DeviceMountError as error:
        raise DeviceMountError(f"{path}: {MOUNT_PARAMETER}: {error}") from None
    return parameters_for(loaded.model, loaded.vector), mount


def _joints_text(model: str) -> str:
    names = MODELS[model].actuator_names
    return f"{names[0]}..{names[-1]}"


def check_model(postures_model: str | None, nominal: KinematicParameters, what: str, nominal_source: str = "") -> None:
    """ModelMismatchError if postures of `postures_model` (None: unknown, not checked) meet a nominal of another."""
    if postures_model is None or postures_model == nominal.model:
        return
    source = f" {nominal_source}" if nominal_source else ""
    raise ModelMismatchError(
        f"{what} holds {postures_model} postures (actuator joints {_joints_text(postures_model)}) but the nominal "
        f"parameters{source} are a {nominal.model}'s (joints {_joints_text(nominal.model)}): give a {postures_model} "
        "nominal parameters file")


def posture_problem(posture: PostureReading, limits: MeasurementLimits = MeasurementLimits(),
                    model: str | None = None) -> tuple[str, str] | None:
    """(reason, description) if a (finite) posture reads beyond a sensor's range, else None.

    The same limits as the core's Measurements.validate: a posture outside them
    would make the whole identification refuse, so the node and the bag reader
    set it aside with this reason and keep every other posture. `model` names
    the actuators in the description (default: the Hexa Slide's sliders).
    """
    names = MODELS[model or DEFAULT_MODEL].actuator_names
    for name, value in zip(names, posture.slider_positions):
        if not limits.slider_min_m <= value <= limits.slider_max_m:
            return SLIDER_BEYOND_STROKE, (
                f"{name} = {value!r} m is beyond the stroke "
                f"[{limits.slider_min_m:g}, {limits.slider_max_m:g}] m")
    for name, value, limit in (("inclinometer_x (alpha)", posture.alpha, limits.inclinometer_range_rad),
                               ("inclinometer_y (beta)", posture.beta, limits.inclinometer_range_rad),
                               ("rotary (phi)", posture.phi, limits.rotary_range_rad)):
        if abs(value) > limit:
            return ANGLE_OUT_OF_RANGE, f"{name} = {value!r} rad is beyond the sensor's range +-{limit:.4g} rad"
    return None


def measurements_from_postures(postures: Sequence[PostureReading],
                               fixed_tolerance_rad: float = FIXED_POSITION_TOLERANCE_RAD) -> Measurements:
    """Stack posture readings into Measurements; kinds from the inclinometer reading."""
    if not postures:
        return Measurements(np.zeros((0, 6)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, str))
    sliders = np.array([p.slider_positions for p in postures], dtype=float)
    angles = np.array([[p.alpha, p.beta] for p in postures], dtype=float)
    rotary = np.array([p.phi for p in postures], dtype=float)
    fixed = np.all(np.abs(angles) <= fixed_tolerance_rad, axis=1)
    return Measurements(sliders, angles, rotary, np.where(fixed, FIXED, SPHERE))


def calibrate(nominal: KinematicParameters, postures: Sequence[PostureReading], *, cost: str = "absolute",
              link_length: float = DeviceModel().link_length, allow_rank_deficient: bool = False,
              identify_device: Sequence[str] = (), noise: NoiseModel | None = None,
              robust_loss: str | None = None, mount: str = DEFAULT_MOUNT) -> IdentificationResult:
    """Identify the parameters from received postures: the one call behind the node and the CLI.

    ``nominal`` is the starting parameter set of any architecture (its model is the
    result's). ``identify_device`` names device defects to identify jointly (e.g. dL,
    alpha0, gamma); ``noise`` (reading noise half-widths) weights the residuals by it.
    ``mount`` is the device's (hanging, or standing for an upright machine).
    A problem the postures do not determine raises RankDeficientError (never a
    number that means nothing) unless ``allow_rank_deficient``.
    """
    options = SolverOptions(cost=cost, device=DeviceModel(link_length=link_length, mount=mount),
                            allow_rank_deficient=allow_rank_deficient, free_device=tuple(identify_device),
                            noise=noise, robust_loss=robust_loss)
    return identify(nominal, measurements_from_postures(postures), options)


def status_fields(result: IdentificationResult) -> dict[str, str]:
    """Key/values for /hexacal/calibration_status (SI units, machine-readable)."""
    model = result.parameters.model
    fields = {
        "outcome": result.reason,
        "model": model,
        "cost": result.cost,
        "rank": str(result.rank),
        "condition_number": f"{result.condition_number:.6g}",
        "iterations": str(result.iterations),
        "postures_used": str(len(result.used_postures)),
        "postures_rejected": str(len(result.rejected_postures)),
        "solve_seconds": f"{result.solve_seconds:.6f}",
        "identifiable": str(result.identifiability.identifiable).lower(),
    }
    fields["identifiability"] = result.identifiability.verdict().replace("\n", " ")
    fields.update({f"rms_residual.{k}": f"{v:.6g}" for k, v in result.rms_residual.items()})
    for index, name in enumerate(DEVICE_PARAMETER_NAMES):
        if name in result.free_device:
            fields[f"device.{name}"] = f"{result.device.vector[index]:.6g}"
            fields[f"std.device.{name}"] = f"{result.device_std[index]:.6g}"
    fields.update({f"std.{name}": f"{s:.6g}" for name, s in zip(parameter_names(model), result.std)})
    for index, why in sorted(result.rejected_postures.items())[:20]:
        fields[f"rejected.{index}"] = why
    return fields


@dataclass
class BagPostures:
    postures: list[PostureReading]
    source: str  # "posture topic" or "raw streams (re-detected)"
    plan: dict[str, str] = field(default_factory=dict)  # recorded posture plan metadata, if any
    ignored_topics: list[str] = field(default_factory=list)
    invalid_messages: int = 0  # messages of hexacal's topics that were not valid readings (skipped)
    # Postures set aside (posture_problem): (index among the bag's postures, reason, description).
    rejected: list[tuple[int, str, str]] = field(default_factory=list)
    # The machine model that recorded the bag: its actuator joint names (else the collector's metadata);
    # None when the bag holds neither.
    model: str | None = None


def _screened(postures: list[PostureReading],
              model: str | None = None) -> tuple[list[PostureReading], list[tuple[int, str, str]]]:
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
    parts = topic.strip("/").split("/")
    return "/".join(parts[-2:]) if len(parts) >= 2 and parts[-2] == "hexacal" else topic.lstrip("/")


def postures_from_bag(path: Path | str, **detector_options) -> BagPostures:
    """Postures of a bag: its posture topic, else re-detected from the raw streams.

    Either machine model: the actuator joints of the posture (or sliders) messages
    tell which (``model``); a bag mixing the joints of two models, or whose joints
    contradict the model its collector recorded (metadata ``hexacal.collector``),
    raises InvalidMeasurementError.

    Topics other than hexacal's are ignored; a bag with neither a posture topic
    nor all three raw streams raises InvalidMeasurementError naming what is
    missing.  Bag-format problems raise the bag layer's BagError subclasses, also
    a hexacal topic whose JointState definition is another message version.
    Messages that do not decode or are not valid readings are skipped and counted
    (``invalid_messages``); postures beyond a sensor's range are set aside with
    the reason (``rejected``).
    """
    from .bag import open_bag

    reader = open_bag(path)
    topics: dict[str, str] = {}
    for topic in reader.topics():
        key = _topic_key(topic)
        if key in topics and key in (POSTURE_TOPIC, *RAW_TOPICS):
            raise InvalidMeasurementError(
                f"bag {path} holds {key} from several namespaces ({topics[key]}, {topic}): "
                "calibrate one machine at a time")
        topics[key] = topic
    ours = {POSTURE_TOPIC, *RAW_TOPICS}
    ignored = sorted(t for k, t in topics.items() if k not in ours)
    plan = {}
    for record in reader.metadata():
        if record.name.startswith("hexacal"):
            plan.update({f"{record.name}.{k}": v for k, v in record.data.items()})
    recorded_model = plan.get(RECORDED_MODEL_KEY) or None
    if recorded_model is not None and recorded_model not in MODELS:
        raise InvalidMeasurementError(f"bag {path}: its metadata names an unknown model {recorded_model!r} "
                                      f"({RECORDED_MODEL_KEY}); hexacal knows {', '.join(MODELS)}")
    _check_types(reader, topics)
    if POSTURE_TOPIC in topics:
        models: set[str] = set()
        postures, invalid = _valid(reader.messages([topics[POSTURE_TOPIC]]),
                                   lambda m: _posture(m, models, recorded_model))
        model = _bag_model(path, models, recorded_model)
        kept, rejected = _screened(postures, model)
        return BagPostures(kept, "posture topic", plan, ignored, invalid, rejected, model)
    missing = [t for t in RAW_TOPICS if t not in topics]
    if missing:
        raise InvalidMeasurementError(
            f"bag {path} has no {POSTURE_TOPIC} topic and lacks the raw stream(s) "
            f"{', '.join('/' + t for t in missing)} needed to re-detect postures"
        )
    models = set()
    postures, invalid = _redetect(reader, topics, models, recorded_model, **detector_options)
    model = _bag_model(path, models, recorded_model)
    kept, rejected = _screened(postures, model)
    return BagPostures(kept, "raw streams (re-detected)", plan, ignored, invalid, rejected, model)


RECORDED_MODEL_KEY = "hexacal.collector.model"  # the collector's metadata record, key 'model'


def _bag_model(path, models: set[str], recorded_model: str | None) -> str | None:
    """The one model of a bag's actuator joints (else the recorded one); two models or a contradiction raise."""
    if len(models) > 1:
        raise InvalidMeasurementError(
            f"bag {path} holds the actuator joints of several models ({', '.join(sorted(models))}): "
            "calibrate one machine at a time")
    if models:
        (model,) = models
        if recorded_model is not None and recorded_model != model:
            raise InvalidMeasurementError(
                f"bag {path}: its messages carry {model} joints ({_joints_text(model)}) but its collector "
                f"recorded a {recorded_model} ({RECORDED_MODEL_KEY})")
        return model
    return recorded_model


def _model_of(decoded, models: set[str], recorded_model: str | None) -> str:
    """The model whose actuator joints a message carries (noted in `models`); else the expected one,
    whose conversion then names the missing joints."""
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


def _check_types(reader, topics: dict[str, str]) -> None:
    from .bag import BagSchemaError, MessageDefinitionNotFoundError, message_definition
    from .bag.schemas import SCHEMA_ENCODING, field_signature

    infos = reader.topics()
    try:
        installed = field_signature(message_definition(JOINT_STATE_TYPE))
    except MessageDefinitionNotFoundError:
        installed = None  # no .msg files to compare with: the bag's own schema decodes it
    for key in (POSTURE_TOPIC, *RAW_TOPICS):
        if key not in topics:
            continue
        topic = topics[key]
        if infos[topic].type_name != JOINT_STATE_TYPE:
            raise BagSchemaError(
                f"topic /{key} has type {infos[topic].type_name}, expected {JOINT_STATE_TYPE}",
                topic=topic, expected=JOINT_STATE_TYPE, found=infos[topic].type_name)
        for encoding, text in reader.schemas(topic) if installed is not None else ():
            found = field_signature(text) if encoding == SCHEMA_ENCODING else installed
            if found != installed:
                raise BagSchemaError(
                    f"topic {topic} was recorded with another version of {JOINT_STATE_TYPE}: "
                    f"{_signature_difference(found, installed)}", topic=topic,
                    expected=JOINT_STATE_TYPE, found=infos[topic].type_name)


def _signature_difference(found, installed) -> str:
    found_fields, installed_fields = dict((n, t) for t, n in found), dict((n, t) for t, n in installed)
    parts = [f"no field {name!r}" for name in installed_fields if name not in found_fields]
    parts += [f"extra field {found_fields[name]} {name}" for name in found_fields if name not in installed_fields]
    parts += [f"field {name!r} is {found_fields[name]}, not {installed_fields[name]}"
              for name in installed_fields if name in found_fields and found_fields[name] != installed_fields[name]]
    if not parts:
        parts = [f"fields in another order ({', '.join(found_fields)})"]
    return "; ".join(parts) + " (installed: " + ", ".join(f"{t} {n}" for t, n in installed) + ")"


def _joint_state(message, checked: set[str]):
    """message.decoded, checked once per topic to have JointState's fields and types.

    The schema check (_check_types) compares the definition text; this catches a
    text the decoder reads differently (e.g. a malformed dependency section).
    """
    decoded = message.decoded
    if message.topic not in checked:
        try:
            stamp = decoded.header.stamp
            usable = (isinstance(stamp.sec, int) and isinstance(stamp.nanosec, int)
                      and all(isinstance(name, str) for name in decoded.name)
                      and all(isinstance(value, float) for value in decoded.position))
        except (AttributeError, TypeError):
            usable = False
        if not usable:
            from .bag import BagSchemaError

            raise BagSchemaError(
                f"topic {message.topic}: its schema does not decode to a {JOINT_STATE_TYPE} "
                f"(header.stamp, name: string[], position: float64[]); got {decoded!r:.200}",
                topic=message.topic, expected=JOINT_STATE_TYPE, found=message.type_name)
        checked.add(message.topic)
    return decoded


def _posture(message, models: set[str], recorded_model: str | None) -> PostureReading:
    from hexacal_msgs_py.conversions import joint_state_to_posture_reading

    return joint_state_to_posture_reading(message, _model_of(message, models, recorded_model))


def _redetect(reader, topics: dict[str, str], models: set[str], recorded_model: str | None,
              **detector_options) -> tuple[list[PostureReading], int]:
    from hexacal_msgs_py.errors import InvalidReadingError
    from hexacal_msgs_py.conversions import (
        joint_state_to_encoder_reading,
        joint_state_to_inclinometer_reading,
        joint_state_to_slider_reading,
    )

    from .bag import BagDecodeError
    from .core.posture_detector import detect_postures, synchronize_arrays

    streams: dict[str, tuple[list[int], list]] = {t: ([], []) for t in RAW_TOPICS}
    convert = {
        SLIDERS_TOPIC: lambda m: joint_state_to_slider_reading(
            m, _model_of(m, models, recorded_model)).slider_positions,
        INCLINOMETER_TOPIC: lambda m: (lambda r: (r.alpha, r.beta))(joint_state_to_inclinometer_reading(m)),
        ENCODER_TOPIC: lambda m: (joint_state_to_encoder_reading(m).phi,),
    }
    by_name = {topics[t]: t for t in RAW_TOPICS}
    invalid, checked = 0, set()
    for message in reader.messages(list(by_name)):
        key = by_name[message.topic]
        try:
            decoded = _joint_state(message, checked)
            value = convert[key](decoded)
        except (InvalidReadingError, BagDecodeError):
            invalid += 1  # a bad reading is skipped; the synchroniser pairs around the gap
            continue
        stamps, values = streams[key]
        stamps.append(decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec)
        values.append(value)
    arrays = [(np.array(streams[t][0], dtype=np.int64), np.array(streams[t][1], dtype=float)) for t in RAW_TOPICS]
    stamps, values = synchronize_arrays(arrays[0][0], arrays[0][1], arrays[1][0], arrays[1][1],
                                        arrays[2][0], arrays[2][1])
    return [d.reading for d in detect_postures(stamps, values, **detector_options)], invalid
