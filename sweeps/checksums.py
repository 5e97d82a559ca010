"""Content checksums of the files a results store writes, and of its manifest (no pandas, no pyarrow).

``checksum(path)`` is the SHA-256 of a file's bytes; ``content_checksum(manifest)`` that of a manifest's
content without its own checksum (JSON with sorted keys). ``manifest.json`` records the first under
``CHECKSUMS`` (by path relative to the folder) and the second under ``SELF_CHECKSUM``;
:class:`sweeps.store.ResultsStore` writes and verifies them (its module docstring says what a changed
file means), and ``intact(root, name)`` is the check on its own, for readers that must not import pandas
(``flocksweep export``'s quick path): True only when the manifest is intact and records ``name``'s
checksum and the file's bytes still have it.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from .files import Unreadable, read_json

CHECKSUMS, SELF_CHECKSUM = "checksums", "manifest_checksum"   # keys of manifest.json
CHANGED = "changed since it was written (its checksum differs from the one recorded in manifest.json)"


def checksum(path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def content_checksum(data: dict) -> str:
    """SHA-256 of a manifest's content without its own checksum (as JSON with sorted keys)."""
    body = {k: v for k, v in data.items() if k != SELF_CHECKSUM}
    return hashlib.sha256(json.dumps(body, sort_keys=True, allow_nan=False).encode()).hexdigest()


def intact(root, *names: str) -> bool:
    """Whether ``manifest.json`` in ``root`` is a JSON object carrying its own valid checksum and records a
    checksum for each of ``names`` (paths relative to ``root``) that the file there still has."""
    root = Path(root)
    try:
        manifest = read_json(root / "manifest.json", {})
    except (Unreadable, OSError):
        return False
    if not isinstance(manifest, dict) or manifest.get(SELF_CHECKSUM) != content_checksum(manifest):
        return False
    sums = manifest.get(CHECKSUMS)
    if not isinstance(sums, dict):
        return False
    return all(isinstance(sums.get(name), str) and (root / name).is_file() and sums[name] == checksum(root / name)
               for name in names)
