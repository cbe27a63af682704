"""
The device turns inclinometer messages carried, looked up for a posture's stamp.

The device turn is the device's rotation about its link axis from its normal mounting
(rad: 0 normal, pi reversed, pi/2 a quarter turn). An inclinometer message may carry it
as its `device_turn` joint (a simulated or instrumented device); when none has, the
operator's setting (the collector's `device_turn` parameter) applies.
"""

from __future__ import annotations

import bisect

from hexacal_msgs_py.names import MAX_DEVICE_TURN

# Changes kept for looking up a posture's turn: postures are captured in stamp order and
# each lookup forgets older changes, so this only bounds a run without postures.
MAX_TURN_CHANGES = 1000


def turn_problem(value: object) -> str | None:
    """Return why `value` is not a device turn (a finite angle within +-2 pi rad), or None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'device_turn must be a number (rad), got {value!r}'
    if not abs(float(value)) <= MAX_DEVICE_TURN:
        return f'device_turn must be a finite angle within +-2 pi rad, got {value!r}'
    return None


class TurnHistory:
    """
    Keep the changes of the device turn carried by inclinometer messages, in stamp order.

    `note` takes every inclinometer message's turn (None: the message carries none);
    `turn_at` answers the turn of a posture from the message paired with its last sample.
    """

    def __init__(self, max_changes: int = MAX_TURN_CHANGES) -> None:
        # (inclinometer stamp, turn carried from then on, None: not carried), in stamp order.
        self._changes: list[tuple[int, float | None]] = []
        self._max_changes = max_changes

    @property
    def changes(self) -> tuple[tuple[int, float | None], ...]:
        """Return the kept (stamp_ns, turn or None) pairs, oldest first."""
        return tuple(self._changes)

    def note(self, stamp_ns: int, turn: float | None) -> None:
        """Note the device turn an inclinometer message stamped `stamp_ns` carries (None: none)."""
        changes = self._changes
        if changes:
            if changes[-1][1] == turn:
                return
        elif turn is None:
            return  # nothing carried yet: the operator's setting applies
        changes.append((stamp_ns, turn))
        if len(changes) > self._max_changes:
            del changes[: len(changes) - self._max_changes]

    def turn_at(self, stamp_ns: int, max_skew_ns: int, default: float) -> float:
        """
        Return the device turn of a posture whose last sample is stamped `stamp_ns`.

        The turn the inclinometer messages carried up to the paired inclinometer stamp (at
        most `max_skew_ns` later), else `default` (the operator's setting). Forgets the
        changes before that one: later postures are later.
        """
        changes = self._changes
        at = bisect.bisect_right(changes, stamp_ns + max_skew_ns, key=lambda change: change[0])
        turn = changes[at - 1][1] if at else None
        if at > 1:
            del changes[: at - 1]
        return default if turn is None else turn
