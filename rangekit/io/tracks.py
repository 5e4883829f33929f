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

:class:`TrackReport` is one run as ``rangekit track`` reports it: the table, the JSON
keys after it, the one-line summary, the warnings and the parameters used (each
tracker's ``track_report`` builds it: :func:`rangekit.localize.duhl.track_report`,
:func:`rangekit.localize.range_ekf.track_report`, ...), so that the command only prints
it.

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
from dataclasses import dataclass, field
from typing import Any

from rangekit.errors import InvalidParameterError

__all__ = ["FORMATS", "INT_COLUMNS", "TrackReport", "format_track", "track_table"]

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


@dataclass(frozen=True)
class TrackReport:
    """One tracker run as ``rangekit track`` reports it.

    Attributes
    ----------
    filter_name : str
        The filter (the subcommand's name, e.g. ``"duhl-ranges"``).
    log : str
        The input log's name.
    columns, rows
        The track table (``track_rows`` of the tracker).
    smoothed : bool
        Whether the rows are the smoothed track.
    extra : dict
        The JSON keys after ``rows`` (the tracker's diagnostics), in order.
    summary : str or None
        One line about the run (the command prints it on stderr unless ``--quiet``).
    warnings : tuple of str
        Plain-language warnings (printed on stderr, ``warning: `` first).
    parameters : dict
        The parameters used, the library's defaults filled in (printed by ``--verbose``
        as :meth:`parameters_text`).

    Examples
    --------
    >>> import json
    >>> r = TrackReport("lmax", "fixes.csv", ("t_s", "x_m"), [[0.0, 1.5]], extra={"n": 1})
    >>> print(r.format("csv"), end="")
    t_s,x_m
    0.0,1.5
    >>> json.loads(r.format("json"))["n"]
    1
    >>> TrackReport("lmax", "f.csv", (), [], parameters={"gate": None, "mounts_deg": (90.0, -90.0)}
    ...             ).parameters_text()
    'gate none, mounts_deg 90,-90'
    """

    filter_name: str
    log: str
    columns: Sequence[str]
    rows: Any
    smoothed: bool = False
    extra: dict = field(default_factory=dict)
    summary: str | None = None
    warnings: tuple[str, ...] = ()
    parameters: dict = field(default_factory=dict)

    def format(self, fmt: str) -> str:
        """The track as text in ``fmt`` (:func:`format_track`)."""
        return format_track(
            self.columns,
            self.rows,
            fmt,
            filter_name=self.filter_name,
            log=self.log,
            smoothed=self.smoothed,
            extra=self.extra,
        )

    def parameters_text(self) -> str:
        """The parameters as ``name value, ...``, each value as every line for people
        writes one (:func:`rangekit.io.results.format_value`)."""
        from rangekit.io.results import format_value

        return ", ".join(f"{k} {format_value(v)}" for k, v in self.parameters.items())
