"""Every subcommand of ``flocksweep``: one module each, holding ``COMMAND`` (a
:class:`flocksweep.command.Command`: name, help line, description, options, handler).

:data:`ORDER` lists them as ``flocksweep --help`` shows them; :func:`load` gives one. ``flocksweep
--help`` imports every command module, so a command module imports at its top only the standard library,
:mod:`flocksweep.simcore.schema` and :mod:`flocksweep.sweeps.failures`; what declaring its options needs
(a table of choices) is imported inside its ``arguments``, and its handler imports the work when the
command runs."""
from __future__ import annotations

import importlib

ORDER = ("simulate", "run", "status", "compile", "export", "report", "calibrate", "init", "targets",
         "posterior", "compare", "sbc", "view", "measure")


def load(name: str):
    """The :class:`~flocksweep.command.Command` of subcommand ``name`` (one of :data:`ORDER`)."""
    return importlib.import_module(f"{__name__}.{name}").COMMAND
