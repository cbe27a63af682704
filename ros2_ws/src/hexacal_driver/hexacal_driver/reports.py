"""
What the driver node logs, and when (ROS-free): start-up, postures, motions, the end.

The node passes the lines returned here to its logger; the decisions of when a line is
due (a new posture held, a commanded motion ended) are made here too.
"""

from __future__ import annotations

import math

from hexacal_driver.drives import DriveFollower
from hexacal_driver.machine import SimulatedMachine
from hexacal_driver.plan import PosturePlan
from hexacal_driver.simulation import DONE, DWELLING, MOVING
from hexacal_identify.core.machine.device import DEFAULT_MOUNT, DeviceDefects
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_msgs_py.measuring_modes import MeasuringMode
from hexacal_msgs_py.models import ActuatorQuantities, HEXA_SLIDE, LINEAR_ACTUATOR, MODELS
import numpy as np

# Commanded mode: a strain of the measuring link beyond this is logged (at most every period);
# m of travel at the actuator's joint (for cranks, Architecture.actuator_limit turns it into rad).
STRAIN_WARNING_M = 0.01
STRAIN_WARNING_PERIOD_S = 5.0


def machine_source(true_params: str, machine: SimulatedMachine) -> str:
    """Return where the true machine comes from and how the device differs from the default."""
    model = machine.model
    if true_params:
        source = true_params
    elif model == HEXA_SLIDE:
        source = 'Table 1'
    else:
        source = f'the default {MODELS[model].title}'
    if model != HEXA_SLIDE:
        source += f' ({model}, joints {", ".join(MODELS[model].actuator_names)})'
    if machine.mount != DEFAULT_MOUNT:
        source += f', {machine.mount} device'
    if machine.defects != DeviceDefects():
        source += f'; device defects {machine.defects.describe()}'
    if machine.device_turn != 0.0:
        source += f'; device turned {machine.device_turn:.6g} rad about its link'
    return source


def actuator_quantities_of(machine: SimulatedMachine) -> ActuatorQuantities:
    """Return the units of the simulated machine's actuators (m and N, or rad and N m)."""
    return MODELS[machine.model].actuator_quantities


def noise_text(noise: NoiseModel, quantities: ActuatorQuantities = LINEAR_ACTUATOR) -> str:
    """Return the noise half-widths as logged (the actuators' in their SI unit, m or rad)."""
    return f'+-{noise.actuator_m:g} {quantities.unit} / +-{noise.angle_rad:g} rad'


def sensors_text(machine: SimulatedMachine) -> str:
    """Return the noise as logged at start-up, with the active sensor effects if any."""
    settings = machine.streams.settings
    effects = f'; {settings.describe()}' if settings.effects else ''
    return f'noise {noise_text(machine.sensors.noise, actuator_quantities_of(machine))}{effects}'


def commanded_start_text(
    machine: SimulatedMachine, topic: str, source: str, rate_hz: float
) -> str:
    """Return the start-up line of commanded mode."""
    follower = machine.require_follower()
    low, high = follower.actuator_stroke_m  # the machine's stroke
    units = actuator_quantities_of(machine)
    return (
        f'following JointTrajectory commands on {topic} (joints '
        f'{", ".join(MODELS[machine.model].actuator_names)}, at most '
        f'{follower.max_speed_m_s:g} {units.speed_unit}, stroke [{low:g}, {high:g}] '
        f'{units.unit}); true machine: '
        f'{source}; {rate_hz:g} Hz, {sensors_text(machine)}; standing at the '
        'fixed-position point'
    )


def drives_start_text(follower: DriveFollower) -> str:
    """
    Return the start-up line of the drives in commanded mode: the mode and its guard.

    The settings keep their slider names (``servo_stiffness_n_per_m``, ``max_force_n``,
    ``max_following_error_m``); for actuators that turn they are in N m/rad, N m and rad, and
    the line says so.
    """
    settings = follower.settings
    units = follower.params.layout.actuator_quantities
    if settings.mode == MeasuringMode.COMPLIANT:
        guard = (
            f'compliant servos of {settings.servo_stiffness_n_per_m:g} {units.stiffness_unit}, '
            f'fault above {settings.max_force_n:g} {units.effort_unit} on a servo or '
            f'{settings.max_link_force_n:g} N on the link'
        )
    else:
        guard = (
            f'stiff drives, fault above {settings.max_following_error_m:g} {units.unit} '
            'following error'
        )
        if settings.mode == MeasuringMode.LVDT:
            guard += f'; LVDT link stroke +-{settings.lvdt_stroke_m:g} m'
        else:
            guard += '; no joint released (release one through hexacal/release/<joint>)'
    return f'measuring_mode {settings.mode.value}: {guard}'


