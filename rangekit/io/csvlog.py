"""Reading and writing the CSV logs that the trackers consume (measurement, step, IMU logs).

One reader serves every log format: it checks the header against the format's required
and optional columns, parses numbers, and raises :class:`~rangekit.errors.LogFormatError`
naming the file, the row (1-based, the header is row 1) and the column of the first
problem. Formats themselves (which columns, which may be empty) are declared by the
modules that use them and documented in ``docs/formats.md``.

Examples
--------
>>> import io
>>> spec = {"t_s": Column(kind="time"), "range_m": Column(nonneg=True, empty_ok=True)}
>>> table = read_table(io.StringIO("t_s,range_m\\n0.0,1.5\\n0.5,\\n"), spec, name="log.csv")
>>> table["t_s"].tolist(), table["range_m"].tolist()
([0.0, 0.5], [1.5, nan])
>>> read_table(io.StringIO("t_s,range_m\\n1.0,2\\n0.5,1\\n"), spec, name="log.csv")
Traceback (most recent call last):
...
rangekit.errors.LogFormatError: log.csv row 3, column 't_s': time 0.5 goes backwards (previous 1)
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from rangekit.errors import InputFileError, LogFormatError

__all__ = ["Column", "read_table", "read_text", "write_table"]


@dataclass(frozen=True)
class Column:
    """How one CSV column is parsed and checked.

    Parameters
    ----------
    kind : {"float", "time", "int", "str"}
        ``"time"`` is a float that must not decrease from row to row.
    required : bool
        The header must contain the column (default True).
    empty_ok : bool
        An empty cell is allowed and read as NaN (floats) or -1 (ints) or "" (str).
    nonneg : bool
        Values must be >= 0 (sigmas, variances, ranges).
    """

    kind: str = "float"
    required: bool = True
    empty_ok: bool = False
    nonneg: bool = False


def _where(name: str, row: int, col: str) -> str:
    return f"{name} row {row}, column {col!r}"


def _parse(cell: str, spec: Column, name: str, row: int, col: str):
    cell = cell.strip()
    if cell == "":
        if not spec.empty_ok:
            raise LogFormatError(f"{_where(name, row, col)}: empty cell (a value is required)")
        return {"int": -1, "str": ""}.get(spec.kind, math.nan)
    if spec.kind == "str":
        return cell
    try:
        v = int(cell) if spec.kind == "int" else float(cell)
    except ValueError:
        what = "an integer" if spec.kind == "int" else "a number"
        raise LogFormatError(f"{_where(name, row, col)}: {cell!r} is not {what}") from None
    if spec.kind != "int" and not math.isfinite(v):
        hint = " (leave the cell empty for 'no value')" if spec.empty_ok else ""
        raise LogFormatError(f"{_where(name, row, col)}: {cell!r} is not finite{hint}")
    if spec.nonneg and v < 0:
        raise LogFormatError(f"{_where(name, row, col)}: {cell} is negative")
    return v


def read_table(
    source: str | os.PathLike | IO[str],
    columns: Mapping[str, Column],
    *,
    name: str | None = None,
    allow_extra: bool = True,
) -> dict[str, np.ndarray]:
    """Read a CSV log into one array per declared column, validating every cell.

    Parameters
    ----------
    source : path or text stream
        The CSV file. Lines starting with ``#`` are comments; the first other line is the
        header.
    columns : mapping of str to Column
        The format: column name -> parsing rule. Optional columns missing from the
        header are returned filled with NaN (or -1 / "").
    name : str, optional
        How the file is named in error messages (default: the path).
    allow_extra : bool
        Accept (and ignore) columns not in ``columns`` (default True).

    Returns
    -------
    dict of str to ndarray
        float64 arrays for float and time columns, int64 for int, object for str; all of
        length equal to the number of data rows.

    Raises
    ------
    InputFileError
        The file cannot be opened.
    LogFormatError
        Missing required column, unknown column (``allow_extra=False``), a row with the
        wrong number of cells, a cell that does not parse or breaks its rule, or a time
        column that decreases. The message names the row and column.
    """
    if hasattr(source, "read"):
        label = name or getattr(source, "name", "<stream>")
        return _read(source, columns, label, allow_extra)
    label, text = read_text(source, name=name)
    return _read(io.StringIO(text, newline=""), columns, label, allow_extra)


def read_text(source: str | os.PathLike | IO[str], *, name: str | None = None) -> tuple[str, str]:
    """``(label, text)`` of a CSV log: a path read through the guarded reader (a regular
    file, at most ``MAX_TABLE_BYTES``, UTF-8 with or without a BOM), or a text stream.

    Raises
    ------
    InputFileError
        The file cannot be opened (the message names ``name``, default the path).
    LogFormatError
        Not UTF-8 text.
    """
    if hasattr(source, "read"):
        return name or getattr(source, "name", "<stream>"), source.read()
    from rangekit.io.guard import MAX_TABLE_BYTES, read_capped

    path = Path(source)
    label = name or str(path)
    try:
        data = read_capped(path, MAX_TABLE_BYTES)
    except InputFileError as e:
        raise InputFileError(str(e).replace(f"'{path}'", repr(label), 1)) from None
    try:
        return label, data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise LogFormatError(f"{label}: not a UTF-8 text CSV file") from None


def _read(fh: IO[str], columns: Mapping[str, Column], name: str, allow_extra: bool):
    try:
        return _read_rows(fh, columns, name, allow_extra)
    except csv.Error as e:  # a cell over the csv module's field limit, a NUL byte
        raise LogFormatError(f"{name}: not a CSV table ({e})") from None


def _read_rows(fh: IO[str], columns: Mapping[str, Column], name: str, allow_extra: bool):
    from rangekit.io.guard import MAX_CSV_CELL

    lines = [(i + 1, ln) for i, ln in enumerate(fh.read().splitlines())]
    lines = [(i, ln) for i, ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise LogFormatError(f"{name}: empty file (no header row)")
    header_row, header_line = lines[0]
    header = [h.strip() for h in next(csv.reader([header_line]))]
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        raise LogFormatError(f"{name} row {header_row}: duplicate column {dupes[0]!r}")
    missing = [c for c, s in columns.items() if s.required and c not in header]
    if missing:
        raise LogFormatError(
            f"{name} row {header_row}: missing column {missing[0]!r} "
            f"(required: {', '.join(c for c, s in columns.items() if s.required)})"
        )
    if not allow_extra:
        extra = [h for h in header if h not in columns]
        if extra:
            raise LogFormatError(
                f"{name} row {header_row}: unknown column {extra[0]!r} "
                f"(known: {', '.join(columns)})"
            )
    idx = {c: header.index(c) for c in columns if c in header}
    values: dict[str, list] = {c: [] for c in columns}
    last_time: dict[str, float] = {}
    for row, line in lines[1:]:
        if len(line) > MAX_CSV_CELL and max(map(len, line.split(","))) > MAX_CSV_CELL:
            raise LogFormatError(f"{name} row {row}: a cell longer than {MAX_CSV_CELL} characters")
        cells = next(csv.reader([line]))
        if len(cells) != len(header):
            raise LogFormatError(
                f"{name} row {row}: {len(cells)} cells, the header has {len(header)}"
            )
        for c, spec in columns.items():
            if c not in idx:
                values[c].append(_parse("", Column(spec.kind, empty_ok=True), name, row, c))
                continue
            v = _parse(cells[idx[c]], spec, name, row, c)
            if spec.kind == "time" and not math.isnan(v):
                prev = last_time.get(c)
                if prev is not None and v < prev:
                    raise LogFormatError(
                        f"{_where(name, row, c)}: time {v:g} goes backwards (previous {prev:g})"
                    )
                last_time[c] = v
            values[c].append(v)
    out: dict[str, np.ndarray] = {}
    for c, spec in columns.items():
        dtype = {"int": np.int64, "str": object}.get(spec.kind, np.float64)
        out[c] = np.array(values[c], dtype=dtype)
    return out


def _cell(v) -> str:
    if isinstance(v, str):
        return v
    if v is None:
        return ""
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    f = float(v)
    return "" if math.isnan(f) else repr(f)


def write_table(
    columns: Sequence[str], rows: Sequence[Sequence], *, header_comment: str = ""
) -> str:
    """Format rows as CSV text (NaN and None as empty cells, floats round-trip exactly).

    Examples
    --------
    >>> print(write_table(["t_s", "x_m"], [[0.0, 1.5], [1.0, float("nan")]]), end="")
    t_s,x_m
    0.0,1.5
    1.0,
    """
    buf = io.StringIO()
    if header_comment:
        for ln in header_comment.splitlines():
            buf.write(f"# {ln}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_cell(v) for v in r])
    return buf.getvalue()
