"""Result formats: tables for people, JSON and CSV for programs (``docs/formats.md``).

Every command that prints results (``range``, ``detect``, ``locate``, ``calibrate``,
``experiment``) renders them here, with one set of rules (``docs/cli.md#output-formats``):

* **table** (people): a value that has a 1-sigma column beside it (:data:`SIGMA_OF`) is
  printed with the decimals its sigma supports, two significant digits of the sigma
  (:func:`sigma_decimals`, as :func:`format_pm`), the sigma with the same decimals; a
  column of :data:`TABLE_DECIMALS` with its fixed decimals; other floats with 6; a
  missing value (None, NaN) and an empty flag list as ``-``; flags joined by ``,``.
* **csv** (programs): floats with at least 6 decimals, more where the sigma needs them
  (a value is never printed coarser than its sigma); missing values empty; flags joined
  by ``;``; a plain header row.
* **json** (programs): full precision, null for missing, flags as lists.
* **text** (a value in a line for people: ``--verbose``'s parameters, notes): up to six
  significant digits (:func:`format_value`).

Examples
--------
>>> rows = [{"a": 0, "b": 1, "distance_m": 2.000614, "sigma_m": 0.00912, "flags": []},
...         {"a": 0, "b": 2, "distance_m": None, "sigma_m": None, "flags": ["detection"]}]
>>> print(format_rows(rows, RANGE_FIELDS, "table"), end="")
a  b  distance_m  sigma_m      flags
0  1      2.0006   0.0091          -
0  2           -        -  detection
>>> print(format_rows(rows, RANGE_FIELDS, "csv"), end="")
a,b,distance_m,sigma_m,flags
0,1,2.000614,0.009120,
0,2,,,detection
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence

import numpy as np

from rangekit.types import Arrivals, RangeResult

__all__ = [
    "SIGMA_OF",
    "TABLE_DECIMALS",
    "arrivals_rows",
    "format_arrivals",
    "format_calibration",
    "format_pm",
    "format_ranges",
    "format_report",
    "format_rows",
    "format_tof",
    "format_value",
    "sigma_decimals",
]

RANGE_FIELDS = ("a", "b", "distance_m", "sigma_m", "flags")
ARRIVAL_FIELDS = (
    "file",
    "channel",
    "beep",
    "onset_sample",
    "onset_s",
    "sigma_samples",
    "snr_db",
    "confidence",
    "flags",
)


#: Value column -> the column holding its 1-sigma (tables print the value to its sigma).
SIGMA_OF = {
    "distance_m": "sigma_m",
    "onset_sample": "sigma_samples",
    "x_m": "sigma_x_m",
    "y_m": "sigma_y_m",
    "heading_deg": "sigma_heading_deg",
    "offset_m": "sigma_offset_m",
    "latency_s": "sigma_latency_s",
    "speed_m_s": "sigma_speed_m_s",
    "ppm": "sigma_ppm",
}
_SIGMA_COLUMNS = frozenset(SIGMA_OF.values())
#: Columns without a sigma column printed in tables with fixed decimals.
TABLE_DECIMALS = {"snr_db": 1, "confidence": 2, "t_s": 6, "onset_s": 6, "arrival_s": 7}
#: Decimals of a float in CSV at least (more where its sigma needs them), and in tables
#: when nothing else applies.
DEFAULT_DECIMALS = 6


def sigma_decimals(sigma: float | None) -> int | None:
    """Decimals that show two significant digits of ``sigma`` (None: no usable sigma).

    Examples
    --------
    >>> sigma_decimals(0.0091), sigma_decimals(0.02), sigma_decimals(30.0), sigma_decimals(0.0)
    (4, 3, 0, None)
    """
    if sigma is None or not isinstance(sigma, (int, float)) or isinstance(sigma, bool):
        return None
    if not (math.isfinite(sigma) and sigma > 0):
        return None
    return min(12, max(0, 1 - math.floor(math.log10(sigma))))


def _missing(v) -> bool:
    return v is None or (isinstance(v, float) and not math.isfinite(v))


def _decimals(row: dict, field: str, fmt: str) -> int | None:
    """Decimals of ``row[field]`` in ``fmt`` (table or csv); None: not a float rule."""
    if field in SIGMA_OF:
        nd = sigma_decimals(row.get(SIGMA_OF[field]))
    elif field in _SIGMA_COLUMNS:  # a sigma, printed with its value's decimals
        nd = sigma_decimals(row.get(field))
    else:
        nd = None
    if fmt == "csv":
        return max(DEFAULT_DECIMALS, nd or 0)
    if nd is not None:
        return nd
    return TABLE_DECIMALS.get(field, DEFAULT_DECIMALS)


def _cell(row: dict, field: str, fmt: str) -> str:
    """One value as text under the rules of the module docstring."""
    v = row[field]
    if isinstance(v, (list, tuple)):
        return (";" if fmt == "csv" else ",").join(str(t) for t in v) or (
            "" if fmt == "csv" else "-"
        )
    if _missing(v):
        return "" if fmt == "csv" else "-"
    if isinstance(v, bool) or not isinstance(v, float):
        return str(v)
    if abs(v) >= 1e6:
        return f"{v:.6g}"
    return f"{v:.{_decimals(row, field, fmt)}f}"


def _json_safe(row: dict) -> dict:
    """Non-finite floats become None (JSON null): JSON has no NaN."""
    return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in row.items()}


def format_value(value) -> str:
    """One value in a line of text for people (``rangekit track --verbose``'s parameters).

    A number with up to six significant digits (Python's ``g``: ``0.33``, ``5000``,
    ``1e-05``; a whole-valued float as a whole number), a missing value (None, NaN) as
    ``none``, a flag (bool) as ``yes`` or ``no``, a sequence as its values joined by ``,``
    (the form options take, ``--mounts 90,-90``; a sequence of sequences joined by ``;``),
    text as it is.

    Examples
    --------
    >>> format_value(0.0004), format_value(29.999999999999996), format_value(0.999)
    ('0.0004', '30', '0.999')
    >>> format_value(None), format_value(float("nan")), format_value(False), format_value(5)
    ('none', 'none', 'no', '5')
    >>> format_value([90.0, -90.0]), format_value(((0.0, 0.15), (0.0, -0.15)))
    ('90,-90', '0,0.15;0,-0.15')
    >>> format_value("from the ranges")
    'from the ranges'
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if value is None:
        return "none"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "none" if math.isnan(value) else f"{float(value):g}"
    if isinstance(value, (list, tuple)):
        nested = any(isinstance(v, (list, tuple, np.ndarray)) for v in value)
        return (";" if nested else ",").join(format_value(v) for v in value)
    return str(value)


def format_pm(value: float, sigma: float, *, sign: bool = False) -> str:
    """``value +- sigma`` with the digits sigma supports: two significant digits of sigma.

    Examples
    --------
    >>> format_pm(50.0012, 0.021, sign=True), format_pm(39.94, 0.3), format_pm(2.0, 0.0)
    ('+50.001 +- 0.021', '39.94 +- 0.30', '2 +- 0')
    """
    digits = sigma_decimals(sigma) or 0
    s = "+" if sign else ""
    return f"{value:{s}.{digits}f} +- {sigma:.{digits}f}"


def format_rows(
    rows: Sequence[dict],
    fields: Sequence[str],
    fmt: str,
    *,
    meta: dict | None = None,
    key: str = "rows",
) -> str:
    """Render dict rows as an aligned table, CSV (header + rows) or one JSON object.

    The number rules are the module's (a value to its sigma in tables, never coarser
    than its sigma in CSV, full precision and null for missing in JSON). JSON holds the
    keys of ``meta`` and the list of rows under ``key``.
    """
    if fmt == "json":
        obj = dict(meta or {})
        obj[key] = [_json_safe(dict(r)) for r in rows]
        return json.dumps(obj, indent=2) + "\n"
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(fields)
        for r in rows:
            w.writerow([_cell(r, f, "csv") for f in fields])
        return buf.getvalue()
    if fmt != "table":
        raise ValueError(f"fmt={fmt!r} must be table, json or csv")
    cells = [list(fields)] + [[_cell(r, f, "table") for f in fields] for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(fields))]
    lines = ["  ".join(c[i].rjust(widths[i]) for i in range(len(fields))).rstrip() for c in cells]
    return "\n".join(lines) + "\n"


