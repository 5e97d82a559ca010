"""An npe estimator's folder, sealed like a results folder: its files' checksums recorded when it is
written, verified before anything in it is read (issue 42).

The folder (``<out>/estimator``, ``<out>/estimator-round<r>``, or a ``method.estimator`` folder)::

    flow.json, flow.eqx              one flow (analysis.calibration.npe_flow), or
    flow.json, member<i>/flow.*      an ensemble's members
    identity.json                    what it was trained for (analysis.calibration.npe: estimator_identity)
    coverage.json                    its held-out coverage verdict
    manifest.json                    the SHA-256 of each file above, with its own checksum

Contract
--------
``seal(where, names=None, **about)``: write ``manifest.json`` (atomically, after the files it vouches for):
the checksums of ``names`` (paths relative to ``where``; None: every file in the folder, which the caller has
just written, all of it) and of the files an intact manifest recorded before and that still have them,
under ``checksums``, with ``about`` (the calibration file and output folder that trained it) and the
manifest's own checksum (``sweeps.checksums``: the results store's helpers, the same format). Nothing is
ever vouched for afresh: a file is recorded only by the writer that wrote it.

``verify(where) -> dict``: the manifest, when the folder is a folder, ``manifest.json`` is present, a JSON
object whose own checksum holds and which records checksums; every file it records is present with the
checksum recorded; and every file in the folder (temporary files of a killed write aside) is recorded.
Otherwise :class:`DamagedEstimator` (``sweeps.files.Unreadable``: exit 2, nothing written) naming the file
and what is wrong, and how to train the estimator again. There is no way to skip the check: an
estimator written before estimators were sealed (no ``manifest.json``) is refused by ``flocksweep
posterior`` the same way, and trained again by ``flocksweep calibrate`` (its stored training runs are found
again, so only the flow is fitted anew).

``read_identity(where) -> dict``: ``identity.json`` of a verified folder, its types checked (a list of
``[name, key]`` parameters, ``bounds`` of finite ``[low, high]`` pairs, one per parameter, a list of
statistic columns, the transforms and measurement as objects); a file that holds anything else is
:class:`DamagedEstimator` naming it. ``read_json(path)``: a small JSON file of the folder, parsed (at most
:data:`MAX_JSON` bytes), or :class:`DamagedEstimator`.

``set_aside(root, where, reason)``: move a damaged or stale estimator folder inside the calibration's
output folder ``root`` to ``quarantine/`` (``sweeps.quarantine``, with its warning), so the estimator
trained in its place is written into an empty folder and sealed whole.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from flocksweep.sweeps.checksums import CHECKSUMS, SELF_CHECKSUM, checksum, content_checksum
from flocksweep.sweeps.files import TEMPORARY, Unreadable, write_json
from flocksweep.sweeps.quarantine import quarantine

MANIFEST = "manifest.json"
IDENTITY_FILE = "identity.json"
COVERAGE_FILE = "coverage.json"   # the held-out coverage verdict (analysis.calibration.npe)
MAX_JSON = 64 << 20          # an identity, flow record or verdict is a few kB; a larger one is not ours


NUMBER = (int, float)
MEASUREMENT = {"interval": (*NUMBER, type(None)), "velocity_interval": (*NUMBER, str, type(None)),
               "max_gap": (*NUMBER, type(None)), "dims": (int, type(None)), "length_unit": str,
               "group_radius": (*NUMBER, type(None)), "fragmentation_cohesion": (*NUMBER, type(None)),
               "dcd_max_delay": (*NUMBER, type(None)), "warmup": (*NUMBER, type(None))}   # what posterior reads of an identity's measurement


class DamagedEstimator(Unreadable):
    """An estimator folder that cannot be trusted or read (module docstring); exit 2."""


def retrain_hint(manifest: dict | None = None) -> str:
    """How to train the estimator again: the calibration that made it, when its manifest says."""
    about = manifest or {}
    if isinstance(about.get("calibration"), str) and isinstance(about.get("out"), str):
        command = f"flocksweep calibrate {about['calibration']} --out {about['out']}"
    else:
        command = "flocksweep calibrate CALIB.toml --out FOLDER (the calibration that trained it, FOLDER holding it)"
    return (f"train it again: {command}; its stored training runs are found again, so only the flow is fitted "
            "anew")


def _files(where: Path) -> list[str]:
    """Every file below ``where`` (relative, sorted), the manifest and temporary files aside."""
    return sorted(str(p.relative_to(where)) for p in where.rglob("*")
                  if (p.is_file() or p.is_symlink()) and p.name != MANIFEST and not TEMPORARY.match(p.name))


def _manifest(where: Path) -> tuple[dict, str | None]:
    """(the manifest, None) or ({}, what is wrong with it)."""
    path = where / MANIFEST
    if not path.exists():
        return {}, ("is missing: the estimator's files cannot be verified (written before estimators were sealed "
                    "with checksums, or its writing was cut short)")
    try:
        data = read_json(path)
    except DamagedEstimator as err:
        return {}, str(err).split(": ", 1)[-1]
    if not isinstance(data, dict):
        return {}, "is not a JSON object"
    if data.get(SELF_CHECKSUM) != content_checksum(data):
        return {}, "changed since it was written (its own checksum does not match)"
    if not isinstance(data.get(CHECKSUMS), dict) or not data[CHECKSUMS]:
        return {}, "records no checksums"
    return data, None


def seal(where, names=None, **about) -> Path:
    """Record the checksums of ``names`` (None: every file now in the folder) in ``manifest.json``
    (module docstring)."""
    where = Path(where)
    previous, problem = _manifest(where)
    sums = {}
    if problem is None:
        sums = {name: value for name, value in previous[CHECKSUMS].items()
                if (where / name).is_file() and checksum(where / name) == value}
        about = {**{k: v for k, v in previous.items() if k not in (CHECKSUMS, SELF_CHECKSUM)}, **about}
    for name in (_files(where) if names is None else names):
        sums[str(name)] = checksum(where / name)
    record = {"written_by": "flocksweep calibrate (npe)", **about, CHECKSUMS: dict(sorted(sums.items()))}
    write_json(where / MANIFEST, {**record, SELF_CHECKSUM: content_checksum(record)})
    return where / MANIFEST


def verify(where) -> dict:
    """The folder's manifest, every file checked against it; :class:`DamagedEstimator` otherwise."""
    where = Path(where)
    if not where.is_dir():
        what = "is not a folder" if where.exists() else "does not exist"
        raise DamagedEstimator(f"{where} {what}; expected the estimator/ folder of an npe calibration's output "
                               "(flocksweep calibrate CALIB.toml with [method] kind = \"npe\" writes it)")
    manifest, problem = _manifest(where)
    if problem is not None:
        raise DamagedEstimator(f"{where / MANIFEST} {problem}; {retrain_hint()}")
    hint = retrain_hint(manifest)
    for name, recorded in manifest[CHECKSUMS].items():
        path = where / name
        if not path.is_file():
            raise DamagedEstimator(f"{path} is missing (the estimator's manifest.json records it); {hint}")
        if not isinstance(recorded, str) or checksum(path) != recorded:
            raise DamagedEstimator(f"{path} changed since it was written (its checksum differs from the one "
                                   f"recorded in the estimator's manifest.json); {hint}")
    for name in _files(where):
        if name not in manifest[CHECKSUMS]:
            raise DamagedEstimator(f"{where / name} cannot be verified (the estimator's manifest.json records no "
                                   f"checksum of it: flocksweep did not write it here); move it out, or {hint}")
    return manifest


