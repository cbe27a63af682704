"""
Decide which nodes a hexacal system runs, with which parameters and remaps.

collector, identify and (with_kinematics) kinematics always; the simulated
driver unless a real machine publishes; the executor when a plan is to be
walked. `launches` takes Python values (bringup's options), `launches_from_arguments`
the launch file's string arguments, so both build the same nodes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from hexacal_msgs_py.interface_names import (
    DEFAULT_COMMAND_TOPIC,
    ENCODER_TOPIC as ENCODER,
    IMU_INCLINOMETER,
    INCLINOMETER_TOPIC as INCLINOMETER,
    SLIDERS_TOPIC as SLIDERS,
)

from hexacal_msgs_py.measuring_modes import measuring_mode as check_mode, MEASURING_MODE_KEY
from hexacal_msgs_py.models import DEFAULT_MODEL

from .launch_spec import NodeLaunch


@dataclass(frozen=True)
class MachineInputs:
    """
    Where the machine's readings come from: topic remaps and the collector's joint mapping.

    Empty fields keep the contract's topics (hexacal/sliders, hexacal/inclinometer,
    hexacal/encoder) and the nodes' defaults (hexacal_msgs_py.inputs).
    """

    sliders_topic: str = ''
    inclinometer_topic: str = ''
    encoder_topic: str = ''
    inclinometer_type: str = ''  # joint_state | imu
    actuator_joints: tuple[str, ...] = ()
    inclinometer_joints: tuple[str, ...] = ()
    rotary_joint: str = ''
    inclinometer_signs: tuple[int, ...] = ()
    inclinometer_offsets_rad: tuple[float, ...] = ()

    def remaps(self, *inputs: str) -> dict[str, str]:
        """Return the `-r` remaps of the given inputs (those set and not the contract's name)."""
        topics = {
            SLIDERS: self.sliders_topic,
            INCLINOMETER: self.inclinometer_topic,
            ENCODER: self.encoder_topic,
        }
        return {name: topics[name] for name in inputs if topics[name] and topics[name] != name}

    def collector_parameters(self) -> dict[str, object]:
        """Return the collector's mapping parameters that are set."""
        values = {
            'actuator_joints': list(self.actuator_joints),
            'inclinometer_joints': list(self.inclinometer_joints),
            'rotary_joint': self.rotary_joint,
            'inclinometer_type': self.inclinometer_type,
            'inclinometer_signs': [int(v) for v in self.inclinometer_signs],
            'inclinometer_offsets_rad': [float(v) for v in self.inclinometer_offsets_rad],
        }
        return {name: value for name, value in values.items() if value}

    def executor_parameters(self) -> dict[str, object]:
        """Return the executor's mapping parameters that are set (inclinometer included)."""
        names: tuple[str, ...] = ('actuator_joints', 'inclinometer_type', 'inclinometer_signs')
        names += ('inclinometer_offsets_rad',)
        if not self.imu:
            names += ('inclinometer_joints',)
        collector = self.collector_parameters()
        return {name: collector[name] for name in names if name in collector}

    @property
    def imu(self) -> bool:
        """Return whether the inclinometer is a sensor_msgs/Imu."""
        return self.inclinometer_type == IMU_INCLINOMETER


def launches(
    namespace: str = '',
    nominal: str = '',
    output_dir: str = '',
    bag_dir: str = '',
    plan: str = '',
    postures: int | None = None,
    record: bool = True,
    driver: Mapping[str, object] | None = None,
    collector: Mapping[str, object] | None = None,
    identify: Mapping[str, object] | None = None,
    with_driver: bool = True,
    model: str = '',
    *,
    executor_plan: str = '',
    command_topic: str = '',
    calibrate_when_done: bool = False,
    shutdown_when_done: bool = False,
    executor: Mapping[str, object] | None = None,
    with_kinematics: bool = False,
    kinematics_parameters: str = '',
    kinematics: Mapping[str, object] | None = None,
    inputs: MachineInputs | None = None,
    measuring_mode: str = '',
    bag_name: str = '',
    calibration_store: str = '',
) -> list[NodeLaunch]:
    """
    Return the NodeLaunch of each node; empty options keep the nodes' defaults.

    `model` (hexa_slide or gough_stewart) goes to the driver and the collector;
    identify and the executor take their model from the nominal file, kinematics from
    its parameters file (else it is told `model`, else the nominal's, else the default
    model, whose store - the one identify deploys into - it follows). An `executor_plan` adds the
    executor (plan, nominal, command_topic, calibrate_when_done, shutdown_when_done) and
    puts the driver in commanded mode on the same command topic; `with_kinematics` adds
    the kinematics node (its `parameters` file, commands on command_topic). `inputs`
    remaps the sensor topics of every node that reads (or, the driver, publishes) them.
    `measuring_mode` ('' keeps the nodes' defaults) goes to the driver and, when it declares
    the parameter, the executor (else the executor follows the plan's mode).
    `bag_name` names the collector's bag ('' = hexacal_<date>_<time>); `calibration_store`
    is the store of identify and kinematics ('' = the model's default store).
    """
    inputs = inputs or MachineInputs()
    mode = {MEASURING_MODE_KEY: check_mode(measuring_mode).value} if measuring_mode else {}
    command_topic = command_topic or DEFAULT_COMMAND_TOPIC
    driver_parameters: dict[str, object] = {}
    collector_model: dict[str, object] = {'model': model} if model else {}
    driver_parameters.update(collector_model)
    if plan:
        driver_parameters['plan'] = plan
    if postures is not None:
        driver_parameters['postures'] = int(postures)
    if executor_plan:  # the simulated machine takes the real one's interface
        driver_parameters['command_topic'] = command_topic
    driver_parameters.update(mode)
    driver_parameters.update(driver or {})
    collector_parameters: dict[str, object] = {'record': bool(record), **collector_model}
    if bag_dir:
        collector_parameters['output_dir'] = str(bag_dir)
    if bag_name:
        collector_parameters['bag_name'] = str(bag_name)
    collector_parameters.update(inputs.collector_parameters())
    collector_parameters.update(collector or {})
    # identify keeps its calibrations in the store; kinematics follows its deploys: the same one.
    store: dict[str, object] = {}
    if calibration_store:
        store['calibration_store'] = str(Path(calibration_store).resolve())
    identify_parameters: dict[str, object] = dict(store)
    if nominal:
        identify_parameters['nominal'] = str(Path(nominal).resolve())
    if output_dir:
        identify_parameters['output_dir'] = str(Path(output_dir).resolve())
    identify_parameters.update(identify or {})
    nodes = [
        NodeLaunch(
            'collector',
            collector_parameters,
            namespace,
            inputs.remaps(SLIDERS, INCLINOMETER, ENCODER),
        ),
        NodeLaunch('identify', identify_parameters, namespace),
    ]
    if with_kinematics:
        kinematics_parameters_: dict[str, object] = {'command_topic': command_topic, **store}
        if kinematics_parameters:
            kinematics_parameters_['parameters'] = str(Path(kinematics_parameters).resolve())
        else:  # the machine's store, the one identify deploys into (its nominal's model)
            kinematics_parameters_['model'] = model or file_model(nominal) or DEFAULT_MODEL
        kinematics_parameters_.update(kinematics or {})
        nodes.append(
            NodeLaunch('kinematics', kinematics_parameters_, namespace, inputs.remaps(SLIDERS))
        )
    if executor_plan:
        executor_parameters: dict[str, object] = {
            'plan': str(Path(executor_plan).resolve()),
            'command_topic': command_topic,
        }
        if nominal:
            executor_parameters['nominal'] = str(Path(nominal).resolve())
        executor_parameters.update(inputs.executor_parameters())
        if mode and executor_takes_measuring_mode():
            executor_parameters.update(mode)
        if calibrate_when_done:
            executor_parameters['calibrate_when_done'] = True
        if shutdown_when_done:
            executor_parameters['shutdown_when_done'] = True
        executor_parameters.update(executor or {})
        # The executor reads the inclinometer as the collector does (a JointState or an Imu) for
        # its fixed-position closed loop.
        nodes.append(
            NodeLaunch(
                'executor', executor_parameters, namespace, inputs.remaps(SLIDERS, INCLINOMETER)
            )
        )
    if with_driver:
        nodes.append(
            NodeLaunch(
                'driver',
                driver_parameters,
                namespace,
                inputs.remaps(SLIDERS, INCLINOMETER, ENCODER),
            )
        )
    return nodes


def executor_takes_measuring_mode() -> bool:
    """Return whether this install's executor declares the parameter measuring_mode."""
    # Imported here: the node's parameter table is not needed to start bringup (numpy-free).
    from ..nodes.executor_parameters import PARAMETERS

    return MEASURING_MODE_KEY in PARAMETERS


def name_list(text: str | Sequence[object]) -> tuple[str, ...]:
    """Return 'a,b', '[a, b]' or ['a', 'b'] as ('a', 'b'); '' as ()."""
    if not isinstance(text, str):
        return tuple(str(item) for item in text)
    text = text.strip()
    if text.startswith('[') and text.endswith(']'):
        text = text[1:-1]
    return tuple(item.strip().strip('\'"') for item in text.split(',') if item.strip())


def number_list(text: str | Sequence[float], kind: type = float) -> tuple:
    """Return '1,-1' / '[0.0, 0.01]' as numbers of `kind` (errors name the text)."""
    try:
        return tuple(kind(float(item)) if kind is int else kind(item) for item in name_list(text))
    except ValueError:
        raise ValueError(f'expected a list of numbers, got {text!r}') from None


def truthy(text: str | bool) -> bool:
    """Return the boolean of a launch argument (true/false, 1/0, yes/no, on/off, '')."""
    if isinstance(text, bool):
        return text
    value = str(text).strip().lower()
    if value in ('true', '1', 'yes', 'on'):
        return True
    if value in ('false', '0', 'no', 'off', ''):
        return False
    raise ValueError(f'expected true or false, got {text!r}')


def launches_from_arguments(values: Mapping[str, str]) -> list[NodeLaunch]:
    """
    Return the nodes of launch/hexacal.launch.py from its launch arguments (strings).

    '' keeps a node's default; the plan walked by the executor is `executor_plan`
    (`plan` stays the simulated driver's own plan when there is none).
    """

    def get(name: str, default: str = '') -> str:
        return str(values.get(name, default) or '').strip()

    inputs = MachineInputs(
        sliders_topic=get('sliders_topic'),
        inclinometer_topic=get('inclinometer_topic'),
        encoder_topic=get('encoder_topic'),
        inclinometer_type=get('inclinometer_type'),
        actuator_joints=name_list(get('actuator_joints')),
        inclinometer_joints=name_list(get('inclinometer_joints')),
        rotary_joint=get('rotary_joint'),
        inclinometer_signs=number_list(get('inclinometer_signs'), int),
        inclinometer_offsets_rad=number_list(get('inclinometer_offsets_rad')),
    )
    nominal, true_params = get('nominal'), get('true_params')
    driver = {'true_params': str(Path(true_params).resolve())} if true_params else {}
    postures = get('postures')
    return launches(
        get('namespace'),
        nominal,
        get('output_dir'),
        get('bag_dir'),
        get('plan'),
        int(postures) if postures else None,
        truthy(get('record', 'true')),
        driver,
        with_driver=truthy(get('use_driver', 'true')),
        model=get('model') or file_model(nominal) or file_model(true_params),
        executor_plan=get('executor_plan'),
        command_topic=get('command_topic'),
        calibrate_when_done=truthy(get('calibrate_when_done')),
        shutdown_when_done=truthy(get('shutdown_when_done')),
        with_kinematics=truthy(get('use_kinematics', 'true')),
        kinematics_parameters=get('kinematics_parameters'),
        inputs=inputs,
        measuring_mode=get('measuring_mode'),
        bag_name=get('bag_name'),
        calibration_store=get('calibration_store'),
    )


def file_model(path: str) -> str:
    """
    Return the model a parameters file names if not the default Hexa Slide, else ''.

    '' also for a file that cannot be read: the node that reads it names the problem.
    """
    if not path:
        return ''
    from hexacal_msgs_py.errors import HexacalContractError
    from hexacal_msgs_py.models import DEFAULT_MODEL
    from hexacal_msgs_py.parameters_file import read_parameters_file

    try:
        model = read_parameters_file(path).model
    except (HexacalContractError, OSError, ValueError):
        return ''
    return '' if model == DEFAULT_MODEL else model
