"""The ranging parameters and true distances a session's sidecar gives, every value type-
and range-checked (rule 1 of :mod:`rangekit.batch`): a wrong value is an error naming the
key, never replaced by a default."""

from __future__ import annotations

from typing import Any

from rangekit.errors import InputFileError, InvalidParameterError

#: Most entries of a sidecar's ``files`` list.
MAX_SIDECAR_FILES = 256


def _number(where: str, v: Any, lo: float, hi: float) -> float:
    """A JSON number within [lo, hi] (booleans are not numbers), else InvalidParameterError."""
    import math

    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InvalidParameterError(f"{where}={v!r} must be a number")
    f = float(v)
    if not (math.isfinite(f) and lo <= f <= hi):
        raise InvalidParameterError(f"{where}={v!r} must be within [{lo:g}, {hi:g}]")
    return f


def _index(where: str, v: Any) -> int:
    """A JSON integer >= 0 (``2.0`` accepted, ``true`` not), else InvalidParameterError."""
    if isinstance(v, float) and v.is_integer():
        v = int(v)
    if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 10**6:
        raise InvalidParameterError(f"{where}={v!r} must be an integer in [0, 1000000]")
    return v


#: Sidecar ``beep`` keys and their type (int or float); others are refused.
_BEEP_KEYS = {
    "f_hz": float,
    "n_bursts": int,
    "spacing": int,
    "burst_len": int,
    "taper": int,
    "amplitude": float,
    "fs": float,
}
#: Largest true distance accepted in a sidecar, m.
_MAX_TRUE_M = 1e5


def _sidecar_values(
    obj: dict, scheme: str | None
) -> tuple[dict[str, Any], tuple[tuple[int, int, float], ...]]:
    """The ranging parameters and true distances a sidecar gives (rule 1 of the module
    docstring), for a session of ``scheme``. Every value is type- and range-checked
    (``InvalidParameterError`` naming the key): a wrong value is never replaced by a
    default silently.

    A sidecar with a ``"setup"`` object (what ``rangekit synth`` writes,
    :mod:`rangekit.io.setup`) gives its parameters from there only: the simulator's truth
    beside it (``devices``, true onsets) is never read as an input."""
    params: dict[str, Any] = {}
    if "setup" in obj:
        params = _setup_params(obj["setup"], scheme)
        obj = {k: v for k, v in obj.items() if k in ("windows", "pairs")}  # truth: scoring only
    beep = obj.get("beep")
    if beep is not None:
        if not isinstance(beep, dict):
            raise InvalidParameterError("'beep' must be an object")
        b: dict[str, Any] = {}
        for k, v in beep.items():
            if k not in _BEEP_KEYS:
                continue  # written by the simulator (e.g. durations), not a parameter
            if _BEEP_KEYS[k] is int:
                b[k] = _index(f"beep.{k}", v)
            else:
                b[k] = _number(f"beep.{k}", v, 0.0, 1e7)
        params["beep"] = b
    if obj.get("temp_c") is not None:
        params["temp_c"] = _number("temp_c", obj["temp_c"], -60.0, 60.0)
    sd = obj.get("self_distance_m")
    devices = obj.get("devices")
    if isinstance(sd, list):
        if not 1 <= len(sd) <= MAX_SIDECAR_FILES:
            raise InvalidParameterError("'self_distance_m' must hold 1 to 256 numbers")
        params["self_distance_m"] = [
            _number(f"self_distance_m[{i}]", v, 0.0, 2.0) for i, v in enumerate(sd)
        ]
    elif sd is not None:
        params["self_distance_m"] = _number("self_distance_m", sd, 0.0, 2.0)
    elif isinstance(devices, list) and devices:
        if all(isinstance(d, dict) and "self_distance_m" in d for d in devices):
            params["self_distance_m"] = [
                _number(f"devices[{i}].self_distance_m", d["self_distance_m"], 0.0, 2.0)
                for i, d in enumerate(devices)
            ]
    if scheme in ("oneway", "echo"):
        if obj.get("period_s") is not None:
            params["period_s"] = _number("period_s", obj["period_s"], 1e-4, 3600.0)
        if obj.get("latency_s") is not None:
            params["latency_s"] = _number("latency_s", obj["latency_s"], 0.0, 10.0)
    truth = []
    windows = obj.get("windows") or []
    pairs = obj.get("pairs") or []
    if not isinstance(windows, list) or not isinstance(pairs, list):
        raise InvalidParameterError("'windows' and 'pairs' must be lists")
    for k, w in enumerate(windows):
        if not isinstance(w, dict) or "window" not in w:
            raise InvalidParameterError(f"windows[{k}] must be an object with a 'window'")
        win = _index(f"windows[{k}].window", w["window"])
        if scheme == "oneway" and isinstance(w.get("distances_m"), list):
            for c, d in enumerate(w["distances_m"]):
                if d is not None:
                    where = f"windows[{k}].distances_m[{c}]"
                    truth.append((win, c, _number(where, d, 0.0, _MAX_TRUE_M)))
        elif scheme == "echo" and w.get("distance_m") is not None:
            d = _number(f"windows[{k}].distance_m", w["distance_m"], 0.0, _MAX_TRUE_M)
            truth.append((win, 0, d))
    for k, p in enumerate(pairs):
        if not isinstance(p, dict) or "a" not in p or "b" not in p:
            raise InvalidParameterError(f"pairs[{k}] must be an object with 'a' and 'b'")
        a, b_ = _index(f"pairs[{k}].a", p["a"]), _index(f"pairs[{k}].b", p["b"])
        if p.get("distance_m") is not None:
            d = _number(f"pairs[{k}].distance_m", p["distance_m"], 0.0, _MAX_TRUE_M)
            truth.append((a, b_, d))
    return params, tuple(truth)


def _setup_params(setup: Any, scheme: str | None) -> dict[str, Any]:
    """The parameters of a sidecar's ``setup`` (:func:`rangekit.io.setup.parse_setup`)."""
    from rangekit.io.setup import parse_setup

    try:
        s = parse_setup(setup, name="setup")
    except InputFileError as e:
        raise InvalidParameterError(str(e).replace("'setup': ", "")) from None
    signal = s.signal or {}
    if "probe" in signal:
        raise InvalidParameterError(
            f"the session played the probe {signal['probe']!r}; batch ranges the built-in "
            "beep only (range it with `rangekit range --template`)"
        )
    params: dict[str, Any] = {}
    beep = signal.get("beep")
    if isinstance(beep, dict):
        params["beep"] = {
            k: (_index(f"setup.signal.beep.{k}", v) if _BEEP_KEYS[k] is int
                else _number(f"setup.signal.beep.{k}", v, 0.0, 1e7))
            for k, v in beep.items()
            if k in _BEEP_KEYS
        }  # fmt: skip
    if s.temp_c is not None:
        params["temp_c"] = s.temp_c
    if s.self_distance_m is not None:
        params["self_distance_m"] = list(s.self_distance_m)
    if scheme in ("oneway", "echo") and s.period_s is not None:
        params["period_s"] = s.period_s
    if scheme == "oneway":
        if s.latency_s is not None:
            params["latency_s"] = s.latency_s
        if s.tx_order is not None:
            params["tx_order"] = list(s.tx_order)
    return params
