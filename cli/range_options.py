"""``rangekit range``'s options, and how they become the library's configuration objects.

Parsing only: option declarations, which options apply to which scheme (usage errors
naming the option), the setup sidecar's values for options not given
(:mod:`rangekit_cli.range_setup`), and the configuration objects of
:func:`rangekit.ranging.run.run_range` built from the values.
"""

from __future__ import annotations

import click
from rangekit_cli._options import (
    LazyHelpOption,
    beep_options,
    calibration_option,
    clock_ppm_option,
    debug_option,
    detector_option,
    format_option,
    number_option,
    output_option,
    self_distance_option,
    shown_default,
    speed_of_sound_option,
    temperature_option,
    template_option,
    verbosity_options,
)
from rangekit_cli.ultrasonic_options import ultrasonic_options


def _series_default(name: str):
    """A default of rangekit.ranging.series, read when help is shown (not at import)."""
    from rangekit.ranging import series

    return getattr(series, name)


#: Every option of ``rangekit range`` after FILES, in help order.
_OPTIONS = (
    click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=True)),
    click.option(
        "--scheme",
        type=click.Choice(["beepbeep", "oneway", "echo"]),
        default="beepbeep",
        show_default=True,
        help="beepbeep = two-way audible beeps, no clock sync; oneway = RF-synchronised "
        "ultrasonic beacons (sample 0 = trigger); echo = SRF02-style pulse-echo (sample 0 = ping).",
    ),
    self_distance_option(
        "Speaker-to-microphone distance in metres: one for all devices, or one per device."
    ),
    temperature_option,
    speed_of_sound_option(),
    clock_ppm_option("1-sigma sample-clock tolerance per device, ppm (widens sigma_m only)."),
    detector_option,
    template_option,
    calibration_option,
    beep_options,
    ultrasonic_options,
    click.option(
        "--series",
        is_flag=True,
        help="Long recordings: range block by block with bounded memory and print a time series "
        "(t_s first); CSV rows are written as they are produced.",
    ),
    number_option(
        "--block",
        "block_s",
        lo=0.001,
        hi=1e6,
        metavar="S",
        help="--series: block length in seconds [default: 2^21 samples over all channels].",
    ),
    number_option(
        "--exchange",
        "exchange_s",
        lo=0.001,
        hi=3600.0,
        metavar="S",
        help="--series beepbeep: longest time from device 0's beep to the last device's beep "
        "of one exchange [default: (N-1) x (beep duration + 0.5 s)].",
    ),
    number_option(
        "--skew",
        "skew_s",
        lo=0.0,
        hi=3600.0,
        metavar="S",
        cls=LazyHelpOption,
        lazy_help=lambda: (
            "--series beepbeep: allowance for the time of flight and for differing recording "
            f"start times {shown_default(_series_default('DEFAULT_SKEW_S'))}."
        ),
    ),
    click.option(
        "--clock-rate",
        "clock_rate",
        default=None,
        metavar="estimate|off|PPM[,PPM...]",
        help="--series beepbeep: correct the devices' sample-clock rates. estimate: from the "
        "spacing of the exchanges, relative to device 0 (reported on stderr; the rows then come "
        "at the end, after the whole recording); PPM,...: known rates, one per device (device 0 "
        "first) or one per device after device 0; off: no correction [default: off].",
    ),
    click.option(
        "--no-setup",
        "no_setup",
        is_flag=True,
        help="Do not read the setup (self-distances, temperature, period, latency, tx order) of "
        "a sidecar NAME.json beside the recordings that names exactly them, such as `rangekit "
        "synth` writes; options given always win over it.",
    ),
    click.option(
        "--jobs",
        type=click.IntRange(1, 256),
        default=None,
        metavar="N",
        help="With --series (beepbeep): N worker processes detect blocks in parallel; the "
        "rows are those of one job, in order (at most 256) [default: 1].",
    ),
    click.option(
        "--strict",
        is_flag=True,
        help="Never print a doubtful distance: a range flagged clipped, low_snr, "
        "ambiguous_first_path, inconsistent_bursts, poor_match, reverb_limited, negative or "
        "order is refused (exit 10). One beepbeep exchange: nothing is written. --series and "
        "oneway/echo rows: every row is written, doubtful ones with an empty distance and the "
        "flag 'withheld', then exit 10.",
    ),
    format_option,
    output_option,
    verbosity_options,
    debug_option,
)


def range_options(f):
    """Apply every option of ``rangekit range`` (help order)."""
    for option in reversed(_OPTIONS):
        f = option(f)
    return f


def given(name: str) -> bool:
    """Whether option ``name`` was given (not left to its default)."""
    src = click.get_current_context().get_parameter_source(name)
    return src != click.core.ParameterSource.DEFAULT


def check_series_options(files, *, scheme, series, kw) -> None:
    """Usage errors for --series options given where they do not apply (each names it)."""
    given = {k: kw.get(k) for k in ("block_s", "exchange_s", "skew_s", "clock_rate", "jobs")}
    names = {"block_s": "--block", "exchange_s": "--exchange", "skew_s": "--skew"}
    names.update(clock_rate="--clock-rate", jobs="--jobs")
    if not series:
        for k, v in given.items():
            if v is not None:
                raise click.UsageError(f"{names[k]} applies to --series only")
    elif scheme != "beepbeep":
        for k in ("exchange_s", "skew_s", "clock_rate", "jobs"):
            if given[k] is not None:
                raise click.UsageError(
                    f"{names[k]} applies to --series with --scheme beepbeep only"
                )
    jobs = given["jobs"]
    if jobs is not None and jobs > 1 and any(f == "-" for f in files):
        raise click.UsageError(
            "--jobs N reads the recording in every worker: give a file, not - (standard input)"
        )


def check_template_options(*, scheme, series, template, calibration) -> None:
    """Usage errors for --template / --calibration / --detector where they do not apply."""
    if series and scheme != "beepbeep" and (template is not None or calibration is not None):
        raise click.UsageError(
            "--template and --calibration apply to --series with --scheme beepbeep only"
        )
    if template is not None and _source_is_commandline("detector"):
        raise click.UsageError(
            "--detector applies to the built-in beep; --template uses the matched filter"
        )


def _source_is_commandline(name: str) -> bool:
    src = click.get_current_context().get_parameter_source(name)
    return src == click.core.ParameterSource.COMMANDLINE
