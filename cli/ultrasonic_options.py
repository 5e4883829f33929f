"""The options of the ultrasonic schemes (oneway, echo) and their configuration objects.

Every option defaults to None: :func:`ultrasonic_setup` parses the options given and
passes them to :func:`rangekit.ranging.ultrasonic_setup.ultrasonic_setup`, which builds
:class:`~rangekit.ranging.config.OneWaySetup` or :class:`~rangekit.ranging.config.EchoSetup`
with the library's defaults for the rest (the help texts read them there too). Used by
``range``, ``batch``, ``plot matched`` and ``calibrate``.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import click
from rangekit_cli._options import (
    BEEP_OPTIONS,
    FiniteRange,
    LazyHelpOption,
    QOrAuto,
    id_list,
    number_option,
    parse_code,
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
        number_option(
            "--latency",
            lo=0.0,
            hi=10.0,
            metavar="S",
            **_help(
                lambda ow, ec: (
                    "oneway: system latency from the trigger to the drive, s, "
                    f"subtracted {shown_default(ow.latency_s)}."
                )
            ),
        ),
        number_option(
            "--period",
            lo=1e-4,
            hi=3600.0,
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
        number_option(
            "--min-range",
            "min_range",
            lo=0.0,
            hi=1000.0,
            metavar="M",
            **_help(
                lambda ow, ec: (
                    "Shortest distance searched, m "
                    f"{_both(_m(ow.min_range_m), _m(ec.min_range_m) + ', the SRF02 ring-down')}."
                )
            ),
        ),
        number_option(
            "--max-range",
            "max_range",
            lo=0.01,
            hi=1000.0,
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
            "--transducer-family",
            "transducer_family",
            type=click.Choice(_families()),
            default=None,
            **_help(
                lambda ow, ec: (
                    "oneway/echo, with --transducer-q auto: what is known of the "
                    "transducers' family. resonator = the resonant piezo of the papers; "
                    "unknown = any shape (a coupled or band-pass element): sigma from "
                    "Akaike weights, so its model error is covered; 1.7-4.5x wider for a "
                    f"resonator {_both(ow.transducer_family, ec.transducer_family)}."
                )
            ),
        ),
        click.option(
            "--code",
            default=None,
            metavar="N|+-...",
            **_help(
                lambda ow, ec: (
                    "Emitted code: a Barker length (2,3,4,5,7,11,13) or chips as "
                    f"+ and - {_both(_code_text(ow.burst.code), _code_text(ec.burst.code))}."
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


def _families() -> tuple[str, ...]:
    """The values of ``--transducer-family`` (the library's; written here, not imported,
    so that loading a command module stays light; tests check they agree)."""
    return ("resonator", "unknown")


def _q_help(ow, ec) -> str:
    return (
        "oneway: Q of the Tx and Rx transducers. auto = unknown: every arrival is timed by "
        f"fitting the burst through resonators of unknown Q (from {ow.transducer.q:g}) and f0 "
        "(with overlapping reflections), the estimates pooled per receiver and transmitter; "
        "Q = known, folded into the template; 0 = the bare drive (the transducers' delay "
        "stays in the ranges) [default: auto]. echo: the same for the one transducer that "
        f"sends and receives (auto: fitted from Q {ec.transducer.q:g})."
    )


def _code_text(code) -> str:
    """A code as the ``--code`` text (:func:`rangekit.signals.codes.code_text`)."""
    from rangekit.signals.codes import code_text

    return code_text(code)


_BEEP_ONLY = BEEP_OPTIONS  # the beep options belong to --scheme beepbeep

#: The parameters of :func:`ultrasonic_options` and their option names (all refused with
#: --scheme beepbeep by :func:`refuse_ultrasonic_options`).
ULTRASONIC_KEYS = {
    "latency": "--latency",
    "period": "--period",
    "tx_order": "--tx-order",
    "channels": "--channels",
    "min_range": "--min-range",
    "max_range": "--max-range",
    "q": "--transducer-q",
    "transducer_family": "--transducer-family",
    "code": "--code",
    "carrier": "--carrier",
    "cycles_per_bit": "--cycles-per-bit",
}


def refuse_ultrasonic_options(kw: dict, *, remove: bool = True) -> None:
    """Usage error for a one-way / echo option given with the two-way scheme, naming it
    (with ``remove``, the options are removed from ``kw``)."""
    for k, opt in ULTRASONIC_KEYS.items():
        if (kw.pop(k, None) if remove else kw.get(k)) is not None:
            raise click.UsageError(f"{opt} applies to --scheme oneway and echo only")


def ultrasonic_setup(
    kw: dict, *, scheme: str, any_receivers: bool = False
) -> OneWaySetup | EchoSetup:
    """The :class:`OneWaySetup` or :class:`EchoSetup` of the options in ``kw``.

    ``kw`` holds the values of :func:`ultrasonic_options` (and of the beep options,
    which, like one-way-only options with ``scheme="echo"``, are usage errors naming the
    option). Only the options given reach the object
    (:func:`rangekit.ranging.ultrasonic_setup.ultrasonic_setup`): the rest are its
    defaults. With ``any_receivers`` (a lab's probe, a calibration rig) the setup takes
    as many receivers as the recordings hold unless ``--channels`` names them.
    """
    from rangekit.ranging.ultrasonic_setup import ultrasonic_setup as build

    for k, opt in _BEEP_ONLY.items():
        if kw.get(k) is not None:
            raise click.UsageError(f"{opt} applies to --scheme beepbeep only")
    code = parse_code(kw.get("code"))
    if scheme == "echo":
        for k in ("latency", "tx_order"):
            if kw.get(k) is not None:
                raise click.UsageError(f"--{k.replace('_', '-')} applies to --scheme oneway only")
    setup = build(
        scheme,
        code=code,
        carrier_hz=kw.get("carrier"),
        cycles_per_bit=kw.get("cycles_per_bit"),
        q=kw.get("q"),
        transducer_family=kw.get("transducer_family"),
        latency_s=kw.get("latency"),
        period_s=kw.get("period"),
        tx_ids=id_list(kw.get("tx_order"), name="--tx-order"),
        channels=kw.get("channels"),
        min_range_m=kw.get("min_range"),
        max_range_m=kw.get("max_range"),
    )
    if any_receivers and kw.get("channels") is None:
        from dataclasses import replace

        setup = replace(setup, channels=None)
    return setup
