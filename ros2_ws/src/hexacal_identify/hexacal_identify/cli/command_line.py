"""
Shared pieces of the ``hexacal`` command line.

Lazy subcommands, progress display.

Imported by every ``hexacal`` start-up: keep its imports to the standard library.
"""

from __future__ import annotations

import argparse
import sys
from typing import Callable


class LazySubcommands(argparse._SubParsersAction):
    """
    Subcommand parsers whose arguments are added only when their command is chosen.

    ``add_parser(name, fill=f, help=..., description=...)`` registers the command
    (its name and help are all `hexacal --help` shows); ``f(parser)`` adds the
    arguments and the handler when the command line names the command, before
    its arguments are parsed. So a command imports only what its own options and
    handler need (the solver for `calibrate`, the studies for `study`), and
    `hexacal --help` none of them.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._fills: dict[str, Callable[[argparse.ArgumentParser], None]] = {}

    def add_parser(
        self, name: str, *, fill: Callable[[argparse.ArgumentParser], None] | None = None, **kwargs
    ) -> argparse.ArgumentParser:
        parser = super().add_parser(name, **kwargs)
        if fill is not None:
            self._fills[name] = fill
        return parser

    def fill(self, name: str) -> argparse.ArgumentParser:
        """Return the parser of command `name`, adding its arguments if they were not yet."""
        parser = self._name_parser_map[name]
        fill = self._fills.pop(name, None)
        if fill is not None:
            fill(parser)
        return parser

    def fill_all(self) -> None:
        for name in list(self._fills):
            self.fill(name)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        if values and values[0] in self._name_parser_map:
            self.fill(values[0])
        super().__call__(parser, namespace, values, option_string)


class Progress:
    """
    Progress on stderr: a one-line display on a terminal, else a line per stage (`stage`).

    Disabled (a --json run), silent.  `prefix` begins each stage line ('hexacal plan: ...').
    """

    def __init__(self, enabled: bool = True, total: int | None = None, prefix: str = 'hexacal'):
        self._bar = None
        self._lines = enabled and not sys.stderr.isatty()
        self._prefix = prefix
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self._bar = tqdm(
                total=total, file=sys.stderr, leave=False, bar_format='{desc} {n_fmt} [{elapsed}]'
            )

    def step(self, description: str) -> None:
        if self._bar is not None:
            self._bar.set_description_str(description)
            self._bar.update(1)

    def stage(self, description: str) -> None:
        """Announce a stage begun: the display's text on a terminal, else a line of its own."""
        if self._bar is not None:
            self._bar.set_description_str(description)
        elif self._lines:
            print(f'{self._prefix}: {description}', file=sys.stderr, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
