"""Content-addressed run identity and seed derivation.

* ``point_key(values)``: canonical JSON of a parameter point {dotted key: resolved value}.
* ``run_seed(sweep_seed, point, replicate)``: a 63-bit seed from
  ``SeedSequence([sweep_seed, *sha256(point) words, replicate])``; ``point=None`` (common random numbers)
  leaves the point out, so replicate r has the same seed everywhere.
* ``run_id(resolved_preset, analysis, group_radius, seed)``: the first 20 hex digits of the SHA-256 of
  the canonical JSON of everything that determines a run's results: the resolved preset (model, initial
  conditions, run settings), the analysis settings, the seed and ``simcore.MODEL_VERSION``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json

import numpy as np

from simcore import MODEL_VERSION


def canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def point_key(values: dict) -> str:
    return canonical(values)


def _words(text: str, count: int = 4) -> list[int]:
    digest = hashlib.sha256(text.encode()).digest()
    return [int.from_bytes(digest[4 * k:4 * k + 4], "little") for k in range(count)]


def run_seed(sweep_seed: int, point: str | None, replicate: int) -> int:
    entropy = [int(sweep_seed)] + (_words(point) if point is not None else []) + [int(replicate)]
    return int(np.random.SeedSequence(entropy).generate_state(1, np.uint64)[0] >> np.uint64(1))


def run_id(resolved_preset: dict, analysis, group_radius: float, seed: int) -> str:
    settings = {**dataclasses.asdict(analysis), "group_radius": float(group_radius)}
    if not settings.get("leadership"):
        settings.pop("leadership", None)  # added later: absent when off, so earlier run ids stay valid
    spec = {"model_version": MODEL_VERSION, "preset": resolved_preset, "analysis": settings, "seed": seed}
    return hashlib.sha256(canonical(spec).encode()).hexdigest()[:20]
