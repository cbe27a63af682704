"""
The rotary hexapod's parameter set (layout, field indices, motor axis angles) and default machine.

What ``rotary_hexapod`` (the kinematics) reads its 66 parameters with, and the machine
``hexacal params default --model rotary_hexapod`` writes.

Per chain, chain-major, 11 fields (SI units: metres and radians):

* ``Ax Ay Az``: the centre of the crank-tip circle on the motor axis, base
  frame (the foot of the crank-tip joint centre on the axis);
* ``Bx By Bz``: the platform joint centre, platform frame;
* ``l``: the rod length (U joint centre to S joint centre);
* ``r``: the crank length (motor axis to U joint centre);
* ``axis_az``, ``axis_el``: azimuth and elevation of the unit motor axis
  direction ``n = (cos el cos az, cos el sin az, sin el)``;
* ``alpha0``: the crank's zero angle, the angle of the crank at reading zero
  measured about ``n`` from the horizontal reference ``h = (-sin az, cos az,
  0)`` (``h = e_z x n / cos el``, unit and normal to n).

Crank direction and tip: with ``w = n x h`` (the second reference, "up" for a
horizontal axis) and the crank angle ``phi = lambda + alpha0``::

    c(phi) = cos phi h + sin phi w,   C = A + r c(phi),   |P + R B - C| = l

Why these 11 are a minimal, complete and parametrically continuous set
(the argument of the paper's section 2.3 for the Hexa Slide, after Fassi et
al.): the reading of one chain is a function of the pose only through the
platform point ``P + R B`` (3 parameters: B) and the locus of the crank tip as
a function of the reading.  That locus is a circle (centre 3, plane normal 2,
radius 1) with a point on it for each reading (the reading's zero, 1: a
constant offset of an angular encoder is the only calibration of it), and the
rod joins it to B at a fixed distance (1).  6 + 1 + 1 + 3 = 11, each
parameter changes the chain's readings in its own way, so none is redundant
within a chain; all 11 are needed to describe an arbitrary as-built chain (the
motor axis tilted and displaced, crank and rod lengths and the encoder zero
off), so the set is complete.  A point on the motor axis "anywhere along the
axis" would add a twelfth parameter whose motion along the axis no reading can
see; taking the crank circle's centre removes it (Fassi's rule: one point per
line is fixed by the next joint).  The direction as two angles instead of
three components removes the unit-norm constraint; the angles are
continuous (a small change of the machine is a small change of them) everywhere
but at a vertical motor axis (``|el| = 90 deg``, where the azimuth is
undefined), which the physical check excludes; motor axes of rotary hexapods
lie near the base plane.

What each cost function cannot see (``core/identifiability``, 40 sphere + 40
fixed-position postures of the default workspace, checked in
``test_architecture_rotary_hexapod``): absolute (eq. 7) and sphere-fixed
(eqs. 8 + 10) identify all 66; sphere (eq. 8) 65: a rotation of the base frame
about Y, as for every model; relative (eqs. 12 + 13) 64: that rotation and a
scaling of the machine about the base origin - the readings are angles, so
nothing measured carries the machine's size once the link length cancels in
the differences (a slider machine reads lengths and has no such gauge); fixed
(eq. 10) 59: the base rotation about Y through the fixed point and six
combinations of the rod lengths l with the crank circles' heights Az (two
exactly, four to ~1e-8 of the largest scaled singular value with 40
postures: with the platform centre pinned, each platform joint only moves on a
small sphere, too little to tell a longer rod from a lower crank circle).
Angles as readings also make the device's link length offset dL the
machine's scale: identified with dL free, any cost is one short.

The default machine (``default_parameters``): six motors on a 0.40 m circle in
the base plane in pairs 40 deg apart around 0, 120 and 240 deg, horizontal
axes pointing along the radius (in each pair one outward, one inward, so the
cranks point away from each other), 0.15 m cranks horizontal at reading zero,
platform joints on a 0.25 m circle 15 mm above the platform plane in pairs
20 deg apart around the motor pairs' angles (each rod leans from its crank tip
towards the middle of its pair: pose Jacobian condition number 10 at home),
rods as long as the hanging home pose [0, 0, -0.75 m] needs, and mm-level
(mrad-level) as-built irregularity so that no symmetry hides a parameter.
The default workspace: x, y within +-0.2 m on the L-sphere, angles within
+-20 deg, crank readings within +-1.2 rad (its "stroke", in rad).
"""

