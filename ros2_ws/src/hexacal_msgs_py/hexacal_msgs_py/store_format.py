"""
The calibration store's file format: directory layout, record and event keys, states, digests.

A store is a directory (docs/formats.md, "Calibration store")::

    <store>/store.json                  {"format": "hexacal-calibration-store", "version": 1}
    <store>/entries/<id>/parameters.yaml  the calibrated parameters file, byte for byte
    <store>/entries/<id>/record.json      where it came from (RECORD_* keys)
    <store>/events/<seq>-<event>-<id>.json  state changes, numbered from 000001 (EVENT_* keys)
    <store>/active.json                 the active calibration (replaced on deploy/rollback)
    <store>/lock                        advisory lock of writers

Nothing is ever overwritten: an entry is a directory written under a temporary name
(TEMP_PREFIX) and renamed; an event is a new file.  ``active.json`` is derived from the
events (they win when the two disagree); it is replaced on every deploy and rollback so
its identity (inode, mtime) tells a reader that the active calibration changed.

ROS-free and core-free: the standard library only.
"""

from __future__ import annotations

import enum
import hashlib
from pathlib import Path
import struct
from typing import Iterable, Protocol, Sequence

STORE_FORMAT = 'hexacal-calibration-store'
STORE_FORMAT_VERSION = 1
# Environment variable that overrides the default store directory (tests, demos, CI).
STORE_ENV = 'HEXACAL_STORE'

FORMAT_FILE = 'store.json'
ENTRIES_DIR = 'entries'
EVENTS_DIR = 'events'
ACTIVE_FILE = 'active.json'
LOCK_FILE = 'lock'
# Anything whose name starts with this is a write in progress (or left by a crash): readers
# ignore it, writers remove it under the lock.
TEMP_PREFIX = '.tmp-'
PARAMETERS_FILE = 'parameters.yaml'
RECORD_FILE = 'record.json'
EVENT_SEQUENCE_DIGITS = 6


class StoreState(enum.StrEnum):
    """
    State of a store entry, derived from the events.

    STORED: no passing verification; VERIFIED: a verification with verdict pass is attached;
    ACTIVE: the active calibration, deployed verified; FORCED: the active calibration,
    deployed with force; ROLLED_BACK: was active and was left by a rollback.
    """

    STORED = 'stored'
    VERIFIED = 'verified'
    ACTIVE = 'active'
    FORCED = 'forced'
    ROLLED_BACK = 'rolled-back'


class EventType(enum.StrEnum):
    """Kind of a store event (its file name and EVENT_TYPE)."""

    VERIFIED = 'verified'
    DEPLOYED = 'deployed'
    ROLLED_BACK = 'rolled-back'


class ActivationReason(enum.StrEnum):
    """Why the active calibration is active (status topic, report)."""

    VERIFIED = 'verified'
    FORCED = 'forced'
    ROLLED_BACK = 'rolled-back'


VERDICT_PASS, VERDICT_FAIL = 'pass', 'fail'

# record.json keys (SI units; absent when not known).
RECORD_FORMAT = 'format'  # STORE_FORMAT_VERSION
RECORD_ID = 'id'
RECORD_TIME = 'time'  # ISO 8601 UTC, when the entry was added
RECORD_NUMBER = 'number'  # 1, 2, ...: the order entries were added in
RECORD_DIGEST = 'digest'  # sha256 of parameters.yaml
RECORD_VECTOR_DIGEST = 'vector_digest'  # vector_digest() of its parameter vector
RECORD_MODEL = 'model'  # the machine model the parameters are of
RECORD_SOURCE = 'source'  # what made it: 'hexacal calibrate', 'identify node', ...
RECORD_POSTURES_DIGEST = 'postures_digest'  # postures_digest() of the postures fitted
RECORD_POSTURES_COUNT = 'postures'  # number of postures given to the fit
RECORD_BAG = 'bag'  # the bag's path and file digest, when fitted from a bag
RECORD_NOMINAL_DIGEST = 'nominal_digest'  # sha256 of the nominal parameters file
RECORD_NOMINAL_FILE = 'nominal_file'
RECORD_COST = 'cost'  # cost function
RECORD_NOISE = 'noise'  # noise model ({'actuator_m': .., 'angle_rad': ..} or None)
RECORD_ROBUST_LOSS = 'robust_loss'
RECORD_LINK_LENGTH = 'link_length_m'
RECORD_MOUNT = 'mount'
RECORD_DEVICE_DEFECTS = 'device_defects'  # identified (name -> value, SI) and the free names
RECORD_DEVICE_PRIOR = 'device_prior'
RECORD_VERSION = 'hexacal_version'
RECORD_FIT = 'fit'  # the fit's figures: FIT_* keys
# Derived when an entry is read (never written in record.json): the latest verification's
# figures (the `hexacal verify --json` object plus VERIFICATION_POSTURES_DIGEST).
RECORD_VERIFICATION = 'verification'

