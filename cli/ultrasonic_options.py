"""The options of the ultrasonic schemes (oneway, echo) and their configuration objects.

Every option defaults to None: :func:`ultrasonic_setup` passes only what was given to
:class:`~rangekit.ranging.config.OneWaySetup` or :class:`~rangekit.ranging.config.EchoSetup`,
whose defaults are the library's (the help texts read them there too). Used by ``range``,
``batch``, ``plot matched`` and ``calibrate``.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from typing import TYPE_CHECKING

import click
from rangekit_cli._options import (
    BEEP_OPTIONS,
    FiniteRange,
    LazyHelpOption,
    QOrAuto,
    float_list,
    shown_default,
    transducer_q_options,
)

if TYPE_CHECKING:
    from rangekit.ranging.config import EchoSetup, OneWaySetup


@functools.cache
def _defaults() -> tuple[OneWaySetup, EchoSetup]:
    """The library's default one-way and echo objects (imported on first use, for help or
    a run, not whenever a command module is loaded: ``plot`` stays light)."""
    from rangekit.ranging.config import EchoSetup, OneWaySetup

    return OneWaySetup(), EchoSetup()


def _help(make):
    """``cls`` and ``lazy_help`` of an option whose help shows the library defaults:
    ``make(oneway, echo)`` returns the text, built when help is shown."""
    return {"cls": LazyHelpOption, "lazy_help": lambda: make(*_defaults())}


def _chips(code: tuple[int, ...]) -> str:
    """A code as the ``--code`` text: its Barker length, or its chips as + and -."""
    from rangekit.signals.barker import BARKER_CODES

    n = next((k for k, v in BARKER_CODES.items() if v == tuple(code) and k > 1), None)
    return str(n) if n is not None else "".join("+" if c > 0 else "-" for c in code)


def _both(ow, ec) -> str:
    """``[default: oneway: A; echo: B]`` (one value when both schemes agree)."""
    if ow == ec:
        return shown_default(ow)
    return shown_default(f"oneway: {ow}; echo: {ec}")


def _m(v: float) -> str:
    return f"{v:g}"


def ultrasonic_options(f):
    """Options of the ultrasonic schemes (oneway, echo) of ``rangekit range``."""
    opts = [
        click.option(
            "--latency",
            type=FiniteRange(0.0, 10.0),
            default=None,
            metavar="S",
            **_help(
                lambda ow, ec: (
                    "oneway: system latency from the trigger to the drive, s, "
                    f"subtracted {shown_default(ow.latency_s)}."
                )
            ),
        ),
        click.option(
            "--period",
            type=FiniteRange(1e-4, 3600.0),
            default=None,
            metavar="S",
            help="oneway/echo: the file holds consecutive windows of this length, s "
            "(0.2 for 5 Hz beacons, 0.07 for SRF02 cycles) [default: one window].",
        ),
        click.option(
            "--tx-order",
            "tx_order",
            default=None,
            metavar="ID[,ID...]",
            help="oneway: transmitter id of each window, repeating [default: none].",
        ),
        click.option(
            "--channels",
            type=click.IntRange(1, 1024),
            default=None,
            **_help(
                lambda ow, ec: (
                    "Channel count every file must have "
                    f"{_both(f'{ow.channels} receivers', ec.channels or 'any')}."
                )
            ),
        ),
        click.option(
            "--min-range",
            "min_range",
            type=FiniteRange(0.0, 1000.0),
            default=None,
            metavar="M",
            **_help(
                lambda ow, ec: (
                    "Shortest distance searched, m "
                    f"{_both(_m(ow.min_range_m), _m(ec.min_range_m) + ', the SRF02 ring-down')}."
                )
            ),
        ),
        click.option(
            "--max-range",
            "max_range",
            type=FiniteRange(0.01, 1000.0),
            default=None,
            metavar="M",
            **_help(
                lambda ow, ec: (
                    "Longest distance searched, m "
                    f"{_both(_m(ow.max_range_m), _m(ec.max_range_m) + ' (the SRF02)')}."
                )
            ),
        ),
        transducer_q_options(
            QOrAuto(),
            None,
            lambda: _q_help(*_defaults()),
        ),
        click.option(
            "--code",
            default=None,
            metavar="N|+-...",
            **_help(
                lambda ow, ec: (
                    "Emitted code: a Barker length (2,3,4,5,7,11,13) or chips as "
                    f"+ and - {_both(_chips(ow.burst.code), _chips(ec.burst.code))}."
                )
            ),
        ),
        click.option(
            "--carrier",
            type=FiniteRange(1.0, 1e7),
            default=None,
            **_help(
                lambda ow, ec: f"Carrier, Hz {_both(ow.burst.carrier_hz, ec.burst.carrier_hz)}."
            ),
        ),
        click.option(
            "--cycles-per-bit",
            "cycles_per_bit",
            type=click.IntRange(1, 1000),
            default=None,
            **_help(
                lambda ow, ec: (
                    "Carrier cycles per chip "
                    f"{_both(ow.burst.cycles_per_bit, ec.burst.cycles_per_bit)}."
                )
            ),
        ),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


def _q_help(ow, ec) -> str:
    return (
        "oneway: Q of the Tx and Rx transducers. auto = unknown: every arrival is timed by "
        f"fitting the burst through resonators of unknown Q (from {ow.transducer.q:g}) and f0 "
        "(with overlapping reflections), the estimates pooled per receiver and transmitter; "
        "Q = known, folded into the template; 0 = the bare drive (the transducers' delay "
        "stays in the ranges) [default: auto]. echo: the same for the one transducer that "
        f"sends and receives (auto: fitted from Q {ec.transducer.q:g})."
    )


def make_burst(kw: dict, *, scheme: str):
    """The CodedBurst of ``scheme`` (the library's) with ``--code``, ``--carrier`` and
    ``--cycles-per-bit`` from ``kw`` applied; its rate is 10 MHz (replaced by each file's:
    this only defers the Nyquist check to the file)."""
    from rangekit.signals.barker import BARKER_CODES

    base = _defaults()[scheme == "echo"].burst
    code = kw.get("code")
    chips = base.code
    if code is None:
        pass
    elif code.strip().isdigit():
        n = int(code)
        if n not in BARKER_CODES:
            raise click.BadParameter(
                f"no Barker code of length {n} (lengths: "
                f"{', '.join(str(k) for k in BARKER_CODES)})",
                param_hint="--code",
            )
        chips = BARKER_CODES[n]
    elif code and set(code) <= {"+", "-"}:
        chips = tuple(1 if ch == "+" else -1 for ch in code)
    else:
        raise click.BadParameter(
            f"{code!r} must be a Barker length or a string of + and -", param_hint="--code"
        )
    given = {"carrier_hz": kw.get("carrier"), "cycles_per_bit": kw.get("cycles_per_bit")}
    given = {k: v for k, v in given.items() if v is not None}
    return replace(base, code=chips, fs=1e7, **given)


_BEEP_ONLY = BEEP_OPTIONS  # the beep options belong to --scheme beepbeep


def ultrasonic_setup(kw: dict, *, scheme: str) -> OneWaySetup | EchoSetup:
    """The :class:`OneWaySetup` or :class:`EchoSetup` of the options in ``kw``.

    ``kw`` holds the values of :func:`ultrasonic_options` (and of the beep options,
    which, like one-way-only options with ``scheme="echo"``, are usage errors naming the
    option). Only the options given reach the object: the rest are its defaults.
    """
    from rangekit.ranging.config import Detection, EchoSetup, OneWaySetup
    from rangekit.signals.transducer import Transducer

    for k, opt in _BEEP_ONLY.items():
        if kw.get(k) is not None:
            raise click.UsageError(f"{opt} applies to --scheme beepbeep only")
    cfg = {"burst": make_burst(kw, scheme=scheme), "detection": Detection()}
    q = kw.get("q")
    if q == 0:
        cfg["transducer"] = None
    elif q is not None and q != "auto":
        cfg["transducer"] = Transducer(q=q)
    given = {"period_s": "period", "min_range_m": "min_range", "max_range_m": "max_range"}
    given["channels"] = "channels"
    cfg.update({k: kw[o] for k, o in given.items() if kw.get(o) is not None})
    if scheme == "echo":
        for k in ("latency", "tx_order"):
            if kw.get(k) is not None:
                raise click.UsageError(f"--{k.replace('_', '-')} applies to --scheme oneway only")
        if q is not None:
            cfg["fit_transducer"] = q == "auto"
        return EchoSetup(**cfg)
    if q is not None:
        cfg["fit_transducers"] = q == "auto"
    if kw.get("latency") is not None:
        cfg["latency_s"] = kw["latency"]
    if kw.get("tx_order") is not None:
        vals = float_list(kw["tx_order"], name="--tx-order", lo=0, hi=1e6)
        if any(v != int(v) for v in vals):
            raise click.BadParameter("ids must be whole numbers", param_hint="--tx-order")
        cfg["tx_ids"] = tuple(int(v) for v in vals)
    return OneWaySetup(**cfg)
