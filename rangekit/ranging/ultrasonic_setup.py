"""One-way and echo configuration objects from plain values, each default the library's.

:func:`ultrasonic_setup` builds a :class:`~rangekit.ranging.config.OneWaySetup` or
:class:`~rangekit.ranging.config.EchoSetup` from values of which any may be None (not
given: the object's default); :func:`scheme_burst` builds the emitted code alone. They hold
what a value *means* (a code written as text, the transducer's ``"auto"`` and ``0``), so
that ``rangekit range``, ``batch``, ``calibrate``, ``plot matched`` and a Python user
build the same object from the same values (the CLI's ultrasonic options are parsed and
passed to these).

Examples
--------
>>> s = ultrasonic_setup("oneway", code="5", q=6.0, period_s=0.2, tx_ids=[2, 0])
>>> s.burst.code, s.transducer.q, s.fit_transducers, s.tx_ids
((1, 1, 1, -1, 1), 6.0, False, (2, 0))
>>> ultrasonic_setup("echo", q=0).transducer is None
True
>>> ultrasonic_setup("echo", latency_s=0.1)
Traceback (most recent call last):
...
rangekit.errors.InvalidParameterError: latency_s applies to scheme 'oneway' only, not 'echo'
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from rangekit.errors import InvalidParameterError
from rangekit.ranging.config import Detection, EchoSetup, OneWaySetup
from rangekit.signals.barker import CodedBurst
from rangekit.signals.codes import parse_code
from rangekit.signals.transducer import Transducer

__all__ = ["BURST_FS", "SCHEMES", "scheme_burst", "ultrasonic_setup"]

#: The ultrasonic schemes and their configuration objects.
SCHEMES = {"oneway": OneWaySetup, "echo": EchoSetup}

#: Sample rate of a burst built here, Hz: each recording's rate replaces it when it is
#: ranged, so this high rate only defers the Nyquist check (of the carrier and chip rate
#: given) to the recording.
BURST_FS = 1e7


def _kind(scheme: str):
    if scheme not in SCHEMES:
        raise InvalidParameterError(f"scheme={scheme!r} must be one of {', '.join(SCHEMES)}")
    return SCHEMES[scheme]


def scheme_burst(
    scheme: str,
    *,
    code: str | Sequence[int] | None = None,
    carrier_hz: float | None = None,
    cycles_per_bit: int | None = None,
    fs: float = BURST_FS,
) -> CodedBurst:
    """The emitted code of ``scheme`` (its setup's default burst) with the values given.

    Parameters
    ----------
    scheme : {"oneway", "echo"}
        Whose default burst the values replace: Barker-7 on 40 kHz, 3 cycles per chip
        (oneway), or the SRF02 ping, 8 cycles of 40 kHz (echo).
    code : str or sequence of int, optional
        A Barker length or chips as ``+``/``-`` (:func:`rangekit.signals.codes.parse_code`),
        or the chips themselves.
    carrier_hz, cycles_per_bit : optional
        Carrier frequency, Hz, and carrier cycles per chip.
    fs : float
        The burst's sample rate [default: :data:`BURST_FS`, replaced by each recording's].
    """
    base = _kind(scheme)().burst
    chips = base.code if code is None else code
    if isinstance(chips, str):
        chips = parse_code(chips)
    given = {"carrier_hz": carrier_hz, "cycles_per_bit": cycles_per_bit}
    given = {k: v for k, v in given.items() if v is not None}
    return replace(base, code=tuple(chips), fs=fs, **given)


def _transducer(q) -> dict:
    """The transducer fields a ``q`` means (None: {}, the setup's defaults)."""
    if q is None:
        return {}
    if q == "auto":
        return {"fit": True}
    if q == 0:
        return {"transducer": None, "fit": False}
    return {"transducer": Transducer(q=q), "fit": False}


def ultrasonic_setup(
    scheme: str,
    *,
    code: str | Sequence[int] | None = None,
    carrier_hz: float | None = None,
    cycles_per_bit: int | None = None,
    q: float | str | None = None,
    transducer_family: str | None = None,
    latency_s: float | None = None,
    period_s: float | None = None,
    tx_ids: Sequence[int] | None = None,
    channels: int | None = None,
    min_range_m: float | None = None,
    max_range_m: float | None = None,
    detection: Detection | None = None,
) -> OneWaySetup | EchoSetup:
    """The :class:`OneWaySetup` (``scheme="oneway"``) or :class:`EchoSetup` of the values
    given; every value left None is the object's default.

    Parameters
    ----------
    scheme : {"oneway", "echo"}
    code, carrier_hz, cycles_per_bit
        The emitted code (:func:`scheme_burst`; its rate is :data:`BURST_FS`, replaced by
        each recording's).
    q : float, "auto" or None
        The transducers: ``"auto"`` = Q unknown, each arrival fitted through resonators
        (from the default transducer); a Q in [0.5, 100] = known, folded into the
        template (not fitted); 0 = the bare drive (no transducer model: its delay stays
        in the ranges); None = the setup's default (fitted).
    transducer_family : {"resonator", "unknown"} or None
        With the fit, what is known of the transducers' family: ``"resonator"`` the
        resonant piezo of the papers, ``"unknown"`` any shape (a wider sigma that covers
        a non-resonator's model error; :func:`~rangekit.ranging.oneway.range_oneway`);
        None = the setup's default (``"resonator"``).
    latency_s, tx_ids
        One-way only: system latency (s) and each window's transmitter id; given with
        ``scheme="echo"`` they are an error.
    period_s, channels, min_range_m, max_range_m, detection
        As :class:`OneWaySetup` / :class:`EchoSetup`.

    Raises
    ------
    InvalidParameterError
        A one-way-only value with ``scheme="echo"``, a bad code, or a value the setup
        refuses (named).
    """
    kind = _kind(scheme)
    burst = scheme_burst(scheme, code=code, carrier_hz=carrier_hz, cycles_per_bit=cycles_per_bit)
    cfg: dict = {"burst": burst, "detection": Detection() if detection is None else detection}
    t = _transducer(q)
    if "transducer" in t:
        cfg["transducer"] = t["transducer"]
    given = {
        "period_s": period_s,
        "min_range_m": min_range_m,
        "max_range_m": max_range_m,
        "channels": channels,
    }
    if transducer_family is not None:
        given["transducer_family"] = transducer_family
    cfg.update({k: v for k, v in given.items() if v is not None})
    if kind is EchoSetup:
        for name, v in (("latency_s", latency_s), ("tx_ids", tx_ids)):
            if v is not None:
                raise InvalidParameterError(
                    f"{name} applies to scheme 'oneway' only, not {scheme!r}"
                )
        if "fit" in t:
            cfg["fit_transducer"] = t["fit"]
        return EchoSetup(**cfg)
    if "fit" in t:
        cfg["fit_transducers"] = t["fit"]
    if latency_s is not None:
        cfg["latency_s"] = latency_s
    if tx_ids is not None:
        cfg["tx_ids"] = tuple(tx_ids)
    return OneWaySetup(**cfg)
