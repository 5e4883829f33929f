"""``rangekit detect``: every channel's beep (or probe) onsets, to check what a range came from."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    beep_options,
    debug_option,
    detail,
    detector_option,
    emit,
    format_option,
    load_template,
    make_beep,
    output_option,
    refuse_beep_options,
    template_option,
    verbosity_options,
)

#: Options that only apply to the matched filter (--template or --detector template).
_TEMPLATE_OPTIONS = {
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
    help="The number of emissions in each channel (e.g. 2 for a two-way exchange), at most "
    "10000: at most N arrivals, the best supported; the ones `range` uses.",
)
@click.option(
    "--min-separation",
    "min_separation",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    metavar="S",
    help="With --template: shortest time between two emissions in seconds (e.g. the firing "
    "period); peaks closer to a stronger arrival are its echoes [default: the probe's duration].",
)
@click.option(
    "--weighting",
    type=click.Choice(["ml", "prewhiten", "scot", "phat", "none"]),
    default=None,
    help="With --template: weighting of the matched filter by the recording's noise "
    "spectrum [default: ml].",
)
@beep_options
@format_option
@output_option
@verbosity_options
@debug_option
def detect_cmd(files, detector, template, expected, min_separation, weighting, fmt, output,
               **beep_kw):  # fmt: skip
    """Beep onsets (or --template probe onsets) in every channel of every FILE.

    A FILE of - is standard input (one per command).

    Prints one row per beep found: file, channel, beep index, onset (float sample index
    from sample 0, and seconds), its 1-sigma in samples, SNR, confidence (fraction of
    bursts whose timing fits the burst spacing) and flags (clipped, low_snr,
    ambiguous_first_path, inconsistent_bursts, poor_match, reverb_limited, dc_or_lowband;
    '-' for none). Exit code 6 if a channel holds no beep.

    With --template the rows are the arrivals of that probe by matched filtering (first
    path of each, strongest arrivals at least the probe's length or --min-separation
    apart, peaks in an arrival's reverberation or ringing belong to it; confidence is the
    first path's height over the arrival's strongest peak). With --expected N at most N
    per channel, the same arrivals `range` uses: every command detects through one
    function (rangekit.detect.detect).

    \b
    Examples:
      rangekit detect recording.wav
      rangekit detect --template sweep.wav --format csv dev1.wav dev2.wav
      rangekit detect --template sweep.wav --expected 2 --format json dev1.wav
      rangekit detect --template tone.wav --min-separation 0.5 log64k.wav
    """
    from rangekit.detect.files import detect_files
    from rangekit.errors import DetectionError
    from rangekit.io.notes import detect_detail

    ctx = click.get_current_context()
    if template is not None:
        if ctx.get_parameter_source("detector") != click.core.ParameterSource.DEFAULT:
            raise click.UsageError(
                "--detector applies to the built-in beep; --template uses the matched filter"
            )
        refuse_beep_options(beep_kw)
    method = "template" if template is not None else detector
    if method != "template":
        extra = {"min_separation": min_separation, "weighting": weighting}
        for key, opt in _TEMPLATE_OPTIONS.items():
            if extra[key] is not None:
                raise click.UsageError(f"{opt} applies to --template only")
    probe = load_template(template)
    signal = probe if probe is not None else make_beep(beep_kw)
    name = template if probe is not None else None
    detail("rangekit: detect: " + detect_detail(method, template=name, expected=expected))
    run = detect_files(
        files, signal=signal, method=method, expected=expected,
        min_separation_s=min_separation, weighting=weighting,
    )  # fmt: skip
    if not (run.empty and output is not None):  # a failed run leaves -o FILE untouched
        emit(run.format(fmt), output)
    try:
        run.finish()  # DetectionError naming the channels without an arrival
    except DetectionError as e:  # exit 6 with its line, as before, even with --debug
        click.echo(f"rangekit: error: {e}", err=True)
        raise SystemExit(e.exit_code) from None
