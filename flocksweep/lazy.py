"""Public names that load their home module on first use: the one mechanism of every package's face.

A package lists its public names and where each lives, and gets its module ``__getattr__`` and
``__dir__``::

    __getattr__, __dir__ = public_names(__name__, globals(), {"simulate": "simulate",
                                                              "Sweep": ("config", "SweepConfig")})

A home is a submodule relative to the package (``"simulate"``, ``"reports.report"``), or a pair of that
submodule and the attribute's name there when they differ. A home that starts with ``flocksweep.`` is an
absolute module name (the namespace's own face forwards to its layers). The returned ``__getattr__``
carries the resolved table as ``__getattr__.homes``. Nothing is imported until a name
is used, so ``import flocksweep`` or ``import flocksweep.simcore`` stays cheap.

This module, like the namespace's ``__init__``, imports only the standard library: every layer may use it
(docs/architecture.md, "the namespace root").
"""
from __future__ import annotations

import importlib


def public_names(package: str, namespace: dict, homes: dict):
    """``(__getattr__, __dir__)`` for ``package`` whose public ``homes`` load on first use."""
    table = {name: home if isinstance(home, tuple) else (home, name) for name, home in homes.items()}

    def __getattr__(name: str):
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attribute = table[name]
        absolute = module if module.startswith("flocksweep.") else f"{package}.{module}"
        return getattr(importlib.import_module(absolute), attribute)

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(table))

    __getattr__.homes = table         # name -> (module, attribute): what tests/test_architecture.py checks
    return __getattr__, __dir__
