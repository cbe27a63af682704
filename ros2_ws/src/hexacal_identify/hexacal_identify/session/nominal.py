"""The nominal parameters file, read again only when it changed (one cache for the node)."""

from __future__ import annotations

import os
from pathlib import Path

from hexacal_msgs_py.errors import HexacalContractError

from ..core.architectures import KinematicParameters

FileIdentity = tuple[str, int, int, int, int, int]


def file_identity(path: str | Path) -> FileIdentity | None:
    """Return what changes when a file is replaced or edited (None: it cannot be stat'ed)."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return (
        os.path.abspath(path),
        info.st_dev,
        info.st_ino,
        info.st_size,
        info.st_mtime_ns,
        info.st_ctime_ns,
    )


class NominalFile:
    """
    The (parameters, device mount) of a nominal file, through load_machine_and_mount.

    Parsing the YAML takes ~4 ms, and the model is looked up for every posture received, so the
    file is read again only when its identity (file_identity) changes. The cache is one tuple,
    replaced whole: the posture thread and the calibration worker share it without a lock.
    """

    def __init__(self) -> None:
        """Start with nothing read."""
        # (identity, loaded); loaded None: the file at that identity cannot be loaded
        self._cache: tuple[FileIdentity, tuple[KinematicParameters, str] | None] | None = None

    def load(self, path: str) -> tuple[KinematicParameters, str]:
        """Return the nominal model and the device mount (ParameterFileError, ValueError)."""
        from ..calibration_steps.machine_files import load_machine_and_mount

        key = file_identity(path)  # None: read_parameters_file names the problem
        cached = self._cache
        if key is not None and cached is not None and cached[0] == key and cached[1] is not None:
            return cached[1]
        loaded = load_machine_and_mount(path)  # immutable: safe to share
        if key is not None:
            self._cache = (key, loaded)
        return loaded

    def model(self, path: str) -> str | None:
        """Return the model the file names; None without a path or a loadable file."""
        if not path:
            return None
        key = file_identity(path)
        if key is None:
            return None
        cached = self._cache
        if cached is not None and cached[0] == key:
            return cached[1][0].model if cached[1] is not None else None
        try:
            return self.load(path)[0].model
        except (HexacalContractError, ValueError):
            self._cache = (key, None)  # the calibration names the problem ('invalid-nominal')
            return None
