"""
Which calibration is deployed, without ROS: the nodes' side of the calibration store.

The store (hexacal_identify.store) keeps every calibration and derives the active one from
its log of deploys and rollbacks. Both nodes read it through an ActiveWatch, which reads the
store again only when the store's active marker changes identity (one stat per look, no
busy loop). The identify node adds its calibrations, attaches its verifications and deploys
or rolls back on request (History); the kinematics node follows the deploys (DeployFollower):
the store's active entry at start and after every change of the marker, and a parameters
message only when its vector_digest (model name and float64 vector) is the active
calibration's. A parameters file keeps every bit of its floats, so the digest of a store
entry's file and that of the message publishing it are the same; any other vector differs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hexacal_msgs_py.errors import ParameterFileError
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.parameters_file import read_parameters_file
from hexacal_msgs_py.store_format import vector_digest
import numpy as np

from .nominal import file_identity, FileIdentity
from ..store import (
    ActivationReason,
    CalibrationStore,
    default_store_dir,
    StoreEntry,
    StoreError,
)

# The status keys that say which calibration is active, since when and why ('' = none).
ACTIVE_KEYS = ('active_calibration', 'active_since', 'active_reason')
NO_ACTIVE: dict[str, object] = {key: '' for key in ACTIVE_KEYS}


def followed_model(named: str, file_model: str | None) -> str | None:
    """
    Return the machine model whose store the kinematics node follows (None: not known).

    `named` is the node's `model` parameter ('' = none), `file_model` the model of its
    parameters file (None without one); they must agree (ValueError naming both).
    """
    if named and named not in MODELS:
        raise ValueError(f"model must be '' or one of {', '.join(MODELS)}, got {named!r}")
    if named and file_model is not None and named != file_model:
        raise ValueError(
            f'model is {named} but the parameters file is a {file_model} model; give one '
            'machine model'
        )
    return named or file_model


def store_dir(configured: str, model: str) -> Path:
    """Return the store a node uses: `configured`, else the machine model's default store."""
    if configured:
        return Path(configured).expanduser().resolve()
    return default_store_dir(model)


@dataclass(frozen=True)
class Active:
    """The active calibration of a store: its entry, since when and why."""

    entry: StoreEntry
    since: str  # ISO 8601 UTC of the deploy or rollback that made it active
    reason: ActivationReason  # verified, forced, rolled-back

    def values(self) -> dict[str, object]:
        """Return the status values: active_calibration, active_since, active_reason."""
        return {
            'active_calibration': self.entry.id,
            'active_since': self.since,
            'active_reason': str(self.reason),
        }

    def describe(self) -> str:
        """Return 'calibration <id> (<reason> since <time>)'."""
        return f'calibration {self.entry.id} ({self.reason} since {self.since})'


def active_of(store: CalibrationStore) -> Active | None:
    """Return the active calibration of `store` (None: none deployed). StoreError propagates."""
    activation = store.activation()
    if activation is None:
        return None
    return Active(activation.entry, activation.since, activation.reason)


class ActiveWatch:
    """The active calibration of one store, read again only when its marker changes identity."""

    def __init__(self, root: Path) -> None:
        """Watch the store at `root` (it need not exist yet)."""
        self.root = root
        self.store = CalibrationStore(root)
        self._identity: FileIdentity | None | bool = False  # False: never looked
        self.active: Active | None = None
        self.error = ''  # why the store cannot be read ('' = it can)

    def look(self) -> bool:
        """Return whether the active calibration may have changed since the last look."""
        identity = file_identity(self.store.active_marker())
        if identity == self._identity:
            return False
        self._identity = identity
        try:
            self.active, self.error = active_of(self.store), ''
        except (StoreError, OSError) as error:
            self.active, self.error = None, str(error)
        return True

    def values(self) -> dict[str, object]:
        """Return the status values of the active calibration, looked at now."""
        self.look()
        return self.active.values() if self.active is not None else dict(NO_ACTIVE)


@dataclass(frozen=True)
class Deployed:
    """An active calibration as the kinematics node takes it: its file read and its digest."""

    active: Active
    model: str
    vector: np.ndarray
    digest: str

    @property
    def path(self) -> Path:
        """Return the entry's parameters file."""
        return self.active.entry.parameters_path


class DeployFollower:
    """
    The kinematics node's deploys: the active calibration of its store, and nothing else.

    `poll()` (on a timer) returns the newly active calibration after a deploy or rollback;
    `deployed_match(model, vector)` says whether a parameters message is the active one.
    """

    def __init__(self, watch: ActiveWatch, candidates: Sequence[ActiveWatch] = ()) -> None:
        """
        Follow the store `watch` looks at.

        `candidates` (the default stores of every model, for a node told no model): until
        one of them has an active calibration, each is looked at on every poll, and the first
        with one is followed from then on (`watch` is the one named meanwhile).
        """
        self.watch = watch
        self.candidates = tuple(candidates)
        self.deployed: Deployed | None = None
        self.problem = ''  # why the active entry cannot be taken ('' = none)

    @classmethod
    def start(cls, configured: str, model: str | None) -> DeployFollower:
        """
        Return the follower of the store `configured`, else of the machine model's default store.

        Without a model (no parameters file, no `model` parameter) the default stores of every
        model are looked at, in the models' order, and the first with an active calibration is
        followed - at start or at its first deploy - so a deploy reaches the node whichever
        machine it runs.
        """
        if configured or model is not None:
            follower = cls(ActiveWatch(store_dir(configured, model or next(iter(MODELS)))))
        else:
            watches = [ActiveWatch(default_store_dir(name)) for name in MODELS]
            follower = cls(watches[0], watches)
        follower.poll()
        return follower

    @property
    def root(self) -> Path:
        """Return the store followed (the first model's default while none is chosen)."""
        return self.watch.root

    @property
    def where(self) -> str:
        """Return the store followed, or the default stores looked at while none is chosen."""
        if not self.candidates:
            return str(self.watch.root)
        return ' or '.join(str(watch.root) for watch in self.candidates)

    def _choose(self) -> None:
        """Follow the first candidate store with an active calibration (once one has it)."""
        for watch in self.candidates:
            watch.look()
            if watch.active is not None:
                self.watch, self.candidates = watch, ()
                return

    def values(self) -> dict[str, object]:
        """Return the status values of the calibration taken from the store."""
        if self.deployed is None:
            return dict(NO_ACTIVE)
        return self.deployed.active.values()

    def poll(self) -> Deployed | None:
        """Return the active calibration when it changed since the last poll, else None."""
        if self.candidates:
            self._choose()
        self.watch.look()  # one stat; the store is read again only when the marker changed
        active = self.watch.active
        if active is None:
            self.problem = self.watch.error
            return None  # nothing deployed (or the store unreadable): keep what is in use
        if self.deployed is not None and self.deployed.active == active:
            return None
        try:
            saved = read_parameters_file(active.entry.parameters_path)
        except (ParameterFileError, OSError) as error:
            self.problem = f'calibration {active.entry.id}: {error}'
            return None
        vector = np.asarray(saved.vector, dtype=float)
        self.problem = ''
        digest = vector_digest(saved.model, vector)
        self.deployed = Deployed(active, saved.model, vector, digest)
        return self.deployed

    def deployed_match(self, model: str, vector: Sequence[float] | np.ndarray) -> Deployed | None:
        """Return the active calibration when (model, vector) is it, else None."""
        self.poll()  # a message may announce a deploy before the timer sees it
        if self.deployed is None:
            return None
        if vector_digest(model, vector) != self.deployed.digest:
            return None
        return self.deployed
