"""Header checks shared by rangekit's JSON input files (floor plans, beacon files)."""

from __future__ import annotations

from collections.abc import Mapping, Set
from typing import Any

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
