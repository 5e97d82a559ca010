"""The chain file: emcee's HDF5 backend with steps written whole, and its settings compared on resume.

:class:`ChainFile` is ``emcee.backends.HDFBackend`` (same file layout, readable by emcee and h5py) with
three changes:

* a step is committed whole: the new acceptance counts and random state go to one of two slots
  (``accepted_slot_<s>`` and ``committed_state_<s>_<i>``, ``s`` the parity of the new step count)
  before the step count is raised, and are read back from the slot of the stored count; a process
  killed (even by SIGKILL) in the middle of writing a step leaves the previous step's state intact, so
  a resume recomputes that step and the chain stays bit-identical to an uninterrupted one. emcee's
  own ``accepted`` and ``random_state_<i>`` are updated after the commit, for other readers;
* SIGINT and SIGTERM wait until the step is written (:func:`sweeps.interrupts.deferred`);
* a failed write is :class:`sweeps.files.WriteFailed` naming the file and the errno.

``differences(stored, wanted, defaults) -> list[str]``: what differs between the settings stored with a
chain (its HDF5 attributes) and this run's, one phrase each (``n_sim: stored 50, now 30``); a setting the
file does not record is a difference too (an older file cannot vouch for it).
``stored_steps(path) -> int``: the steps a chain file holds (0 when there is none or it cannot be read).
"""
from __future__ import annotations

import os

import emcee
import h5py
import numpy as np

from sweeps.files import write_failed
from sweeps.interrupts import deferred

GROUP = "mcmc"
DIGESTS = {"chain_model": "the model (preset, fixed overrides, run settings)",
           "chain_targets": "the targets (observed statistics, their sd/cov or samples)",
           "emulator_fingerprint": "the emulator (training results, surrogate, targets or prior)"}


class ChainFile(emcee.backends.HDFBackend):
    """emcee's HDF5 backend whose steps are committed whole (see the module docstring)."""

    def _slot(self, group) -> int:
        return int(group.attrs["iteration"]) % 2

    def save_step(self, state, accepted):
        self._check(state, accepted)
        try:
            with deferred(), self.open("a") as f:
                g = f[self.name]
                iteration = int(g.attrs["iteration"])
                total = self._stage(g, iteration, state, accepted)
                self._commit(g, iteration, state, total)
        except OSError as err:
            raise write_failed(self.filename, err) from None

    def _stage(self, g, iteration: int, state, accepted) -> np.ndarray:
        """Write step ``iteration``'s row and its state into the free slot; nothing is committed yet."""
        g["chain"][iteration, :, :] = state.coords
        g["log_prob"][iteration, :] = state.log_prob
        if state.blobs is not None:
            g["blobs"][iteration, :] = state.blobs
        total = self._accepted(g) + accepted
        slot = (iteration + 1) % 2
        name = f"accepted_slot_{slot}"
        if name not in g:
            g.create_dataset(name, data=total)
        else:
            g[name][...] = total
        for i, value in enumerate(state.random_state):
            g.attrs[f"committed_state_{slot}_{i}"] = value
        return total

    def _commit(self, g, iteration: int, state, total: np.ndarray) -> None:
        """Raise the step count (the commit), then update emcee's own fields for other readers."""
        g.attrs["iteration"] = iteration + 1
        g["accepted"][...] = total
        for i, value in enumerate(state.random_state):
            g.attrs[f"random_state_{i}"] = value

    def grow(self, ngrow, blobs):
        try:
            with deferred():
                super().grow(ngrow, blobs)
        except OSError as err:
            raise write_failed(self.filename, err) from None

    def reset(self, nwalkers, ndim):
        try:
            with deferred():
                super().reset(nwalkers, ndim)
        except OSError as err:
            raise write_failed(self.filename, err) from None

    def _accepted(self, group) -> np.ndarray:
        name = f"accepted_slot_{self._slot(group)}"
        return np.array(group[name][...] if name in group else group["accepted"][...])

    @property
    def accepted(self):
        with self.open() as f:
            return self._accepted(f[self.name])

    @property
    def random_state(self):
        with self.open() as f:
            g = f[self.name]
            prefix = f"committed_state_{self._slot(g)}_"
            slotted = sorted((int(k[len(prefix):]), v) for k, v in g.attrs.items() if k.startswith(prefix))
            if slotted:
                return [v for _, v in slotted]
            legacy = sorted((int(k[len("random_state_"):]), v) for k, v in g.attrs.items()
                            if k.startswith("random_state_"))
        return [v for _, v in legacy] if legacy else None


def differences(stored: dict, wanted: dict, defaults: dict | None = None) -> list[str]:
    """Phrases for the settings that differ (see the module docstring)."""
    out = []
    for key, want in wanted.items():
        have = stored.get(key, (defaults or {}).get(key))
        have = have.decode() if isinstance(have, bytes) else have
        have = have.item() if isinstance(have, np.generic) else have
        label = key
        if have is None:
            out.append(f"{label}: not recorded in the file (written by an older flocksweep)")
            continue
        try:
            same = type(want)(have) == want
        except (TypeError, ValueError):
            same = False
        if not same:
            out.append(f"{label}: {DIGESTS[key]} differ" if key in DIGESTS else f"{label}: stored {have!r}, now {want!r}")
    return out


def stored_attrs(path) -> dict:
    """The attributes of a chain file's group ({} when the file holds no chain yet; ValueError when it
    cannot be read as an HDF5 file)."""
    try:
        with h5py.File(os.fspath(path), "r") as f:
            return dict(f[GROUP].attrs) if GROUP in f else {}
    except OSError as err:
        raise ValueError(f"{path} cannot be read as a chain file ({type(err).__name__}: {err})") from None


def stored_steps(path) -> int:
    """Steps held by the chain file at ``path`` (0 when there is none or it cannot be read)."""
    if not os.path.exists(path):
        return 0
    try:
        return int(stored_attrs(path).get("iteration", 0))
    except ValueError:
        return 0
