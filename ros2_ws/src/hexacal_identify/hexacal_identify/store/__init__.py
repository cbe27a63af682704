"""
The calibration store (ROS-free): every calibration kept with its provenance, deploy, rollback.

A store is a directory per machine (``default_store_dir(model)``, ``--store DIR``, the identify
node's ``calibration_store``).  ``add`` keeps a parameters file with a record of where it came
from; ``attach_verification`` adds a verification's figures; ``deploy`` makes an entry the
active calibration - only with a passing verification on postures not used in the fit and
within plausible reach of the active one, unless forced; ``rollback`` returns to the previous
active one.  Nothing is overwritten: entries are written whole under a temporary name and
renamed, state changes are new event files, and the states are derived from them.  The layout
and keys are the contract's (``hexacal_msgs_py.store_format``; docs/formats.md).

For the nodes:

* keep a calibration: ``store.add(output_file, calibration_record(result, source='identify
  node', postures=postures, nominal_file=nominal_path, ...))``;
* attach a verification: ``store.attach_verification(entry.id, figures,
  postures_digest=postures_digest(postures))`` (``figures['verdict']`` 'pass'/'fail');
* follow deploys: stat ``store.active_marker()`` (a new inode and mtime on every deploy and
  rollback; absent before the first), then ``store.activation()`` (entry, since, reason);
* match a parameters message: ``store.find_digest(vector_digest(model, vector))``.

Importing this package imports neither numpy nor the core; the plausibility check does when it
runs.
"""

from __future__ import annotations

import os
from pathlib import Path

from hexacal_msgs_py.store_format import (
    ActivationReason,
    bytes_digest,
    file_digest,
    postures_digest,
    STORE_ENV,
    StoreState,
    vector_digest,
)

from .calibration_store import CalibrationStore, hexacal_version, utc_now
from .plausibility import (
    DEFAULT_MAX_PARAMETER_CHANGE_M,
    DEFAULT_MAX_POSE_CHANGE_M,
    DEFAULT_MAX_ROTATION_CHANGE_RAD,
)
from .provenance import bag_digest, calibration_record, fit_figures
from .store_entry import Activation, DeployRefused, Refusal, StoreEntry, StoreError


def default_store_dir(model: str) -> Path:
    """
    Return the default store directory of a machine model.

    ``$HEXACAL_STORE/<model>`` when the environment variable is set (tests, demos, a site
    directory), else ``$XDG_DATA_HOME/hexacal/calibrations/<model>`` (XDG_DATA_HOME defaults to
    ``~/.local/share``).
    """
    base = os.environ.get(STORE_ENV)
    if base:
        return Path(base).expanduser() / model
    data_home = os.environ.get('XDG_DATA_HOME') or str(Path.home() / '.local' / 'share')
    return Path(data_home).expanduser() / 'hexacal' / 'calibrations' / model


__all__ = [
    'Activation',
    'ActivationReason',
    'CalibrationStore',
    'DEFAULT_MAX_PARAMETER_CHANGE_M',
    'DEFAULT_MAX_POSE_CHANGE_M',
    'DEFAULT_MAX_ROTATION_CHANGE_RAD',
    'DeployRefused',
    'Refusal',
    'StoreEntry',
    'StoreError',
    'StoreState',
    'bag_digest',
    'bytes_digest',
    'calibration_record',
    'default_store_dir',
    'file_digest',
    'fit_figures',
    'hexacal_version',
    'postures_digest',
    'vector_digest',
    'utc_now',
]
