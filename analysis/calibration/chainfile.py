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
* a failed write is :class:`sweeps.files.WriteFailed` naming the file and the errno (also when the
  HDF5 library finds the file damaged half-way, a full disk's usual trace: ``KeyError: ... addr
  overflow``);
* every row carries a content checksum (``row_checksum[t]``: CRC-32 of the row's coordinates and
  log-probabilities as stored), staged with the row and committed with it. A file written before
  checksums existed gets them from its next step on (``checksums_from``).

``check_chain(path) -> int``: the steps a chain file holds, after reading everything a resume needs (the
step count, the rows, their checksums, the acceptance counts and random state of the committed slot);
:class:`DamagedChain` (a ``ValueError`` saying what is wrong) for a file that cannot be read or whose
content changed since it was written. Never deletes or moves anything.

``differences(stored, wanted, defaults) -> list[str]``: what differs between the settings stored with a
chain (its HDF5 attributes) and this run's, one phrase each (``n_sim: stored 50, now 30``); a setting the
file does not record is a difference too (an older file cannot vouch for it).
``stored_steps(path) -> int``: the steps a chain file holds (0 when there is none or it cannot be read).
"""
from __future__ import annotations

import os
import zlib

import emcee
import h5py
import numpy as np

from flocksweep.sweeps.files import WriteFailed, write_failed
from flocksweep.sweeps.interrupts import deferred

GROUP = "mcmc"
DIGESTS = {"chain_model": "the model (preset, fixed overrides, run settings)",
           "chain_targets": "the targets (observed statistics, their sd/cov or samples)",
           "emulator_fingerprint": "the emulator (training results, surrogate, targets or prior)"}
CHECKSUM = "row_checksum"
# what h5py raises for a file it cannot make sense of: OSError (truncated, not HDF5), KeyError (a damaged
# object header: 'Unable to synchronously open object (addr overflow ...)'), RuntimeError, ValueError
READ_ERRORS = (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError)


class DamagedChain(ValueError):
    """A chain file that cannot be read, or whose content changed since it was written."""


def row_checksum(coords, log_prob, dtype) -> int:
    """CRC-32 of one row (its coordinates and log-probabilities as stored in ``dtype``)."""
    data = np.ascontiguousarray(coords, dtype=dtype).tobytes() + np.ascontiguousarray(log_prob, dtype=dtype).tobytes()
    return zlib.crc32(data)


def _damaged_write(path, err: BaseException):
    """``err`` (raised while writing the chain file) as a WriteFailed naming the file."""
    if isinstance(err, OSError):
        return write_failed(path, err)
    text = str(err).strip().splitlines()
    return WriteFailed(None, f"the file became unreadable while it was written ({type(err).__name__}: "
                             f"{text[0] if text else ''}); free space if the disk is full, then run the same "
                             "command again (the file is set aside and the chain starts again)", os.fspath(path))


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
        except (OSError, KeyError, RuntimeError) as err:
            raise _damaged_write(self.filename, err) from None

    def _stage(self, g, iteration: int, state, accepted) -> np.ndarray:
        """Write step ``iteration``'s row and its state into the free slot; nothing is committed yet."""
        g["chain"][iteration, :, :] = state.coords
        g["log_prob"][iteration, :] = state.log_prob
        if state.blobs is not None:
            g["blobs"][iteration, :] = state.blobs
        if CHECKSUM in g:
            g[CHECKSUM][iteration] = row_checksum(state.coords, state.log_prob, g["chain"].dtype)
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
                with self.open("a") as f:
                    g = f[self.name]
                    size = g["chain"].shape[0]
                    if CHECKSUM not in g:
                        g.attrs["checksums_from"] = int(g.attrs["iteration"])
                        g.create_dataset(CHECKSUM, (size,), maxshape=(None,), dtype=np.uint32)
                    else:
                        g[CHECKSUM].resize(size, axis=0)
        except (OSError, KeyError, RuntimeError) as err:
            raise _damaged_write(self.filename, err) from None

    def reset(self, nwalkers, ndim):
        try:
            with deferred():
                super().reset(nwalkers, ndim)
        except (OSError, KeyError, RuntimeError) as err:
            raise _damaged_write(self.filename, err) from None

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
    except READ_ERRORS as err:
        raise DamagedChain(f"{path} cannot be read as a chain file ({type(err).__name__}: {err})") from None


def check_chain(path) -> int:
    """The steps the chain file at ``path`` holds, everything a resume reads checked (see the module
    docstring); DamagedChain saying what is wrong."""
    try:
        with h5py.File(os.fspath(path), "r") as f:
            if GROUP not in f:
                return 0
            g = f[GROUP]
            steps = int(g.attrs.get("iteration", 0))
            if steps == 0:
                return 0
            chain, log_prob = g["chain"][:steps], g["log_prob"][:steps]
            walkers = int(g.attrs["nwalkers"])
            if chain.shape[:2] != (steps, walkers) or log_prob.shape != (steps, walkers):
                raise DamagedChain(f"{path} holds {chain.shape[0]} rows where its step count says {steps}")
            slot = steps % 2
            accepted = g[f"accepted_slot_{slot}"] if f"accepted_slot_{slot}" in g else g["accepted"]
            if accepted.shape != (walkers,):
                raise DamagedChain(f"{path}: its acceptance counts do not match its {walkers} walkers")
            if not any(k.startswith((f"committed_state_{slot}_", "random_state_")) for k in g.attrs):
                raise DamagedChain(f"{path}: its random state is missing")
            if CHECKSUM in g:
                first = int(g.attrs.get("checksums_from", 0))
                stored = g[CHECKSUM][first:steps]
                for t, want in enumerate(stored, start=first):
                    if row_checksum(chain[t], log_prob[t], chain.dtype) != int(want):
                        raise DamagedChain(f"{path}: row {t + 1} of its chain changed since it was written "
                                           "(its checksum does not match)")
            return steps
    except DamagedChain:
        raise
    except READ_ERRORS as err:
        text = str(err).strip().splitlines()
        raise DamagedChain(f"{path} cannot be read as a chain file ({type(err).__name__}: "
                           f"{text[0] if text else ''})") from None


def stored_steps(path) -> int:
    """Steps held by the chain file at ``path`` (0 when there is none or it cannot be read)."""
    if not os.path.exists(path):
        return 0
    try:
        return int(stored_attrs(path).get("iteration", 0))
    except ValueError:
        return 0