FIT_REASON = 'reason'
FIT_RANK = 'rank'
FIT_PARAMETERS = 'parameters'  # number of parameters (full rank)
FIT_CONDITION = 'condition_number'
FIT_COST = 'cost'
FIT_ITERATIONS = 'iterations'
FIT_RMS_RESIDUAL = 'rms_residual'
FIT_POSTURES_USED = 'postures_used'
FIT_POSTURES_REJECTED = 'postures_rejected'
FIT_ADEQUACY = 'adequacy'

# Event file keys.
EVENT_SEQUENCE = 'seq'
EVENT_TIME = 'time'
EVENT_TYPE = 'event'  # an EventType value
EVENT_ID = 'id'  # the entry verified / deployed / restored
EVENT_VERDICT = 'verdict'  # verified: 'pass' / 'fail'
EVENT_FIGURES = 'figures'  # verified: the verification figures
EVENT_FORCED = 'forced'  # deployed: bool
EVENT_REFUSALS = 'refusals'  # deployed with force: what would have refused it
EVENT_CHECKS = 'checks'  # deployed: the plausibility figures against the previous active one
EVENT_PREVIOUS = 'previous'  # deployed / rolled-back: the id active before
# In the verification figures: postures_digest() of the postures verified on.
VERIFICATION_POSTURES_DIGEST = 'postures_digest'
VERIFICATION_VERDICT = 'verdict'
# In the verification figures: sha256 of the parameters file verified (must be the entry's).
VERIFICATION_CALIBRATED_DIGEST = 'calibrated_digest'

# active.json keys.
ACTIVE_ID = 'id'
ACTIVE_SINCE = 'since'
ACTIVE_REASON = 'reason'  # an ActivationReason value
ACTIVE_EVENT = 'event'  # sequence number of the event that made it active
ACTIVE_DIGEST = 'digest'

_DIGEST_CHUNK = 1 << 20


def file_digest(path: Path | str) -> str:
    """Return the sha256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, 'rb') as stream:
        for chunk in iter(lambda: stream.read(_DIGEST_CHUNK), b''):
            digest.update(chunk)
    return digest.hexdigest()


def bytes_digest(data: bytes) -> str:
    """Return the sha256 (hex) of bytes (a parameters message's file text, ...)."""
    return hashlib.sha256(data).hexdigest()


class _Posture(Protocol):
    # Read-only (properties): a frozen PostureReading is one.
    @property
    def actuator_positions(self) -> Sequence[float]:
        ...

    @property
    def alpha(self) -> float:
        ...

    @property
    def beta(self) -> float:
        ...

    @property
    def phi(self) -> float:
        ...


def postures_digest(postures: Iterable[_Posture]) -> str:
    """
    Return the sha256 (hex) of postures: what they measured, not where they were read from.

    Over each posture's actuator positions, alpha, beta, phi and device turn as little-endian
    float64, in order; the same postures give the same digest from a bag (``hexacal calibrate``)
    or from the posture topic (identify node).
    """
    digest = hashlib.sha256(b'hexacal-postures-v1')
    for posture in postures:
        values = [
            *posture.actuator_positions,
            posture.alpha,
            posture.beta,
            posture.phi,
            getattr(posture, 'device_turn', 0.0),
        ]
        digest.update(struct.pack(f'<I{len(values)}d', len(values), *map(float, values)))
    return digest.hexdigest()


# A calibrated parameters file says in its header comment which postures it was fitted to
# ('# fitted postures: <postures_digest>'), so that a verification on them is told apart
# without a store.
FITTED_POSTURES_COMMENT = 'fitted postures: '


def fitted_postures_digest(path: Path | str) -> str | None:
    """Return the postures_digest a parameters file's header names, or None (none, unreadable)."""
    try:
        with open(path, encoding='utf-8') as stream:
            for line in stream:
                if not line.startswith('#'):
                    return None
                text = line[1:].strip()
                if text.startswith(FITTED_POSTURES_COMMENT):
                    return text[len(FITTED_POSTURES_COMMENT):].strip() or None
    except (OSError, UnicodeDecodeError):
        return None
    return None


def vector_digest(model: str, values: Iterable[float]) -> str:
    """
    Return the sha256 (hex) of a parameter vector: the model name and little-endian float64s.

    What a parameters message (a vector, not a file) is matched to store entries by.
    """
    numbers = [float(v) for v in values]
    digest = hashlib.sha256(b'hexacal-vector-v1\0' + model.encode('utf-8') + b'\0')
    digest.update(struct.pack(f'<{len(numbers)}d', *numbers))
    return digest.hexdigest()


def event_file_name(sequence: int, event: EventType | str, entry_id: str) -> str:
    """Return the file name of event number `sequence` (sorts by number)."""
    return f'{sequence:0{EVENT_SEQUENCE_DIGITS}d}-{EventType(event)}-{entry_id}.json'


def event_sequence(name: str) -> int | None:
    """Return the sequence number of an event file name, None for anything else."""
    head = name.split('-', 1)[0]
    if not name.endswith('.json') or not head.isdigit() or name.startswith(TEMP_PREFIX):
        return None
    return int(head)