from __future__ import annotations

from dataclasses import dataclass

from hexacal_msgs_py.models import MODELS, ROTARY_HEXAPOD
import numpy as np

from .base import KinematicParameters


LAYOUT = MODELS[ROTARY_HEXAPOD]
N_CHAINS = LAYOUT.n_chains
FIELDS_PER_CHAIN = LAYOUT.fields_per_chain
N_PARAMETERS = LAYOUT.n_parameters
A_SLICE = slice(0, 3)
B_SLICE = slice(3, 6)
L_INDEX = 6
R_INDEX = 7
AZ_INDEX = 8
EL_INDEX = 9
ALPHA0_INDEX = 10

BASE_RADIUS_M = 0.40
CRANK_M = 0.15
PLATFORM_RADIUS_M = 0.25
PLATFORM_JOINT_HEIGHT_M = 0.015
HOME_DEPTH_M = 0.75  # the device's default link length: the home pose is [0, 0, -0.75] m
# Crank angle range of the default workspace (rad about the zero), and postures' limits.
STROKE_RAD = (-1.2, 1.2)
_MOTOR_ANGLES_DEG = (-20.0, 20.0, 100.0, 140.0, 220.0, 260.0)
_PLATFORM_ANGLES_DEG = (-10.0, 10.0, 110.0, 130.0, 230.0, 250.0)
# Motor axis along the radius, outward (+1) or inward (-1): the cranks of a pair point apart.
_AXIS_OUTWARD = (-1.0, 1.0, -1.0, 1.0, -1.0, 1.0)
# As-built irregularity per chain (mm; mrad for the three angles): A xyz, B xyz, l, r, az, el,
# alpha0.
_AS_BUILT = np.array(
    [
        [1.2, -0.8, 0.5, -0.4, 0.3, 0.2, 0.7, 0.3, 2.0, -1.5, 3.0],
        [-0.9, 1.1, -0.3, 0.5, -0.2, -0.1, -0.4, -0.2, -1.0, 2.5, -2.0],
        [0.6, 0.4, 0.9, -0.3, -0.5, 0.3, 0.2, 0.4, 1.5, 1.0, 1.0],
        [-1.1, -0.6, -0.7, 0.2, 0.4, -0.2, -0.6, -0.3, -2.5, -1.0, -3.5],
        [0.8, -1.2, 0.2, -0.5, 0.1, 0.1, 0.5, 0.1, 0.5, 2.0, 2.5],
        [-0.5, 0.9, -0.6, 0.4, -0.3, -0.3, -0.3, -0.4, -1.5, -2.0, -1.5],
    ]
)


def axis_frame(azimuth: np.ndarray, elevation: np.ndarray) -> tuple[np.ndarray, ...]:
    """
    Return n, h, w = n x h and dh/daz, dw/daz for motor axis angles (each (..., 3)).

    n the unit motor axis, h = (-sin az, cos az, 0) the crank's zero reference and w the
    crank's direction a quarter turn further (module doc).
    """
    ca, sa = np.cos(azimuth), np.sin(azimuth)
    ce, se = np.cos(elevation), np.sin(elevation)
    zero = np.zeros_like(ca)
    n = np.stack([ce * ca, ce * sa, se], axis=-1)
    h = np.stack([-sa, ca, zero], axis=-1)
    w = np.stack([-se * ca, -se * sa, ce], axis=-1)
    dh_daz = np.stack([-ca, -sa, zero], axis=-1)
    dw_daz = np.stack([se * sa, -se * ca, zero], axis=-1)
    return n, h, w, dh_daz, dw_daz


