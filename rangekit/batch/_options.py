"""How a batch ranges sessions without a sidecar value (:class:`BatchOptions`), and option
values as plain JSON (:func:`json_value`: what a results file's metadata records and a
resume compares)."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

from rangekit.errors import InvalidParameterError

if TYPE_CHECKING:
    from rangekit.ranging.calibration import Calibration
    from rangekit.signals import Beep, Probe

#: Schemes a session can be ranged with.
SCHEMES = ("beepbeep", "oneway", "echo")


@dataclass(frozen=True)
class TwoWayOptions:
    """The two-way (BeepBeep) ranging options of a batch: the keyword arguments of
    :func:`rangekit.ranging.range_files` (and :func:`~rangekit.ranging.pipeline.range_channels`
    through it), typed. ``None`` leaves the library's default (a session's sidecar value,
    where it has one, replaces ``beep``, ``temp_c`` and ``self_distance_m``).

    >>> TwoWayOptions(temp_c=25.0, detector="xcorr").kwargs()
    {'detector': 'xcorr', 'temp_c': 25.0}
    >>> TwoWayOptions.from_dict({"temp": 25.0})
    Traceback (most recent call last):
    ...
    rangekit.errors.InvalidParameterError: unknown two-way batch option 'temp' (known: beep, ...)
    """

    beep: Beep | None = None
    detector: str | None = None
    temp_c: float | None = None
    speed_m_s: float | None = None
    self_distance_m: float | tuple[float, ...] | None = None
    clock_ppm: float | None = None
    probe: Probe | None = None
    calibration: Calibration | None = None

    def __post_init__(self) -> None:
        sd = self.self_distance_m
        if isinstance(sd, list):
            object.__setattr__(self, "self_distance_m", tuple(sd))

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> TwoWayOptions:
        """From keyword arguments of ``range_files``; an unknown key is an error naming it."""
        known = [f.name for f in fields(cls)]
        for k in values:
            if k not in known:
                raise InvalidParameterError(
                    f"unknown two-way batch option {k!r} (known: {', '.join(known)})"
                )
        return cls(**values)

    def kwargs(self) -> dict[str, Any]:
        """The options that are set, as keyword arguments of ``range_files``."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        return {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in out.items() if v is not None
        }


@dataclass(frozen=True)
class BatchOptions:
    """How sessions without a sidecar value are ranged.

    ``scheme`` is the default scheme; ``beepbeep`` the two-way options
    (:class:`TwoWayOptions`, or a dict of its fields); ``oneway`` and ``echo`` those of
    the sessions of each scheme: a :class:`~rangekit.ranging.config.OneWaySetup` /
    :class:`~rangekit.ranging.config.EchoSetup` (kept as its keywords), or a mapping of
    the keyword arguments of :func:`rangekit.ranging.ultrasonic.range_ultrasonic_files`
    except ``scheme`` (``temp_c``, ``speed_m_s``, ``probe``, ``calibration`` among them;
    ``None`` is a value there, ``tx=None`` being no transducer model). ``pair_by_name`` changes
    no ranging: set it when the sessions come from :func:`pair_sessions_by_name`, so that
    the results file records it and a resume with sessions grouped by rules 1-3 (other
    names, which would mix) is refused.
    """

    scheme: str = "beepbeep"
    beepbeep: TwoWayOptions = field(default_factory=TwoWayOptions)
    oneway: Mapping[str, Any] = field(default_factory=dict)
    echo: Mapping[str, Any] = field(default_factory=dict)
    pair_by_name: bool = False

    def __post_init__(self) -> None:
        if self.scheme not in SCHEMES:
            raise InvalidParameterError(f"scheme={self.scheme!r} must be one of {SCHEMES}")
        if not isinstance(self.beepbeep, TwoWayOptions):
            object.__setattr__(self, "beepbeep", TwoWayOptions.from_dict(self.beepbeep))
        from rangekit.ranging.config import EchoSetup, OneWaySetup

        for name, kind in (("oneway", OneWaySetup), ("echo", EchoSetup)):
            v = getattr(self, name)
            if isinstance(v, (OneWaySetup, EchoSetup)):
                if not isinstance(v, kind):
                    raise InvalidParameterError(
                        f"{name}={type(v).__name__}(...) must be a {kind.__name__}"
                    )
                v = v.kwargs()
            object.__setattr__(self, name, dict(v))  # a copy: the caller's may change later

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
    if isinstance(v, Mapping):
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
