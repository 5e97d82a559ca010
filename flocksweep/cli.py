"""The ``flocksweep`` command line: the parser of every subcommand, and :func:`main`, which runs one.

    flocksweep simulate | run | status | compile | export | report | calibrate | targets | posterior |
               compare | sbc | view | measure  [options]      (flocksweep COMMAND --help)

Each subcommand is declared one way, in its own module of :mod:`flocksweep.commands` (a
:class:`flocksweep.command.Command`: help line, description, options, handler); this module only builds
the parser from them and runs the handler of the command named.

Exit status (sweeps/failures.py, docs/errors.md): 0 on success, 2 for bad input (a config error names
the key, the value and what is allowed; nothing is written), 3 when another runner holds the results
directory, 4 when a write fails (the file and errno named; what was saved is kept), 5 when runs were
left missing because their worker processes died, 130 after Ctrl-C and 143 after SIGTERM (finished work
saved, the way to resume printed). Every one of these is a single message on stderr, never a traceback.

This module is the top of the import graph (docs/architecture.md): it may import every layer. Each
command imports what it needs when it runs, and the parser declares only the arguments of the command
named on the command line, so ``flocksweep simulate`` loads neither the calibration, the reports, the
viewer nor pandas (tests/flocksweep/test_cli.py checks it).
"""
from __future__ import annotations

import argparse
import sys

from flocksweep import version
from flocksweep.commands import ORDER, load
from flocksweep.sweeps.failures import explain, show_warnings
from flocksweep.sweeps.interrupts import ignored, signals_as_exceptions


ALL = "*"   # build_parser(ALL): every command's arguments declared (tests and documentation)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser: every command of :data:`ORDER` with its help line; the options of ``command`` (or, with
    :data:`ALL`, of every command) declared. Command modules are light (their handlers import the work),
    so neither ``flocksweep --help`` nor ``flocksweep simulate`` loads the reports, the viewer or the
    calibration."""
    parser = argparse.ArgumentParser(prog="flocksweep", description="Reproducible flocking-model sweeps: "
                                     "simulate, sweep, report, calibrate, view. `flocksweep COMMAND --help` "
                                     "describes a command.")
    parser.add_argument("--version", action="version", version=f"flocksweep {version()}",
                        help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in ORDER:
        declared = load(name)
        if name == command or command == ALL:
            declared.declare(sub)
        else:   # listed by name and help line only
            sub.add_parser(name, help=declared.help)
    return parser


def _command_of(argv) -> str | None:
    """The subcommand named on the command line (its first word not starting with '-'), else None."""
    argv = sys.argv[1:] if argv is None else argv
    for word in argv:
        if not str(word).startswith("-"):
            return word if word in ORDER else None
    return None


def main(argv=None) -> int:
    args = build_parser(_command_of(argv)).parse_args(argv)
    show_warnings()
    try:
        with signals_as_exceptions():
            return load(args.command).handler(args)
    except BaseException as err:  # noqa: BLE001 - expected failures become one line; bugs raise
        known = explain(err)
        if known is None:
            raise
        code, message = known
        with ignored():   # a second Ctrl-C does not cut the message short
            print(f"flocksweep: {message}", file=sys.stderr)
            if isinstance(err, KeyboardInterrupt):
                _after_interrupt(args)
        return code


def _after_interrupt(args) -> None:
    """What an interrupted command saved and how to resume it (each command leaves ``args.on_interrupt``)."""
    hint = getattr(args, "on_interrupt", None)
    try:
        print(f"  {hint() if hint else 'nothing to resume: run the command again'}", file=sys.stderr)
    except Exception as err:  # noqa: BLE001 - the summary is a courtesy; the interrupt is what matters
        print(f"  (could not read what was saved: {type(err).__name__}: {err})", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