def read_json(path, missing: bool = False):
    """A JSON file of an estimator folder, parsed; :class:`DamagedEstimator` naming it when it is not one
    (``missing``: None when it does not exist)."""
    path = Path(path)
    try:
        if missing and not path.exists():
            return None
        if not path.is_file():
            raise DamagedEstimator(f"{path} is missing or not a file")
        if path.stat().st_size > MAX_JSON:
            raise DamagedEstimator(f"{path}: {path.stat().st_size:,} bytes, more than an estimator's JSON file holds")
        return json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError, RecursionError) as err:
        raise DamagedEstimator(f"{path}: not valid JSON ({type(err).__name__}: {err})") from None
    except OSError as err:
        raise DamagedEstimator(f"{path} cannot be read ({err.strerror or err})") from None


def _pairs(value, kind) -> bool:
    return isinstance(value, list) and value != [] and all(
        isinstance(v, list) and len(v) == 2 and all(isinstance(x, kind) and not isinstance(x, bool) for x in v)
        for v in value)


def read_identity(where) -> dict:
    """``identity.json``, its types checked (module docstring)."""
    path = Path(where) / IDENTITY_FILE
    identity = read_json(path)
    problem = _identity_problem(identity)
    if problem:
        raise DamagedEstimator(f"{path}: {problem}; not an identity flocksweep writes: {retrain_hint()}")
    return identity


def _identity_problem(identity) -> str:
    if not isinstance(identity, dict):
        return f"a JSON {type(identity).__name__}, not an object"
    parameters, columns, bounds = identity.get("parameters"), identity.get("columns"), identity.get("bounds")
    if not _pairs(parameters, str):
        return f"parameters: got {parameters!r:.80}; expected a list of [name, key] pairs"
    if not (isinstance(columns, list) and columns and all(isinstance(c, str) for c in columns)):
        return f"columns: got {columns!r:.80}; expected a list of statistic names"
    if not _pairs(bounds, (int, float)) or len(bounds) != len(parameters) or not all(
            math.isfinite(a) and math.isfinite(b) and a < b for a, b in bounds):
        return f"bounds: got {bounds!r:.80}; expected one finite [low, high] pair per parameter"
    for key in ("transforms", "measurement"):
        if identity.get(key) is not None and not isinstance(identity[key], dict):
            return f"{key}: got {identity[key]!r:.80}; expected an object"
    transforms = identity.get("transforms") or {}
    for name, entry in transforms.items():
        if not (isinstance(entry, dict) and isinstance(entry.get("transform"), str)
                and isinstance(entry.get("range"), list) and len(entry["range"]) == 2
                and all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) for v in entry["range"])):
            return f"transforms.{name}: got {entry!r:.80}; expected {{transform, range: [low, high]}}"
    measurement = identity.get("measurement") or {}
    for key, kinds in MEASUREMENT.items():
        value = measurement.get(key)
        if identity.get("measurement") is not None and key not in measurement:
            return f"measurement: no {key}"
        if key in measurement and not (isinstance(value, kinds) and not isinstance(value, bool)):
            return f"measurement.{key}: got {value!r:.40}"
    rounds = identity.get("rounds", 1)
    if not ((isinstance(rounds, int) and not isinstance(rounds, bool) and rounds >= 1) or rounds == "sequential"):
        return f"rounds: got {rounds!r:.40}; expected an integer >= 1"
    return ""


def set_aside(root, where, reason: str) -> Path | None:
    """Move the estimator folder ``where`` (inside ``root``) to ``root/quarantine/`` with a warning."""
    where = Path(where)
    if not where.exists():
        return None
    return quarantine(root, where, reason)
