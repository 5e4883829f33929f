"""Headline numbers of a benchmark as machine-readable lines, for ``benchmarks/run.py``.

A benchmark states each of its headline numbers once with :func:`row`, which prints one
line ``@row {json}`` to stdout (and nothing else); ``run.py`` collects these lines from
every benchmark's output and prints them as one summary table (``docs/performance.md``).
A benchmark run on its own prints them among its own output; they are meant to be
greppable (``grep '^@row '``).

Ratio
-----
``ratio`` compares rangekit with a peer measured **in the same run**, and is above 1 when
rangekit is faster (or smaller) than the peer, whatever the unit:

* throughput units (higher is better: ``x-realtime``, ``x``, anything ending in ``/s``):
  ``ratio = value / peer_value``, i.e. ``t_peer / t_rangekit`` for the same work;
* time and memory units (lower is better: ``s``, ``ms``, ``us``, ``ns``, those followed by
  ``/something`` such as ``us/step``, and ``B``, ``kB``, ``MB``, ``GB``):
  ``ratio = peer_value / value``.

The ratio is computed from ``peer_value`` unless given (e.g. from medians, or when the
peer's number is in another unit); a unit outside these lists needs an explicit ratio.

A number that was not measured in the run (a paper's timing, another machine's) is
context, not a peer: it goes in ``note`` ("context: Kim & Kim 2013 report 550 us/step"),
and :func:`row` refuses a peer named "(reported)" or "(paper)".

Run nothing here: this module is imported by the benchmarks (``from _report import row``;
the benchmark's own folder is first on ``sys.path``).
"""

from __future__ import annotations

import json
import math
import numbers
import sys
import time
from collections.abc import Callable
from typing import Any

#: The marker that starts a row line; ``run.py`` parses lines that start with it.
PREFIX = "@row "

#: Units where a larger number is better (besides those ending in "/s").
HIGHER_IS_BETTER = frozenset({"x-realtime", "x"})
#: Units where a smaller number is better: times (also per something, "us/step") and sizes.
LOWER_IS_BETTER = frozenset({"s", "ms", "us", "ns", "B", "kB", "MB", "GB"})

#: The keys of a row, in order.
FIELDS = ("bench", "metric", "value", "unit", "peer", "peer_value", "ratio", "note")


def higher_is_better(unit: str) -> bool:
    """Whether a larger ``value`` in ``unit`` means rangekit did better.

    Raises
    ------
    ValueError
        The unit is in neither list of the module docstring.
    """
    if unit in HIGHER_IS_BETTER or unit.endswith("/s"):
        return True
    if unit in LOWER_IS_BETTER or unit.split("/", 1)[0] in LOWER_IS_BETTER:
        return False
    raise ValueError(
        f"unit={unit!r}: unknown whether higher or lower is better; pass ratio= explicitly"
    )


def _number(name: str, v: Any) -> float | None:
    """A finite float, or None for a missing or non-finite number (JSON null)."""
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        raise TypeError(f"{name}={v!r} must be a real number or None")
    f = float(v)
    return f if math.isfinite(f) else None


def row(
    bench: str,
    metric: str,
    value: float | None,
    unit: str,
    *,
    peer: str | None = None,
    peer_value: float | None = None,
    ratio: float | None = None,
    note: str = "",
) -> dict[str, Any]:
    """Print one headline number of a benchmark as a line ``@row {json}`` on stdout.

    Parameters
    ----------
    bench : str
        Short name of the benchmark (its file name without ``bench_`` and ``.py``, e.g.
        ``"detect"``).
    metric : str
        What was measured, e.g. ``"detect_changepoint float64, 10 min"``.
    value : float or None
        The number; None or non-finite (not measured) is written as JSON null.
    unit : str
        Its unit, e.g. ``"x-realtime"``, ``"us/step"``, ``"s"``, ``"MB"``, ``"updates/s"``.
    peer : str, optional
        The peer it is compared with, measured in the same run (never a reported number:
        that goes in ``note``).
    peer_value : float, optional
        The peer's number in the same unit.
    ratio : float, optional
        rangekit relative to the peer, > 1 = rangekit faster / smaller (module
        docstring). Default: computed from ``peer_value`` and the unit.
    note : str
        Anything the number needs to be read right (sizes, scaling, verdicts).

    Returns
    -------
    dict
        The row as printed (keys :data:`FIELDS`).

    Raises
    ------
    ValueError
        Empty ``bench``, ``metric`` or ``unit``; a text with a line break; a ratio to
        compute for a unit of unknown direction; a peer named "(reported)" or "(paper)".
    TypeError
        A number that is not a real number.
    """
    for name, text in (("bench", bench), ("metric", metric), ("unit", unit)):
        if not isinstance(text, str) or not text.strip():
            raise ValueError(f"{name}={text!r} must be a non-empty string")
    texts = {"bench": bench, "metric": metric, "unit": unit, "peer": peer, "note": note}
    for name, text in texts.items():
        if text is not None and ("\n" in str(text) or "\r" in str(text)):
            raise ValueError(f"{name}={text!r} must be one line")
    if peer is not None and any(w in peer.lower() for w in ("(reported)", "(paper)")):
        raise ValueError(
            f"peer={peer!r}: a peer is measured in the same run; a reported number is "
            "context and goes in note"
        )
    v = _number("value", value)
    pv = _number("peer_value", peer_value)
    r = _number("ratio", ratio)
    if r is None and ratio is None and v is not None and pv is not None and v > 0 and pv > 0:
        r = v / pv if higher_is_better(unit) else pv / v
    out = {
        "bench": bench,
        "metric": metric,
        "value": v,
        "unit": unit,
        "peer": peer,
        "peer_value": pv,
        "ratio": r,
        "note": note,
    }
    sys.stdout.write(PREFIX + json.dumps(out, allow_nan=False) + "\n")
    sys.stdout.flush()
    return out


def best_of(fn: Callable[[], Any], repeats: int) -> tuple[float, float, Any]:
    """``(best wall s, best CPU s, last result)`` of ``repeats`` calls of ``fn()``.

    Wall is ``time.perf_counter``, CPU ``time.process_time`` (user + system of this
    process, all threads). On a shared machine under load the wall time of a call grows
    with the other jobs while its CPU time barely does, so a goal is judged on the CPU
    time (the wall time beside it): see ``docs/performance.md``.
    """
    wall = cpu = math.inf
    res = None
    for _ in range(max(1, repeats)):
        c0, t0 = time.process_time(), time.perf_counter()
        res = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu, res


def goal_verdict(name: str, ok: bool, cpu_text: str, wall_text: str = "") -> str:
    """``"goal >= 800x: NOT met on CPU time (355x; wall 178x)"``, the form ``run.py``
    collects as a goal's verdict (met / not met)."""
    extra = f"; wall {wall_text}" if wall_text else ""
    return f"{name}: {'met' if ok else 'NOT met'} on CPU time ({cpu_text}{extra})"
