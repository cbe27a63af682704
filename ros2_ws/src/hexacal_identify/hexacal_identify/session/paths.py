"""Where the identify node writes: only under its output directory."""

from __future__ import annotations

import glob
import os
from pathlib import Path

DEFAULT_OUTPUT = 'hexacal_calibration.yaml'


def output_path(output: str, output_dir: str) -> Path:
    """Return the file `output` names, which must lie under `output_dir` (ValueError otherwise)."""
    if not output:
        raise ValueError('output must name a file')
    directory = Path(output_dir or os.getcwd()).expanduser().resolve()
    target = (directory / Path(output).expanduser()).resolve()
    if target == directory or not target.is_relative_to(directory):
        raise ValueError(
            f'output {output!r} is outside output_dir {str(directory)!r}: '
            'the node writes only under output_dir'
        )
    return target


def interrupted_writes(target: Path) -> list[Path]:
    """
    Return the temporary files of writes of `target` that a crash interrupted.

    save_parameters writes '.<name>.<random>.tmp' beside the target, then renames it: a leftover
    one is a write that never finished, never a calibration.
    """
    return sorted(target.parent.glob(f'.{glob.escape(target.name)}.*.tmp'))
