"""The output of every tracker, as ``rangekit track`` writes it: CSV, an aligned table or JSON.

A tracker returns a ``(columns, rows)`` table (``track_rows`` of
:mod:`rangekit.localize.range_ekf`, :mod:`~rangekit.localize.anchor_ekf`,
:mod:`~rangekit.localize.particle`, ...). :func:`track_table` turns its rows into Python
values (whole numbers for the id columns of :data:`INT_COLUMNS`, None for NaN: an empty
cell, JSON null); :func:`format_track` writes them:

- ``csv``: a header row and one row per epoch (:func:`rangekit.io.csvlog.write_table`:
  floats round-trip exactly, empty cells for missing values);
- ``table``: aligned columns with the number rules of every verb's tables
  (:func:`rangekit.io.results.format_rows`);
- ``json``: one object ``{"filter", "log", "smoothed", "columns", "rows", ...}`` with the
  tracker's further keys (``extra``) after them.

Examples
--------
>>> cols, rows = ("t_s", "x_m", "target"), [[0.0, 1.25, 0.0], [1.0, float("nan"), 1.0]]
>>> track_table(cols, rows)
[[0.0, 1.25, 0], [1.0, None, 1]]
>>> print(format_track(cols, rows, "csv", filter_name="lmax", log="fixes.csv"), end="")
t_s,x_m,target
0.0,1.25,0
1.0,,1
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

from rangekit.errors import InvalidParameterError

__all__ = ["FORMATS", "INT_COLUMNS", "format_track", "track_table"]

#: The formats of :func:`format_track`.
FORMATS = ("table", "json", "csv")

#: Track columns that hold whole numbers (written as integers).
INT_COLUMNS = frozenset({"target", "status", "n_particles", "n_hypotheses"})


def _row(columns: Sequence[str], values) -> list:
    out = []
    for c, v in zip(columns, values, strict=True):
        f = float(v)
        if not math.isfinite(f):
            out.append(None)
        elif c in INT_COLUMNS:
            out.append(int(f))
        else:
            out.append(f)
    return out


def track_table(columns: Sequence[str], rows) -> list[list]:
    """The rows (numbers, or an array of shape (n, len(columns))) as Python values: ints
    in :data:`INT_COLUMNS`, None for NaN and infinities, floats elsewhere."""
    return [_row(columns, r) for r in rows]


def format_track(
    columns: Sequence[str],
    rows,
    fmt: str,
    *,
    filter_name: str,
    log: str,
    smoothed: bool = False,
    extra: dict | None = None,
) -> str:
    """A track as text in ``fmt`` (``"csv"``, ``"table"`` or ``"json"``).

    Parameters
    ----------
    columns, rows
        The tracker's table (one row per epoch, and target).
    fmt : {"csv", "table", "json"}
    filter_name, log, smoothed, extra
        JSON only: the filter's name, the input log's name, whether the track is the
        smoothed one, and further keys (the tracker's diagnostics).
    """
    table = track_table(columns, rows)
    if fmt == "csv":
        from rangekit.io.csvlog import write_table

        return write_table(columns, table)
    if fmt == "table":  # aligned, with the number rules of every verb's tables
        from rangekit.io.results import format_rows

        return format_rows([dict(zip(columns, r, strict=True)) for r in table], columns, "table")
    if fmt != "json":
        raise InvalidParameterError(f"fmt={fmt!r} must be one of {', '.join(FORMATS)}")
    obj = {
        "filter": filter_name,
        "log": str(log),
        "smoothed": bool(smoothed),
        "columns": list(columns),
        "rows": table,
        **(extra or {}),
    }
    return json.dumps(obj, indent=2) + "\n"
