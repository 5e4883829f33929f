"""DUHL input logs (Kim & Kim 2013 §III-§V): wheel odometry, ultrasonic distances, beacons.

The DUHL filter consumes two streams (Kim & Kim 2013, Fig. 3): the odometry input
``u_k = [v_k^R, v_k^L]`` of eq (14) at the odometry rate (100 Hz in §V) and, at the Tx
activation rate (5 Hz), the distances ``d^i = [d_1^i, d_2^i, d_3^i]`` from one ceiling
transmitter ``T_i`` to the three receivers (eq (3)). Both go in one CSV file, one
measurement per row, rows in time order, typed by ``kind``:

==========  ==========================================================================
kind        columns used
==========  ==========================================================================
odometry    ``t_s, v_right_mps, v_left_mps``: right and left wheel velocities (m/s)
            measured over the interval that ends at ``t_s`` and starts at the previous
            odometry row. The first odometry row only marks the start time (its
            velocities are read but belong to no interval; write 0).
distance    ``t_s, tx, d1_m, d2_m, d3_m``: distances (m, >= 0) from transmitter ``tx``
            (an id >= 0 of the beacon file) to receivers 1, 2, 3 (at 0°, 120°, 240°
            from the heading, eq (1)). An empty ``d`` cell is a receiver that heard
            nothing (NaN).
==========  ==========================================================================

Column header, exactly these eight names (order free, no other columns):
``t_s,kind,tx,v_right_mps,v_left_mps,d1_m,d2_m,d3_m``, or for a rig with more than three
tags (``rangekit track range-ekf --rig``) further distance columns ``d4_m, d5_m, ...``
numbered without gaps (range to tag 4, 5, ...; DUHL's robot has three receivers and
refuses a log that fills them). Cells a kind does not use must be empty. ``#`` lines are
comments. A distance row at the same ``t_s`` as an odometry row
was taken at the pose reached at the end of that odometry interval; :meth:`DUHLLog.to_csv`
writes odometry rows first at equal times.

The transmitter positions come from a *beacon file* (JSON, :func:`read_beacons`)::

    {"format": "rangekit-beacons", "version": 1, "units": "m",
     "transmitters": [{"id": 1, "x_m": 0.0, "y_m": 0.0, "z_m": 2.011}, ...]}

Both formats are documented in ``docs/formats.md``.

Examples
--------
>>> import io
>>> text = '''t_s,kind,tx,v_right_mps,v_left_mps,d1_m,d2_m,d3_m
... 0.00,odometry,,0.0,0.0,,,
... 0.01,odometry,,0.31,0.29,,,
... 0.01,distance,4,,,2.05,2.11,
... '''
>>> log = read_duhl_log(io.StringIO(text), name="run.csv")
>>> log.odometry.v_right_mps.tolist(), log.distances.tx.tolist()
([0.0, 0.31], [4])
>>> log.distances.d_m.tolist()
[[2.05, 2.11, nan]]
"""

from __future__ import annotations

import io
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np

from rangekit._jsondoc import check_header, json_number
from rangekit.errors import InputFileError, InvalidParameterError, LogFormatError
from rangekit.io.csvlog import Column, read_table, read_text, write_table
from rangekit.io.results import format_value

__all__ = [
    "BEACON_FORMAT",
    "BEACON_VERSION",
    "LOG_COLUMNS",
    "Beacons",
    "DUHLLog",
    "DistanceRows",
    "OdometryRows",
    "parse_beacons",
    "read_beacons",
    "read_duhl_log",
]

#: The header of a DUHL log, in order.
LOG_COLUMNS = ("t_s", "kind", "tx", "v_right_mps", "v_left_mps", "d1_m", "d2_m", "d3_m")

_D_COLS = ("d1_m", "d2_m", "d3_m")
_V_COLS = ("v_right_mps", "v_left_mps")

_SPEC = {
    "t_s": Column(kind="time"),
    "kind": Column(kind="str"),
    "tx": Column(kind="int", empty_ok=True, nonneg=True),  # empty reads as -1
    "v_right_mps": Column(empty_ok=True),
    "v_left_mps": Column(empty_ok=True),
    "d1_m": Column(empty_ok=True, nonneg=True),
    "d2_m": Column(empty_ok=True, nonneg=True),
    "d3_m": Column(empty_ok=True, nonneg=True),
}

