"""The calibration call shared by the identify node and ``hexacal calibrate``, and bag -> postures.

The node and the CLI both go through :func:`calibrate`, so a bag calibrated
offline gives the same parameters as the node that received the same postures.
No rclpy here: the message objects from a bag are decoded by mcap_ros2 and read
through the contract's name-based conversions.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
from hexacal_msgs_py.names import ENCODER_TOPIC, INCLINOMETER_TOPIC, JOINT_STATE_TYPE, POSTURE_TOPIC, SLIDERS_TOPIC
from hexacal_msgs_py.readings import PostureReading

from .core.device import DEVICE_PARAMETER_NAMES, DeviceModel
from .core.errors import InvalidMeasurementError
from .core.identification import IdentificationResult, SolverOptions, identify
from .core.measurements import FIXED, SPHERE, Measurements, NoiseModel
from .core.model import HexaParameters, parameter_names

# A posture whose inclinometer reads zero on both axes (within this, rad) was taken at the fixed
# position [0, 0, -L] (section 3.2's second procedure). 5e-5 rad is 37 um at L = 0.75 m: above
# the noise of an averaged reading, far below the spread of sphere postures.
FIXED_POSITION_TOLERANCE_RAD = 5e-5
RAW_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)
TABLE1_FILE = Path(__file__).parent / "data" / "table1_exact.yaml"  # the default "exact" machine


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


def calibrate(nominal: HexaParameters, postures: Sequence[PostureReading], *, cost: str = "absolute",
              link_length: float = DeviceModel().link_length, allow_rank_deficient: bool = False,
              identify_device: Sequence[str] = (), noise: NoiseModel | None = None,
              robust_loss: str | None = None) -> IdentificationResult:
    """Identify the parameters from received postures: the one call behind the node and the CLI.

    ``identify_device`` names device defects to identify jointly (e.g. dL, alpha0,
    gamma); ``noise`` (reading noise half-widths) weights the residuals by it.
    A problem the postures do not determine raises RankDeficientError (never a
    number that means nothing) unless ``allow_rank_deficient``.
    """
    options = SolverOptions(cost=cost, device=DeviceModel(link_length=link_length),
                            allow_rank_deficient=allow_rank_deficient, free_device=tuple(identify_device),
                            noise=noise, robust_loss=robust_loss)
    return identify(nominal, measurements_from_postures(postures), options)


def status_fields(result: IdentificationResult) -> dict[str, str]:
    """Key/values for /hexacal/calibration_status (SI units, machine-readable)."""
    fields = {
        "outcome": result.reason,
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
    fields.update({f"std.{name}": f"{s:.6g}" for name, s in zip(parameter_names(), result.std)})
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


def _topic_key(topic: str) -> str:
    """'hexacal/posture' for '/hexacal/posture' and for a namespaced '/left/hexacal/posture'."""
    parts = topic.strip("/").split("/")
    return "/".join(parts[-2:]) if len(parts) >= 2 and parts[-2] == "hexacal" else topic.lstrip("/")


def postures_from_bag(path: Path | str, **detector_options) -> BagPostures:
    """Postures of a bag: its posture topic, else re-detected from the raw streams.

    Topics other than hexacal's are ignored; a bag with neither a posture topic
    nor all three raw streams raises InvalidMeasurementError naming what is
    missing.  Bag-format problems raise the bag layer's BagError subclasses.
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
    _check_types(reader, topics)
    if POSTURE_TOPIC in topics:
        postures, invalid = _valid(reader.messages([topics[POSTURE_TOPIC]]), _posture)
        return BagPostures(postures, "posture topic", plan, ignored, invalid)
    missing = [t for t in RAW_TOPICS if t not in topics]
    if missing:
        raise InvalidMeasurementError(
            f"bag {path} has no {POSTURE_TOPIC} topic and lacks the raw stream(s) "
            f"{', '.join('/' + t for t in missing)} needed to re-detect postures"
        )
    postures, invalid = _redetect(reader, topics, **detector_options)
    return BagPostures(postures, "raw streams (re-detected)", plan, ignored, invalid)


def _valid(messages, convert) -> tuple[list, int]:
    """Convert every message that is a valid reading; count (and skip) the others."""
    from hexacal_msgs_py.errors import InvalidReadingError

    converted, invalid = [], 0
    for message in messages:
        try:
            converted.append(convert(message.decoded))
        except InvalidReadingError:
            invalid += 1  # NaN, missing joint, mismatched lengths: recorded as received, not used
    return converted, invalid


def _check_types(reader, topics: dict[str, str]) -> None:
    from .bag import BagSchemaError

    infos = reader.topics()
    for key in (POSTURE_TOPIC, *RAW_TOPICS):
        if key in topics and infos[topics[key]].type_name != JOINT_STATE_TYPE:
            raise BagSchemaError(
                f"topic /{key} has type {infos[topics[key]].type_name}, expected {JOINT_STATE_TYPE}"
            )


def _posture(message) -> PostureReading:
    from hexacal_msgs_py.conversions import joint_state_to_posture_reading

    return joint_state_to_posture_reading(message)


def _redetect(reader, topics: dict[str, str], **detector_options) -> tuple[list[PostureReading], int]:
    from hexacal_msgs_py.errors import InvalidReadingError
    from hexacal_msgs_py.conversions import (
        joint_state_to_encoder_reading,
        joint_state_to_inclinometer_reading,
        joint_state_to_slider_reading,
    )

    from .posture_detector import detect_postures, synchronize_arrays

    streams: dict[str, tuple[list[int], list]] = {t: ([], []) for t in RAW_TOPICS}
    convert = {
        SLIDERS_TOPIC: lambda m: joint_state_to_slider_reading(m).slider_positions,
        INCLINOMETER_TOPIC: lambda m: (lambda r: (r.alpha, r.beta))(joint_state_to_inclinometer_reading(m)),
        ENCODER_TOPIC: lambda m: (joint_state_to_encoder_reading(m).phi,),
    }
    by_name = {topics[t]: t for t in RAW_TOPICS}
    invalid = 0
    for message in reader.messages(list(by_name)):
        key = by_name[message.topic]
        decoded = message.decoded
        try:
            value = convert[key](decoded)
        except InvalidReadingError:
            invalid += 1  # a bad reading is skipped; the synchroniser pairs around the gap
            continue
        stamps, values = streams[key]
        stamps.append(decoded.header.stamp.sec * 1_000_000_000 + decoded.header.stamp.nanosec)
        values.append(value)
    arrays = [(np.array(streams[t][0], dtype=np.int64), np.array(streams[t][1], dtype=float)) for t in RAW_TOPICS]
    stamps, values = synchronize_arrays(arrays[0][0], arrays[0][1], arrays[1][0], arrays[1][1],
                                        arrays[2][0], arrays[2][1])
    return [d.reading for d in detect_postures(stamps, values, **detector_options)], invalid
