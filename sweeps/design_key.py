"""The identity of a sweep's design, so that a rerun with nothing to compute reads the stored design.

Building a design (:func:`sweeps.design.expand`) resolves and validates the preset of every design point
and hashes every run: a fraction of a millisecond a point, tens of seconds for 100,000 points, which a
rerun of a finished sweep would spend only to learn that every run id is in the store.

``design_key(config) -> str | None``: the SHA-256 of everything the design (its runs' ids, seeds,
indices and columns) is a function of: the sweep as run (its tables after ``--set``, and the
replicates), the model preset's data and its resolved base preset (which carries the digest of an
``init.from_file`` it names), simcore's model version, the versions of Python, numpy, scipy and SALib
(run seeds, sampled and sensitivity designs) and the bytes of every module of ``simcore``,
``observables`` and ``sweeps`` (the code that resolves, validates and hashes the runs). Two
configurations with the same key have the same design, bit for bit. None (never reused) for a command
model, a plug-in dynamics and a sweep that varies ``dynamics``, ``plugin`` or ``init.from_file``: their
runs depend on files outside these packages and the sweep.

``reusable_design(store, key) -> DataFrame | None``: the folder's ``design.parquet`` when its
``manifest.json`` can vouch for the files (:meth:`sweeps.store.ResultsStore.trust`), records ``key`` as
the design's (``design_key``) and the checksum ``design.parquet`` has; else None (then the design is
built as always). :func:`sweeps.runner.run_sweep` uses it only when it then finds nothing to compute;
any run to compute builds the whole design first, as a first run does.
"""
from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import json
import sys
from pathlib import Path

from flocksweep.simcore import MODEL_VERSION
from flocksweep.simcore.registry import is_builtin

from .files import json_ready

KEY = "design_key"   # in manifest.json
PACKAGES = ("simcore", "observables", "sweeps")   # the folders whose code builds a design
LIBRARIES = ("numpy", "scipy", "SALib")
OUTSIDE = ("dynamics", "plugin", "plugin_sha256", "init.from_file", "init.from_file_sha256")   # swept: never reused


def _version(name: str) -> str:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 of the bytes of every module of :data:`PACKAGES` (their paths and contents, in path order)."""
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for package in PACKAGES:
        folder = root / package
        for path in sorted(folder.rglob("*.py")):
            digest.update(f"{package}/{path.relative_to(folder).as_posix()}\0".encode())
            digest.update(path.read_bytes())
            digest.update(b"\0")
    return digest.hexdigest()


def design_key(config) -> str | None:
    """See the module docstring."""
    if config.command is not None or config.preset_path is None:
        return None
    from flocksweep.simcore.params import canonical_key

    from .design import base_preset

    if any(canonical_key(key) in OUTSIDE for key in config.swept_keys):
        return None
    base = base_preset(config)
    if not is_builtin(base.model.dynamics):
        return None
    what = {"source": config.source, "replicates": config.replicates, "preset": config.preset_data,
            "base": base.to_dict(), "model_version": MODEL_VERSION,
            "python": list(sys.version_info[:3]), "libraries": {name: _version(name) for name in LIBRARIES},
            "code": code_digest()}
    text = json.dumps(json_ready(what), sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def reusable_design(store, key: str | None):
    """See the module docstring."""
    if key is None or not (store.root / "design.parquet").exists() or store.trust():
        return None
    if store.manifest().get(KEY) != key or "design.parquet" not in store.checksums():
        return None
    try:
        return store.design()   # verified against its recorded checksum (Unreadable otherwise)
    except Exception:  # noqa: BLE001 - a damaged design is built again, as if there were none
        return None
