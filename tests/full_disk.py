"""``flocksweep`` with a full disk for one file, for the fault battery (tests/faults.py) and the tests.

    python -m full_disk MODULE FILENAME ARGS...

runs ``flocksweep ARGS`` in which the atomic write of every file named FILENAME by the module MODULE
(its ``atomic_path``, e.g. ``flocksweep.analysis.calibration.inference`` and ``posterior.nc``) goes to
``/dev/full``: the temporary file the writer is given is a symbolic link to that device, which answers
every write with ENOSPC as a full disk does, whichever library writes (Python's file objects, HDF5's own
C writes). Every other file is written as usual.
"""
from __future__ import annotations

import contextlib
import importlib
import os
import sys
from pathlib import Path


def filling(real, filename: str):
    """``real`` (an ``atomic_path``), giving /dev/full as the temporary file of ``filename``."""

    @contextlib.contextmanager
    def full(path):
        with real(path) as tmp:
            if Path(path).name == filename:
                os.unlink(tmp)
                os.symlink("/dev/full", tmp)
            yield tmp
    return full


def main(argv: list[str]) -> int:
    module, filename, args = argv[0], argv[1], argv[2:]
    target = importlib.import_module(module)
    target.atomic_path = filling(target.atomic_path, filename)
    from flocksweep.cli import main as flocksweep
    return flocksweep(args)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
