"""
The calibration store: entries with provenance, verification, deploy and rollback.

The layout and keys are the contract's (hexacal_msgs_py.store_format, docs/formats.md).
States are derived by replaying the event files in order: a deploy pushes an entry on the
activation stack, a rollback pops it; the top is the active calibration.
"""

from __future__ import annotations

from datetime import datetime, timezone
import hashlib
import math
from pathlib import Path
import secrets
from typing import Any

from hexacal_msgs_py import store_format as fmt
from hexacal_msgs_py.store_format import EventType, StoreState

from . import store_writes
from .checks import on_other_postures, plausibility_refusals, verification_refusals
from .events import History, replay
from .plausibility import (
    DEFAULT_MAX_PARAMETER_CHANGE_M,
    DEFAULT_MAX_POSE_CHANGE_M,
    DEFAULT_MAX_ROTATION_CHANGE_RAD,
)
from .store_entry import Activation, DeployRefused, StoreEntry, StoreError

ID_HEX_DIGITS = 12
MIN_PREFIX = 4


def utc_now() -> str:
    """Return the time now as ISO 8601 UTC with microseconds ('2026-11-24T01:02:03.456789Z')."""
    return datetime.now(timezone.utc).strftime('%Y-%m-%dT%H:%M:%S.%fZ')


