"""A recording's setup: what the user knew before measuring, apart from any truth.

``rangekit synth`` writes its sidecar ``NAME.json`` with a ``"setup"`` object beside the
simulator's truth (``devices``, ``pairs``, ``windows``: positions, true onsets and
distances). The setup holds only what a user would know and give as options
(``docs/formats.md``, "Setup"):

* ``scheme``: ``"beepbeep"``, ``"oneway"`` or ``"echo"``;
* ``self_distance_m``: one speaker-to-microphone distance per device (beepbeep);
* ``temp_c``: the air temperature;
* ``signal``: what was played (``{"beep": {...}}`` or ``{"probe": "FILE"}``), for messages;
* ``period_s``, ``latency_s``, ``tx_order`` (oneway), ``period_s`` (echo).

:func:`find_setup` finds the setup that describes a set of recordings: ``NAME.json``
beside them (``NAME`` the recording's stem, or for ``NAME_devI.wav`` mono files the
shared ``NAME``) whose ``files`` list names exactly those recordings. ``rangekit range``
uses it for the options not given (and says so on stderr); the truth is never read.

Examples
--------
>>> s = parse_setup({"scheme": "beepbeep", "self_distance_m": [0.1, 0.12], "temp_c": 21.0},
...                 name="x.json")
>>> s.self_distance_m, s.temp_c
((0.1, 0.12), 21.0)
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rangekit.errors import InputFileError, RangekitError

__all__ = ["Setup", "find_setup", "parse_setup", "setup_defaults"]

_SCHEMES = ("beepbeep", "oneway", "echo")
_DEV = re.compile(r"^(?P<stem>.+)_dev\d+$")


@dataclass(frozen=True)
class Setup:
    """The setup of a recording (see the module docstring); None = not given."""

    path: str
    scheme: str
    self_distance_m: tuple[float, ...] | None = None
    temp_c: float | None = None
    period_s: float | None = None
    latency_s: float | None = None
    tx_order: tuple[int, ...] | None = None
    signal: dict[str, Any] | None = None


def _number(obj: dict, key: str, name: str, lo: float, hi: float) -> float | None:
    v = obj.get(key)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputFileError(f"'{name}': setup.{key} must be a number, got {v!r}")
    if not lo <= v <= hi:
        raise InputFileError(f"'{name}': setup.{key}={v!r} must be within [{lo:g}, {hi:g}]")
    return float(v)


def parse_setup(obj: Any, *, name: str) -> Setup:
    """Validate a ``"setup"`` object (booleans are not numbers; ranges as for the options).

    Raises
    ------
    InputFileError
        A field of the wrong type or out of range; the message names the file and field.
    """
    if not isinstance(obj, dict):
        raise InputFileError(f"'{name}': setup must be a JSON object")
    scheme = obj.get("scheme")
    if scheme not in _SCHEMES:
        raise InputFileError(f"'{name}': setup.scheme={scheme!r} must be one of {_SCHEMES}")
    sd = obj.get("self_distance_m")
    if sd is not None:
        vals = sd if isinstance(sd, list) else [sd]
        if not vals or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v <= 2 for v in vals
        ):
            raise InputFileError(
                f"'{name}': setup.self_distance_m must be metres in [0, 2] (one per device)"
            )
        sd = tuple(float(v) for v in vals)
    tx = obj.get("tx_order")
    if tx is not None:
        if not isinstance(tx, list) or not all(
            isinstance(t, int) and not isinstance(t, bool) and t >= 0 for t in tx
        ):
            raise InputFileError(f"'{name}': setup.tx_order must be a list of ids >= 0")
        tx = tuple(tx)
    signal = obj.get("signal")
    return Setup(
        path=name,
        scheme=scheme,
        self_distance_m=sd,
        temp_c=_number(obj, "temp_c", name, -60.0, 60.0),
        period_s=_number(obj, "period_s", name, 1e-3, 60.0),
        latency_s=_number(obj, "latency_s", name, 0.0, 1.0),
        tx_order=tx,
        signal=signal if isinstance(signal, dict) else None,
    )


def _candidates(recordings: list[Path]) -> list[Path]:
    first = recordings[0]
    out = [first.with_suffix(".json")]
    m = _DEV.match(first.stem)
    if m:
        out.append(first.with_name(m["stem"] + ".json"))
    return out


def find_setup(recordings: list[str | os.PathLike]) -> Setup | None:
    """The setup of a sidecar beside ``recordings`` that names exactly them, or None.

    A candidate that is missing, not a regular file, not JSON, without ``setup``, or
    whose ``files`` differ from the recordings' names is not this recording's setup
    (None); a ``setup`` that is malformed raises :class:`InputFileError`.
    """
    paths = [Path(p) for p in recordings]
    if not paths:
        return None
    names = [p.name for p in paths]
    folder = {p.parent.resolve() for p in paths}
    from rangekit.io.sidecar import read_json

    for cand in _candidates(paths):
        if not cand.exists():
            continue
        try:
            obj = read_json(cand)  # guarded: regular file, size cap, JSON limits
        except (OSError, RangekitError):
            continue
        if not isinstance(obj, dict) or "setup" not in obj:
            continue
        if obj.get("files") != names or {cand.parent.resolve()} != folder:
            continue
        return parse_setup(obj["setup"], name=str(cand))
    return None


def setup_defaults(setup: Setup, scheme: str, unset: Collection[str]) -> dict[str, Any]:
    """The values ``setup`` gives a ``scheme``'s options that are not set.

    ``unset`` names the options left to their defaults, among ``self_distance_m``,
    ``temp_c``, ``period_s``, ``latency_s``, ``tx_order``. Two-way: the self-distances
    and temperature; one-way: the period, latency, transmitter order and temperature;
    echo: the period and temperature. A setup for another scheme gives nothing.

    Examples
    --------
    >>> s = Setup("x.json", "beepbeep", self_distance_m=(0.1, 0.1), temp_c=25.0)
    >>> setup_defaults(s, "beepbeep", {"self_distance_m", "temp_c"})
    {'self_distance_m': (0.1, 0.1), 'temp_c': 25.0}
    >>> setup_defaults(s, "oneway", {"temp_c"})
    {}
    """
    if setup.scheme != scheme:
        return {}
    wanted = {"beepbeep": ("self_distance_m",), "oneway": ("period_s", "latency_s", "tx_order")}
    out = {}
    for key in (*wanted.get(scheme, ("period_s",)), "temp_c"):
        value = getattr(setup, key)
        if value is not None and key in unset:
            out[key] = value
    return out
