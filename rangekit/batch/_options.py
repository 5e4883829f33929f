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
    from rangekit.physics import Medium
    from rangekit.ranging.calibration import Calibration
    from rangekit.ranging.config import EchoSetup, OneWaySetup
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
class UltrasonicOptions:
    """The one-way or echo ranging options of a batch, typed like :class:`TwoWayOptions`.

    ``setup`` is the job (:class:`~rangekit.ranging.config.OneWaySetup` or
    :class:`~rangekit.ranging.config.EchoSetup`; None: the library's defaults),
    ``medium`` the speed of sound (:class:`~rangekit.physics.Medium`; None: the
    library's), ``probe`` a lab's probe instead of the coded burst, ``calibration`` a
    calibration of the scheme. A session's sidecar values (temperature, period, latency,
    transmitter order) replace the job's for that session.

    >>> from rangekit.ranging.config import EchoSetup
    >>> UltrasonicOptions(EchoSetup(period_s=0.07)).kwargs()["period_s"]
    0.07
    >>> UltrasonicOptions().kwargs()
    {}
    """

    setup: OneWaySetup | EchoSetup | None = None
    medium: Medium | None = None
    probe: Probe | None = None
    calibration: Calibration | None = None

    def kwargs(self) -> dict[str, Any]:
        """As keyword arguments of
        :func:`~rangekit.ranging.ultrasonic.range_ultrasonic_files` (except ``scheme``);
        what is not set is left out (the library's default)."""
        out: dict[str, Any] = {} if self.setup is None else self.setup.kwargs()
        if self.medium is not None:
            out.update(self.medium.kwargs())
        if self.probe is not None:
            out["probe"] = self.probe
        if self.calibration is not None:
            out["calibration"] = self.calibration
        return out


@dataclass(frozen=True)
class BatchOptions:
    """How sessions without a sidecar value are ranged.

    ``scheme`` is the default scheme; ``beepbeep`` the two-way options
    (:class:`TwoWayOptions`, or a dict of its fields); ``oneway`` and ``echo`` those of
    the sessions of each scheme: an :class:`UltrasonicOptions`, or just its job, a
    :class:`~rangekit.ranging.config.OneWaySetup` /
    :class:`~rangekit.ranging.config.EchoSetup` (the medium then the library's).
    ``pair_by_name`` changes
    no ranging: set it when the sessions come from :func:`pair_sessions_by_name`, so that
    the results file records it and a resume with sessions grouped by rules 1-3 (other
    names, which would mix) is refused.
    """

    scheme: str = "beepbeep"
    beepbeep: TwoWayOptions = field(default_factory=TwoWayOptions)
    oneway: UltrasonicOptions = field(default_factory=UltrasonicOptions)
    echo: UltrasonicOptions = field(default_factory=UltrasonicOptions)
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
                v = UltrasonicOptions(setup=v)
            if not isinstance(v, UltrasonicOptions):
                raise InvalidParameterError(
                    f"{name}={type(v).__name__}(...) must be an UltrasonicOptions or a "
                    f"{kind.__name__}"
                )
            if v.setup is not None and not isinstance(v.setup, kind):
                raise InvalidParameterError(
                    f"{name}={type(v.setup).__name__}(...) must be a {kind.__name__}"
                )
            object.__setattr__(self, name, v)

    def fingerprint(self) -> str:
        """A stable JSON text of every option that changes results (checked on resume):
        option values as JSON (:func:`json_value`), not Python reprs."""
        parts: dict[str, Any] = {
            "scheme": self.scheme,
            "grouping": "pair-by-name" if self.pair_by_name else "rules",
            "beepbeep": json_value(self.beepbeep),
            "oneway": json_value(self.oneway.kwargs()),
            "echo": json_value(self.echo.kwargs()),
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
