"""Options that describe the measurement setup: the air (temperature, speed of sound), the
transducers (``--transducer-q``), the self-distances, the clock tolerance and a
calibration (``--calibration``, read and checked against the scheme). Each defaults to
the library's value (read when it is used or shown, never copied)."""

from __future__ import annotations

import functools

import click
from rangekit_cli._options_types import FiniteRange, LazyHelpOption, shown_default
from rangekit_cli._options_verbosity import warn

__all__ = [
    "calibration_option",
    "clock_ppm_option",
    "read_calibration",
    "refuse_self_distance",
    "self_distance_option",
    "speed_of_sound_option",
    "temperature_option",
    "transducer_q_options",
]


def _temp_c() -> float:
    from rangekit.physics import DEFAULT_TEMP_C

    return DEFAULT_TEMP_C


def _clock_ppm() -> float:
    from rangekit.ranging.beepbeep import DEFAULT_CLOCK_PPM

    return DEFAULT_CLOCK_PPM


def transducer_q_options(type_: click.ParamType, default, help):
    """``--transducer-q`` (parameter ``q``) and the old ``--q``, hidden, kept for one release.

    The old spelling gives the same value with a one-line deprecation note on stderr;
    both at once are a usage error (exit 2). ``help`` is a text, or a function returning
    it (built when help is shown: :class:`LazyHelpOption`). Returns a decorator.
    """
    lazy = {"cls": LazyHelpOption, "lazy_help": help} if callable(help) else {"help": help}

    def deco(f):
        @click.option(
            "--transducer-q",
            "q",
            type=type_,
            default=default,
            show_default=default is not None,
            **lazy,
        )
        @click.option("--q", "q_deprecated", type=type_, default=None, hidden=True)
        @functools.wraps(f)
        def wrapper(*args, q_deprecated=None, **kw):
            if q_deprecated is not None:
                ctx = click.get_current_context()
                if ctx.get_parameter_source("q") == click.core.ParameterSource.COMMANDLINE:
                    raise click.UsageError("give --transducer-q only (--q is its old spelling)")
                kw["q"] = q_deprecated
                warn("rangekit: --q is deprecated and goes in the next release: --transducer-q")
            return f(*args, **kw)

        return wrapper

    return deco


def temperature_option(f):
    """--temperature C: air temperature (sets the speed of sound)."""
    return click.option(
        "--temperature",
        "temp_c",
        type=FiniteRange(-60.0, 60.0),
        cls=LazyHelpOption,
        default=_temp_c,  # rangekit.physics.DEFAULT_TEMP_C
        show_default=True,
        help="Air temperature, C.",
    )(f)


def _self_distance() -> float:
    from rangekit.ranging.config import TwoWaySetup

    return TwoWaySetup().self_distance_m


def self_distance_option(help: str):
    """--self-distance M[,M...] (string; parse with :func:`float_list`), None when not
    given: the default is :class:`rangekit.ranging.config.TwoWaySetup`'s, shown in the
    help when help is shown."""
    return click.option(
        "--self-distance",
        "self_distance",
        metavar="M[,M...]",
        default=None,
        cls=LazyHelpOption,
        lazy_help=lambda: f"{help}  {shown_default(_self_distance())}",
    )


def speed_of_sound_option(help: str = "Speed of sound in m/s (overrides --temperature)."):
    """--speed-of-sound MPS (``speed``), None when not given."""
    return click.option(
        "--speed-of-sound",
        "speed",
        type=FiniteRange(100.0, 2000.0),
        default=None,
        metavar="MPS",
        help=help,
    )


def clock_ppm_option(help: str):
    """--clock-ppm PPM: 1-sigma sample-clock tolerance per device."""
    return click.option(
        "--clock-ppm",
        "clock_ppm",
        type=FiniteRange(0.0, 1e4),
        cls=LazyHelpOption,
        default=_clock_ppm,  # rangekit.ranging.beepbeep.DEFAULT_CLOCK_PPM
        show_default=True,
        help=help,
    )


calibration_option = click.option(
    "--calibration",
    type=click.Path(dir_okay=False),
    default=None,
    metavar="CAL.json",
    help="Apply a calibration from `rangekit calibrate` (beepbeep, oneway): its offset "
    "replaces --self-distance (--latency for oneway), its fitted speed of sound, if any, "
    "replaces --temperature.",
)


def refuse_self_distance(sd) -> None:
    """Usage error for --self-distance given with --calibration (None: not given)."""
    if sd is not None and any(v != 0 for v in sd):
        raise click.UsageError(
            "give --self-distance or --calibration, not both: the calibration's offset "
            "already holds the speaker-to-microphone distances"
        )


def read_calibration(path, scheme: str):
    """The calibration of ``--calibration`` (None without it), checked against the scheme."""
    if path is None:
        return None
    from rangekit.ranging.calibration import read_calibration as read

    cal = read(path)
    if cal.scheme != scheme:
        raise click.UsageError(f"'{path}' is a calibration for --scheme {cal.scheme}, not {scheme}")
    return cal
