"""``rangekit range``: distances between devices from their recordings."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    debug_option,
    detector_option,
    emit,
    float_list,
    format_option,
    make_beep,
    output_option,
)


@click.command("range")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=True))
@click.option(
    "--scheme",
    type=click.Choice(["beepbeep"]),
    default="beepbeep",
    show_default=True,
    help="Ranging scheme: beepbeep = two-way, no clock synchronisation.",
)
@click.option(
    "--self-distance",
    "self_distance",
    metavar="M[,M...]",
    default="0",
    show_default=True,
    help="Speaker-to-microphone distance in metres: one for all devices, or one per device.",
)
@click.option(
    "--temperature",
    "temp_c",
    type=FiniteRange(-60.0, 60.0),
    default=20.0,
    show_default=True,
    help="Air temperature, C.",
)
@click.option(
    "--speed-of-sound",
    "speed",
    type=FiniteRange(100.0, 2000.0),
    default=None,
    metavar="MPS",
    help="Speed of sound in m/s (overrides --temperature).",
)
@click.option(
    "--clock-ppm",
    "clock_ppm",
    type=FiniteRange(0.0, 1e4),
    default=30.0,
    show_default=True,
    help="1-sigma sample-clock tolerance per device, ppm (widens sigma_m only).",
)
@detector_option
@beep_options
@format_option
@output_option
@debug_option
def range_cmd(
    files, scheme, self_distance, temp_c, speed, clock_ppm, detector, fmt, output, **beep_kw
):
    """Distances between devices that played the beep in turn.

    FILE... is one WAV with one channel per device (channel i = device i), or one mono
    WAV per device (file i = device i). Devices played in index order (device 0 first).
    Prints every pair's distance with its 1-sigma uncertainty.

    \b
    Examples:
      rangekit range exchange.wav --self-distance 0.1
      rangekit range phone0.wav phone1.wav phone2.wav --format json
    """
    from rangekit.io.results import format_ranges
    from rangekit.ranging import range_files

    sd = float_list(self_distance, name="--self-distance", lo=0.0, hi=2.0)
    beep = make_beep(beep_kw)
    result = range_files(
        files,
        scheme=scheme,
        beep=beep,
        detector=detector,
        temp_c=temp_c,
        speed_m_s=speed,
        self_distance_m=sd[0] if len(sd) == 1 else sd,
        clock_ppm=clock_ppm,
    )
    meta = {"scheme": scheme, "detector": detector, "files": [str(f) for f in files]}
    emit(format_ranges(result, fmt, meta=meta), output)
