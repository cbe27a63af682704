"""What the store hands out: entries, the activation, and its errors."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hexacal_msgs_py.store_format import ActivationReason, StoreState


class StoreError(Exception):
    """A bad store, or an unknown or ambiguous id; the message names it."""


@dataclass(frozen=True)
class Refusal:
    """One reason a deploy is refused: a short slug and a sentence with the figures."""

    reason: str
    detail: str


class DeployRefused(StoreError):
    """
    A deploy refused by a check; ``reason`` is the first check's slug.

    ``refusals`` lists every check that refused; the message says why and that
    ``--force`` (``force=True``) deploys anyway, recorded as forced.
    """

    def __init__(self, entry_id: str, refusals: tuple[Refusal, ...]) -> None:
        self.entry_id = entry_id
        self.refusals = refusals
        self.reason = refusals[0].reason if refusals else 'refused'
        super().__init__(
            f'refused to deploy {entry_id[:8]}: '
            + '; '.join(f'{r.detail} ({r.reason})' for r in refusals)
            + '; --force deploys it anyway (recorded as forced)'
        )


@dataclass(frozen=True)
class StoreEntry:
    """
    One calibration of a store.

    ``record`` is record.json with, once verified, the latest verification's figures under
    ``verification``; ``digest`` is the sha256 of the parameters file's bytes.
    """

    id: str  # noqa: A003 (the shared API's name)
    time: str
    state: StoreState
    verdict: str | None
    parameters_path: Path
    record: dict[str, Any] = field(compare=False)
    digest: str

    @property
    def short_id(self) -> str:
        """Return the first 8 characters of the id (unique in any store of fewer entries)."""
        return self.id[:8]

    @property
    def active(self) -> bool:
        """Return whether this entry is the active calibration."""
        return self.state in (StoreState.ACTIVE, StoreState.FORCED)


@dataclass(frozen=True)
class Activation:
    """The active calibration, since when (ISO 8601 UTC) and why."""

    entry: StoreEntry
    since: str
    reason: ActivationReason
    event: int  # sequence number of the event that made it active
