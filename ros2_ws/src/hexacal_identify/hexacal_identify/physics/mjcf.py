"""
The machine as a MuJoCo model (MJCF text): any architecture, the measuring device, the physics.

Pure text: nothing here imports mujoco, so the export (``hexacal export --format mjcf``) works
without it; the simulated machine (hexacal_driver.physics_machine) compiles the same text.

Built at one pose (the assembly pose, the model's reference configuration):

* each chain from ``Architecture.mechanism`` (the one owner of its kinematics): its bodies in
  a tree from the base, every body frame parallel to the base frame at the assembly pose, its
  actuated joint's value the actuator reading lambda (``ref``), its axial spring
  (a slide with MuJoCo joint stiffness; omitted for a rigid chain) between encoder and joint
  centres, and its spherical platform joint an equality ``connect`` to the platform;
* the platform: a free body in the platform frame (eq. 2's R), its mass, centre of mass and
  principal inertia, the payload a point mass welded to it;
* the measuring device (core/machine/device.py): the link's universal joint at the device's base
joint
  O (the base origin), its first hinge about -Y and its second about -X of the device frame
  turned by ``device_turn`` about Z, so that the hinge angles are (beta, alpha) of eq. 4; the
  link (length L + dL) ends at the platform frame origin P, a ``connect`` (the platform-side
  universal joint and the rotary sensor's axis make it spherical); an axial slide in the link is
  its spring (``link.axial_stiffness``) or, in the lvdt mode, the LVDT; the inclinometer is an
  accelerometer site on the link whose frame is the device frame;
* position servos (``general`` actuators: force = kp (ctrl - q) - kd q') named like the
  contract's actuator joints (``slider_1`` ...), controls = actuator setpoints in the model's
  actuator unit: on a slide (a slider, a leg) m, kp in N/m, kd in N s/m; on a hinge (a motor
  turning a crank) rad, kp in N m/rad, kd in N m s/rad (the physical description's drives);
* stiff constraint settings: equality solref (2 dt, 1), solimp (0.9999, 0.9999, 0.001, 0.5,
  2), Newton, contacts off.  MuJoCo's defaults leave the closed chains millimetres open; these
  close them to nanometres at rest.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

from hexacal_msgs_py.measuring_modes import MeasuringMode
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.physical_file import PhysicalDescription
import numpy as np

from ..core.architectures.base import (
    ACTUATED,
    ACTUATOR_BODY,
    COMPLIANCE,
    HINGE,
    KinematicParameters,
)
from ..core.architectures.common import rotation_from_trig
from ..core.machine.device import DEFAULT_MOUNT, STANDING

DEFAULT_TIMESTEP_S = 1e-4
# solimp: (dmin, dmax, width, midpoint, power): the constraint's impedance near 1 at any violation.
STIFF_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
SOLVER_TOLERANCE = 1e-12
ROD_RADIUS_M = 0.02  # bodies' radius for their inertia about their own axis and drawing
SLIDER_RADIUS_M = 0.04
# N m s / rad on passive hinges: settles joint chatter, no force at rest.
PASSIVE_JOINT_DAMPING = 0.05
PLATFORM_NAME = 'platform'
LINK_NAME = 'device_link'
LINK_SPRING_JOINT = 'device_link_axial'
LINK_HINGES = ('device_beta', 'device_alpha')  # the device's universal joint, base side first
INCLINOMETER_SITE = 'inclinometer'
INCLINOMETER_SENSOR = 'inclinometer_accelerometer'


@dataclass(frozen=True)
class MachineNames:
    """Names in the MJCF of what the simulation reads and drives, per chain (0-based)."""

    actuators: tuple[str, ...]  # the servos, named like the contract's actuator joints
    actuated_joints: tuple[str, ...]  # encoder side: the joint the servo drives
    spring_joints: tuple[str | None, ...]  # the chain's axial spring (None: rigid chain)
    link_spring_joint: str | None  # the link's axial slide (spring or LVDT; None: rigid link)
    equalities: tuple[str, ...]  # the connect constraints: chains, then the link


@dataclass(frozen=True)
class MachineMjcf:
    """MJCF text of a machine and the names in it."""

    xml: str
    names: MachineNames
    assembly_pose: np.ndarray  # (6,) the reference configuration's pose
    link_length: float  # m, the true link length at zero spring deflection


def chain_joint_name(chain: int, body: str, index: int) -> str:
    """Return the MJCF name of joint ``index`` of ``body`` in ``chain`` (0-based)."""
    return f'chain_{chain + 1}_{body}_{index}'


def _vec(values: Any) -> str:
    return ' '.join(repr(float(v)) for v in np.asarray(values, dtype=float).reshape(-1))


def _quat(rotation: np.ndarray) -> np.ndarray:
    """Return the unit quaternion (w, x, y, z) of a rotation matrix."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    quaternion = np.array(q)
    return quaternion / np.linalg.norm(quaternion)


