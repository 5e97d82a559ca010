"""A subcommand of ``flocksweep``, declared one way.

Every subcommand is a module of :mod:`flocksweep.commands` holding ``COMMAND``, a :class:`Command`: its
name, its line in ``flocksweep --help``, its description, the function that declares its options on an
``argparse`` parser, and its handler, which returns the exit status (docs/errors.md). Options are declared
here, in the command-line layer, and nowhere below it; a handler imports the code it calls when it runs,
so a command module costs nothing to import (``flocksweep --help`` imports them all). The command line
(:mod:`flocksweep.cli`) builds its parser from :data:`flocksweep.commands.ORDER`.

A new command is one module in ``flocksweep/commands/`` and its name in ``ORDER``::

    from flocksweep.command import Command

    def arguments(p):
        p.add_argument("dir", help="results directory of a sweep")

    def handler(args) -> int:
        from flocksweep.sweeps.status import status    # the work, loaded when the command runs
        print(status(args.dir)["runs"])
        return 0

    COMMAND = Command("count", "count a sweep's runs", "Print how many runs a results directory holds.",
                      arguments, handler)
"""
from __future__ import annotations

from argparse import ArgumentParser, Namespace
from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Command:
    """One subcommand: ``flocksweep NAME``."""

    name: str
    help: str                                           # its line in `flocksweep --help`
    description: str                                    # the first paragraph of `flocksweep NAME --help`
    arguments: Callable[[ArgumentParser], None]         # declares its options
    handler: Callable[[Namespace], int]                 # runs it; returns the exit status

    def declare(self, subparsers) -> ArgumentParser:
        """Its parser, added to ``subparsers`` with its options."""
        parser = subparsers.add_parser(self.name, help=self.help, description=self.description)
        self.arguments(parser)
        return parser
