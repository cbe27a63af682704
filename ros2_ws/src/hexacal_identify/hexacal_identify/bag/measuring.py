"""
The measuring procedure a bag was recorded in: its metadata record ``hexacal.measuring``.

The collector writes, from the machine driver's status ('hexacal driver' on
hexacal/calibration_status): ``measuring_mode`` (passive_actuator, lvdt or compliant; absent:
unknown) and ``released_actuators``, a JSON list of ``[stamp_ns, joint]``: from the status's
stamp on, that actuator joint was released ('' : none).  A posture's released actuator is the
one of the last change at or before its stamp, so recorded and re-detected postures read the
same.  The record is rewritten (a later record of the same name wins) whenever it changes.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field
import json
from typing import Mapping

MEASURING_METADATA = 'hexacal.measuring'
MODE_KEY = 'measuring_mode'
RELEASED_KEY = 'released_actuators'


@dataclass
class MeasuringRecord:
    """The measuring mode (None: unknown) and the released-actuator changes [(stamp ns, joint)]."""

    mode: str | None = None
    released: list[tuple[int, str]] = field(default_factory=list)

    def note(self, mode: str | None, released: str | None, stamp_ns: int) -> bool:
        """Take one driver status; return True if the record changed."""
        changed = False
        if mode and mode != self.mode:
            self.mode, changed = mode, True
        if released is not None and (not self.released or self.released[-1][1] != released):
            if self.released or released:
                self.released.append((int(stamp_ns), released))
                changed = True
        return changed

    def released_at(self, stamp_ns: int) -> str:
        """Return the actuator released at `stamp_ns` ('' : none, or not known)."""
        index = bisect_right([stamp for stamp, _ in self.released], stamp_ns)
        return self.released[index - 1][1] if index else ''

    def to_metadata(self) -> dict[str, str]:
        """Return the metadata record's mapping (strings)."""
        data = {RELEASED_KEY: json.dumps([[stamp, joint] for stamp, joint in self.released])}
        if self.mode:
            data[MODE_KEY] = self.mode
        return data

    @classmethod
    def from_metadata(cls, data: Mapping[str, str]) -> MeasuringRecord:
        """Read a record's mapping; entries that do not parse are left out (unknown)."""
        try:
            pairs = json.loads(data.get(RELEASED_KEY, '[]'))
            released = sorted((int(stamp), str(joint)) for stamp, joint in pairs)
        except (TypeError, ValueError):
            released = []
        return cls(data.get(MODE_KEY) or None, released)
