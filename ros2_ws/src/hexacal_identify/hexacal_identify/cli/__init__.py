"""
The `hexacal` command line.

One module per group of subcommands; `main` parses and dispatches.
"""

from .commands import build_parser, main

__all__ = ['build_parser', 'main']