#: Columns each kind must fill, and columns it must leave empty.
_NEEDS = {"odometry": _V_COLS, "distance": ("tx",)}
_EMPTY = {"odometry": ("tx", *_D_COLS), "distance": _V_COLS}

#: Value of the ``"format"`` key of a beacon JSON document.
BEACON_FORMAT = "rangekit-beacons"
#: Beacon format version this module reads and writes.
BEACON_VERSION = 1

_TOP_KEYS = {"format", "version", "units", "transmitters", "name", "notes"}
_TX_KEYS = ("id", "x_m", "y_m", "z_m")


# --------------------------------------------------------------------------- the CSV log


@dataclass(frozen=True, eq=False)
class OdometryRows:
    """Odometry input u_k of eq (14): ``t_s`` (n,) strictly increasing, ``v_right_mps`` and
    ``v_left_mps`` (n,) wheel velocities over the interval ending at ``t_s[k]`` (entry 0
    belongs to no interval)."""

    t_s: np.ndarray
    v_right_mps: np.ndarray
    v_left_mps: np.ndarray


@dataclass(frozen=True, eq=False)
class DistanceRows:
    """Ultrasonic distances d^i of eq (3): ``t_s`` (m,), ``tx`` (m,) int64 transmitter ids,
    ``d_m`` (m, K) distances to receivers (tags) 1-K in metres, K >= 3 (the ``d{k}_m``
    columns), NaN where a receiver missed."""

    t_s: np.ndarray
    tx: np.ndarray
    d_m: np.ndarray


def _empty_odometry() -> OdometryRows:
    return OdometryRows(np.zeros(0), np.zeros(0), np.zeros(0))


def _empty_distances() -> DistanceRows:
    return DistanceRows(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 3)))


@dataclass(frozen=True, eq=False)
class DUHLLog:
    """A parsed DUHL log: the odometry and distance rows, each in time order.

    Attributes
    ----------
    odometry : OdometryRows
    distances : DistanceRows
    """

    odometry: OdometryRows = field(default_factory=_empty_odometry)
    distances: DistanceRows = field(default_factory=_empty_distances)

    def to_csv(
        self, path_or_buffer: str | os.PathLike | IO[str] | None = None, *, comment: str = ""
    ) -> str | None:
        """Write the log in the documented format.

        Rows are merged in time order; at equal times odometry rows come first, and rows
        of one kind keep their order. Floats are written so that they read back exactly.

        Parameters
        ----------
        path_or_buffer : path, text stream or None
            Where to write; None returns the text instead. A path is written atomically.
        comment : str
            Written as ``#`` lines before the header.

        Returns
        -------
        str or None
            The CSV text when ``path_or_buffer`` is None, else None.

        Examples
        --------
        >>> log = DUHLLog(OdometryRows(np.array([0.0, 0.2]), np.array([0.0, 0.3]),
        ...                            np.array([0.0, 0.3])),
        ...               DistanceRows(np.array([0.2]), np.array([1]),
        ...                            np.array([[2.0, np.nan, 2.1]])))
        >>> print(log.to_csv(), end="")
        t_s,kind,tx,v_right_mps,v_left_mps,d1_m,d2_m,d3_m
        0.0,odometry,,0.0,0.0,,,
        0.2,odometry,,0.3,0.3,,,
        0.2,distance,1,,,2.0,,2.1
        """
        o, d = self.odometry, self.distances
        n_d = max(3, d.d_m.shape[1] if d.d_m.ndim == 2 else 3)
        columns = (*LOG_COLUMNS[:5], *(f"d{k + 1}_m" for k in range(n_d)))
        rows: list[tuple[float, int, int, list]] = []
        for i in range(o.t_s.size):
            cells = [o.t_s[i], "odometry", None, o.v_right_mps[i], o.v_left_mps[i]]
            rows.append((float(o.t_s[i]), 0, i, [*cells, *([None] * n_d)]))
        for i in range(d.t_s.size):
            cells = [d.t_s[i], "distance", int(d.tx[i]), None, None, *d.d_m[i]]
            rows.append((float(d.t_s[i]), 1, i, cells))
        rows.sort(key=lambda r: (r[0], r[1], r[2]))
        text = write_table(columns, [r[3] for r in rows], header_comment=comment)
        if path_or_buffer is None:
            return text
        if hasattr(path_or_buffer, "write"):
            path_or_buffer.write(text)
            return None
        from rangekit.io.sidecar import write_text_atomic

        write_text_atomic(path_or_buffer, text)
        return None