def _rod_inertia(mass: float, segment: np.ndarray, radius: float) -> np.ndarray:
    """Return the full inertia (ixx iyy izz ixy ixz iyz) of a rod about its centre, base axes."""
    axis = segment[1] - segment[0]
    length = float(np.linalg.norm(axis))
    mass = max(mass, 1e-6)  # a moving body needs mass and inertia in MuJoCo
    if length < 1e-9:
        tensor = np.eye(3) * 0.4 * mass * radius**2
    else:
        unit = axis / length
        transverse = mass * (length**2 / 12.0 + radius**2 / 4.0)
        axial = 0.5 * mass * radius**2
        tensor = transverse * (np.eye(3) - np.outer(unit, unit)) + axial * np.outer(unit, unit)
    return np.array(
        [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]
    )


def _device_rotation(alpha: float, beta: float, turn: float) -> np.ndarray:
    """Return the device frame at readings (alpha, beta): R_z(turn) R_Y(-beta) R_X(-alpha)."""
    ca, sa, cb, sb = math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
    ct, st = math.cos(turn), math.sin(turn)
    rz = np.array([[ct, -st, 0.0], [st, ct, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cb, 0.0, -sb], [0.0, 1.0, 0.0], [sb, 0.0, cb]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, sa], [0.0, -sa, ca]])
    return rz @ ry @ rx


def device_readings_at(
    position: np.ndarray, mount: str = DEFAULT_MOUNT, device_turn: float = 0.0
) -> tuple[float, float]:
    """Return the ideal (alpha, beta) of the device turned by ``device_turn``, P at position."""
    p = np.asarray(position, dtype=float)
    ct, st = math.cos(device_turn), math.sin(device_turn)
    p = np.array([ct * p[0] + st * p[1], -st * p[0] + ct * p[1], p[2]])  # R_z(turn)^T p
    if mount == STANDING:
        p = -p
    u = p / np.linalg.norm(p)
    return math.asin(max(-1.0, min(1.0, -u[1]))), math.atan2(u[0], -u[2])


