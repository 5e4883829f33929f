"""Result formats: tables for people, JSON and CSV for programs (``docs/formats.md``)."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence

import numpy as np

from rangekit.types import Arrivals, RangeResult

__all__ = ["arrivals_rows", "format_arrivals", "format_pm", "format_ranges", "format_rows"]

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


def _json_safe(row: dict) -> dict:
    """Non-finite floats become None (JSON null): JSON has no NaN."""
    return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in row.items()}


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6f}" if abs(v) < 1e6 else f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return ";".join(str(t) for t in v)
    return str(v)


def format_pm(value: float, sigma: float, *, sign: bool = False) -> str:
    """``value +- sigma`` with the digits sigma supports: two significant digits of sigma.

    Examples
    --------
    >>> format_pm(50.0012, 0.021, sign=True), format_pm(39.94, 0.3), format_pm(2.0, 0.0)
    ('+50.001 +- 0.021', '39.94 +- 0.30', '2 +- 0')
    """
    if not (math.isfinite(sigma) and sigma > 0):
        digits = 0
    else:
        digits = min(9, max(0, 1 - math.floor(math.log10(sigma))))
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
    """Render dict rows as an aligned table, CSV (header + rows) or one JSON object."""
    if fmt == "json":
        obj = dict(meta or {})
        obj[key] = list(rows)
        return json.dumps(obj, indent=2) + "\n"
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(fields)
        for r in rows:
            w.writerow([_fmt(r[f]) for f in fields])
        return buf.getvalue()
    if fmt != "table":
        raise ValueError(f"fmt={fmt!r} must be table, json or csv")
    cells = [list(fields)] + [[_fmt(r[f]) for f in fields] for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(fields))]
    lines = ["  ".join(c[i].rjust(widths[i]) for i in range(len(fields))).rstrip() for c in cells]
    return "\n".join(lines) + "\n"


def format_ranges(result: RangeResult, fmt: str, *, meta: dict | None = None) -> str:
    """Ranges of one exchange in ``fmt`` (table, json or csv).

    JSON: one object with the keys of ``meta``, ``speed_of_sound_m_s`` and a list
    ``ranges`` of objects with ``a``, ``b``, ``distance_m``, ``sigma_m``, ``flags``.
    """
    rows = [_json_safe(r.as_dict()) for r in result.ranges]
    m = {**(meta or {}), "speed_of_sound_m_s": result.speed_m_s}
    if fmt == "table":
        for r in rows:
            r["flags"] = ",".join(r["flags"]) or "-"
    return format_rows(rows, RANGE_FIELDS, fmt, meta=m, key="ranges")


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
    if fmt == "table":
        rows = [
            {
                **r,
                "onset_sample": f"{r['onset_sample']:.3f}",
                "onset_s": f"{r['onset_s']:.6f}",
                "sigma_samples": f"{r['sigma_samples']:.3f}",
                "snr_db": f"{r['snr_db']:.1f}",
                "confidence": f"{r['confidence']:.2f}",
            }
            for r in rows
        ]
    if fmt == "table":
        rows = [{**r, "flags": ",".join(r["flags"]) or "-"} for r in rows]
    if fmt == "json":
        rows = [_json_safe(r) for r in rows]
    return format_rows(rows, ARRIVAL_FIELDS, fmt, meta=meta, key="arrivals")
