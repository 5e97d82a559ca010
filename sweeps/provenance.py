"""Provenance stamp stored with every result: package versions, git revision, machine.

``stamp()`` returns a JSON-ready dict; it never fails (unknown values are reported as ``None``).
"""
from __future__ import annotations

import importlib.metadata
import os
import platform
import subprocess
from pathlib import Path


PACKAGES = ("flocksweep", "numpy", "numba", "llvmlite", "scipy", "pandas", "pyarrow", "matplotlib")


def package_versions() -> dict:
    out = {}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


def git_revision(where: Path | None = None) -> str | None:
    """HEAD commit of the checkout holding this package (with '+dirty' for local changes), or None."""
    where = where or Path(__file__).resolve().parent.parent
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=where, capture_output=True, text=True,
                             timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=where,
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


def machine() -> dict:
    return {"platform": platform.platform(), "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(), "cpus": os.cpu_count()}


def stamp() -> dict:
    from flocksweep.simcore.simulate import MODEL_VERSION   # here: importing the simulator loads numba (status stays quick)

    return {"model_version": MODEL_VERSION, "packages": package_versions(), "git_revision": git_revision(),
            "machine": machine()}
