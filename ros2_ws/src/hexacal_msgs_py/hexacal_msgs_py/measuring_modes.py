"""
The measuring modes: how the machine is driven while the link is attached (ROS-free).

With the measuring link attached the platform has 5 degrees of freedom (the paper's section 4),
so six position-controlled actuators over-constrain it.  A measuring procedure says how that is
resolved; one name (``measuring_mode``) is used everywhere: plan files, parameters, bags, the
command line.

* ``passive_actuator`` (the paper's procedure; the default): per posture one actuator is
  released (``released_actuator`` in the plan, an actuator joint name) and the other five are
  commanded; the link puts the platform, and the released actuator, where the constraint says
  and the released actuator's encoder reads where it went.
* ``lvdt``: a spring-loaded telescopic link whose length an LVDT measures (the fourth device
  reading, joint ``LINK_LENGTH_JOINT``, m); all six actuators are commanded and the link length
  L_m replaces L per posture in eq. 4.
* ``compliant``: all six commanded against the rigid link, for drives that can run
  torque-limited during calibration (hexacal's behaviour before the modes had names).

This module imports nothing but the standard library, so launch tooling can read it.
"""

from __future__ import annotations

import enum

from hexacal_msgs_py.models import LINK_LENGTH_JOINT  # noqa: F401 - re-exported

MEASURING_MODE_KEY = 'measuring_mode'  # the plan files' (and parameters') key
RELEASED_ACTUATOR_KEY = 'released_actuator'  # a plan posture's key: an actuator joint name
# The LVDT link's default stroke about its nominal length, +- m (a future driver parameter; the
# planner's --lvdt-stroke-m).
DEFAULT_LVDT_STROKE_M = 0.005
# The axial force the measuring link of the documented kind bears (N): a 0.75 m link of 1.5 kg,
# axially 1e7 N/m (physical_file.py's defaults), U joints at both ends.  That stiffness is a tube
# of EA = k L = 7.5e6 N (aluminium 20 x 1.8 mm); pinned at its U joints it buckles at
# pi^2 E I / L^2 = 5.3 kN, and an instrument's miniature U joints and rotary-sensor bearing are
# rated far lower.  500 N is a tenth of the buckling load, and stretches the link 50 um: 25 times
# a 2 um reading, beyond which its length is no measurement anyway.  The drives fault above it
# (the driver's max_link_force_n; max_force_n of a servo, whose force the rigid link carries).
LINK_FORCE_LIMIT_N = 500.0
# Compliant servos against the rigid link absorb what the targets of a nominal model miss on the
# true machine before the targets are refined: millimetres (up to 4.7 mm at the demo's planned
# postures, the nominal set of the documented tolerances), the link's tension about twice the
# largest servo force.  20 N/mm keeps that near 190 N, inside LINK_FORCE_LIMIT_N; a stiff
# position loop (2e6 N/m) would load the link with 18.6 kN.  (N/m; the driver's and the executor's
# servo_stiffness_n_per_m.)
COMPLIANT_SERVO_STIFFNESS_N_PER_M = 2e4
# The executor's guard keeps its predicted forces this fraction of the drives' limits: its
# prediction on the model misses what the model misses (the mismatch of the next standing).
GUARD_FORCE_FRACTION = 0.8


class MeasuringMode(enum.StrEnum):
    """How the six actuators are driven while the measuring link is attached (module doc)."""

    PASSIVE_ACTUATOR = 'passive_actuator'
    LVDT = 'lvdt'
    COMPLIANT = 'compliant'


DEFAULT_MEASURING_MODE = MeasuringMode.PASSIVE_ACTUATOR
MEASURING_MODES: tuple[str, ...] = tuple(mode.value for mode in MeasuringMode)


def measuring_mode(value: object) -> MeasuringMode:
    """Return the MeasuringMode named `value`; ValueError naming the allowed values."""
    if isinstance(value, str) and value in MEASURING_MODES:
        return MeasuringMode(value)
    raise ValueError(
        f'{MEASURING_MODE_KEY} must be one of {", ".join(MEASURING_MODES)} '
        f'(default {DEFAULT_MEASURING_MODE.value}), got {value!r}'
    )
