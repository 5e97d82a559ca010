"""``flocksweep export --csv``'s quick path: the runs table read with pyarrow alone (no pandas) and written
as CSV byte for byte as the pandas path (:func:`sweeps.export.export_results`) writes it.

``runs_csv(root, path, with_fixed) -> (path, rows, columns) | None`` writes ``root``'s runs table like
``load_results(root, with_fixed).runs.drop(columns="part").to_csv(path, index=False)`` (atomically,
:mod:`sweeps.files`), or returns None, having written nothing, when it cannot vouch for the same
result; the caller then takes the pandas path, which reads, verifies and warns as it always did.

It goes ahead only when the checks the pandas path makes can pass without a word
(:func:`sweeps.checksums.intact`): ``manifest.json`` carries its own valid checksum and records those of
``design.parquet`` and ``runs.parquet``, which both still have them (so both are exactly as flocksweep
wrote them: readable, the runs table consolidated and in design order), and every column of the runs
table has a type whose CSV text it knows (float64, integers, booleans, text, all-null). A missing,
changed or unrecorded file, an edited manifest, a folder from before checksums, or a runs table never
consolidated (an interrupted sweep) take the pandas path, with its warnings.

The text of a cell is what pandas writes for the column ``pd.read_parquet`` makes of it: a float
``repr`` (shortest round trip, as numpy's), an integer's digits (an integer column with nulls is a
float column in pandas: ``6.0``), ``True``/``False``, text as is, and an empty field for a null or a
NaN; a fixed setting's column (``--with-fixed``) has the cells pandas gives a column of that one value.
Rows and quoting go through :mod:`csv` with the dialect ``DataFrame.to_csv`` uses (``,``, ``"``
doubled, quoted only when needed, ``\\n``). ``tests/sweeps/test_quick_export.py`` compares both paths.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

from .checksums import intact
from .files import atomic_path, read_json


def runs_csv(root, path, with_fixed: bool = False) -> tuple[Path, int, int] | None:
    """Write the runs table of ``root`` as CSV at ``path`` (see the module docstring), or return None."""
    root = Path(root)
    if not intact(root, "design.parquet", "runs.parquet"):
        return None
    import pyarrow.parquet as pq   # only here; ParquetFile (not read_table) leaves pyarrow.dataset and pandas out

    table = pq.ParquetFile(root / "runs.parquet").read()
    columns = {name: _cells(table.column(name)) for name in table.column_names if name != "part"}
    if any(cells is None for cells in columns.values()):
        return None
    order = _design_order(table)
    if order is None:
        return None
    if with_fixed:
        from .fixed_settings import fixed_settings   # the presets' code: only for --with-fixed

        for name, value in fixed_settings(read_json(root / "model.json", {})).items():
            columns.setdefault(name, [_fixed_cell(value)] * table.num_rows)
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle, lineterminator="\n", delimiter=",", quotechar='"', doublequote=True,
                            quoting=csv.QUOTE_MINIMAL)
        writer.writerow(list(columns))
        writer.writerows(zip(*([cells[k] for k in order] for cells in columns.values())))
    return Path(path), table.num_rows, len(columns)


def _design_order(table) -> list[int] | None:
    """Row positions sorted by ``index`` (stable, as the pandas path sorts), or None for an index with nulls."""
    if "index" not in table.column_names:
        return list(range(table.num_rows))
    index = table.column("index").to_pylist()
    if any(value is None or (isinstance(value, float) and math.isnan(value)) for value in index):
        return None
    return sorted(range(len(index)), key=index.__getitem__)


def _cells(column) -> list[str] | None:
    """The CSV text of each cell of an Arrow column as pandas writes it, or None for a type it does not know."""
    import pyarrow.types as kind

    values = column.to_pylist()
    if kind.is_float64(column.type) or (kind.is_integer(column.type) and column.null_count):
        return ["" if v is None or math.isnan(v) else repr(float(v)) for v in values]
    if kind.is_integer(column.type):
        return [str(v) for v in values]
    if kind.is_boolean(column.type):
        return ["" if v is None else str(v) for v in values]
    if kind.is_string(column.type) or kind.is_large_string(column.type) or kind.is_null(column.type):
        return ["" if v is None else v for v in values]
    return None


def _fixed_cell(value) -> str:
    """The CSV text pandas writes for a column holding ``value`` in every row (a fixed setting)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)
