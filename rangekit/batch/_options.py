"""How a batch ranges sessions without a sidecar value (:class:`BatchOptions`), and option
values as plain JSON (:func:`json_value`: what a results file's metadata records and a
resume compares)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any

from rangekit.errors import InvalidParameterError

#: Schemes a session can be ranged with.
SCHEMES = ("beepbeep", "oneway", "echo")


@dataclass(frozen=True)
class BatchOptions:
    """How sessions without a sidecar value are ranged.

    ``scheme`` is the default scheme; ``beepbeep`` holds the keyword arguments of
    :func:`rangekit.ranging.range_files` (``beep``, ``detector``, ``temp_c``,
    ``speed_m_s``, ``self_distance_m``, ``clock_ppm``); ``oneway`` and ``echo`` those of
    :func:`rangekit.ranging.ultrasonic.range_ultrasonic_files` except ``scheme``, for the
    sessions of each scheme. ``pair_by_name`` changes no ranging: set it when the sessions
    come from :func:`pair_sessions_by_name`, so that the results file records it and a
    resume with sessions grouped by rules 1-3 (other names, which would mix) is refused.
    """

    scheme: str = "beepbeep"
    beepbeep: dict[str, Any] = field(default_factory=dict)
    oneway: dict[str, Any] = field(default_factory=dict)
    echo: dict[str, Any] = field(default_factory=dict)
    pair_by_name: bool = False

    def __post_init__(self) -> None:
        if self.scheme not in SCHEMES:
            raise InvalidParameterError(f"scheme={self.scheme!r} must be one of {SCHEMES}")

    def fingerprint(self) -> str:
        """A stable JSON text of every option that changes results (checked on resume):
        option values as JSON (:func:`json_value`), not Python reprs."""
        parts: dict[str, Any] = {
            "scheme": self.scheme,
            "grouping": "pair-by-name" if self.pair_by_name else "rules",
            "beepbeep": json_value(self.beepbeep),
            "oneway": json_value(self.oneway),
            "echo": json_value(self.echo),
        }
        return json.dumps(parts, sort_keys=True, allow_nan=False)


def json_value(v: Any) -> Any:
    """An option value as plain JSON: a dataclass (``Beep``, ``Transducer``, ``Probe``,
    ``Calibration``, ...) as an object of its fields plus ``"type"``; a tuple as a list; an
    array by its length and SHA-1 (a probe's samples); a non-finite float as its text.

    >>> from rangekit.signals import Beep
    >>> json_value({"detector": "changepoint", "beep": Beep(f_hz=17000.0), "speed": None})
    ... # doctest: +NORMALIZE_WHITESPACE
    {'beep': {'type': 'Beep', 'f_hz': 17000.0, 'n_bursts': 4, 'spacing': 5000,
    'burst_len': 441, 'taper': 22, 'amplitude': 0.9, 'fs': 44100.0},
    'detector': 'changepoint', 'speed': None}
    """
    import dataclasses
    import math

    if v is None or isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, float):
        return v if math.isfinite(v) else repr(v)
    if isinstance(v, dict):
        return {str(k): json_value(x) for k, x in sorted(v.items())}
    if isinstance(v, (list, tuple)):
        return [json_value(x) for x in v]
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        out = {"type": type(v).__name__}
        out.update({f.name: json_value(getattr(v, f.name)) for f in dataclasses.fields(v)})
        return out
    if hasattr(v, "tobytes") and hasattr(v, "shape"):  # a numpy array
        import hashlib

        if v.shape == ():
            return json_value(v.item())
        return {"shape": list(v.shape), "sha1": hashlib.sha1(v.tobytes()).hexdigest()}
    if hasattr(v, "item"):  # a numpy scalar
        return json_value(v.item())
    return repr(v)