def _distance_columns(text: str, label: str) -> tuple[str, ...]:
    """``d1_m, ..., dK_m`` of the header (K >= 3, numbered without gaps)."""
    header = next(
        (ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), ""
    )
    names = [c.strip() for c in header.split(",")]
    ks = sorted(int(c[1:-2]) for c in names if re.fullmatch(r"d[1-9][0-9]{0,3}_m", c))
    n = max([3, *ks])
    missing = [f"d{k}_m" for k in range(1, n + 1) if k not in ks]
    if missing and ks and max(ks) > 3:
        raise LogFormatError(
            f"{label}: distance columns d1_m ... d{n}_m must all be present "
            f"(missing {', '.join(missing)})"
        )
    return tuple(f"d{k}_m" for k in range(1, n + 1))


def _data_rows(text: str) -> list[int]:
    """File row (1-based line) of every data row, as :mod:`rangekit.io.csvlog` counts."""
    rows = [
        i + 1
        for i, ln in enumerate(text.splitlines())
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    return rows[1:]  # the first is the header


def read_duhl_log(source: str | os.PathLike | IO[str], *, name: str | None = None) -> DUHLLog:
    """Read and validate a DUHL log (format in the module docstring).

    Parameters
    ----------
    source : path or text stream
    name : str, optional
        How the file is named in error messages (default: the path, or ``<stream>``).

    Returns
    -------
    DUHLLog
        Empty rows of a kind if the log has none (a header-only file is a legal, empty log).

    Raises
    ------
    LogFormatError
        A missing or unknown column; an unknown ``kind``; a cell the kind needs left empty
        or a cell it does not use filled; a number that does not parse or is not finite;
        a negative distance or transmitter id; time going backwards; two odometry rows at
        the same time (an interval of zero length). The message names the file, the row
        (1-based, the header is row 1, comment lines counted) and the column.
    InputFileError
        The file cannot be opened.
    """
    label, text = read_text(source, name=name)
    d_cols = _distance_columns(text, label)
    spec = {**_SPEC, **{c: Column(empty_ok=True, nonneg=True) for c in d_cols}}
    tab = read_table(io.StringIO(text, newline=""), spec, name=label, allow_extra=False)
    rownum = _data_rows(text)
    kind = tab["kind"]
    last_odo = None
    for i in range(kind.size):
        k = kind[i]
        where = f"{label} row {rownum[i]}"
        if k not in _NEEDS:
            raise LogFormatError(
                f"{where}, column 'kind': unknown kind {k!r} (use {', '.join(_NEEDS)})"
            )
        for c in _NEEDS[k]:
            v = tab[c][i]
            if (c == "tx" and v < 0) or (c != "tx" and math.isnan(v)):
                raise LogFormatError(f"{where}, column {c!r}: a {k} row needs a value here")
        for c in (*_EMPTY[k], *d_cols[3:]) if k == "odometry" else _EMPTY[k]:
            v = tab[c][i]
            if (c == "tx" and v >= 0) or (c != "tx" and not math.isnan(v)):
                raise LogFormatError(
                    f"{where}, column {c!r}: a {k} row leaves this cell empty "
                    f"(got {format_value(v)})"
                )
        if k == "odometry":
            t = float(tab["t_s"][i])
            if last_odo is not None and t <= last_odo:
                raise LogFormatError(
                    f"{where}, column 't_s': odometry time {t:g} repeats the previous "
                    "odometry row's (an odometry interval must be > 0 s)"
                )
            last_odo = t
    oi = np.flatnonzero(kind == "odometry")
    di = np.flatnonzero(kind == "distance")
    odometry = OdometryRows(tab["t_s"][oi], tab["v_right_mps"][oi], tab["v_left_mps"][oi])
    d_m = np.column_stack([tab[c][di] for c in (*_D_COLS, *d_cols[3:])]).reshape(-1, len(d_cols))
    distances = DistanceRows(tab["t_s"][di], tab["tx"][di].astype(np.int64), d_m)
    return DUHLLog(odometry, distances)


# --------------------------------------------------------------------------- the beacon file


@dataclass(frozen=True, eq=False)
class Beacons:
    """Ceiling transmitters: ids and positions (Kim & Kim 2013 §II-B, ``T_i = [x_i, y_i, z_i]``).

    Parameters
    ----------
    ids : array_like of int, shape (n,)
        Distinct transmitter ids >= 0 (the ``tx`` of a DUHL log), n >= 2 (eq (3) needs
        two Txs).
    xyz_m : array_like, shape (n, 3)
        Positions in metres, finite; row i belongs to ``ids[i]``.

    Raises
    ------
    InvalidParameterError
        Wrong shapes, fewer than 2 transmitters, a negative or repeated id, a non-finite
        coordinate.

    Examples
    --------
    >>> b = Beacons([1, 2], [[0.0, 0.0, 2.0], [2.0, 0.0, 2.0]])
    >>> b.position(2).tolist(), b.position([2, 1])[:, 0].tolist()
    ([2.0, 0.0, 2.0], [2.0, 0.0])
    """

    ids: np.ndarray
    xyz_m: np.ndarray

    def __post_init__(self) -> None:
        raw_ids = np.asarray(self.ids)
        if raw_ids.ndim != 1 or not (raw_ids.size == 0 or np.issubdtype(raw_ids.dtype, np.integer)):
            raise InvalidParameterError(f"ids must be a 1-D array of integers, got {raw_ids!r}")
        ids = raw_ids.astype(np.int64)
        xyz = np.array(self.xyz_m, dtype=np.float64)
        if xyz.shape != (ids.size, 3):
            raise InvalidParameterError(
                f"xyz_m must have shape ({ids.size}, 3) for {ids.size} ids, got {xyz.shape}"
            )
        if ids.size < 2:
            raise InvalidParameterError(
                f"{ids.size} transmitter(s): at least 2 are needed (Kim & Kim 2013, eq (3))"
            )
        if np.any(ids < 0):
            raise InvalidParameterError(f"id {int(ids[ids < 0][0])} is negative (ids are >= 0)")
        uniq, counts = np.unique(ids, return_counts=True)
        if np.any(counts > 1):
            raise InvalidParameterError(f"id {int(uniq[counts > 1][0])} appears more than once")
        if not np.all(np.isfinite(xyz)):
            bad = int(np.flatnonzero(~np.all(np.isfinite(xyz), axis=1))[0])
            raise InvalidParameterError(
                f"transmitter {int(ids[bad])} has a non-finite position {xyz[bad].tolist()}"
            )
        ids.flags.writeable = False
        xyz.flags.writeable = False
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "xyz_m", xyz)
        object.__setattr__(self, "_row", {int(t): r for r, t in enumerate(ids)})

    def __len__(self) -> int:
        return int(self.ids.size)

    def position(self, ids: int | Sequence[int] | np.ndarray) -> np.ndarray:
        """Positions of transmitters by id: shape (3,) for one id, (..., 3) for an array.

        Raises
        ------
        InvalidParameterError
            An id that is not in the set.
        """
        a = np.asarray(ids)
        if a.size and not np.issubdtype(a.dtype, np.integer):
            raise InvalidParameterError(f"ids={ids!r} must be integers")
        flat = a.reshape(-1)
        rows = np.empty(flat.size, dtype=np.int64)
        for j, t in enumerate(flat.tolist()):
            r = self._row.get(int(t))  # type: ignore[attr-defined]
            if r is None:
                raise InvalidParameterError(
                    f"transmitter {t} is not in the beacons (ids: {self.ids.tolist()})"
                )
            rows[j] = r
        return self.xyz_m[rows].reshape(*a.shape, 3)

    def to_json(self) -> dict[str, Any]:
        """The beacons as a JSON-ready dict (round-trips through :func:`parse_beacons`).

        Examples
        --------
        >>> Beacons([1, 2], [[0, 0, 2.0], [2, 0, 2.0]]).to_json()["transmitters"][1]
        {'id': 2, 'x_m': 2.0, 'y_m': 0.0, 'z_m': 2.0}
        """
        return {
            "format": BEACON_FORMAT,
            "version": BEACON_VERSION,
            "units": "m",
            "transmitters": [
                {"id": int(t), "x_m": float(p[0]), "y_m": float(p[1]), "z_m": float(p[2])}
                for t, p in zip(self.ids, self.xyz_m, strict=True)
            ],
        }