def json_safe(value: Any) -> Any:
    """Return plain JSON values (numpy values as Python's; NaN and inf as null)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if hasattr(value, 'tolist'):  # numpy arrays and scalars, without importing numpy
        return json_safe(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value


class CalibrationStore:
    """A calibration store directory (created by the first write)."""

    def __init__(self, root: Path | str) -> None:
        self.root = Path(root)
        self.entries_dir = self.root / fmt.ENTRIES_DIR
        self.events_dir = self.root / fmt.EVENTS_DIR

    def __repr__(self) -> str:
        return f'CalibrationStore({str(self.root)!r})'

    # ----- reading -----------------------------------------------------------------------
    def _check_root(self) -> bool:
        """Return whether the store exists; StoreError if `root` is something else."""
        if not self.root.exists():
            return False
        if not self.root.is_dir():
            raise StoreError(f'calibration store {self.root} is not a directory')
        marker = self.root / fmt.FORMAT_FILE
        # The header is made before anything else: a name listed without it means no store,
        # unless the header appeared during the listing (looked for again after it).
        names = {path.name for path in self.root.iterdir()}
        if fmt.FORMAT_FILE not in names and not marker.exists():
            if any(not name.startswith('.') for name in names):
                raise StoreError(
                    f'{self.root} is not a calibration store (no {fmt.FORMAT_FILE}); name an '
                    'empty or new directory'
                )
            return False
        header = store_writes.read_json(marker)
        if not isinstance(header, dict) or header.get('format') != fmt.STORE_FORMAT:
            raise StoreError(f'{marker}: not a {fmt.STORE_FORMAT} header')
        if header.get('version') != fmt.STORE_FORMAT_VERSION:
            raise StoreError(
                f'{marker}: store format version {header.get("version")!r}; this hexacal reads '
                f'version {fmt.STORE_FORMAT_VERSION}'
            )
        return True

    def _records(self) -> dict[str, dict[str, Any]]:
        """Return id -> record of every whole entry (temporary names ignored)."""
        if not self._check_root() or not self.entries_dir.is_dir():
            return {}
        records = {}
        for directory in self.entries_dir.iterdir():
            if directory.name.startswith(fmt.TEMP_PREFIX):
                continue
            record = store_writes.read_json(directory / fmt.RECORD_FILE)
            if not isinstance(record, dict) or record.get(fmt.RECORD_ID) != directory.name:
                raise StoreError(f'{directory}: its {fmt.RECORD_FILE} is not its entry record')
            parameters = directory / fmt.PARAMETERS_FILE
            try:
                digest = fmt.file_digest(parameters)
            except OSError as error:
                raise StoreError(f'{parameters}: unreadable ({error})') from None
            if digest != record.get(fmt.RECORD_DIGEST):
                # Edited in place: what was verified is not what would be deployed.
                raise StoreError(
                    f'{parameters} was modified after it was stored (sha256 {digest[:12]}, '
                    f'recorded {str(record.get(fmt.RECORD_DIGEST))[:12]})'
                )
            records[directory.name] = record
        return records

    def _events(self) -> list[tuple[int, Path, Any]]:
        """Return (number, path, contents) of every event, in order."""
        if not self._check_root() or not self.events_dir.is_dir():
            return []
        numbered = sorted(
            (sequence, path)
            for path in self.events_dir.iterdir()
            if (sequence := fmt.event_sequence(path.name)) is not None
        )
        return [(sequence, path, store_writes.read_json(path)) for sequence, path in numbered]

    def _entry(self, record: dict[str, Any], history: History) -> StoreEntry:
        entry_id = record[fmt.RECORD_ID]
        directory = self.entries_dir / entry_id
        verification = history.verifications.get(entry_id)
        verdict = verification.get(fmt.VERIFICATION_VERDICT) if verification else None
        active = history.active
        if active is not None and active.id == entry_id:
            state = StoreState.FORCED if active.forced else StoreState.ACTIVE
        elif entry_id in history.rolled_back:
            state = StoreState.ROLLED_BACK
        elif verdict == fmt.VERDICT_PASS and on_other_postures(record, verification):
            state = StoreState.VERIFIED
        else:
            state = StoreState.STORED
        full = dict(record)
        if verification is not None:
            full[fmt.RECORD_VERIFICATION] = verification
        return StoreEntry(
            id=entry_id,
            time=record.get(fmt.RECORD_TIME, ''),
            state=state,
            verdict=verdict,
            parameters_path=directory / fmt.PARAMETERS_FILE,
            record=full,
            digest=record.get(fmt.RECORD_DIGEST, ''),
        )

    def _read(self) -> tuple[list[StoreEntry], History]:
        # Events first: an event's entry was renamed into place before the event was written,
        # so it is among the records listed after, even while a writer works.
        events = self._events()
        records = self._records()
        history = replay(events, records)
        ordered = sorted(
            records.values(),
            key=lambda r: (
                r.get(fmt.RECORD_NUMBER, 0),
                r.get(fmt.RECORD_TIME, ''),
                r[fmt.RECORD_ID],
            ),
        )
        return [self._entry(record, history) for record in ordered], history

    def entries(self) -> list[StoreEntry]:
        """Return every entry, oldest first."""
        return self._read()[0]

    def get(self, id_or_prefix: str) -> StoreEntry:
        """Return the entry of an id or a unique prefix of one (at least 4 characters)."""
        return self._find(self._read()[0], id_or_prefix)

    def _find(self, entries: list[StoreEntry], id_or_prefix: str) -> StoreEntry:
        key = id_or_prefix.strip().lower()
        if len(key) < MIN_PREFIX:
            raise StoreError(f'id {id_or_prefix!r} is too short: give at least {MIN_PREFIX} hex')
        matches = [e for e in entries if e.id.startswith(key)]
        if not matches:
            raise StoreError(f'no entry {id_or_prefix!r} in calibration store {self.root}')
        if len(matches) > 1:
            raise StoreError(
                f'id {id_or_prefix!r} is ambiguous in {self.root}: '
                + ', '.join(e.id for e in matches)
            )
        return matches[0]

    def find_digest(self, digest: str) -> StoreEntry | None:
        """
        Return the entry whose parameters have this digest: the active one, else the newest.

        The sha256 of the parameters file, or the ``vector_digest`` of its parameter vector
        (what a parameters message is matched by).
        """
        matches = [
            e
            for e in self.entries()
            if digest in (e.digest, e.record.get(fmt.RECORD_VECTOR_DIGEST))
        ]
        if not matches:
            return None
        active = [e for e in matches if e.active]
        return active[0] if active else matches[-1]

    def active(self) -> StoreEntry | None:
        """Return the active calibration, None before the first deploy."""
        activation = self.activation()
        return None if activation is None else activation.entry

    def activation(self) -> Activation | None:
        """Return the active calibration with since when and why, None before the first deploy."""
        entries, history = self._read()
        top = history.active
        if top is None:
            return None
        entry = next(e for e in entries if e.id == top.id)
        return Activation(entry, top.since, top.reason, top.event)

    def active_marker(self) -> Path:
        """
        Return the file replaced on every deploy and rollback (watch its inode and mtime).

        It holds the active id, since when and why (fmt.ACTIVE_* keys); it does not exist
        before the first deploy.  The events are the truth: active() reads them.
        """
        return self.root / fmt.ACTIVE_FILE

    # ----- writing -----------------------------------------------------------------------
    def _prepare(self) -> None:
        """Create the store if new: its header first, so no reader sees a store without one."""
        if not self._check_root():
            self.root.mkdir(parents=True, exist_ok=True)
            header = {'format': fmt.STORE_FORMAT, 'version': fmt.STORE_FORMAT_VERSION}
            store_writes.write_new_file(  # False: another writer made it just now, the same header
                self.root / fmt.FORMAT_FILE, store_writes.json_text(header).encode('utf-8')
            )
        self.entries_dir.mkdir(exist_ok=True)
        self.events_dir.mkdir(exist_ok=True)

    def _writing(self):
        self._prepare()
        return store_writes.writer_lock(self.root)

    def _clean(self) -> None:
        store_writes.remove_leftovers(self.root, self.entries_dir, self.events_dir)

    def add(self, parameters_file: Path | str, record: dict[str, Any]) -> StoreEntry:
        """
        Copy a parameters file into a new entry with its provenance record; atomic.

        The store sets the record's id, time, digest and format (and model and hexacal
        version when not given).  StoreError if the file is not a parameters file.
        """
        from hexacal_msgs_py.errors import ParameterFileError
        from hexacal_msgs_py.parameters_file import read_parameters_file

        path = Path(parameters_file)
        try:
            data = path.read_bytes()
            contents = read_parameters_file(path)
        except OSError as error:
            raise StoreError(f'cannot read parameters file {path}: {error}') from None
        except ParameterFileError as error:
            raise StoreError(f'not stored: {error}') from None
        digest = fmt.bytes_digest(data)
        with self._writing():
            self._clean()
            number = len(self._records()) + 1
            time = utc_now()
            entry_id = hashlib.sha256(
                f'{digest} {time} {secrets.token_hex(8)}'.encode()
            ).hexdigest()[:ID_HEX_DIGITS]
            full = json_safe(dict(record))
            full.setdefault(fmt.RECORD_MODEL, contents.model)
            full.setdefault(fmt.RECORD_VERSION, hexacal_version())
            full.update(
                {
                    fmt.RECORD_FORMAT: fmt.STORE_FORMAT_VERSION,
                    fmt.RECORD_ID: entry_id,
                    fmt.RECORD_TIME: time,
                    fmt.RECORD_DIGEST: digest,
                    fmt.RECORD_VECTOR_DIGEST: fmt.vector_digest(
                        contents.model, contents.vector.tolist()
                    ),
                    fmt.RECORD_NUMBER: number,
                }
            )
            store_writes.write_directory(
                self.entries_dir / entry_id,
                {
                    fmt.PARAMETERS_FILE: data,
                    fmt.RECORD_FILE: store_writes.json_text(full).encode('utf-8'),
                },
            )
            entries, history = self._read()
            self._update_marker(entries, history)
            return self._find(entries, entry_id)

    def _append(self, history: History, kind: EventType, entry_id: str, **fields: Any) -> int:
        """Write the next event file; return its sequence number."""
        sequence = history.last_sequence + 1
        while True:
            payload = {
                fmt.EVENT_SEQUENCE: sequence,
                fmt.EVENT_TIME: utc_now(),
                fmt.EVENT_TYPE: str(kind),
                fmt.EVENT_ID: entry_id,
                **json_safe(fields),
            }
            name = fmt.event_file_name(sequence, kind, entry_id)
            if store_writes.write_new_file(
                self.events_dir / name, store_writes.json_text(payload).encode('utf-8')
            ):
                return sequence
            sequence += 1  # taken by a writer that ignored the lock: never overwrite

    def attach_verification(
        self,
        id: str,  # noqa: A002 (the shared API's name)
        figures: dict[str, Any],
        postures_digest: str | None = None,
    ) -> StoreEntry:
        """
        Attach a verification's figures (``hexacal verify --json``) to an entry.

        The figures must hold ``verdict`` ('pass'/'fail'); ``postures_digest`` (here or in the
        figures) is the digest of the postures verified on, which deploy compares with the
        fit's.  A ``calibrated_digest`` in the figures must be the entry's.
        """
        figures = json_safe(dict(figures))
        if postures_digest is not None:
            figures[fmt.VERIFICATION_POSTURES_DIGEST] = postures_digest
        verdict = figures.get(fmt.VERIFICATION_VERDICT)
        if verdict not in (fmt.VERDICT_PASS, fmt.VERDICT_FAIL):
            raise StoreError(
                f"verification figures need a verdict 'pass' or 'fail', got {verdict!r}"
            )
        with self._writing():
            self._clean()
            entries, history = self._read()
            entry = self._find(entries, id)
            calibrated = figures.get(fmt.VERIFICATION_CALIBRATED_DIGEST)
            if calibrated is not None and calibrated != entry.digest:
                raise StoreError(
                    f'the verification is of another parameters file (sha256 {calibrated[:12]}) '
                    f'than entry {entry.short_id} (sha256 {entry.digest[:12]})'
                )
            self._append(history, EventType.VERIFIED, entry.id, verdict=verdict, figures=figures)
            entries, history = self._read()
            self._update_marker(entries, history)
            return self._find(entries, entry.id)

    def deploy(
        self,
        id: str,  # noqa: A002 (the shared API's name)
        force: bool = False,
        max_parameter_change_m: float = DEFAULT_MAX_PARAMETER_CHANGE_M,
        max_pose_change_m: float = DEFAULT_MAX_POSE_CHANGE_M,
        *,
        max_rotation_change_rad: float = DEFAULT_MAX_ROTATION_CHANGE_RAD,
    ) -> StoreEntry:
        """
        Make an entry the active calibration.

        Refused (DeployRefused) unless its latest verification passed on postures other than
        the fit's and it is within the thresholds of the active calibration (largest length
        parameter change, largest platform position and rotation change over the default
        workspace), or
        with force=True: then recorded as forced (state FORCED) with what would have refused it.
        Deploying the active entry again changes nothing.
        """
        with self._writing():
            self._clean()
            entries, history = self._read()
            entry = self._find(entries, id)
            active = history.active
            if active is not None and active.id == entry.id:
                self._update_marker(entries, history)
                return entry
            refusals = list(verification_refusals(entry))
            checks = None
            if active is not None:
                previous = self._find(entries, active.id)
                found, checks = plausibility_refusals(
                    previous,
                    entry,
                    max_parameter_change_m,
                    max_pose_change_m,
                    max_rotation_change_rad,
                )
                refusals.extend(found)
            if refusals and not force:
                raise DeployRefused(entry.id, tuple(refusals))
            self._append(
                history,
                EventType.DEPLOYED,
                entry.id,
                forced=bool(refusals),
                refusals=[{'reason': r.reason, 'detail': r.detail} for r in refusals],
                checks=checks,
                previous=None if active is None else active.id,
            )
            entries, history = self._read()
            self._update_marker(entries, history)
            return self._find(entries, entry.id)

    def rollback(self) -> StoreEntry:
        """Return to the calibration active before the current one (StoreError if none)."""
        with self._writing():
            self._clean()
            entries, history = self._read()
            if len(history.stack) < 2:
                raise StoreError(
                    f'nothing to roll back to in {self.root}: '
                    + (
                        'no calibration was deployed'
                        if not history.stack
                        else f'{history.stack[-1].id[:8]} is the first deployed calibration'
                    )
                )
            left, restored = history.stack[-1], history.stack[-2]
            self._append(history, EventType.ROLLED_BACK, restored.id, previous=left.id)
            entries, history = self._read()
            self._update_marker(entries, history)
            return self._find(entries, restored.id)

    def _update_marker(self, entries: list[StoreEntry], history: History) -> None:
        """Replace active.json when it does not say what the events say (e.g. after a crash)."""
        top = history.active
        if top is None:
            return
        entry = next(e for e in entries if e.id == top.id)
        payload = {
            fmt.ACTIVE_ID: top.id,
            fmt.ACTIVE_SINCE: top.since,
            fmt.ACTIVE_REASON: str(top.reason),
            fmt.ACTIVE_EVENT: top.event,
            fmt.ACTIVE_DIGEST: entry.digest,
        }
        marker = self.active_marker()
        try:
            if store_writes.read_json(marker) == payload:
                return
        except (StoreError, FileNotFoundError):
            pass
        store_writes.replace_file(marker, store_writes.json_text(payload).encode('utf-8'))


def hexacal_version() -> str:
    """Return the installed hexacal_identify version ('unknown' outside an install)."""
    from importlib import metadata

    try:
        return metadata.version('hexacal_identify')
    except metadata.PackageNotFoundError:
        return 'unknown'