def format_ranges(result: RangeResult, fmt: str, *, meta: dict | None = None) -> str:
    """Ranges of one exchange in ``fmt`` (table, json or csv).

    JSON: one object with the keys of ``meta``, ``speed_of_sound_m_s`` and a list
    ``ranges`` of objects with ``a``, ``b``, ``distance_m``, ``sigma_m``, ``flags``.
    """
    rows = [r.as_dict() for r in result.ranges]
    m = {**(meta or {}), "speed_of_sound_m_s": result.speed_m_s}
    return format_rows(rows, RANGE_FIELDS, fmt, meta=m, key="ranges")


def tof_fields(scheme: str) -> list[str]:
    """Columns of one-way (with ``tx``) and echo rows."""
    fields = ["file", "window"] + (["tx"] if scheme == "oneway" else [])
    return [*fields, "channel", "distance_m", "sigma_m", "snr_db", "arrival_s", "flags"]


def format_tof(rows: list[dict], fmt: str, *, scheme: str, meta: dict | None = None) -> str:
    """One-way / echo rows (``range_ultrasonic_files``) in ``fmt``; JSON key ``ranges``."""
    return format_rows(rows, tof_fields(scheme), fmt, meta=meta, key="ranges")


def arrivals_rows(arr: Arrivals, *, file: str, channel: int) -> list[dict]:
    """One dict per detected arrival, with the fields of ``ARRIVAL_FIELDS``.

    ``flags`` is the list of the arrival's flag names (:data:`rangekit.types.ARRIVAL_FLAGS`);
    :func:`format_arrivals` writes it as ranges are written: comma-joined in a table ('-' for
    none), ';'-joined in CSV (empty for none), a list in JSON.
    """
    return [
        {
            "file": file,
            "channel": channel,
            "beep": i,
            "onset_sample": float(arr.onset[i]),
            "onset_s": float(arr.onset_s[i]),
            "sigma_samples": float(arr.sigma[i]),
            "snr_db": float(arr.snr_db[i]),
            "confidence": float(arr.confidence[i]),
            "flags": list(arr.flag_names(i)),
        }
        for i in range(len(arr))
    ]


