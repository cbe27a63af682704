"""
Renamed names of the contract: each still works, warns, and names the release that removes it.

A module keeps a renamed name in its ``DEPRECATED_NAMES`` ({old name: new name}) and answers it
from its ``__getattr__`` (PEP 562) through `deprecated_attribute`; a renamed field is a property
that calls `warn_deprecated`. The warning is a DeprecationWarning that names the new name and
`REMOVED_IN`, the release that removes the old one (CHANGELOG.md, "Deprecated").

ROS-free: the standard library only.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any
import warnings

REMOVED_IN = '0.3.0'  # the release that removes every name deprecated here


def warn_deprecated(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn (DeprecationWarning) that `old` is deprecated for `new` and removed in REMOVED_IN."""
    warnings.warn(
        f'{old} is deprecated and will be removed in hexacal {REMOVED_IN}: use {new}',
        DeprecationWarning,
        stacklevel=stacklevel,
    )


def deprecated_attribute(
    module: str, name: str, renamed: Mapping[str, str], namespace: Mapping[str, Any]
) -> Any:
    """
    Return the new object of a renamed module attribute, with the warning; else AttributeError.

    For a module's ``__getattr__``: `renamed` maps old names to new ones, `namespace` is the
    module's globals.
    """
    if name not in renamed:
        raise AttributeError(f'module {module!r} has no attribute {name!r}')
    warn_deprecated(f'{module}.{name}', renamed[name])
    return namespace[renamed[name]]


__all__ = ['REMOVED_IN', 'deprecated_attribute', 'warn_deprecated']
