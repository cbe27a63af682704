"""
The identify node's calibration store: every calibration kept, verified, deployed on request.

What the node decides about the store, without ROS: which store (the `calibration_store`
parameter, else the machine model's default store), the status values and answers of adding,
verifying, deploy and rollback. The provenance record is store.provenance's (the CLI's too);
the store's own rules (what is deployable, the plausibility check, nothing overwritten) are
the store's.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
import threading

from hexacal_msgs_py.names import DEPLOY_FORCE_SERVICE
from hexacal_msgs_py.parameters_file import ParametersFile, read_parameters_file

from .deployment import ActiveWatch, NO_ACTIVE, store_dir
from .outcome import failure, Level, Outcome
from ..core.jsonsafe import json_safe
from ..store import CalibrationStore, DeployRefused, StoreEntry, StoreError

DEPLOYED = 'deployed'
ROLLED_BACK = 'rolled-back'
DEPLOY_REFUSED = 'deploy-refused'
ROLLBACK_REFUSED = 'rollback-refused'
NO_CALIBRATION = 'no-calibration'
STORE_ERROR = 'store-error'
ACTIVE = 'active'  # the start-up status: a calibration is active
NONE_DEPLOYED = 'none-deployed'


class History:
    """The store of one identify node, opened per store directory (thread-safe)."""

    def __init__(self) -> None:
        """Start with no store opened; each call names its store."""
        self._lock = threading.Lock()  # store writes from the worker, status reads elsewhere
        self._watches: dict[Path, ActiveWatch] = {}

    def _watch(self, configured: str, model: str) -> ActiveWatch:
        root = store_dir(configured, model)
        watch = self._watches.get(root)
        if watch is None:  # setdefault: two threads opening it keep one watch
            watch = self._watches.setdefault(root, ActiveWatch(root))
        return watch

    def root(self, configured: str, model: str) -> Path:
        """Return the directory of the store `configured` names, else the model's default."""
        return self._watch(configured, model).root

    def store(self, configured: str, model: str) -> CalibrationStore:
        """Return the store `configured` names, else the model's default store."""
        return self._watch(configured, model).store

    def active_values(self, configured: str, model: str) -> dict[str, object]:
        """Return the status values that say which calibration is active ('' = none)."""
        try:
            with self._lock:
                return self._watch(configured, model).values()
        except (StoreError, OSError):
            return dict(NO_ACTIVE)

    def active_status(self, configured: str, model: str) -> tuple[str, dict[str, object]]:
        """Return the message and values of a status saying what is active (outcome first)."""
        values = self.active_values(configured, model)
        root = self.root(configured, model)
        if values['active_calibration']:
            outcome = ACTIVE
            message = (
                f'{ACTIVE}: calibration {values["active_calibration"]} '
                f'({values["active_reason"]} since {values["active_since"]}), store {root}'
            )
        else:
            outcome = NONE_DEPLOYED
            message = f'{NONE_DEPLOYED}: no calibration deployed in store {root}'
        return message, {'outcome': outcome, 'calibration_store': str(root), **values}

    def active_parameters(self, configured: str, model: str) -> ParametersFile | None:
        """Return the active calibration's parameters file, read (None: none deployed)."""
        entry = self.store(configured, model).active()
        return None if entry is None else read_parameters_file(entry.parameters_path)

    def add(
        self, configured: str, model: str, parameters_file: Path, record: dict[str, object]
    ) -> tuple[StoreEntry | None, dict[str, object]]:
        """Keep a calibration; return its entry (None: not kept) and the status values."""
        store, root = self.store(configured, model), self.root(configured, model)
        try:
            with self._lock:
                entry = store.add(parameters_file, record)
        except (StoreError, OSError) as error:
            return None, {'calibration_store': str(root), 'store_error': str(error)}
        return entry, {'calibration_id': entry.id, 'calibration_store': str(root)}

    def find(self, configured: str, model: str, parameters_file: Path) -> StoreEntry | None:
        """Return the store entry of a parameters file (its digest), or None."""
        try:
            digest = hashlib.sha256(parameters_file.read_bytes()).hexdigest()
            with self._lock:
                return self.store(configured, model).find_digest(digest)
        except (StoreError, OSError):
            return None

    def attach(
        self, configured: str, model: str, entry_id: str, figures: dict[str, object]
    ) -> dict[str, object]:
        """Attach a verification's figures to a calibration; the status values."""
        try:
            with self._lock:
                self.store(configured, model).attach_verification(entry_id, json_safe(figures))
        except (StoreError, OSError) as error:
            return {'calibration_id': entry_id, 'store_error': str(error)}
        return {'calibration_id': entry_id}

    def deploy(
        self,
        configured: str,
        model: str,
        entry_id: str | None,
        force: bool,
        deploy_service: str,
    ) -> Outcome:
        """Deploy calibration `entry_id` (None: no calibration yet); the answer and status."""
        store, root = self.store(configured, model), self.root(configured, model)
        where = {'calibration_store': str(root), 'force': force}
        if entry_id is None:
            return failure(
                NO_CALIBRATION,
                f'no calibration in this session to deploy: calibrate, verify, then call '
                f'{deploy_service} again (or `hexacal deploy ID --store {root}`)',
                **where,
            )
        try:
            with self._lock:
                store.deploy(entry_id, force=force)
        except DeployRefused as error:
            text = f'{error} (here: {DEPLOY_FORCE_SERVICE})'  # the node's way to force it
            refused = failure(DEPLOY_REFUSED, text, calibration_id=entry_id, **where)
            refused.values['reason'] = error.reason  # the first check that refused
            refused.values['refusals'] = ', '.join(r.reason for r in error.refusals)
            return refused
        except (StoreError, OSError) as error:
            return failure(STORE_ERROR, str(error), calibration_id=entry_id, **where)
        values = self.active_values(configured, model)
        how = 'forced' if force else 'verified'
        message = f'{DEPLOYED}: calibration {entry_id} is active ({how}), store {root}'
        return Outcome(
            True,
            message,
            Level.WARN if force else Level.OK,
            {'outcome': DEPLOYED, 'calibration_id': entry_id, **where, **values},
        )

    def rollback(self, configured: str, model: str) -> Outcome:
        """Return to the previously active calibration; the answer and status."""
        store, root = self.store(configured, model), self.root(configured, model)
        where = {'calibration_store': str(root)}
        try:
            with self._lock:
                entry = store.rollback()
        except (StoreError, OSError) as error:
            return failure(ROLLBACK_REFUSED, str(error), **where)
        values = self.active_values(configured, model)
        message = f'{ROLLED_BACK}: calibration {entry.id} is active again, store {root}'
        values = {'outcome': ROLLED_BACK, 'calibration_id': entry.id, **where, **values}
        return Outcome(True, message, Level.OK, values)
