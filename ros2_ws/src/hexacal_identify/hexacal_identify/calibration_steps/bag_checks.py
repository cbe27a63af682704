"""
A bag's topics and messages checked before they are read: types, schemas, machine model.

An input topic must have the message type and, where the installed definitions are known,
the same fields as the installed version (`check_types`); each decoded message is checked once
per topic to have the fields it is read by. A bag's actuator joint names tell which model
recorded it (slider_1..6: Hexa Slide, leg_1..6: Gough-Stewart; the collector also stores it in
the bag's ``hexacal.collector`` metadata).
"""

from __future__ import annotations

from hexacal_msgs_py.models import DEFAULT_MODEL
from hexacal_msgs_py.names import (
    ENCODER_TOPIC,
    IMU_TYPE,
    INCLINOMETER_TOPIC,
    JOINT_STATE_TYPE,
    SLIDERS_TOPIC,
)

from .posture_checks import joints_text
from ..core.errors import InvalidMeasurementError


RAW_TOPICS = (SLIDERS_TOPIC, INCLINOMETER_TOPIC, ENCODER_TOPIC)


RECORDED_MODEL_KEY = 'hexacal.collector.model'  # the collector's metadata record, key 'model'


def topic_key(topic: str) -> str:
    """'hexacal/posture' for '/hexacal/posture' and for a namespaced '/left/hexacal/posture'."""
    parts = topic.strip('/').split('/')
    return (
        '/'.join(parts[-2:]) if len(parts) >= 2 and parts[-2] == 'hexacal' else topic.lstrip('/')
    )


def bag_model(path, models: set[str], recorded_model: str | None) -> str | None:
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
                f'bag {path}: its messages carry {model} joints ({joints_text(model)}) but its '
                f'collector recorded a {recorded_model} ({RECORDED_MODEL_KEY})'
            )
        return model
    return recorded_model


def model_of(decoded, models: set[str], recorded_model: str | None) -> str:
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


def check_types(reader, expected: dict[str, str]) -> None:
    """Each topic of `expected` (bag topic -> type) has that type, in the installed version."""
    from ..bag import BagSchemaError, message_definition, MessageDefinitionNotFoundError
    from ..bag.schemas import field_signature, SCHEMA_ENCODING

    infos = reader.topics()
    installed: dict[str, object] = {}
    for topic, type_name in expected.items():
        if infos[topic].type_name != type_name:
            shown = (
                topic_key(topic)
                if topic_key(topic).startswith('hexacal/')
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


def decoded_joint_state(message, checked: set[str]):
    """
    Message.decoded, checked once per topic to have JointState's fields and types.

    The schema check (check_types) compares the definition text; this catches a
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
            from ..bag import BagSchemaError

            raise BagSchemaError(
                f'topic {message.topic}: its schema does not decode to a {JOINT_STATE_TYPE} '
                f'(header.stamp, name: string[], position: float64[]); got {decoded!r:.200}',
                topic=message.topic,
                expected=JOINT_STATE_TYPE,
                found=message.type_name,
            )
        checked.add(message.topic)
    return decoded


def decoded_imu(message, checked: set[str]):
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
            from ..bag import BagSchemaError

            raise BagSchemaError(
                f'topic {message.topic}: its schema does not decode to a {IMU_TYPE} '
                f'(header.stamp, orientation, orientation_covariance); got {decoded!r:.200}',
                topic=message.topic,
                expected=IMU_TYPE,
                found=message.type_name,
            )
        checked.add(message.topic)
    return decoded