def format_arrivals(rows: list[dict], fmt: str, *, meta: dict | None = None) -> str:
    """Arrival rows (from :func:`arrivals_rows`) in ``fmt``; JSON key ``arrivals``."""
    return format_rows(rows, ARRIVAL_FIELDS, fmt, meta=meta, key="arrivals")


#: Columns of a calibration in CSV (one row) and the order of its table.
CALIBRATION_FIELDS = (
    "scheme",
    "model",
    "n_recordings",
    "offset_m",
    "sigma_offset_m",
    "latency_s",
    "sigma_latency_s",
    "speed_m_s",
    "sigma_speed_m_s",
    "rms_residual_m",
    "probe",
)


def format_calibration(cal, fmt: str) -> str:
    """A fitted :class:`~rangekit.ranging.calibration.Calibration` in ``fmt``.

    table: a summary for people, each fitted value to the digits its sigma supports
    (:func:`format_pm`); json: the object ``rangekit calibrate -o`` writes; csv: one row
    of :data:`CALIBRATION_FIELDS` (latency only for oneway, the speed's sigma only when
    it was fitted; empty otherwise).
    """
    if fmt == "json":
        return json.dumps(cal.to_dict(), indent=2) + "\n"
    row = {f: getattr(cal, f) for f in CALIBRATION_FIELDS}
    if cal.scheme != "oneway":
        row.update(latency_s=None, sigma_latency_s=None)
    if cal.model != "offset+speed":
        row["sigma_speed_m_s"] = None
    if fmt == "csv":
        return format_rows([row], CALIBRATION_FIELDS, "csv")
    if fmt != "table":
        raise ValueError(f"fmt={fmt!r} must be table, json or csv")
    dists = ", ".join(f"{d:g}" for d in cal.distances_m)
    lines = [
        f"calibration: {cal.scheme}, model {cal.model}, {cal.n_recordings} measurements at "
        f"{dists} m",
        f"  offset_m     {format_pm(cal.offset_m, cal.sigma_offset_m, sign=True)}",
    ]
    if cal.scheme == "oneway":
        lines.append(f"  latency_s    {format_pm(cal.latency_s, cal.sigma_latency_s, sign=True)}")
    if cal.model == "offset+speed":
        lines.append(f"  speed_m_s    {format_pm(cal.speed_m_s, cal.sigma_speed_m_s)}")
    else:
        lines.append(f"  speed_m_s    {cal.speed_m_s:.2f} (from the temperature; not fitted)")
    lines.append(f"  rms residual {cal.rms_residual_m * 1e3:.2f} mm")
    return "\n".join(lines) + "\n"


#: Columns of an experiment report's rows in CSV.
REPORT_FIELDS = ("metric", "condition", "paper", "measured", "unit", "note", "oracle")


def format_report(report, fmt: str) -> str:
    """An :class:`~rangekit.experiments.report.ExperimentReport` in ``fmt``.

    table: the report's own table (title and parameters first); json: its documented
    object; csv: one row per number with :data:`REPORT_FIELDS` (a plain header row; the
    title and parameters are in the JSON form).
    """
    if fmt == "json":
        return report.to_json_text()
    if fmt == "csv":
        rows = [{f: r.get(f) for f in REPORT_FIELDS} for r in report.to_json()["rows"]]
        return format_rows(rows, REPORT_FIELDS, "csv")
    if fmt != "table":
        raise ValueError(f"fmt={fmt!r} must be table, json or csv")
    text = report.to_table()
    return text if text.endswith("\n") else text + "\n"
