"""Options that describe the signal played: the beep (its options, refused with a probe),
the coded burst of the ultrasonic schemes (``--code``, ``--carrier``, ``--cycles-per-bit``
as a :class:`~rangekit.signals.barker.CodedBurst`), or the probe file of ``--template``,
and the arrival detector."""

from __future__ import annotations

import click
from rangekit_cli._options_types import FiniteRange, LazyHelpOption, shown_default

__all__ = [
    "BEEP_OPTIONS",
    "TEMPLATE_HELP",
    "beep_options",
    "detector_option",
    "load_template",
    "make_beep",
    "make_burst",
    "parse_code",
    "refuse_beep_options",
    "template_option",
]


def _beep_help(text: str, name: str) -> dict:
    """An option help ending in the default of :class:`rangekit.signals.Beep`'s ``name``,
    read when help is shown (:class:`LazyHelpOption`)."""

    def make() -> str:
        from rangekit.signals import Beep

        return f"{text} {shown_default(getattr(Beep(), name))}."

    return {"cls": LazyHelpOption, "lazy_help": make}


def beep_options(f):
    """--freq/--bursts/--spacing/--burst-len/--taper/--beep-fs: the beep that was played."""
    opts = [
        click.option(
            "--freq",
            "f_hz",
            type=FiniteRange(1.0, 1e7),
            default=None,
            **_beep_help("Beep frequency in Hz", "f_hz"),
        ),
        click.option(
            "--bursts",
            "n_bursts",
            type=click.IntRange(1, 64),
            default=None,
            **_beep_help(
                "Bursts per beep, at most 64 (the detectors' work grows with it)", "n_bursts"
            ),
        ),
        click.option(
            "--spacing",
            type=click.IntRange(1, 10**7),
            default=None,
            **_beep_help(
                "Samples between burst starts; the whole beep lasts at most 10 s", "spacing"
            ),
        ),
        click.option(
            "--burst-len",
            "burst_len",
            type=click.IntRange(8, 10**7),
            default=None,
            **_beep_help("Samples per burst", "burst_len"),
        ),
        click.option(
            "--taper",
            type=click.IntRange(0, 10**7),
            default=None,
            **_beep_help("Raised-cosine taper samples at each end", "taper"),
        ),
        click.option(
            "--beep-fs",
            "beep_fs",
            type=FiniteRange(1000.0, 1e7),
            default=None,
            **_beep_help("Sample rate the beep is defined at, Hz", "fs"),
        ),
    ]
    for o in reversed(opts):
        f = o(f)
    return f


#: The options of :func:`beep_options`, by parameter name.
BEEP_OPTIONS = {
    "f_hz": "--freq",
    "n_bursts": "--bursts",
    "spacing": "--spacing",
    "burst_len": "--burst-len",
    "taper": "--taper",
    "beep_fs": "--beep-fs",
}


def refuse_beep_options(kw: dict) -> None:
    """Usage error if a beep option was given with ``--template`` (the probe replaces it)."""
    for key, opt in BEEP_OPTIONS.items():
        if kw.get(key) is not None:
            raise click.UsageError(f"{opt} describes the built-in beep; drop it or --template")


def make_beep(kw: dict, *, amplitude: float | None = None):
    """Build a Beep from the options of :func:`beep_options` (popped from ``kw``)."""
    from rangekit.signals import Beep

    args = {}
    for key, name in (
        ("f_hz", "f_hz"),
        ("n_bursts", "n_bursts"),
        ("spacing", "spacing"),
        ("burst_len", "burst_len"),
        ("taper", "taper"),
        ("beep_fs", "fs"),
    ):
        v = kw.pop(key, None)
        if v is not None:
            args[name] = v
    if amplitude is not None:
        args["amplitude"] = amplitude
    return Beep(**args)


def parse_code(code: str | None):
    """``--code`` (a Barker length or chips as + and -) as chips, None when not given
    (:func:`rangekit.signals.codes.parse_code`); a bad text is a usage error naming it."""
    if code is None:
        return None
    from rangekit.errors import InvalidParameterError
    from rangekit.signals.codes import parse_code as parse

    try:
        return parse(code)
    except InvalidParameterError as e:
        raise click.BadParameter(str(e), param_hint="--code") from None


def make_burst(kw: dict, *, scheme: str):
    """The CodedBurst of ``scheme`` (the library's) with ``--code``, ``--carrier`` and
    ``--cycles-per-bit`` from ``kw`` applied
    (:func:`rangekit.ranging.ultrasonic_setup.scheme_burst`); its rate is 10 MHz (replaced
    by each file's: this only defers the Nyquist check to the file)."""
    from rangekit.ranging.ultrasonic_setup import scheme_burst

    return scheme_burst(
        scheme,
        code=parse_code(kw.get("code")),
        carrier_hz=kw.get("carrier"),
        cycles_per_bit=kw.get("cycles_per_bit"),
    )


def detector_option(f):
    """--detector changepoint|xcorr (rangekit.detect.DETECTORS, tested equal)."""
    return click.option(
        "--detector",
        type=click.Choice(["changepoint", "xcorr"]),
        default="changepoint",
        show_default=True,
        help="Arrival detector for the beep: STFT change point + edge fit, or the whole-beep "
        "cross-correlation baseline.",
    )(f)


TEMPLATE_HELP = (
    "The probe signal that was played (a mono WAV/FLAC, e.g. from `rangekit design sweep`), "
    "instead of the built-in beep; matched filtering with first-path selection; resampled "
    "to each recording's rate."
)


def template_option(f):
    """--template FILE (``template``): the probe that was played, None for the beep."""
    return click.option(
        "--template",
        "template",
        type=click.Path(),
        default=None,
        metavar="FILE",
        help=TEMPLATE_HELP,
    )(f)


def load_template(path: str | None):
    """The probe in the file ``path`` of :func:`template_option`, or None without one.

    Returns a :class:`~rangekit.signals.probe.Probe` (sample 0 = the emission's start,
    trailing silence dropped; :func:`~rangekit.signals.probe.read_probe`). Errors are the
    library's, one line naming the file: missing or unreadable (exit 3), not audio,
    multichannel or silent (exit 4).
    """
    if path is None:
        return None
    from rangekit.signals.probe import read_probe

    return read_probe(path)