def machine_mjcf(
    params: KinematicParameters,
    physical: PhysicalDescription,
    pose: np.ndarray,
    *,
    link_length: float | None = None,
    mount: str = DEFAULT_MOUNT,
    device_turn: float = 0.0,
    measuring_mode: str = MeasuringMode.PASSIVE_ACTUATOR,
    lvdt_stiffness: float = 0.0,
    with_device: bool = True,
    timestep: float = DEFAULT_TIMESTEP_S,
    stiff: bool = True,
    model_name: str | None = None,
) -> MachineMjcf:
    """
    Return the MJCF of ``params`` with ``physical`` and the device, assembled at ``pose``.

    ``link_length``: the device's true link length L + dL at zero spring deflection (None: |P|
    of the pose; the pose must then lie on the link's sphere, as every pose of the machine
    does).  ``measuring_mode`` lvdt makes the link's axial slide the LVDT (spring
    ``lvdt_stiffness`` N/m about ``link_length``); otherwise the link's spring is
    ``physical.link_axial_stiffness`` (None: a rigid link).  ``stiff`` False keeps MuJoCo's
    default constraint settings (they leave the chains millimetres open).
    """
    if physical.model != params.model:
        raise ValueError(
            f'the physical description is of a {physical.model}, the parameters of a '
            f'{params.model}'
        )
    pose = np.asarray(pose, dtype=float).reshape(6)
    arch = params.architecture
    try:
        chains = arch.mechanism(params, pose)
    except NotImplementedError:
        raise ValueError(
            f'the {params.model} architecture does not describe its mechanism '
            '(Architecture.mechanism: its bodies and joints), so it has no MuJoCo model'
        ) from None
    actuator_names = MODELS[params.model].actuator_names
    rotation = rotation_from_trig(np.cos(pose[3:6]), np.sin(pose[3:6]))
    if link_length is None:
        link_length = float(np.linalg.norm(pose[:3]))
    if not (np.isfinite(link_length) and link_length > 0):
        raise ValueError(f'link_length must be a positive length in m, got {link_length}')
    stiffness = physical.structure_axial_stiffness
    equality = ''
    if stiff:
        equality = f' solref="{_vec([2 * timestep, 1.0])}" solimp="{_vec(STIFF_SOLIMP)}"'

    lines = [
        f'<mujoco model="{model_name or "hexacal_" + params.model}">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{timestep!r}" gravity="{_vec(physical.gravity)}" '
        f'integrator="implicitfast" solver="Newton" iterations="200" '
        f'tolerance="{SOLVER_TOLERANCE!r}" noslip_iterations="0">',
        '    <flag contact="disable"/>',
        '  </option>',
        '  <visual><global offwidth="1280" offheight="960"/></visual>',
        '  <worldbody>',
        '    <light pos="0 0 3" dir="0 0 -1" directional="true"/>',
        '    <geom name="floor" type="plane" size="2 2 0.01" pos="0 0 -2" rgba="0.8 0.8 0.8 1"'
        ' contype="0" conaffinity="0"/>',
    ]
    actuated, springs, equalities = [], [], []
    connects = []
    for c, chain in enumerate(chains):
        parent_origin = np.zeros(3)
        depth = 0
        closing = []
        for body in chain.bodies:
            origin = body.joints[0].anchor if body.joints else body.segment[0]
            name = f'chain_{c + 1}_{body.name}'
            indent = '    ' + '  ' * depth
            lines.append(f'{indent}<body name="{name}" pos="{_vec(origin - parent_origin)}">')
            if body.carries == ACTUATOR_BODY:
                mass, com = physical.actuator_moving_mass, body.segment.mean(axis=0)
                radius = SLIDER_RADIUS_M
            else:
                mass = physical.leg_mass
                com = body.segment[0] + physical.leg_com_fraction * (
                    body.segment[1] - body.segment[0]
                )
                radius = ROD_RADIUS_M
            lines.append(
                f'{indent}  <inertial pos="{_vec(com - origin)}" mass="{max(mass, 1e-6)!r}" '
                f'fullinertia="{_vec(_rod_inertia(mass, body.segment, radius))}"/>'
            )
            for k, joint in enumerate(body.joints):
                jname = chain_joint_name(c, body.name, k)
                attrs = (
                    f'name="{jname}" pos="{_vec(joint.anchor - origin)}" '
                    f'axis="{_vec(joint.axis)}"'
                )
                if joint.role == ACTUATED:
                    # ref: the joint's value at the assembly is the reading, slide or hinge.
                    actuated.append(jname)
                    kind = 'hinge' if joint.kind == HINGE else 'slide'
                    lines.append(
                        f'{indent}  <joint {attrs} type="{kind}" ref="{chain.actuator!r}" '
                        f'limited="false"/>'
                    )
                elif joint.role == COMPLIANCE:
                    if stiffness is None:
                        continue
                    springs.append((c, jname))
                    damping = 2.0 * math.sqrt(stiffness[c] * max(mass, 1e-3))
                    lines.append(
                        f'{indent}  <joint {attrs} type="slide" stiffness="{stiffness[c]!r}" '
                        f'damping="{damping!r}" limited="false"/>'
                    )
                else:
                    kind = 'hinge' if joint.kind == HINGE else 'slide'
                    lines.append(
                        f'{indent}  <joint {attrs} type="{kind}" '
                        f'damping="{PASSIVE_JOINT_DAMPING!r}" limited="false"/>'
                    )
            segment = body.segment - origin
            if np.linalg.norm(segment[1] - segment[0]) > 1e-9:
                lines.append(
                    f'{indent}  <geom type="capsule" fromto="{_vec(segment)}" '
                    f'size="{radius * 0.5!r}" contype="0" conaffinity="0" mass="0"/>'
                )
            else:
                lines.append(
                    f'{indent}  <geom type="box" pos="{_vec(segment[0])}" '
                    f'size="{radius!r} {radius!r} {radius * 0.5!r}" contype="0" '
                    'conaffinity="0" mass="0"/>'
                )
            closing.append(f'{indent}</body>')
            parent_origin = origin
            depth += 1
        lines.extend(reversed(closing))
        last = f'chain_{c + 1}_{chain.bodies[-1].name}'
        ename = f'chain_{c + 1}_platform_joint'
        equalities.append(ename)
        connects.append(
            f'    <connect name="{ename}" body1="{last}" body2="{PLATFORM_NAME}" '
            f'anchor="{_vec(chain.platform_joint - parent_origin)}"{equality}/>'
        )

    # The platform: a free body in the platform frame.
    inertia = np.maximum(np.asarray(physical.platform_inertia), 1e-6)
    lines += [
        f'    <body name="{PLATFORM_NAME}" pos="{_vec(pose[:3])}" quat="{_vec(_quat(rotation))}">',
        '      <freejoint name="platform_free"/>',
        f'      <inertial pos="{_vec(physical.platform_com)}" mass="{physical.platform_mass!r}" '
        f'diaginertia="{_vec(inertia)}"/>',
    ]
    joints = params.platform_points
    if len(joints) >= 3:
        lines.append(
            '      <geom type="cylinder" size="'
            f'{float(np.max(np.hypot(joints[:, 0], joints[:, 1])))!r} 0.005" '
            f'pos="0 0 {float(np.mean(joints[:, 2]))!r}" contype="0" conaffinity="0" mass="0" '
            'rgba="0.3 0.5 0.8 0.6"/>'
        )
    lines.append('      <site name="platform_frame" size="0.01"/>')
    if physical.payload_mass > 0:
        lines += [
            f'      <body name="payload" pos="{_vec(physical.payload_com)}">',
            f'        <inertial pos="0 0 0" mass="{physical.payload_mass!r}" '
            'diaginertia="1e-6 1e-6 1e-6"/>',
            '        <geom type="sphere" size="0.03" contype="0" conaffinity="0" mass="0"/>',
            '      </body>',
        ]
    lines.append('    </body>')

    link_spring = None
    if with_device:
        alpha, beta = device_readings_at(pose[:3], mount, device_turn)
        frame = _device_rotation(alpha, beta, device_turn)
        turn = _device_rotation(0.0, 0.0, device_turn)
        end = pose[:3]
        direction = end / np.linalg.norm(end)
        link_end = direction * link_length  # where the link ends at zero spring deflection
        com = physical.link_com_fraction * link_end
        link_inertia = _rod_inertia(
            physical.link_mass, np.array([np.zeros(3), link_end]), ROD_RADIUS_M
        )
        lvdt = measuring_mode == MeasuringMode.LVDT
        link_stiffness = lvdt_stiffness if lvdt else physical.link_axial_stiffness
        lines += [
            f'    <body name="{LINK_NAME}" pos="0 0 0">',
            f'      <inertial pos="{_vec(com)}" mass="{max(physical.link_mass, 1e-6)!r}" '
            f'fullinertia="{_vec(link_inertia)}"/>',
            f'      <joint name="{LINK_HINGES[0]}" type="hinge" pos="0 0 0" '
            f'axis="{_vec(turn @ [0.0, -1.0, 0.0])}" damping="{PASSIVE_JOINT_DAMPING!r}"/>',
            f'      <joint name="{LINK_HINGES[1]}" type="hinge" pos="0 0 0" '
            f'axis="{_vec(frame @ [-1.0, 0.0, 0.0])}" damping="{PASSIVE_JOINT_DAMPING!r}"/>',
        ]
        if lvdt or link_stiffness is not None:
            link_spring = LINK_SPRING_JOINT
            spring = 0.0 if link_stiffness is None else float(link_stiffness)
            damping = 2.0 * math.sqrt(max(spring, 1.0) * max(physical.link_mass, 1e-3))
            lines.append(
                f'      <joint name="{LINK_SPRING_JOINT}" type="slide" pos="0 0 0" '
                f'axis="{_vec(direction)}" stiffness="{spring!r}" damping="{damping!r}" '
                'limited="false"/>'
            )
        lines += [
            f'      <geom type="capsule" fromto="0 0 0 {_vec(link_end)}" size="0.008" '
            'contype="0" conaffinity="0" mass="0" rgba="0.9 0.4 0.1 1"/>',
            f'      <site name="{INCLINOMETER_SITE}" pos="{_vec(com)}" '
            f'quat="{_vec(_quat(frame))}" size="0.015"/>',
            '    </body>',
        ]
        equalities.append('device_link_platform_joint')
        connects.append(
            f'    <connect name="device_link_platform_joint" body1="{LINK_NAME}" '
            f'body2="{PLATFORM_NAME}" anchor="{_vec(end)}"{equality}/>'
        )
    lines.append('  </worldbody>')
    lines += ['  <equality>', *connects, '  </equality>']
    # The assembly as a keyframe: MuJoCo's viewer starts from zero controls, which the servos
    # would chase; load this key first.
    lines += [
        '  <keyframe>',
        f'    <key name="assembly" ctrl="{_vec([chain.actuator for chain in chains])}"/>',
        '  </keyframe>',
    ]
    lines.append('  <actuator>')
    for c, jname in enumerate(actuated):
        kp, kd = physical.drive_kp[c], physical.drive_kd[c]
        lines.append(
            f'    <general name="{actuator_names[c]}" joint="{jname}" gaintype="fixed" '
            f'gainprm="{kp!r}" biastype="affine" biasprm="0 {-kp!r} {-kd!r}"/>'
        )
    lines.append('  </actuator>')
    if with_device:
        lines += [
            '  <sensor>',
            f'    <accelerometer name="{INCLINOMETER_SENSOR}" site="{INCLINOMETER_SITE}"/>',
            '  </sensor>',
        ]
    lines.append('</mujoco>')
    spring_by_chain: list[str | None] = [None] * len(chains)
    for c, jname in springs:
        spring_by_chain[c] = jname
    names = MachineNames(
        actuators=tuple(actuator_names),
        actuated_joints=tuple(actuated),
        spring_joints=tuple(spring_by_chain),
        link_spring_joint=link_spring,
        equalities=tuple(equalities),
    )
    return MachineMjcf('\n'.join(lines) + '\n', names, pose.copy(), float(link_length))
