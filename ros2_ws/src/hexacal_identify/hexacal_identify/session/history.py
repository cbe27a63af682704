"""
The identify node's calibration store: every calibration kept, verified, deployed on request.

What the node decides about the store, without ROS: which store (the `calibration_store`
parameter, else the machine model's default store), the provenance record of a calibration,
the status values and answers of deploy and rollback. The store's own rules (what is
deployable, the plausibility check, nothing overwritten) are the store's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import hashlib
from pathlib import Path
import threading
from typing import Any, TYPE_CHECKING

from hexacal_msgs_py import store_format as fmt

from .deployment import ActiveWatch, NO_ACTIVE, store_dir
from .outcome import failure, Level, Outcome
from ..core.jsonsafe import json_safe
from ..store import (
    CalibrationStore,
    DeployRefused,
    file_digest,
    postures_digest,
    StoreEntry,
    StoreError,
)

if TYPE_CHECKING:
    from ..core.measurements import NoiseModel

DEPLOYED = 'deployed'
ROLLED_BACK = 'rolled-back'
DEPLOY_REFUSED = 'deploy-refused'
ROLLBACK_REFUSED = 'rollback-refused'
NO_CALIBRATION = 'no-calibration'
STORE_ERROR = 'store-error'


def fit_figures(result: Any) -> dict[str, object]:
    """Return the fit's figures of an IdentificationResult (store FIT_* keys, SI)."""
    figures: dict[str, object] = {
        fmt.FIT_REASON: result.reason,
        fmt.FIT_RANK: result.rank,
        fmt.FIT_PARAMETERS: int(len(result.parameters.vector)),
        fmt.FIT_CONDITION: result.condition_number,
        fmt.FIT_COST: result.cost,
        fmt.FIT_ITERATIONS: result.iterations,
        fmt.FIT_RMS_RESIDUAL: dict(result.rms_residual),
        fmt.FIT_POSTURES_USED: len(result.used_postures),
        fmt.FIT_POSTURES_REJECTED: len(result.rejected_postures),
    }
    if result.weighted:  # the residual variance over the noise model's: ~1 when it fits
        figures[fmt.FIT_ADEQUACY] = {'variance_factor': result.variance_factor}
    return figures


def calibration_record(
    *,
    bag: str,
    postures: Sequence[Any],
    nominal_path: str,
    cost: str,
    noise: NoiseModel | None,
    robust_loss: str,
    link_length: float,
    mount: str | None,
    device_defects: Mapping[str, object] | None,
    device_prior: object,
    fit: Mapping[str, object],
) -> dict[str, object]:
    """Return the provenance record of a calibration made by the identify node (store keys)."""
    record: dict[str, object] = {
        fmt.RECORD_SOURCE: 'identify node',
        fmt.RECORD_POSTURES_COUNT: len(postures),
        fmt.RECORD_POSTURES_DIGEST: postures_digest(postures),
        fmt.RECORD_NOMINAL_FILE: str(nominal_path),
        fmt.RECORD_NOMINAL_DIGEST: _digest(nominal_path),
        fmt.RECORD_COST: cost,
        fmt.RECORD_NOISE: None
        if noise is None
        else {'actuator_m': noise.actuator_m, 'angle_rad': noise.angle_rad},
        fmt.RECORD_ROBUST_LOSS: robust_loss or None,
        fmt.RECORD_LINK_LENGTH: link_length,
        fmt.RECORD_MOUNT: mount,
        fmt.RECORD_DEVICE_DEFECTS: dict(device_defects or {}),
        fmt.RECORD_DEVICE_PRIOR: str(device_prior.describe()) if device_prior else None,
        fmt.RECORD_FIT: dict(fit),
    }
    if bag:
        record[fmt.RECORD_BAG] = {'path': bag, 'digest': _digest(bag)}
    return json_safe(record)


def _digest(path: str) -> str | None:
    """Return the sha256 of a file, None when it cannot be read (e.g. a bag directory)."""
    try:
        return file_digest(path)
    except OSError:
        return None


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
            refused = failure(DEPLOY_REFUSED, str(error), calibration_id=entry_id, **where)
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
