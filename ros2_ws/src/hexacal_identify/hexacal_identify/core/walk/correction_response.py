"""
How the machine answers a fixed-position correction, learned from the corrections (ROS-free).

A correction asks the model for the inclinometer change that zeroes the reading (eq. 4's
derivative, `platform_paths.fixed_position_correction`).  The machine answers with another
change: the model is millimetres off and, in ``passive_actuator``, five actuators and the link
put the platform where the passive closure says, not where it was commanded.  Seen on the
simulated machines, each correction then left 25 % (MuJoCo Hexa Slide) to 70 % (kinematic,
with the sign of one angle flipping) of the reading it corrected, and five corrections did not
reach the tolerance.

`CorrectionResponse` keeps a 2 x 2 estimate B of the reading change per change asked for
(identity at first) and updates it from each correction's outcome with Broyden's secant
update, B += (done - B asked) asked^T / |asked|^2; the next correction asks for -B^-1 r, so the
corrections converge superlinearly on a machine whose answer differs from the model's.  Not
learned: a change too small to read above the sensor's noise; one too large for the answer to
be linear (a platform landing centimetres off: learned from, the next correction was three
times the model's and would have jammed the passive system); an update that would scale the
model's correction beyond `MAX_GAIN` either way.  (The update is written here: scipy's
broyden1/broyden2 drive a function they call themselves, while each evaluation here is a move
of the machine that the walk's state machine makes between its steps.)

It also keeps the side the posture's nudged corrections approach from (`side`, arrival.nudge):
on the MuJoCo Gough-Stewart the released actuator's stiction left each small correction
about 35 urad off, on alternating sides as the approach alternated, and the readings flipped
around the 20 urad tolerance until the posture was skipped.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MIN_LEARNED_CHANGE_RAD = 1e-4  # a change this large reads well above the judged noise (~1e-6)
MAX_LEARNED_CHANGE_RAD = 0.02  # 15 mm on a 0.75 m link: eq. 4 and the machine first order
MAX_GAIN = 2.5  # B's singular values are kept within [1 / MAX_GAIN, MAX_GAIN]


@dataclass
class CorrectionResponse:
    """The machine's answer to the corrections of one fixed-position posture (module doc)."""

    gain: np.ndarray = field(default_factory=lambda: np.eye(2))
    # The side (unit vector, 3) every nudged correction approaches its target from
    # (arrival.nudge); None until the first nudge.
    side: np.ndarray | None = None
    _reading: np.ndarray | None = None  # the reading the last correction was sent for
    _asked: np.ndarray | None = None  # the change it asked for (rad)

    def ask(self, reading: np.ndarray) -> np.ndarray:
        """
        Return the reading change (2,) to ask the model for, so that the machine zeroes it.

        Learns from the previous correction first: its reading then, the change it asked for
        and `reading` now.  Call `sent` once the correction is commanded.
        """
        reading = np.asarray(reading, dtype=float)
        if self._reading is not None and self._asked is not None:
            self._learn(self._asked, reading - self._reading)
        return -np.linalg.solve(self.gain, reading)

    def sent(self, reading: np.ndarray, asked: np.ndarray) -> None:
        """Remember the correction commanded: asked for `asked` (rad) at `reading`."""
        self._reading = np.asarray(reading, dtype=float).copy()
        self._asked = np.asarray(asked, dtype=float).copy()

    def _learn(self, asked: np.ndarray, done: np.ndarray) -> None:
        size = float(asked @ asked)
        if not MIN_LEARNED_CHANGE_RAD**2 <= size <= MAX_LEARNED_CHANGE_RAD**2:
            return
        updated = self.gain + np.outer(done - self.gain @ asked, asked) / size
        singular = np.linalg.svd(updated, compute_uv=False)
        if singular[-1] >= 1.0 / MAX_GAIN and singular[0] <= MAX_GAIN:
            self.gain = updated


__all__ = [
    'CorrectionResponse', 'MAX_GAIN', 'MAX_LEARNED_CHANGE_RAD', 'MIN_LEARNED_CHANGE_RAD'
]
