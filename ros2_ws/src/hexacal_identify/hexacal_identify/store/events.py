"""The store's events replayed: the states of its entries and the active calibration."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hexacal_msgs_py import store_format as fmt
from hexacal_msgs_py.store_format import ActivationReason, EventType

from .store_entry import StoreError


@dataclass
class Activated:
    """An entry on the activation stack: since when and why it is (or was) active."""

    id: str  # noqa: A003 (the entry id, as StoreEntry.id)
    forced: bool
    since: str
    reason: ActivationReason
    event: int


@dataclass
class History:
    """What the events say, replayed in order."""

    last_sequence: int = 0
    verifications: dict[str, dict[str, Any]] = field(default_factory=dict)
    stack: list[Activated] = field(default_factory=list)
    rolled_back: set[str] = field(default_factory=set)

    @property
    def active(self) -> Activated | None:
        return self.stack[-1] if self.stack else None


def replay(events: list[tuple[int, Path, Any]], known: dict[str, Any]) -> History:
    """
    Return what the events say: verifications, the activation stack, the rolled-back ids.

    A deploy pushes its entry on the stack, a rollback pops the top; the top is active.
    StoreError names an event that names no entry in `known` or that no deploy explains.
    """
    history = History()
    for sequence, path, event in events:
        entry_id = event.get(fmt.EVENT_ID) if isinstance(event, dict) else None
        if entry_id not in known:
            raise StoreError(f'{path}: names no entry of the store ({entry_id!r})')
        history.last_sequence = sequence
        kind = event.get(fmt.EVENT_TYPE)
        time = event.get(fmt.EVENT_TIME, '')
        if kind == EventType.VERIFIED:
            history.verifications[entry_id] = event.get(fmt.EVENT_FIGURES) or {}
        elif kind == EventType.DEPLOYED:
            forced = bool(event.get(fmt.EVENT_FORCED))
            reason = ActivationReason.FORCED if forced else ActivationReason.VERIFIED
            history.stack.append(Activated(entry_id, forced, time, reason, sequence))
            history.rolled_back.discard(entry_id)
        elif kind == EventType.ROLLED_BACK:
            if len(history.stack) < 2 or history.stack[-2].id != entry_id:
                raise StoreError(f'{path}: a rollback to {entry_id} that no deploy explains')
            history.rolled_back.add(history.stack.pop().id)
            restored = history.stack[-1]
            restored.since, restored.event = time, sequence
            restored.reason = ActivationReason.ROLLED_BACK
        else:
            raise StoreError(f'{path}: unknown event {kind!r}')
    return history