def axis_angles(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return (azimuth, elevation) of unit motor axis directions (..., 3)."""
    direction = np.asarray(direction, dtype=float)
    return (
        np.arctan2(direction[..., 1], direction[..., 0]),
        np.arcsin(np.clip(direction[..., 2], -1.0, 1.0)),
    )


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Return ``angle`` in [-pi, pi)."""
    return np.mod(angle + np.pi, 2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class RotaryHexapodParameters(KinematicParameters):
    """The 66 kinematic parameters of a 6-RUS rotary hexapod, chain-major (module doc)."""

    @property
    def rod_lengths(self) -> np.ndarray:
        """l, (6,)."""
        return self.per_chain[:, L_INDEX]

    @property
    def crank_lengths(self) -> np.ndarray:
        """r, (6,)."""
        return self.per_chain[:, R_INDEX]

    @property
    def crank_zeros(self) -> np.ndarray:
        """alpha0, (6,) rad."""
        return self.per_chain[:, ALPHA0_INDEX]

    @property
    def axis_directions(self) -> np.ndarray:
        """Return the unit motor axis directions n, (6, 3)."""
        return axis_frame(self.per_chain[:, AZ_INDEX], self.per_chain[:, EL_INDEX])[0]

    def crank_directions(self, readings: np.ndarray) -> np.ndarray:
        """Return the unit crank directions c (..., 6, 3) at actuator readings (..., 6)."""
        _, h, w, _, _ = axis_frame(self.per_chain[:, AZ_INDEX], self.per_chain[:, EL_INDEX])
        phi = np.asarray(readings, dtype=float) + self.crank_zeros
        return np.cos(phi)[..., None] * h + np.sin(phi)[..., None] * w

    @classmethod
    def from_parts(
        cls,
        axis_points: np.ndarray,
        platform_points: np.ndarray,
        rod_lengths: np.ndarray,
        crank_lengths: np.ndarray,
        axis_directions: np.ndarray,
        crank_zeros: np.ndarray,
    ) -> 'RotaryHexapodParameters':
        azimuth, elevation = axis_angles(axis_directions)
        blocks = np.column_stack(
            [
                np.asarray(axis_points),
                np.asarray(platform_points),
                np.asarray(rod_lengths),
                np.asarray(crank_lengths),
                azimuth,
                elevation,
                np.asarray(crank_zeros),
            ]
        )
        return cls(blocks.reshape(-1))


def default_rotary_hexapod() -> RotaryHexapodParameters:
    """Return the shipped default rotary hexapod (module doc), rounded to 1e-10 like the others."""
    motor = np.radians(_MOTOR_ANGLES_DEG)
    radial = np.column_stack([np.cos(motor), np.sin(motor), np.zeros(N_CHAINS)])
    axes = radial * np.asarray(_AXIS_OUTWARD)[:, None]
    axis_points = BASE_RADIUS_M * radial
    platform_angles = np.radians(_PLATFORM_ANGLES_DEG)
    platform = np.column_stack(
        [
            PLATFORM_RADIUS_M * np.cos(platform_angles),
            PLATFORM_RADIUS_M * np.sin(platform_angles),
            np.full(N_CHAINS, PLATFORM_JOINT_HEIGHT_M),
        ]
    )
    # Crank horizontal at reading zero (phi = 0: along h); rods as long as the home pose needs.
    azimuth, elevation = axis_angles(axes)
    _, h, _, _, _ = axis_frame(azimuth, elevation)
    tips = axis_points + CRANK_M * h
    home_joints = platform + np.array([0.0, 0.0, -HOME_DEPTH_M])
    rods = np.round(np.linalg.norm(home_joints - tips, axis=1), 3)
    exact = np.column_stack(
        [
            axis_points,
            platform,
            rods,
            np.full(N_CHAINS, CRANK_M),
            azimuth,
            elevation,
            np.zeros(N_CHAINS),
        ]
    )
    exact = exact + _AS_BUILT / 1000.0
    return RotaryHexapodParameters(np.round(exact, 10).reshape(-1))


__all__ = [
    'A_SLICE',
    'ALPHA0_INDEX',
    'axis_angles',
    'axis_frame',
    'AZ_INDEX',
    'B_SLICE',
    'CRANK_M',
    'default_rotary_hexapod',
    'EL_INDEX',
    'FIELDS_PER_CHAIN',
    'L_INDEX',
    'LAYOUT',
    'N_CHAINS',
    'N_PARAMETERS',
    'R_INDEX',
    'RotaryHexapodParameters',
    'STROKE_RAD',
    'wrap_angle',
]