def _parse(obj: Any) -> Beacons:
    """Beacons from a parsed JSON document, or InvalidParameterError naming the key."""
    check_header(
        obj,
        what="a beacon file",
        fmt=BEACON_FORMAT,
        version=BEACON_VERSION,
        body="transmitters",
        allowed=_TOP_KEYS,
    )
    txs = obj["transmitters"]
    if not isinstance(txs, list):
        raise InvalidParameterError(f"transmitters={txs!r} must be a list of transmitters")
    if len(txs) < 2:
        raise InvalidParameterError(
            f"transmitters has {len(txs)} entr{'y' if len(txs) == 1 else 'ies'}: at least 2 "
            "are needed (Kim & Kim 2013, eq (3))"
        )
    ids, xyz, seen = [], [], {}
    for i, t in enumerate(txs):
        where = f"transmitters[{i}]"
        if not isinstance(t, Mapping):
            raise InvalidParameterError(f"{where}={t!r} must be an object with {list(_TX_KEYS)}")
        for k in _TX_KEYS:
            if k not in t:
                raise InvalidParameterError(f"{where}: missing key {k!r}")
        extra = sorted(set(t) - set(_TX_KEYS))
        if extra:
            raise InvalidParameterError(f"{where}: unknown key {extra[0]!r}")
        tid = t["id"]
        if isinstance(tid, bool) or not isinstance(tid, (int, np.integer)):
            raise InvalidParameterError(f"{where}.id={tid!r} must be an integer")
        if tid < 0:
            raise InvalidParameterError(f"{where}.id={tid!r} must be >= 0")
        if int(tid) in seen:
            raise InvalidParameterError(
                f"{where}.id={tid!r} repeats transmitters[{seen[int(tid)]}].id"
            )
        seen[int(tid)] = i
        ids.append(int(tid))
        xyz.append([json_number(f"{where}.{k}", t[k]) for k in _TX_KEYS[1:]])
    return Beacons(np.array(ids, dtype=np.int64), np.array(xyz))


