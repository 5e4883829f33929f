"""``rangekit design``: probe signals to play."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    debug_option,
    make_beep,
    note,
    verbosity_options,
)
from rangekit_cli._options_types import LazyHelpOption, library_default, library_help

BURST = "rangekit.signals.barker:CodedBurst"
SWEEP = "rangekit.signals.probe:linear_sweep"
FADE = "rangekit.signals.probe:DEFAULT_FADE_S"
#: design sweep's options by the names of rangekit.signals.design.design_sweep's arguments.
NAMES = {"f0_hz": "--f0", "f1_hz": "--f1", "duration_s": "--duration", "fs": "--fs"}
NAMES["fade_s"] = "--fade"


def _code_default() -> str:
    """The default code of :class:`rangekit.signals.CodedBurst` as ``--code`` takes it."""
    from rangekit.signals.codes import code_text

    return code_text(library_default(BURST, "code"))


@click.group("design")
def design():
    """Write probe signals as playable WAV files."""


@design.command("beep")
@beep_options
@click.option("--amplitude", type=float, default=0.9, show_default=True, help="Peak level (0, 1].")
@click.option(
    "--fs",
    "fs",
    type=FiniteRange(1000.0, 1e7),
    default=None,
    **library_help(
        "Sample rate of the file, Hz",
        lambda: f"the beep's, {library_default('rangekit.signals:Beep', 'fs'):g}",
    ),
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False), required=True, help="WAV file to write."
)
@verbosity_options
@debug_option
def design_beep(amplitude, fs, output, **beep_kw):
    """The rangekit beep as a 16-bit PCM WAV to copy to every phone.

    --fs changes only the file's sample rate: the beep keeps its timing in seconds
    (spacing and burst lengths count samples at --beep-fs), so `rangekit range` needs no
    extra option for a 48 kHz copy.

    Tone bursts (16 kHz, 4 bursts, starts 5000 samples apart at 44.1 kHz by default) with
    raised-cosine tapers. Every parameter can be changed; the same options must then be
    given to `rangekit range` and `rangekit detect`.
    """
    from rangekit.io.notes import beep_note
    from rangekit.signals.design import design_beep

    d = design_beep(make_beep(beep_kw, amplitude=amplitude), fs=fs, what="--fs")
    d.write(output)
    note(beep_note(output, d.signal, fs=d.fs))


@design.command("barker")
@click.option(
    "--code",
    default=None,
    metavar="N|+-...",
    **library_help("A Barker length (2,3,4,5,7,11,13) or chips as + and -", _code_default),
)
@click.option(
    "--carrier",
    type=FiniteRange(1.0, 1e7),
    default=None,
    **library_help("Carrier, Hz", lambda: library_default(BURST, "carrier_hz")),
)
@click.option(
    "--cycles-per-bit",
    "cycles_per_bit",
    type=click.IntRange(1, 1000),
    default=None,
    **library_help("Carrier cycles per chip", lambda: library_default(BURST, "cycles_per_bit")),
)
@click.option(
    "--amplitude", type=FiniteRange(0.0, 1.0), default=0.9, show_default=True, help="Peak level."
)
@click.option(
    "--fs",
    "fs",
    type=FiniteRange(1000.0, 1e7),
    default=lambda: library_default(BURST, "fs"),
    show_default=True,
    cls=LazyHelpOption,
    help="Sample rate of the file, Hz; must carry the code's main lobe.",
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False), required=True, help="WAV file to write."
)
@verbosity_options
@debug_option
def design_barker(code, carrier, cycles_per_bit, amplitude, fs, output):
    """A Barker-coded BPSK burst (Kim & Kim 2013) as a 16-bit PCM WAV.

    The drive signal: each chip of the code is --cycles-per-bit cycles of the carrier,
    sign-flipped for a - chip; sample 0 is the drive's start. The default is the 7-bit
    Barker code on 40 kHz with 3 cycles per bit (525 us). `--code + --cycles-per-bit 8`
    gives the SRF02's 8-cycle ping. Refuses a --fs whose Nyquist frequency is below the
    code's main lobe (carrier + carrier / cycles-per-bit).

    \b
    Example:
      rangekit design barker -o barker.wav
    """
    from rangekit_cli._options import make_burst

    from rangekit.io.notes import burst_note
    from rangekit.signals.barker import CodedBurst
    from rangekit.signals.design import design_barker

    b = make_burst(
        {"code": code, "carrier": carrier, "cycles_per_bit": cycles_per_bit}, scheme="oneway"
    )
    d = design_barker(CodedBurst(b.code, b.carrier_hz, b.cycles_per_bit, amplitude, fs))
    d.write(output)
    note(burst_note(output, d.signal))


@design.command("sweep")
@click.option(
    "--f0",
    "f0",
    type=FiniteRange(0.0, 1e7),
    required=True,
    metavar="HZ",
    help="Start frequency, Hz.",
)
@click.option(
    "--f1", "f1", type=FiniteRange(0.0, 1e7), required=True, metavar="HZ", help="End frequency, Hz."
)
@click.option(
    "--duration",
    type=FiniteRange(1e-3, 600.0),
    required=True,
    metavar="S",
    help="Length of the sweep, s, within [0.001, 600].",
)
@click.option(
    "--fs",
    "fs",
    type=FiniteRange(1000.0, 1e7),
    default=lambda: library_default(SWEEP, "fs"),
    show_default=True,
    cls=LazyHelpOption,
    metavar="HZ",
    help="Sample rate of the file, Hz; both frequencies must lie below fs / 2.",
)
@click.option(
    "--fade",
    type=FiniteRange(0.0, 300.0),
    default=None,
    metavar="S",
    cls=LazyHelpOption,
    lazy_help=lambda: (
        "Raised-cosine fade at each end, s, at most half of --duration "
        f"[default: min({library_default(FADE):g}, duration / 10)]."
    ),
)
@click.option(
    "--amplitude",
    type=FiniteRange(0.0, 1.0, min_open=True),
    default=0.5,
    show_default=True,
    metavar="A",
    help="Peak level, in (0, 1].",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    required=True,
    help="File to write (WAV; FLAC, ... by the suffix).",
)
@verbosity_options
@debug_option
def design_sweep(f0, f1, duration, fs, fade, amplitude, output):
    """A linear sweep (chirp) from --f0 to --f1 as a 16-bit PCM WAV.

    x(t) = A w(t) sin(2 pi (f0 t + (f1 - f0) t^2 / (2 T))), 0 <= t < T, with half-cosine
    fades w at both ends; --f1 below --f0 gives a down-sweep. Sample 0 is the start of
    the emission. Play the file on every device and give it to `rangekit range`,
    `detect`, `batch` or `calibrate` as --template; the range resolution is about
    c / |f1 - f0| (11 cm for 17-20 kHz), the timing far finer.

    \b
    Examples:
      rangekit design sweep --f0 17000 --f1 20000 --duration 0.1 -o sweep.wav
      rangekit design sweep --f0 20 --f1 20000 --duration 1 --fs 48000 -o full.wav
    """
    from rangekit.io.notes import sweep_note
    from rangekit.signals.design import design_sweep
    from rangekit.signals.probe import SweepError

    try:
        d = design_sweep(f0, f1, duration, fs=fs, fade_s=fade, amplitude=amplitude, names=NAMES)
    except SweepError as e:  # the library's check, as a usage error naming the options
        if e.param is None:
            raise click.UsageError(e.reason) from None
        raise click.BadParameter(e.reason, param_hint=e.param) from None
    d.write(output)
    note(sweep_note(output, d.signal, f0_hz=f0, f1_hz=f1, duration_s=duration, fade_s=fade))
