"""The chain file of an emcee calibration, shared by BSL and the emulator method.

``open_chain(path, resume, meta, defaults=None, needs="the same settings") -> emcee.backends.HDFBackend``
opens ``path`` (group ``"mcmc"``). Without ``resume`` an existing file is FileExistsError (remove it or
resume). An initialised file must carry every ``meta`` key with the same value (strings compared as
strings, other values converted to the type of the wanted value); a key missing from an older file takes
its value from ``defaults`` when given there. A mismatch is ValueError naming the key and ``needs``.
Writing ``meta`` into the file is the caller's job once emcee has created the group.

``progress_tau(chain) -> float``: the mean over parameters of emcee's integrated autocorrelation time of
``chain`` (steps, walkers, d), with no length check: an estimate for a progress display, nan when it
cannot be computed (fewer than 2 rows, a constant parameter).
"""
from __future__ import annotations

import math
import os

import numpy as np

GROUP = "mcmc"


def open_chain(path, resume: bool, meta: dict, defaults: dict | None = None, needs: str = "the same settings"):
    import emcee

    path = os.fspath(path)
    if os.path.exists(path) and not resume:
        raise FileExistsError(f"{path} exists; remove it to start afresh or pass resume=True")
    backend = emcee.backends.HDFBackend(path, name=GROUP)
    if backend.initialized:
        with backend.open("r") as f:
            attrs = dict(f[GROUP].attrs)
        for key, want in meta.items():
            have = attrs.get(key, (defaults or {}).get(key))
            have = have.decode() if isinstance(have, bytes) else have
            if have is None or type(want)(have) != want:
                raise ValueError(f"{path}: stored {key}={have!r} does not match this run's {want!r}; "
                                 f"resume needs {needs}")
    return backend


def progress_tau(chain: np.ndarray) -> float:
    import emcee

    if chain.shape[0] < 2:
        return math.nan
    try:
        with np.errstate(all="ignore"):
            tau = np.asarray(emcee.autocorr.integrated_time(chain, tol=0), dtype=float)
    except Exception:  # noqa: BLE001 - an estimate for a progress display; never abort a run for it
        return math.nan
    return float(np.mean(tau)) if np.all(np.isfinite(tau)) else math.nan
