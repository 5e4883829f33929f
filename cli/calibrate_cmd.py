"""``rangekit calibrate``: offset (and speed of sound) from recordings at known distances."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    debug_option,
    detail,
    detector_option,
    format_option,
    make_beep,
    progress,
    refuse_beep_options,
    speed_of_sound_option,
    temperature_option,
    template_option,
    verbosity_options,
)
from rangekit_cli._options_types import LazyHelpOption, library_default
from rangekit_cli.ultrasonic_options import (
    refuse_ultrasonic_options,
    ultrasonic_options,
    ultrasonic_setup,
)


def parse_recording(text: str, default_m: float | None) -> tuple[list[str], float]:
    """``PATH[+PATH][@M]`` -> (paths, distance), by the library's parser
    (:func:`rangekit.ranging.calibration.parse_recording`); --distance when no @M."""
    from rangekit.errors import InvalidParameterError
    from rangekit.ranging.calibration import parse_recording as parse

    try:
        paths, dist = parse(text, default_m)
    except InvalidParameterError as e:
        raise click.BadParameter(str(e)) from None
    if dist is None:
        raise click.UsageError(f"no distance for {text!r}: give --distance M or write it as FILE@M")
    return paths, dist


@click.command("calibrate")
@click.argument("recordings", nargs=-1, required=True, metavar="RECORDING...")
@click.option(
    "--distance",
    type=FiniteRange(1e-3, 1e4),
    default=None,
    metavar="M",
    help="Known distance in metres of every RECORDING that does not give its own as FILE@M.",
)
@click.option(
    "--scheme",
    type=click.Choice(["beepbeep", "oneway"]),
    default="beepbeep",
    show_default=True,
    help="beepbeep: each RECORDING is one exchange of two devices (a 2-channel file, or "
    "dev0.wav+dev1.wav); oneway: each RECORDING is one file whose sample 0 is the trigger.",
)
@template_option
@click.option(
    "--fit-speed/--no-fit-speed",
    "fit_speed",
    default=None,
    help="Fit the effective speed of sound too [default: when the recordings are at two or more "
    "distinct distances].",
)
@click.option(
    "--tolerance",
    type=FiniteRange(0.0, 1.0),
    default=lambda: library_default("rangekit.ranging.calibration:DEFAULT_TOLERANCE_M"),
    show_default=True,
    cls=LazyHelpOption,
    metavar="M",
    help="1-sigma of the known distances (how well the devices were placed), m.",
)
@temperature_option
@speed_of_sound_option()
@detector_option
@beep_options
@ultrasonic_options
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(dir_okay=False),
    metavar="CAL.json",
    help="Where to write the calibration (JSON; written only when the fit is accepted).",
)
@format_option
@verbosity_options
@debug_option
def calibrate_cmd(
    recordings,
    distance,
    scheme,
    template,
    fit_speed,
    tolerance,
    temp_c,
    speed,
    detector,
    output,
    fmt,
    **kw,
):
    """Fit a device pair's (or link's) offset, and speed of sound, from known distances.

    Model d = c tau + b (calibration.md of the documentation): tau is what the scheme
    measures (two-way: half the difference of the two devices' intervals; one-way: the
    arrival time from the trigger) and b the offset (two-way: the mean speaker-to-microphone
    distance, any latency cancels; one-way: -c x the system latency). Recordings at ONE
    distance fit b with c from --temperature; at two or more distances c is fitted too. Too
    few recordings (fewer than 3, or 4 for the speed), or recordings that disagree with the
    others beyond their uncertainty, are refused (exit 7) and named.

    RECORDING is FILE, or dev0.wav+dev1.wav (two-way with one mono file per device), with
    an optional @M giving its own distance in metres.

    \b
    Examples:
      rangekit calibrate --template sweep.wav --distance 1.0 t1.wav t2.wav t3.wav -o cal.json
      rangekit calibrate a.wav@0.5 b.wav@0.5 c.wav@2 d.wav@2 --template sweep.wav -o cal.json
      rangekit calibrate --scheme oneway --template chirp.wav --distance 2 r*.wav -o ow_cal.json
      rangekit range --template sweep.wav --calibration cal.json exchange.wav
    """

    from rangekit_cli._options import load_template

    from rangekit.io.notes import calibrate_detail
    from rangekit.io.results import format_calibration
    from rangekit.ranging.calibration import calibrate_recordings
    from rangekit.ranging.config import Medium

    probe = load_template(template)
    recs = [parse_recording(r, distance) for r in recordings]
    medium = Medium(temp_c=temp_c, speed_m_s=speed)
    detail("rangekit: calibrate: " + calibrate_detail(
        scheme, n_recordings=len(recs), medium=medium, detector=detector,
        template=template if probe is not None else None,
    ))  # fmt: skip
    if scheme == "beepbeep":
        refuse_ultrasonic_options(kw)
        if probe is not None:
            refuse_beep_options(kw)
        args = {"beep": make_beep(kw), "detector": detector}
    else:
        if kw.get("latency") is not None:
            raise click.UsageError("--latency is what a one-way calibration fits; leave it out")
        # a calibration rig: any receivers
        setup = ultrasonic_setup(kw, scheme=scheme, any_receivers=True)
        args = {"setup": setup}
    with progress(len(recs), "calibrate", unit="files") as bar:
        cal = calibrate_recordings(
            recs, scheme=scheme, speed_m_s=medium.c, probe=probe, fit_speed=fit_speed,
            tolerance_m=tolerance, progress=bar.report, **args,
        )  # fmt: skip
    cal.write(output)
    click.echo(format_calibration(cal, fmt), nl=False)
