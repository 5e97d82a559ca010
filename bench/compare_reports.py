"""Two report folders, file by file: does a change to the report's code change what it says?

    python bench/compare_reports.py BEFORE_DIR AFTER_DIR

Every file of either folder is compared: text files (report.md, report.html, tables/*.csv, the viewer
pages, .flocksweep-report.json) byte for byte; SVG figures after dropping what differs between any two
saves (the date and matplotlib's random ids); PNG figures byte for byte, and when they differ, by their
decoded pixels (size, and the share of pixels that differ). Prints one line per differing file and exits
1 if any differ (0: the two reports are identical).
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

_SVG_DATE = re.compile(rb"<dc:date>[^<]*</dc:date>")
_SVG_ID = re.compile(rb"\b(p|image|m|c|t|h)[0-9a-f]{10}\b")


def _svg(data: bytes) -> bytes:
    ids = {}
    data = _SVG_DATE.sub(b"", data)
    return _SVG_ID.sub(lambda m: ids.setdefault(m.group(0), b"id%d" % len(ids)), data)


def _png_difference(a: Path, b: Path) -> str:
    import numpy as np
    from PIL import Image

    pa, pb = np.asarray(Image.open(a).convert("RGBA")), np.asarray(Image.open(b).convert("RGBA"))
    if pa.shape != pb.shape:
        return f"size {pa.shape[1]}x{pa.shape[0]} -> {pb.shape[1]}x{pb.shape[0]}"
    share = float((pa != pb).any(axis=2).mean())
    return f"same size, {share:.2%} of pixels differ" if share else "same pixels (different bytes)"


def compare(before: Path, after: Path) -> list[str]:
    names = sorted({p.relative_to(before) for p in before.rglob("*") if p.is_file()}
                   | {p.relative_to(after) for p in after.rglob("*") if p.is_file()})
    out = []
    for name in names:
        a, b = before / name, after / name
        if not a.exists() or not b.exists():
            out.append(f"{name}: only in {'after' if not a.exists() else 'before'}")
            continue
        da, db = a.read_bytes(), b.read_bytes()
        if name.suffix == ".svg":
            da, db = _svg(da), _svg(db)
        if da == db:
            continue
        out.append(f"{name}: {_png_difference(a, b)}" if name.suffix == ".png" else f"{name}: differs")
    return out


def main() -> None:
    before, after = Path(sys.argv[1]), Path(sys.argv[2])
    found = compare(before, after)
    for line in found:
        print(line)
    print(f"{len(found)} file(s) differ" if found else "identical: every file (SVG up to its date and ids)")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
