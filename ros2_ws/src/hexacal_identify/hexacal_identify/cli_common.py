"""Shared pieces of the ``hexacal`` command line: progress display and parameter-file arguments."""
from __future__ import annotations

import sys
from pathlib import Path

from .core.model import HexaParameters


class Progress:
    """A one-line progress display on stderr when it is a terminal; silent otherwise."""

    def __init__(self, enabled: bool = True, total: int | None = None):
        self._bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self._bar = tqdm(total=total, file=sys.stderr, leave=False, bar_format="{desc} {n_fmt} [{elapsed}]")

    def step(self, description: str) -> None:
        if self._bar is not None:
            self._bar.set_description_str(description)
            self._bar.update(1)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def load_params_arg(path: Path) -> HexaParameters:
    """A parameters YAML named on the command line, validated (ParameterFileError names the bad key)."""
    from hexacal_msgs_py.parameters_file import load_parameters

    return HexaParameters(load_parameters(path))
