"""The claims of a stored sweep: ``claims_of(results, files=()) -> (claims, columns, skipped)``.

The claims a sweep declared (``sweep.effective.json["claims"]``, its includes written out when it ran)
followed by those of ``files`` (claims files or sweep files, e.g. ``flocksweep report --claims``), all
validated against the stored design and metric columns (:func:`sweeps.claims.table_columns`).
``columns.factors`` are the columns that identify a design point (what :func:`.evaluate.evaluate` takes
as ``factors``). A stored claim that no longer validates (e.g. results computed before a metric it
names existed: their runs are done, so they keep their old columns until rerun with ``--force``) is
left out and listed in ``skipped`` as (id, reason); a claim of ``files`` that does not validate, or an
id used twice, is a :class:`~simcore.schema.ConfigError`.
"""
from __future__ import annotations

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.claims import claims_from_records, read_claims_file, table_columns
from flocksweep.sweeps.config import RESERVED_COLUMNS


def claims_of(results, files=()) -> tuple[tuple, object, list]:
    columns = table_columns(results.design, results.metrics, RESERVED_COLUMNS)
    claims, skipped = [], []
    for record in results.sweep.get("claims", []):
        try:
            claims += claims_from_records([record], columns)
        except ConfigError as err:
            skipped.append((record.get("id", "?"), str(err)))
    seen = {c.id: "the sweep file" for c in claims}
    for path in files:
        for claim in read_claims_file(path, columns):
            if claim.id in seen:
                raise ConfigError(f"{path}: claims.{claim.id}", f"claim id {claim.id!r} is also declared in "
                                                                  f"{seen[claim.id]}; ids must be unique")
            seen[claim.id] = str(path)
            claims.append(claim)
    return tuple(claims), columns, skipped