def plan_start_text(machine: SimulatedMachine, source: str, rate_hz: float) -> str:
    """Return the start-up line of plan mode."""
    walker = machine.require_walker()
    return (
        f'{machine.require_plan().describe()}; true machine: {source}; {rate_hz:g} Hz, settle '
        f'{walker.settle_s:g} s, dwell {walker.dwell_s:g} s (one pass '
        f'{walker.lap_duration_s:.1f} s), {sensors_text(machine)}'
        f'{", looping" if walker.loop else ""}'
    )


def device_turn_text(previous: float, turn: float, plan: PosturePlan | None) -> str:
    """Return the line logged when the device_turn parameter changes."""
    return (
        f'device_turn {previous:.6g} -> {turn:.6g} rad: the device is turned about its link axis'
        + (
            ' (for the postures whose plan names no turn)'
            if plan is not None and plan.device_turns
            else ''
        )
    )


def command_text(
    count: int,
    target: np.ndarray,
    duration_s: float,
    quantities: ActuatorQuantities = LINEAR_ACTUATOR,
) -> str:
    """Return the line logged for an accepted JointTrajectory command (mm, or deg for cranks)."""
    scale = quantities.display_scale
    return (
        f'command {count}: to [{", ".join(f"{v * scale:.3f}" for v in target)}] '
        f'{quantities.display} in {duration_s:.2f} s'
    )


class WalkReport:
    """Decide the lines of a plan walk: each posture when first held, the end of each lap."""

    def __init__(self, plan: PosturePlan, loop: bool) -> None:
        """Report on `plan`, walked once or in a loop."""
        self.plan = plan
        self.loop = loop
        self._last: tuple[int, int, str] | None = None

    def lines(
        self, index: int, lap: int, phase: str, elapsed_s: float, turn: float
    ) -> list[str]:
        """Return the lines due at this sample (posture `index` of `lap`, device turn rad)."""
        state = (index, lap, phase)
        if phase not in (DWELLING, DONE) or state == self._last:
            return []
        self._last = state
        plan = self.plan
        if phase == DONE:
            return [
                f"end of plan '{plan.name}': {len(plan)} postures in {elapsed_s:.1f} s; "
                'standing at the last posture'
            ]
        pose = plan.poses[index]
        lap_text = f' (lap {lap + 1})' if self.loop else ''
        lines = [
            f'posture {index + 1}/{len(plan)}{lap_text} ({plan.kinds[index]}): '
            f'position [{pose[0] * 1e3:.1f}, {pose[1] * 1e3:.1f}, {pose[2] * 1e3:.1f}] mm, '
            f'angles [{math.degrees(pose[3]):.1f}, {math.degrees(pose[4]):.1f}, '
            f'{math.degrees(pose[5]):.1f}] deg'
            + (f', device turned {turn:.6g} rad' if turn != 0.0 else '')
        ]
        if self.loop and index == len(plan) - 1:
            lines.append(f"end of plan '{plan.name}' lap {lap + 1}: looping")
        return lines


