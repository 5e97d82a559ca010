"""Output folders that are rebuilt (a report): only files we wrote are ever deleted.

``OwnedFolder(root, marker, flag="--out", adopt=False)`` is a folder a command fills and, on a later
build, refreshes. ``claim()`` (before anything is written) refuses, with a ConfigError at ``flag``, a
folder that exists, is not empty and holds no ``marker`` file, i.e. one we did not write, unless ``adopt``
(the command's default location, which it owns by convention: nothing found there is deleted, files of
the same name are overwritten). ``stale(patterns)`` lists the files the previous build recorded that
match the glob patterns, to be removed before this build writes its own; ``finish()`` records in the
marker every file that appeared or changed since ``claim()`` plus the previous build's files still
there, so the next build removes exactly those. Files that were in the folder and were not ours are
never listed and never removed.

A build can be stopped half-way (Ctrl-C, SIGTERM, SIGKILL, a full disk): ``claim()`` therefore writes the
marker at once, listing the files that were not ours (``foreign``) and the previous build's, before the
build writes anything. The same command run again finds that marker: the files that appeared since (the
stopped build's) are ours, the recorded foreign ones are still not.
"""
from __future__ import annotations

import json
from pathlib import Path

from flocksweep.simcore.schema import ConfigError

from .files import write_json


class OwnedFolder:
    def __init__(self, root, marker: str, flag: str = "--out", adopt: bool = False):
        self.root, self.marker, self.flag, self.adopt = Path(root), marker, flag, adopt
        self.previous: set[str] = set()
        self.foreign: set[str] = set()

    def _files(self) -> dict[str, tuple[int, int]]:
        if not self.root.is_dir():
            return {}
        return {p.relative_to(self.root).as_posix(): (p.stat().st_mtime_ns, p.stat().st_size)
                for p in self.root.rglob("*") if p.is_file() and p.name != self.marker}

    def claim(self) -> "OwnedFolder":
        """Check the folder may be written (see the module docstring) and note what is in it."""
        if self.root.exists() and not self.root.is_dir():
            raise ConfigError(self.flag, f"{self.root} is a file; expected a folder")
        marker = self.root / self.marker
        before = self._files()
        if marker.is_file():
            record = _record(marker)
            self.previous = set(record.get("files", []))
            if "foreign" in record:   # a build was stopped half-way: what appeared since is its work
                self.previous |= set(before) - set(record["foreign"])
        elif before and not self.adopt:
            raise ConfigError(self.flag, f"{self.root} is not empty and was not written by flocksweep; choose a new "
                                         "or empty folder (nothing was written, nothing deleted)")
        self.foreign = set(before) - self.previous
        self._before = before
        write_json(marker, {"files": sorted(self.previous), "foreign": sorted(self.foreign)})
        return self

    def stale(self, patterns) -> list[Path]:
        """Files of the previous build that match any glob pattern (relative to the folder)."""
        return sorted(self.root / name for name in self.previous
                      if any(Path(name).match(pattern) for pattern in patterns) and (self.root / name).is_file())

    def finish(self) -> None:
        """Record the files this build wrote (and the previous build's still present) in the marker."""
        now = self._files()
        ours = {name for name, stamp in now.items()
                if name not in self.foreign or self._before.get(name) != stamp}
        write_json(self.root / self.marker, {"files": sorted(ours)})


def _record(marker: Path) -> dict:
    """The marker's record ({} when damaged: delete nothing, record afresh)."""
    try:
        record = json.loads(marker.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError, OSError):
        return {}
    if not isinstance(record, dict) or not all(isinstance(record.get(k, []), list) for k in ("files", "foreign")):
        return {}
    return {k: [str(x) for x in v] for k, v in record.items() if k in ("files", "foreign")}
