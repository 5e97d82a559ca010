"""``flocksweep export``'s quick path: the runs table read with pyarrow alone (no pandas) and written as
CSV or Parquet byte for byte as the pandas path (:func:`sweeps.export.export_with_pandas`) writes it.

``runs_csv(root, path, with_fixed)`` and ``runs_parquet(root, path, with_fixed)`` write ``root``'s runs
table like ``load_results(root, with_fixed).runs.drop(columns="part").to_csv(path, index=False)`` (or
``.to_parquet(path, index=False)``), atomically (:mod:`sweeps.files`), and return ``(path, rows,
columns)``; or they return None, having written nothing, when they cannot vouch for the same result, and
the caller takes the pandas path, which reads, verifies and warns as it always did.

They go ahead only when the checks the pandas path makes pass without a word
(:func:`sweeps.checksums.intact`): ``manifest.json`` carries its own valid checksum and records those of
``design.parquet`` and ``runs.parquet``, which both still have them (so both are exactly as flocksweep
wrote them: readable, the runs table consolidated). A missing, changed or unrecorded file, an edited
manifest, a folder from before checksums, or a runs table never consolidated (an interrupted sweep) take
the pandas path, with its warnings.

CSV: every column must have a type whose CSV text is known (float64, integers, booleans, text,
all-null). The text of a cell is what pandas writes for the column ``pd.read_parquet`` makes of it: a
float ``repr`` (shortest round trip, as numpy's), an integer's digits (an integer column with nulls is a
float column in pandas: ``6.0``), ``True``/``False``, text as is, and an empty field for a null or a NaN;
a fixed setting's column (``--with-fixed``) has the cells pandas gives a column of that one value. Rows
go in design order (stable by ``index``) and through :mod:`csv` with the dialect ``DataFrame.to_csv``
uses (``,``, ``"`` doubled, quoted only when needed, ``\\n``).

Parquet: pandas stores its own description of the frame in the file (the ``pandas`` schema metadata:
every column's dtype, the pandas and pyarrow versions), so the table is written again only when that
description is one this code can reproduce: written by the pandas and pyarrow installed now, in design
order, every column of a kind pandas reads and writes back unchanged (``PANDAS_COLUMNS``: float64, int64,
bool, its text, all-null; text it wrote from Python objects comes back as its text type,
``PANDAS_REWRITES``). The metadata is then the stored one without ``part`` and with the fixed columns
pandas would add; the data pass through Arrow untouched. Anything else takes the pandas path.

``tests/sweeps/test_quick_export.py`` compares both paths byte for byte.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from .checksums import intact
from .files import atomic_path, read_json


def stored_runs(root):
    """The runs table ``runs.parquet`` of ``root`` as an Arrow table, when the manifest vouches for it and
    for ``design.parquet`` (see the module docstring); else None."""
    if not intact(root, "design.parquet", "runs.parquet"):
        return None
    import pyarrow.parquet as pq   # only here; ParquetFile (not read_table) leaves pyarrow.dataset and pandas out

    return pq.ParquetFile(Path(root) / "runs.parquet").read()


def fixed_columns(root, table) -> dict:
    """The ``--with-fixed`` columns of ``root`` ({dotted key: value}, :mod:`sweeps.fixed_settings`) that the
    stored runs ``table`` lacks (``part`` included, as :func:`sweeps.results.load_results` adds them)."""
    from .fixed_settings import fixed_settings   # the presets' code: only for --with-fixed

    stored = set(table.column_names)
    return {k: v for k, v in fixed_settings(read_json(Path(root) / "model.json", {})).items() if k not in stored}


def runs_csv(root, path, with_fixed: bool = False) -> tuple[Path, int, int] | None:
    """Write the runs table of ``root`` as CSV at ``path`` (see the module docstring), or return None."""
    table = stored_runs(root)
    if table is None:
        return None
    columns = {name: _cells(table.column(name)) for name in table.column_names if name != "part"}
    if any(cells is None for cells in columns.values()):
        return None
    order = _design_order(table)
    if order is None:
        return None
    for name, value in (fixed_columns(root, table) if with_fixed else {}).items():
        columns[name] = [_fixed_cell(value)] * table.num_rows
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


# (Arrow type, pandas_type, numpy_type) of the columns pandas writes for the dtypes a runs table has
PANDAS_COLUMNS = {("double", "float64", "float64"), ("int64", "int64", "int64"), ("bool", "bool", "bool"),
                  ("large_string", "object", "str"), ("null", "empty", "object")}
# ... and what pandas writes back for a text column it wrote from Python objects (None among the text)
PANDAS_REWRITES = {("string", "unicode", "object"): ("large_string", "object", "str")}
PANDAS_KEYS = ["index_columns", "column_indexes", "columns", "attributes", "creator", "pandas_version"]


def runs_parquet(root, path, with_fixed: bool = False) -> tuple[Path, int, int] | None:
    """Write the runs table of ``root`` as Parquet at ``path``, byte for byte as the pandas path's
    ``to_parquet(index=False)`` (see the module docstring), or return None."""
    table = stored_runs(root)
    if table is None or _design_order(table) != list(range(table.num_rows)):
        return None
    from importlib.metadata import version

    import pyarrow as pa
    import pyarrow.parquet as pq

    meta = _pandas_metadata(table, pa.__version__, version("pandas"))
    stored = None if meta is None else _stored_columns(pa, table, meta)
    if stored is None:
        return None
    entries, columns = stored
    for name, value in (fixed_columns(root, table) if with_fixed else {}).items():
        kind = _fixed_kind(value)
        if kind is None or not table.num_rows:
            return None
        columns[name] = _constant(pa, value, kind[0], table.num_rows)
        entries.append({"name": name, "field_name": name, "pandas_type": kind[1], "numpy_type": kind[2],
                        "metadata": None})
    out = pa.table(columns).combine_chunks().replace_schema_metadata(
        {b"pandas": json.dumps({**meta, "columns": entries}).encode()})
    with atomic_path(path) as tmp:
        pq.write_table(out, tmp, compression="snappy")
    return Path(path), out.num_rows, out.num_columns


def _pandas_metadata(table, pyarrow_version: str, pandas_version: str) -> dict | None:
    """The ``pandas`` schema metadata of the stored ``table`` when the pyarrow and pandas installed now
    wrote it (None otherwise: only pandas itself knows what another version writes)."""
    import json

    raw = (table.schema.metadata or {}).get(b"pandas")
    meta = json.loads(raw) if raw else None
    same_writer = (isinstance(meta, dict) and list(meta) == PANDAS_KEYS and meta["index_columns"] == []
                   and meta["creator"] == {"library": "pyarrow", "version": pyarrow_version}
                   and meta["pandas_version"] == pandas_version and not meta["attributes"])
    return meta if same_writer and [c.get("name") for c in meta["columns"]] == table.column_names else None


def _stored_columns(pa, table, meta: dict) -> tuple[list, dict] | None:
    """The metadata entries and Arrow columns pandas would write back for the stored table but ``part``
    (None when a column is of a kind it might change)."""
    entries, columns = [], {}
    for entry in (c for c in meta["columns"] if c["name"] != "part"):
        column = table.column(entry["name"])
        kind = PANDAS_REWRITES.get((str(column.type), entry.get("pandas_type"), entry.get("numpy_type")))
        if kind is not None:
            column = _large_text(pa, column)
            entry = {**entry, "pandas_type": kind[1], "numpy_type": kind[2]}
        if not _pandas_column(column, entry):
            return None
        entries.append(entry)
        columns[entry["name"]] = column
    return entries, columns


def _pandas_column(column, entry: dict) -> bool:
    """Whether pandas reads the stored ``column`` (its metadata ``entry``) and writes it back unchanged."""
    kind = (str(column.type), entry.get("pandas_type"), entry.get("numpy_type"))
    return kind in PANDAS_COLUMNS and entry.get("metadata") is None


def _large_text(pa, column):
    """A ``string`` column as ``large_string`` (64-bit offsets), from its buffers (a cast would load
    pyarrow.compute)."""
    from array import array

    chunks = []
    for chunk in column.chunks:
        validity, offsets, data = chunk.buffers()
        wide = array("q", memoryview(offsets).cast("i")[:chunk.offset + len(chunk) + 1])
        chunks.append(pa.Array.from_buffers(pa.large_string(), len(chunk), [validity, pa.py_buffer(wide), data],
                                            chunk.null_count, chunk.offset))
    return pa.chunked_array(chunks, pa.large_string())


def _constant(pa, value, kind: str, rows: int):
    """An Arrow array of ``rows`` times ``value`` of type ``kind``, built from its buffers (``pa.array`` of
    Python values would import pandas)."""
    from array import array

    if kind == "null":
        return pa.nulls(rows)
    if kind == "large_string":
        text = value.encode("utf-8")
        offsets = array("q", range(0, (rows + 1) * len(text), len(text))) if text else array("q", [0]) * (rows + 1)
        buffers = [None, pa.py_buffer(offsets), pa.py_buffer(text * rows)]
    elif kind == "bool_":
        buffers = [None, pa.py_buffer((b"\xff" if value else b"\x00") * ((rows + 7) // 8))]
    else:
        buffers = [None, pa.py_buffer(array("d" if kind == "float64" else "q", [value]) * rows)]
    return pa.Array.from_buffers(getattr(pa, kind)(), rows, buffers)


def _fixed_kind(value) -> tuple[str, str, str] | None:
    """(Arrow type, pandas_type, numpy_type) of the column pandas makes of ``value`` repeated, or None."""
    if value is None:
        return ("null", "empty", "object")
    if isinstance(value, bool):
        return ("bool_", "bool", "bool")
    if isinstance(value, int):
        return ("int64", "int64", "int64") if -2**63 <= value < 2**63 else None
    if isinstance(value, float):
        return ("float64", "float64", "float64")
    return ("large_string", "object", "str") if isinstance(value, str) else None
