"""``rangekit detect``: every channel's beep (or probe) onsets, to check what a range came from."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    beep_options,
    debug_option,
    detector_option,
    emit,
    format_option,
    load_template,
    make_beep,
    output_option,
    template_option,
)

#: The beep options, by parameter name, for the usage error with --template.
_BEEP_OPTIONS = {
    "f_hz": "--freq",
    "n_bursts": "--bursts",
    "spacing": "--spacing",
    "burst_len": "--burst-len",
    "taper": "--taper",
    "beep_fs": "--beep-fs",
}


#: Options that only apply with --template, by parameter name.
_TEMPLATE_OPTIONS = {
    "expected": "--expected",
    "min_separation": "--min-separation",
    "weighting": "--weighting",
}


@click.command("detect")
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=True))
@detector_option
@template_option
@click.option(
    "--expected",
    type=click.IntRange(1, 10000),
    default=None,
    metavar="N",
    help="With --template: the number of emissions in each channel (e.g. 2 for a two-way "
    "exchange), at most 10000; exactly N arrivals, the ones `range` uses.",
)
@click.option(
    "--min-separation",
    "min_separation",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    metavar="S",
    help="With --template: shortest time between two emissions in seconds (e.g. the firing "
    "period); peaks closer to a stronger arrival are its echoes [the probe's duration].",
)
@click.option(
    "--weighting",
    type=click.Choice(["ml", "prewhiten", "scot", "phat", "none"]),
    default=None,
    help="With --template: weighting of the matched filter by the recording's noise spectrum [ml].",
)
@beep_options
@format_option
@output_option
@debug_option
def detect_cmd(files, detector, template, expected, min_separation, weighting, fmt, output,
               **beep_kw):  # fmt: skip
    """Beep onsets (or --template probe onsets) in every channel of every FILE.

    Prints one row per beep found: file, channel, beep index, onset (float sample index
    from sample 0, and seconds), its 1-sigma in samples, SNR and confidence (fraction of
    bursts whose timing fits the burst spacing). Exit code 6 if a channel holds no beep.

    With --template the rows are the arrivals of that probe (first path of each,
    strongest arrivals at least the probe's length or --min-separation apart, peaks in an
    arrival's reverberation or ringing belong to it; confidence is the first path's
    height over the arrival's strongest peak) and the detector is 'template'; with
    --expected N exactly N per channel, the same arrivals `range` uses. JSON rows also
    carry each arrival's flags (clipped, low_snr, ambiguous_first_path, poor_match,
    reverb_limited, dc_or_lowband).

    \b
    Examples:
      rangekit detect recording.wav
      rangekit detect --template sweep.wav --format csv dev1.wav dev2.wav
      rangekit detect --template sweep.wav --expected 2 --format json dev1.wav
      rangekit detect --template tone.wav --min-separation 0.5 log64k.wav
    """
    from rangekit.detect import detect
    from rangekit.detect.template import detect_template
    from rangekit.io.audio import read_audio
    from rangekit.io.results import arrivals_rows, format_arrivals

    ctx = click.get_current_context()
    if template is not None:
        if ctx.get_parameter_source("detector") != click.core.ParameterSource.DEFAULT:
            raise click.UsageError(
                "--detector applies to the built-in beep; --template uses the matched filter"
            )
        for key, opt in _BEEP_OPTIONS.items():
            if beep_kw.get(key) is not None:
                raise click.UsageError(f"{opt} describes the built-in beep; drop it or --template")
    if template is None:
        extra = {"expected": expected, "min_separation": min_separation, "weighting": weighting}
        for key, opt in _TEMPLATE_OPTIONS.items():
            if extra[key] is not None:
                raise click.UsageError(f"{opt} applies to --template only")
    probe = load_template(template)
    tkw = {"expected": expected, "min_separation_s": min_separation}
    if weighting is not None:
        tkw["weighting"] = weighting
    beep = None if probe is not None else make_beep(beep_kw)
    rows, empty = [], []
    for f in files:
        x, fs = read_audio(f)
        for ch in range(x.shape[1]):
            if probe is None:
                arr = detect(x[:, ch], fs=fs, beep=beep, detector=detector)
            else:
                arr = detect_template(x[:, ch], fs=fs, probe=probe, what=f"'{f}'", **tkw)
            if len(arr) == 0:
                empty.append(f"{f}#{ch}")
            new = arrivals_rows(arr, file=str(f), channel=ch)
            if probe is not None and fmt == "json":
                for i, r in enumerate(new):
                    r["flags"] = list(arr.flag_names(i))
            rows += new
    meta = (
        {"detector": detector} if probe is None else {"detector": "template", "template": template}
    )
    if probe is not None and expected is not None:
        meta["expected"] = expected
    if not (empty and output is not None):  # a failed run leaves -o FILE untouched
        emit(format_arrivals(rows, fmt, meta=meta), output)
    if empty:
        what = "no beep" if probe is None else f"no arrival of '{template}'"
        click.echo(f"rangekit: error: {what} found in {', '.join(empty)}", err=True)
        raise SystemExit(6)
