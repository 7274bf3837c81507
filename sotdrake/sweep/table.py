"""The table of a sweep: one row per case, its parameters then its summary.

Columns: ``case`` (index in the list of cases), the parameters, ``status`` (``ok`` or ``error``),
``error`` (``"ExceptionType: message"``, empty when ok), then the summary's keys. Nested summary
dicts are flattened with dots (``{'a': {'b': 1}}`` → ``a.b``); lists and other non-scalar values
are written as JSON text. Rows are sorted by ``case`` and the columns appear in the order they are
first met along the sorted rows, so the same results give the same table whatever the engine and
the order in which cases finished. Nothing here measures time: timings belong to the sweep's
``sweep.json``, never to the compared table.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..exceptions import InvalidInput

RESERVED = ("case", "status", "error")


Cell = bool | int | float | str | None
"""A table cell: a scalar, or JSON text for anything else."""


def _cell(value) -> Cell:
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, np.ndarray):
        value = value.tolist()
    return json.dumps(value, sort_keys=True, default=str)


def flatten(summary: Mapping, prefix: str = "") -> dict[str, Cell]:
    """``summary`` with nested mappings flattened to dotted keys and every value a table cell."""
    flat: dict[str, Cell] = {}
    for key, value in summary.items():
        name = f"{prefix}{key}"
        for flat_name, cell in (flatten(value, f"{name}.") if isinstance(value, Mapping) else {name: _cell(value)}).items():
            if flat_name in flat:  # ({"a.b": 1, "a": {"b": 2}}: one column, two values)
                raise InvalidInput(f"summary: two values for the column {flat_name!r} (a dotted key and a nested one)")
            flat[flat_name] = cell
    return flat


def check_parameter_name(name: object, where: str) -> str:
    """``name`` if it can name a case parameter (a column): a non-empty string, not a reserved column."""
    if not isinstance(name, str) or not name:
        raise InvalidInput(f"{where}: parameter names are non-empty strings, got {name!r:.60}")
    if name in RESERVED:
        raise InvalidInput(f"{where}: a case parameter cannot be named {name!r} (reserved columns: {RESERVED})")
    return name


def make_row(index: int, case: Mapping, summary: Mapping | None, error: str = "") -> dict[str, Cell]:
    """The row of case ``index``: its parameters, status, error and flattened ``summary``.
    A summary key that repeats a parameter or a reserved column is prefixed with ``summary.``;
    when that prefixed column is taken too (``{'x': 2, 'summary': {'x': 3}}`` with a parameter
    ``x``), no value is dropped: :class:`InvalidInput` naming both keys (in a sweep, the case
    becomes an error row)."""
    row: dict[str, Cell] = {"case": int(index)}
    for name, value in case.items():
        row[check_parameter_name(name, "a case")] = _cell(value)
    row["status"] = "error" if error else "ok"
    row["error"] = error
    flat = flatten(summary or {})
    for key, value in flat.items():
        column = key
        if key in row:
            column = f"summary.{key}"
            if column in flat or column in row:
                raise InvalidInput(f"summary: the key {key!r} repeats a column of the case ({column!r} would hold it) "
                                   f"and {column!r} is taken too: rename one of them")
        row[column] = value
    return row


def columns(rows: Sequence[Mapping]) -> list[str]:
    """The columns of ``rows`` (sorted by case) in the order they first appear."""
    seen: dict[str, None] = {}
    for row in sorted(rows, key=lambda r: r["case"]):
        seen.update(dict.fromkeys(row))
    return list(seen)


def _text(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def write_csv(rows: Sequence[Mapping], path: Path) -> Path:
    """Write ``rows`` sorted by case; floats with ``repr`` (every digit), missing cells empty."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = columns(rows)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream, lineterminator="\n")
        writer.writerow(names)
        for row in sorted(rows, key=lambda r: r["case"]):
            writer.writerow([_text(row.get(name)) for name in names])
    return path


def write_parquet(rows: Sequence[Mapping], path: Path) -> Path | None:
    """Write ``rows`` as Parquet if ``pyarrow`` is installed; returns None without it."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return None
    names = columns(rows)
    ordered = sorted(rows, key=lambda r: r["case"])
    data = {}
    for name in names:
        values = [row.get(name) for row in ordered]
        kinds = {type(v) for v in values if v is not None}
        if kinds <= {int, float} and kinds != {int} and kinds:
            values = [None if v is None else float(v) for v in values]
        elif len(kinds) > 1:  # mixed kinds (e.g. a number here, a text there): all as text
            values = [None if v is None else _text(v) for v in values]
        data[name] = values
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(data), path)
    return path


def read_csv(path: Path) -> list[dict[str, str]]:
    """The rows of a table written by :func:`write_csv`, every cell as its text."""
    with Path(path).open(newline="") as stream:
        return list(csv.DictReader(stream))
