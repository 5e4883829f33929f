"""Header and number checks shared by rangekit's JSON input files (floor plans, beacon files)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Set
from typing import Any

import numpy as np

from rangekit.errors import InvalidParameterError


def check_header(
    obj: Any,
    *,
    what: str,
    fmt: str,
    version: int,
    body: str,
    allowed: Set[str],
) -> None:
    """Check a JSON document's ``format``, ``version``, ``units`` and its ``body`` key.

    Raises :class:`~rangekit.errors.InvalidParameterError` naming the first problem:
    not an object, a missing or unknown key, another format, an unsupported version, or
    units other than metres. ``what`` names the document in the message ("a floor
    plan"); ``allowed`` is every top-level key the format knows.
    """
    if not isinstance(obj, Mapping):
        raise InvalidParameterError(f"{what} must be a JSON object, got {type(obj).__name__}")
    for k in ("format", "version", "units", body):
        if k not in obj:
            raise InvalidParameterError(f"missing key {k!r}")
    unknown = sorted(set(obj) - set(allowed))
    if unknown:
        raise InvalidParameterError(f"unknown key {unknown[0]!r}")
    if obj["format"] != fmt:
        raise InvalidParameterError(f"format={obj['format']!r} must be {fmt!r}")
    if isinstance(obj["version"], bool) or obj["version"] != version:
        raise InvalidParameterError(
            f"version={obj['version']!r} is not supported (this rangekit reads {version})"
        )
    if obj["units"] != "m":
        raise InvalidParameterError(f"units={obj['units']!r} must be 'm'")


#: Largest magnitude of a coordinate or length in a JSON input file, m (1000 km: far
#: beyond any building; larger values overflow the geometry, e.g. squared to inf).
MAX_COORD_M = 1e6


def json_number(where: str, v: Any, *, limit: float = MAX_COORD_M) -> float:
    """A finite float of magnitude <= ``limit`` from a JSON value (booleans are not
    numbers), or InvalidParameterError naming ``where``."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise InvalidParameterError(f"{where}={v!r} must be a number")
    try:
        f = float(v)
    except OverflowError:  # an int too large for a float
        f = math.inf
    if not math.isfinite(f):
        raise InvalidParameterError(f"{where}={v!r} must be finite")
    if abs(f) > limit:
        raise InvalidParameterError(f"{where}={v!r} must be within [-{limit:g}, {limit:g}]")
    return f