class MotionReport:
    """Decide the lines of commanded mode: the link's strain, the end of each motion."""

    def __init__(self) -> None:
        """Start with no motion seen."""
        self._last_phase = ''

    @staticmethod
    def strain_warning(
        strain_m: float,
        quantities: ActuatorQuantities = LINEAR_ACTUATOR,
        limit: float = STRAIN_WARNING_M,
    ) -> str | None:
        """
        Return the warning while the link strains the machine beyond `limit`.

        ``strain_m`` and ``limit`` are in the actuators' unit (m, or rad for cranks), shown in
        mm or deg.
        """
        if strain_m <= limit:
            return None
        return (
            f'the measuring link strains the machine: actuators {quantities.shown(strain_m, 1)} '
            'from their setpoints (commanded positions off the link sphere: move along it)'
        )

    def lines(
        self, machine: SimulatedMachine, phase: str, commands_accepted: int
    ) -> tuple[str | None, str | None]:
        """Return this tick's strain warning and end-of-motion line (each may be None)."""
        strain = machine.require_follower().strain_m
        units = actuator_quantities_of(machine)
        limit = machine.true_params.architecture.actuator_limit(STRAIN_WARNING_M)
        warning = self.strain_warning(strain, units, limit)
        return warning, self.motion_line(phase, strain, commands_accepted, units)

    def motion_line(
        self,
        phase: str,
        strain_m: float,
        commands_accepted: int,
        quantities: ActuatorQuantities = LINEAR_ACTUATOR,
    ) -> str | None:
        """Return one line when a commanded motion ends (with the link's strain), else None."""
        if phase == self._last_phase:
            return None
        self._last_phase = phase
        if phase == MOVING or not commands_accepted:
            return None
        if strain_m > 1e-6:
            return (
                'standing at the commanded position (actuators '
                f'{quantities.shown_small(strain_m, 0)} from the setpoints: the strain of the '
                'measuring link)'
            )
        return 'standing at the commanded position'


def link_overload_warning(follower: DriveFollower) -> str | None:
    """
    Return the warning for a motion that just ended at rest having loaded the link past its limit.

    The compliant drives fault on it; a released actuator's (passive_actuator) may not fault,
    since the link is then a load-bearing member whose load the drives cannot limit, and the
    load of a real link is the user's to know.  None when it stayed inside or is not known.
    """
    peak = follower.move_peaks['link_force_n']
    limit = follower.settings.max_link_force_n
    if follower.link_force() is None or peak <= limit:
        return None
    event, joint = follower.move_link_peak_after
    after = {'move': ', on a move', 'release': f', after the release of {joint}',
             'lock': f', after the lock of {joint}'}.get(event, '')
    return (
        f'the measuring link carried up to {peak:.4g} N on the way here{after}, beyond its '
        f'{limit:g} N limit (max_link_force_n)'
    )


def finish_lines(
    published: int,
    published_before_plan: int,
    plan_start_stamp_ns: int | None,
    commands: tuple[int, int] | None,
    dropped: tuple[int, ...] = (),
) -> list[str]:
    """
    Return the lines printed when the node stops; commands (followed, rejected) if commanded.

    `dropped`: the messages the sensor effect `drops` lost per stream (sliders, inclinometer,
    encoder), named when there were any.
    """
    lines = [
        f'published {published} messages on each sensor stream, '
        f'{published - published_before_plan} of them since the plan '
        f'started (first stamp {plan_start_stamp_ns} ns)'
    ]
    if any(dropped):
        lines[0] += (
            f'; the sensor model dropped {", ".join(str(count) for count in dropped)} of them '
            '(sliders, inclinometer, encoder)'
        )
    if commands is not None:
        lines.append(f'commands: {commands[0]} followed, {commands[1]} rejected')
    return lines


# Commanded mode: the drives' status is published at least this often.
DRIVER_STATUS_PERIOD_S = 1.0


class DriveStatusReport:
    """
    The drives' status ('hexacal driver'): when it is due, its level, text and fields.

    Due on a change of state, release or fault, when forced (a service answered, a command was
    refused), else every DRIVER_STATUS_PERIOD_S.
    """

    def __init__(self, period_s: float = DRIVER_STATUS_PERIOD_S):
        """Publish at least every `period_s` (s)."""
        self.period_ns = int(period_s * 1e9)
        self._key: tuple | None = None
        self._due_ns = 0

    def report(
        self, follower: DriveFollower, now_ns: int, force: bool = False
    ) -> tuple[str, str, dict[str, object], str] | None:
        """
        Return (level, message, fields, a new fault's text or '') if due now; else None.

        The level is 'ERROR' while the drives are faulted, else 'OK'.
        """
        key = (follower.state, follower.released_joint, follower.fault)
        if not force and key == self._key and now_ns < self._due_ns:
            return None
        new_fault = follower.fault.text if follower.fault is not None and key != self._key else ''
        self._key = key
        self._due_ns = now_ns + self.period_ns
        released = follower.released_joint
        if follower.fault is not None:
            level, message = 'ERROR', f'fault: {follower.fault.text}'
        else:
            level = 'OK'
            message = f'{follower.mode.value}' + (f', {released} released' if released else '')
        return level, message, follower.status_values(), new_fault
