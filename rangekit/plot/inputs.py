"""The tables ``rangekit plot`` draws: range series, tracks, batch results (CSV, JSON, JSONL).

Every reader takes a file whose format follows its suffix:

* ``.csv``: one header row, columns by name, ``#`` comment lines, an empty cell = no
  value (read by :func:`rangekit.io.csvlog.read_table`, so the checks and messages are
  those of every rangekit CSV log);
* ``.json``: one object holding a list of row objects under ``ranges``, ``rows`` or
  ``results`` (``{"columns": [...], "rows": [[...], ...]}``, the ``rangekit track``
  JSON, is accepted too), or a bare list of row objects; ``null`` = no value;
* ``.jsonl``: one JSON object per line (blank lines skipped).

Unknown columns are ignored. A malformed file raises
:class:`~rangekit.errors.LogFormatError` naming the file, the row (CSV row numbers count
the header as row 1; JSON rows are ``ranges[i]``, JSONL rows ``line n``) and the column.

Examples
--------
>>> import pathlib, tempfile
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> _ = (d / "s.csv").write_text("t_s,a,b,distance_m,sigma_m\\n0,0,1,2.5,0.01\\n1,0,1,,\\n")
>>> [(s.key, s.distance_m.tolist()) for s in read_range_series(d / "s.csv")]
[('0-1', [2.5, nan])]
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rangekit.errors import InvalidParameterError, LogFormatError
from rangekit.io.csvlog import Column, read_table

__all__ = [
    "INPUT_FORMATS",
    "BatchErrors",
    "RangeSeries",
    "TrackPath",
    "read_batch_errors",
    "read_columns",
    "read_range_series",
    "read_track",
    "read_truth_pairs",
]

#: Input suffixes the readers accept.
INPUT_FORMATS = (".csv", ".json", ".jsonl")

#: Keys under which a JSON object may hold its list of rows, in the order tried.
_LIST_KEYS = ("ranges", "rows", "results")


def _label(path: Path) -> str:
    from rangekit.io.guard import is_stdin

    return "standard input" if is_stdin(path) else str(path)


def _stdin_table() -> tuple[str, str]:
    """``(suffix, text)`` of a table on standard input (``-``), its format sniffed: a
    JSON document when it starts with ``[`` or parses whole as an object, JSON lines when
    it starts with ``{`` otherwise, CSV else."""
    from rangekit.io.guard import MAX_TABLE_BYTES, read_stdin

    data = read_stdin(MAX_TABLE_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise LogFormatError("standard input: not a UTF-8 text file") from None
    head = text.lstrip()[:1]
    if head == "[":
        return ".json", text
    if head == "{":
        try:
            json.loads(text)
        except (ValueError, RecursionError):
            return ".jsonl", text
        return ".json", text
    return ".csv", text


def _header(lines) -> list[str]:
    """The header cells of CSV ``lines`` (first line neither blank nor a comment)."""
    for line in lines:
        if line.strip() and not line.lstrip().startswith("#"):
            return [h.strip() for h in next(csv.reader([line]))]
    return []


def _csv_header(path: Path) -> list[str]:
    """The header cells of a CSV file (first line that is neither blank nor a comment)."""
    from rangekit.errors import InputFileError
    from rangekit.io.guard import regular_file

    try:
        regular_file(path)  # never opens a FIFO or a device
        with open(path, newline="", encoding="utf-8") as fh:
            return _header(fh)
    except (OSError, UnicodeDecodeError, csv.Error, InputFileError):
        return []  # read_table raises the right error


def _msg(e: Exception) -> str:
    """A JSON error in a few words: the decoder's, or too deep / a too long number."""
    if isinstance(e, json.JSONDecodeError):
        return f"line {e.lineno}: {e.msg}"
    if isinstance(e, RecursionError):
        return "nested too deeply"
    return str(e).split(";")[0]


def _json_rows(path: Path) -> list[tuple[str, dict]]:
    """``(where, row object)`` of a JSON or JSONL file; ``where`` names the row in messages."""
    from rangekit.io.guard import MAX_TABLE_BYTES, read_capped

    name = _label(path)
    data = read_capped(path, MAX_TABLE_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise LogFormatError(f"{name}: not a UTF-8 text file") from None
    return _parse_json_rows(text, name, jsonl=path.suffix.lower() == ".jsonl")


def _parse_json_rows(text: str, name: str, *, jsonl: bool) -> list[tuple[str, dict]]:
    """``(where, row object)`` of JSON (or JSON lines) ``text`` named ``name``."""
    rows: list[tuple[str, dict]] = []
    if jsonl:
        for n, line in enumerate(text.splitlines(), start=1):
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except (ValueError, RecursionError) as e:  # JSONDecodeError is a ValueError
                raise LogFormatError(f"{name} line {n}: not JSON ({_msg(e)})") from None
            if not isinstance(obj, dict):
                raise LogFormatError(f"{name} line {n}: not a JSON object")
            rows.append((f"{name} line {n}", obj))
        return rows
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as e:
        raise LogFormatError(f"{name}: not JSON ({_msg(e)})") from None
    key = ""
    if isinstance(doc, dict):
        if isinstance(doc.get("columns"), list) and isinstance(doc.get("rows"), list):
            cols = doc["columns"]
            for i, r in enumerate(doc["rows"]):
                if not isinstance(r, list) or len(r) != len(cols):
                    raise LogFormatError(
                        f"{name} rows[{i}]: not a list of {len(cols)} values (the columns)"
                    )
                rows.append((f"{name} rows[{i}]", dict(zip(cols, r, strict=True))))
            return rows
        key = next((k for k in _LIST_KEYS if isinstance(doc.get(k), list)), "")
        if not key:
            raise LogFormatError(
                f"{name}: a JSON object without a list of rows (keys tried: "
                f"{', '.join(_LIST_KEYS)})"
            )
        doc = doc[key]
    if not isinstance(doc, list):
        raise LogFormatError(f"{name}: neither a list of rows nor an object holding one")
    for i, r in enumerate(doc):
        where = f"{name} {key}[{i}]" if key else f"{name} [{i}]"
        if not isinstance(r, dict):
            raise LogFormatError(f"{where}: not a JSON object")
        rows.append((where, r))
    return rows


def _json_value(v, spec: Column, where: str, col: str):
    """One JSON value parsed like a CSV cell under ``spec``."""
    at = f"{where}, column {col!r}"
    if v is None or v == "":
        if not spec.empty_ok:
            raise LogFormatError(f"{at}: no value (a value is required)")
        return {"int": -1, "str": ""}.get(spec.kind, math.nan)
    if spec.kind == "str":
        if isinstance(v, bool) or not isinstance(v, (str, int, float)):
            raise LogFormatError(f"{at}: {v!r} is not a string or number")
        return v if isinstance(v, str) else json.dumps(v)
    if isinstance(v, str):
        try:
            v = float(v)
        except ValueError:
            raise LogFormatError(f"{at}: {v!r} is not a number") from None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise LogFormatError(f"{at}: {v!r} is not a number")
    if not math.isfinite(v):
        raise LogFormatError(f"{at}: {v!r} is not finite")
    if spec.kind == "int":
        if v != int(v):
            raise LogFormatError(f"{at}: {v!r} is not an integer")
        v = int(v)
    if spec.nonneg and v < 0:
        raise LogFormatError(f"{at}: {v} is negative")
    return v


def read_columns(
    path: str | os.PathLike, spec: Mapping[str, Column]
) -> tuple[dict[str, np.ndarray], frozenset[str]]:
    """Read the columns of ``spec`` from a CSV, JSON or JSONL table.

    Parameters
    ----------
    path : path-like
        The table; its suffix (:data:`INPUT_FORMATS`) chooses the format. ``-`` is
        standard input, its format sniffed (JSON when it starts with ``[`` or is one
        object, JSON lines when it starts with ``{`` otherwise, else CSV).
    spec : mapping of str to Column
        Column name -> parsing rule (:class:`rangekit.io.csvlog.Column`). ``"time"``
        columns must not decrease, as in CSV logs.

    Returns
    -------
    columns : dict of str to ndarray
        One array per column of ``spec`` (NaN, -1 or "" where empty or absent).
    present : frozenset of str
        The columns of ``spec`` the file has (to tell an absent column from an empty one).

    Raises
    ------
    InvalidParameterError
        The suffix is not one of :data:`INPUT_FORMATS`.
    InputFileError
        The file cannot be opened.
    LogFormatError
        Not a table of that format, a missing required column, a value that breaks its
        rule; the message names the file, the row and the column.
    """
    from rangekit.io.guard import is_stdin

    path = Path(path)
    text = None
    if is_stdin(path):
        suffix, text = _stdin_table()
    else:
        suffix = path.suffix.lower()
    if suffix not in INPUT_FORMATS:
        shown = repr(path.suffix) if path.suffix else "(no suffix)"
        raise InvalidParameterError(
            f"{str(path)!r}: unknown input format {shown} (use {', '.join(INPUT_FORMATS)})"
        )
    if suffix == ".csv":
        if text is not None:
            data = read_table(io.StringIO(text, newline=""), spec, name=_label(path))
            return data, frozenset(spec) & frozenset(_header(text.splitlines()))
        data = read_table(path, spec, name=_label(path))
        return data, frozenset(spec) & frozenset(_csv_header(path))
    if text is not None:
        rows = _parse_json_rows(text, _label(path), jsonl=suffix == ".jsonl")
    else:
        rows = _json_rows(path)
    present = frozenset(c for c in spec if any(c in r for _, r in rows))
    missing = [c for c, s in spec.items() if s.required and c not in present]
    if missing:
        raise LogFormatError(
            f"{_label(path)}: missing column {missing[0]!r} (required: "
            f"{', '.join(c for c, s in spec.items() if s.required)})"
        )
    out: dict[str, np.ndarray] = {}
    for c, s in spec.items():
        vals = []
        last = None
        for where, r in rows:
            v = _json_value(
                r.get(c), s if c in present else Column(s.kind, empty_ok=True), where, c
            )
            if s.kind == "time" and not (isinstance(v, float) and math.isnan(v)):
                if last is not None and v < last:
                    raise LogFormatError(
                        f"{where}, column {c!r}: time {v:g} goes backwards (previous {last:g})"
                    )
                last = v
            vals.append(v)
        dtype = {"int": np.int64, "str": object}.get(s.kind, np.float64)
        out[c] = np.array(vals, dtype=dtype)
    return out, present


# --- range series ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RangeSeries:
    """One range time series (one pair, or one transmitter and receiver, or one sensor).

    Attributes
    ----------
    key : str
        Legend label: ``"A-B"`` (beepbeep pair), ``"tx T ch C"`` (one-way; ``tx -`` without
        a firing order) or ``"ch C"`` (echo); ``""`` when the table has no key column.
    t_s : ndarray
        Times (s), ascending.
    distance_m : ndarray
        Distances (m); NaN = no range at that time.
    sigma_m : ndarray
        1-sigma of each distance (m); NaN = none.
    """

    key: str
    t_s: np.ndarray
    distance_m: np.ndarray
    sigma_m: np.ndarray


_SERIES_SPEC = {
    "t_s": Column(required=False),  # required, with its own message
    "distance_m": Column(empty_ok=True),
    "sigma_m": Column(empty_ok=True, nonneg=True),
    "a": Column(kind="str", required=False, empty_ok=True),
    "b": Column(kind="str", required=False, empty_ok=True),
    "tx": Column(kind="str", required=False, empty_ok=True),
    "channel": Column(kind="str", required=False, empty_ok=True),
}


def read_range_series(path: str | os.PathLike) -> list[RangeSeries]:
    """Range time series from the output of ``rangekit range --series`` (CSV or JSON).

    Columns: ``t_s`` (s), ``distance_m``, ``sigma_m`` (m; empty or null = no range) and
    the series key: ``a, b`` (beepbeep pairs), else ``tx, channel`` (one-way), else
    ``channel`` (echo). Other columns are ignored. Rows need not be in time order; each
    series is sorted by time (stable).

    Returns
    -------
    list of RangeSeries
        In the order of each key's first row.

    Raises
    ------
    LogFormatError
        No ``t_s`` column (the message says that ``rangekit range --series`` writes it),
        or any malformed value.
    """
    cols, present = read_columns(path, _SERIES_SPEC)
    if "t_s" not in present:
        raise LogFormatError(
            f"{_label(Path(path))}: missing column 't_s' (the time of each range; `rangekit range "
            "--series` writes it)"
        )
    if {"a", "b"} <= present:
        keys = [f"{a}-{b}" for a, b in zip(cols["a"], cols["b"], strict=True)]
    elif {"tx", "channel"} <= present:
        keys = [f"tx {t or '-'} ch {c}" for t, c in zip(cols["tx"], cols["channel"], strict=True)]
    elif "channel" in present:
        keys = [f"ch {c}" for c in cols["channel"]]
    else:
        keys = [""] * len(cols["t_s"])
    out = []
    for k in dict.fromkeys(keys):
        idx = np.flatnonzero(np.array([kk == k for kk in keys], dtype=bool))
        idx = idx[np.argsort(cols["t_s"][idx], kind="stable")]
        out.append(RangeSeries(k, cols["t_s"][idx], cols["distance_m"][idx], cols["sigma_m"][idx]))
    return out


def read_truth_pairs(path: str | os.PathLike) -> dict[str, float]:
    """True distance of each pair key (``"A-B"``, as :class:`RangeSeries` keys them) from
    the JSON sidecar ``rangekit synth beepbeep`` writes (its ``pairs`` list).

    Raises
    ------
    InputFileError
        The file cannot be opened.
    InvalidParameterError
        Not JSON, or no ``pairs`` list of ``{a, b, distance_m}``; the message names the
        file as ``--truth`` (the option of ``rangekit plot ranges`` that reads it).
    """
    from rangekit.errors import InputFileError
    from rangekit.io.sidecar import read_json

    try:
        obj = read_json(path)  # guarded: regular file, size, nesting, finite numbers
    except InputFileError as e:
        if "JSON" in str(e) or "not UTF-8" in str(e):
            raise InvalidParameterError(f"--truth '{path}' is not JSON: {e}") from None
        raise
    pairs = obj.get("pairs") if isinstance(obj, dict) else None
    try:
        return {f"{int(p['a'])}-{int(p['b'])}": float(p["distance_m"]) for p in pairs}
    except (TypeError, KeyError, ValueError):
        raise InvalidParameterError(
            f"--truth '{path}' has no \"pairs\" list of {{a, b, distance_m}} (a sidecar "
            "of `rangekit synth beepbeep`)"
        ) from None


# --- tracks ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrackPath:
    """One target's track (or truth) with its position covariance.

    Attributes
    ----------
    target : str
        The ``target`` column's value (``""`` when the table has none).
    xy_m : ndarray, shape (n, 2)
        Positions (m), in file order; NaN where a cell was empty.
    cov_m2 : ndarray, shape (n, 2, 2)
        Position covariance (m²) from ``var_x_m2, var_y_m2[, cov_xy_m2]`` or from
        ``sigma_x_m, sigma_y_m`` (dead reckoning); NaN where the table has none.
    spread_m : ndarray, shape (n,)
        The particle filter's ``spread_m`` (m); NaN where none.
    """

    target: str
    xy_m: np.ndarray
    cov_m2: np.ndarray
    spread_m: np.ndarray


_TRACK_SPEC = {
    "x_m": Column(empty_ok=True),
    "y_m": Column(empty_ok=True),
    "target": Column(kind="str", required=False, empty_ok=True),
    "var_x_m2": Column(required=False, empty_ok=True, nonneg=True),
    "var_y_m2": Column(required=False, empty_ok=True, nonneg=True),
    "cov_xy_m2": Column(required=False, empty_ok=True),
    "sigma_x_m": Column(required=False, empty_ok=True, nonneg=True),
    "sigma_y_m": Column(required=False, empty_ok=True, nonneg=True),
    "spread_m": Column(required=False, empty_ok=True, nonneg=True),
}


def read_track(path: str | os.PathLike) -> list[TrackPath]:
    """Tracks (one per ``target``) from a ``rangekit track`` output or a truth table.

    Columns ``x_m, y_m`` (required); ``target`` (one path per value, in the order of
    first appearance); the covariance from ``var_x_m2, var_y_m2`` and ``cov_xy_m2`` (0 when
    absent or empty: the DUHL track has none), or else from ``sigma_x_m, sigma_y_m`` (dead
    reckoning); ``spread_m`` (particle filter). Every track format of ``docs/formats.md``
    and ``docs/theory/ahn2007.md`` reads this way; other columns are ignored.
    """
    cols, present = read_columns(path, _TRACK_SPEC)
    n = len(cols["x_m"])
    xy = np.column_stack([cols["x_m"], cols["y_m"]])
    cov = np.full((n, 2, 2), np.nan)
    if {"var_x_m2", "var_y_m2"} <= present:
        vx, vy = cols["var_x_m2"], cols["var_y_m2"]
        cxy = cols["cov_xy_m2"]
        cxy = np.where(np.isnan(cxy), 0.0, cxy)
    elif {"sigma_x_m", "sigma_y_m"} <= present:
        vx, vy = cols["sigma_x_m"] ** 2, cols["sigma_y_m"] ** 2
        cxy = np.zeros(n)
    else:
        vx = vy = cxy = np.full(n, np.nan)
    cov[:, 0, 0], cov[:, 1, 1] = vx, vy
    cov[:, 0, 1] = cov[:, 1, 0] = np.where(np.isnan(vx) | np.isnan(vy), np.nan, cxy)
    targets = cols["target"] if "target" in present else np.full(n, "", dtype=object)
    out = []
    for t in dict.fromkeys(targets.tolist()):
        i = np.flatnonzero(targets == t)
        out.append(TrackPath(str(t), xy[i], cov[i], cols["spread_m"][i]))
    return out


# --- batch results --------------------------------------------------------------------------


@dataclass(frozen=True)
class BatchErrors:
    """Absolute range errors of a batch, grouped.

    Attributes
    ----------
    by : str or None
        The grouping column (None: one group, key ``""``).
    errors_m : dict of str to ndarray
        Group value -> ``|distance_m - true_distance_m|`` (m) of its usable rows, in file
        order; groups in the order of first appearance.
    n_rows : int
        Data rows in the file.
    n_skipped : int
        Rows without both distances, or whose ``status`` is not ``ok``.
    """

    by: str | None
    errors_m: dict[str, np.ndarray]
    n_rows: int
    n_skipped: int


def read_batch_errors(path: str | os.PathLike, *, by: str | None = None) -> BatchErrors:
    """Absolute range errors of batch results (CSV or JSONL), grouped by column ``by``.

    Rows need ``distance_m`` and ``true_distance_m``; a row where either is empty (null),
    or whose ``status`` column (if the table has one) is neither empty nor ``ok``, is
    skipped and counted.

    Raises
    ------
    LogFormatError
        A missing column (``by`` included), a malformed value, or no usable row at all.
    """
    spec = {
        "distance_m": Column(empty_ok=True),
        "true_distance_m": Column(empty_ok=True),
        "status": Column(kind="str", required=False, empty_ok=True),
    }
    if by is not None:
        spec[by] = Column(kind="str", empty_ok=True)
    cols, _ = read_columns(path, spec)
    d, truth = cols["distance_m"], cols["true_distance_m"]
    status = np.array([s.strip().lower() for s in cols["status"]], dtype=object)
    ok = np.isfinite(d) & np.isfinite(truth) & ((status == "") | (status == "ok"))
    n = len(d)
    if not np.any(ok):
        raise LogFormatError(
            f"{_label(Path(path))}: no row has both distance_m and true_distance_m with status ok "
            f"({n} rows): no error to plot"
        )
    err = np.abs(d - truth)
    groups = cols[by] if by is not None else np.full(n, "", dtype=object)
    out = {}
    for g in dict.fromkeys(groups[ok].tolist()):
        out[str(g)] = err[ok & (groups == g)]
    return BatchErrors(by, out, n, int(n - np.count_nonzero(ok)))
