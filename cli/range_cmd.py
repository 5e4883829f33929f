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
    make_burst,
    output_option,
    temperature_option,
    ultrasonic_options,
)


@click.command("range")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=True))
@click.option(
    "--scheme",
    type=click.Choice(["beepbeep", "oneway", "echo"]),
    default="beepbeep",
    show_default=True,
    help="beepbeep = two-way audible beeps, no clock sync; oneway = RF-synchronised "
    "ultrasonic beacons (sample 0 = trigger); echo = SRF02-style pulse-echo (sample 0 = ping).",
)
@click.option(
    "--self-distance",
    "self_distance",
    metavar="M[,M...]",
    default="0",
    show_default=True,
    help="Speaker-to-microphone distance in metres: one for all devices, or one per device.",
)
@temperature_option
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
@ultrasonic_options
@format_option
@output_option
@debug_option
def range_cmd(files, scheme, self_distance, temp_c, speed, clock_ppm, detector, fmt, output, **kw):
    """Distances from recordings: two-way beeps, one-way beacons or pulse-echo.

    beepbeep: FILE... is one WAV with one channel per device (channel i = device i), or
    one mono WAV per device (file i = device i). Devices played in index order (device 0
    first). Prints every pair's distance with its 1-sigma uncertainty.

    oneway / echo: each FILE is ranged on its own; each channel is a receiver (oneway) or
    a sensor (echo); sample 0 is the RF trigger (oneway) or the ping (echo). With
    --period the file holds consecutive activation windows (cycles). Prints one row per
    (file, window, channel); an empty distance means nothing in range.

    \b
    Examples:
      rangekit range exchange.wav --self-distance 0.1
      rangekit range phone0.wav phone1.wav phone2.wav --format json
      rangekit range --scheme oneway beacons.wav --period 0.2 --tx-order 0,1,2,3,4,5
      rangekit range --scheme echo srf02.wav --period 0.07 --format json
    """
    if scheme != "beepbeep":
        _range_ultrasonic(files, scheme, temp_c, speed, fmt, output, kw)
        return
    from rangekit.io.results import format_ranges
    from rangekit.ranging import range_files

    _refuse_ultrasonic_options(kw)
    sd = float_list(self_distance, name="--self-distance", lo=0.0, hi=2.0)
    beep = make_beep(kw)
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


_ULTRASONIC_KEYS = (
    "latency",
    "period",
    "tx_order",
    "channels",
    "min_range",
    "max_range",
    "q",
    "code",
    "carrier",
    "cycles_per_bit",
)


def _refuse_ultrasonic_options(kw: dict) -> None:
    for k in _ULTRASONIC_KEYS:
        if kw.pop(k, None) is not None:
            opt = "--" + k.replace("_", "-")
            raise click.UsageError(f"{opt} applies to --scheme oneway and echo only")


def _range_ultrasonic(files, scheme, temp_c, speed, fmt, output, kw):
    from rangekit.ranging.ultrasonic import (
        SRF02_MAX_RANGE_M,
        SRF02_MIN_RANGE_M,
        format_tof,
        range_ultrasonic_files,
    )
    from rangekit.signals.transducer import Transducer

    for k in ("f_hz", "n_bursts", "spacing", "burst_len", "taper", "beep_fs"):
        if kw.get(k) is not None:
            opt = {"f_hz": "--freq", "n_bursts": "--bursts", "beep_fs": "--beep-fs"}.get(
                k, "--" + k.replace("_", "-")
            )
            raise click.UsageError(f"{opt} applies to --scheme beepbeep only")
    burst = make_burst(kw, scheme=scheme)
    q = kw["q"]
    trans = None if q == 0 else Transducer(q=4.0 if q is None else q)
    lo = kw["min_range"]
    hi = kw["max_range"]
    args = {"temp_c": temp_c, "speed_m_s": speed, "period_s": kw["period"]}
    if scheme == "oneway":
        tx_order = None
        if kw["tx_order"] is not None:
            vals = float_list(kw["tx_order"], name="--tx-order", lo=0, hi=1e6)
            if any(v != int(v) for v in vals):
                raise click.BadParameter("ids must be whole numbers", param_hint="--tx-order")
            tx_order = [int(v) for v in vals]
        args.update(
            tx=trans,
            rx=trans,
            latency_s=kw["latency"] or 0.0,
            tx_ids=tx_order,
            min_range_m=0.0 if lo is None else lo,
            max_range_m=15.0 if hi is None else hi,
        )
        channels = 3 if kw["channels"] is None else kw["channels"]
    else:
        for k in ("latency", "tx_order"):
            if kw[k] is not None:
                raise click.UsageError(f"--{k.replace('_', '-')} applies to --scheme oneway only")
        args.update(
            transducer=trans,
            min_range_m=SRF02_MIN_RANGE_M if lo is None else lo,
            max_range_m=SRF02_MAX_RANGE_M if hi is None else hi,
        )
        channels = kw["channels"]
    rows = range_ultrasonic_files(files, scheme=scheme, channels=channels, burst=burst, **args)
    meta = {"scheme": scheme, "files": [str(f) for f in files]}
    emit(format_tof(rows, fmt, scheme=scheme, meta=meta), output)
