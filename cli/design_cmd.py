"""``rangekit design``: probe signals to play."""

from __future__ import annotations

import click
from rangekit_cli._options import FiniteRange, beep_options, debug_option, make_beep


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
    help="Sample rate of the file, Hz [the beep's, 44100].",
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False), required=True, help="WAV file to write."
)
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
    import numpy as np

    from rangekit.io.audio import write_audio
    from rangekit.signals.beep import beep_continuous, check_beep_fits

    beep = make_beep(beep_kw, amplitude=amplitude)
    rate = beep.fs if fs is None else fs
    check_beep_fits(beep, fs=rate, what="--fs")
    x = beep_continuous(np.arange(int(np.ceil(beep.duration_s * rate))) / rate, beep=beep)
    write_audio(output, x, fs=rate, subtype="PCM_16")
    click.echo(
        f"wrote {output}: {beep.n_bursts} x {beep.f_hz:g} Hz bursts of "
        f"{beep.burst_s * 1e3:.1f} ms, "
        f"{beep.spacing_s * 1e3:.1f} ms apart, {beep.duration_s:.3f} s at {rate:g} Hz",
        err=True,
    )


@design.command("barker")
@click.option(
    "--code",
    default=None,
    metavar="N|+-...",
    help="A Barker length (2,3,4,5,7,11,13) or chips as + and - [7].",
)
@click.option("--carrier", type=FiniteRange(1.0, 1e7), default=None, help="Carrier, Hz [40000].")
@click.option(
    "--cycles-per-bit",
    "cycles_per_bit",
    type=click.IntRange(1, 1000),
    default=None,
    help="Carrier cycles per chip [3].",
)
@click.option(
    "--amplitude", type=FiniteRange(0.0, 1.0), default=0.9, show_default=True, help="Peak level."
)
@click.option(
    "--fs",
    "fs",
    type=FiniteRange(1000.0, 1e7),
    default=192000.0,
    show_default=True,
    help="Sample rate of the file, Hz; must carry the code's main lobe.",
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False), required=True, help="WAV file to write."
)
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

    from rangekit.io.audio import write_audio
    from rangekit.signals.barker import CodedBurst, burst_waveform

    b = make_burst(
        {"code": code, "carrier": carrier, "cycles_per_bit": cycles_per_bit}, scheme="oneway"
    )
    burst = CodedBurst(b.code, b.carrier_hz, b.cycles_per_bit, amplitude, fs)
    write_audio(output, burst_waveform(burst), fs=fs, subtype="PCM_16")
    chips = "".join("+" if c > 0 else "-" for c in burst.code)
    click.echo(
        f"wrote {output}: code {chips} on {burst.carrier_hz:g} Hz, {burst.cycles_per_bit} "
        f"cycles per chip, {burst.duration_s * 1e6:.1f} us at {fs:g} Hz",
        err=True,
    )