def parse_beacons(obj: Any, *, name: str = "<beacons>") -> Beacons:
    """Build :class:`Beacons` from a parsed beacon JSON document.

    Parameters
    ----------
    obj : dict
        ``{"format": "rangekit-beacons", "version": 1, "units": "m", "transmitters":
        [{"id": ..., "x_m": ..., "y_m": ..., "z_m": ...}, ...]}``; optional ``"name"``
        and ``"notes"`` are ignored.
    name : str
        How the document is named in error messages.

    Returns
    -------
    Beacons
        In the order of the file.

    Raises
    ------
    InvalidParameterError
        ``"{name}: {problem}"`` for a missing or unknown key (top level or in a
        transmitter), another format, version or unit, fewer than 2 transmitters, an id
        that is not an integer >= 0 or repeats, a coordinate that is not a finite number.

    Examples
    --------
    >>> doc = {"format": "rangekit-beacons", "version": 1, "units": "m", "transmitters": [
    ...     {"id": 1, "x_m": 0.0, "y_m": 0.0, "z_m": 2.011},
    ...     {"id": 2, "x_m": 3.0, "y_m": 0.0, "z_m": 2.011}]}
    >>> parse_beacons(doc).ids.tolist()
    [1, 2]
    >>> doc["transmitters"][1]["id"] = 1
    >>> parse_beacons(doc, name="b.json")
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: b.json: transmitters[1].id=1 repeats transmitters[0].id
    """
    try:
        return _parse(obj)
    except InvalidParameterError as e:
        raise InvalidParameterError(f"{name}: {e}") from None


def read_beacons(path: str | os.PathLike) -> Beacons:
    """Read and validate a beacon JSON file (format in ``docs/formats.md``).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Beacons

    Raises
    ------
    InputFileError
        If the file is missing, is not JSON, or is not a valid beacon file; the message
        names the file and the problem (``'b.json' is not a valid beacon file:
        transmitters[2]: missing key 'z_m'``).
    """
    from rangekit.io.sidecar import read_json

    obj = read_json(path)
    try:
        return _parse(obj)
    except InvalidParameterError as e:
        raise InputFileError(f"'{os.fspath(path)}' is not a valid beacon file: {e}") from e
