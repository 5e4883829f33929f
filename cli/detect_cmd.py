"""``rangekit detect``: every channel's beep onsets, for checking what a range came from."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    beep_options,
    debug_option,
    detector_option,
    emit,
    format_option,
    make_beep,
    output_option,
)


@click.command("detect")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=True))
@detector_option
@beep_options
@format_option
@output_option
@debug_option
def detect_cmd(files, detector, fmt, output, **beep_kw):
    """Beep onsets in every channel of every FILE.

    Prints one row per beep found: file, channel, beep index, onset (float sample index
    from sample 0, and seconds), its 1-sigma in samples, SNR and confidence (fraction of
    bursts whose timing fits the burst spacing). Exit code 6 if a channel holds no beep.
    """
    from rangekit.detect import detect
    from rangekit.io.audio import read_audio
    from rangekit.io.results import arrivals_rows, format_arrivals

    beep = make_beep(beep_kw)
    rows, empty = [], []
    for f in files:
        x, fs = read_audio(f)
        for ch in range(x.shape[1]):
            arr = detect(x[:, ch], fs=fs, beep=beep, detector=detector)
            if len(arr) == 0:
                empty.append(f"{f}#{ch}")
            rows += arrivals_rows(arr, file=str(f), channel=ch)
    emit(format_arrivals(rows, fmt, meta={"detector": detector}), output)
    if empty:
        click.echo(f"rangekit: error: no beep found in {', '.join(empty)}", err=True)
        raise SystemExit(6)
