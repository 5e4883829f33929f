"""``rangekit plot spectrogram`` and ``plot matched``: figures of a recording."""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    debug_option,
    detail,
    detector_option,
    load_template,
    make_beep,
    note,
    refuse_beep_options,
    speed_of_sound_option,
    temperature_option,
    template_option,
    verbosity_options,
)
from rangekit_cli._plot_options import channel_option, check_figure, figure_output
from rangekit_cli.ultrasonic_options import ultrasonic_options, ultrasonic_setup


def _window_option(name: str, dest: str, help: str):
    return click.option(name, dest, type=FiniteRange(min=0.0), default=None, metavar="X", help=help)


@click.command("spectrogram")
@click.argument("recording", type=click.Path(dir_okay=True), metavar="REC.wav")
@channel_option
@detector_option
@template_option
@beep_options
@_window_option("--t0", "t0_s", "Start of the time window to show, s [default: 0].")
@_window_option("--t1", "t1_s", "End of the time window to show, s [default: the recording's end].")
@_window_option("--fmin", "fmin_hz", "Lowest frequency to show, Hz [default: 0].")
@_window_option("--fmax", "fmax_hz", "Highest frequency to show, Hz [default: fs/2].")
@figure_output
@verbosity_options
@debug_option
def spectrogram_cmd(
    recording, channel, detector, template, t0_s, t1_s, fmin_hz, fmax_hz, output, **beep_kw
):
    """STFT spectrogram (dB) of one channel, with the detected onsets marked.

    The onsets are those `rangekit detect` prints for that channel (same detector, beep
    options or --template); a channel without any is drawn without marks. --t0/--t1 and
    --fmin/--fmax zoom into a long recording (the STFT is computed on the window only).

    \b
    Examples:
      rangekit plot spectrogram x.wav -o x.png
      rangekit plot spectrogram x.wav --t0 0.1 --t1 0.3 --fmin 14000 --fmax 18000 -o zoom.png
      rangekit plot spectrogram sw.wav --template sweep.wav -o sw.png
    """
    from rangekit.io.notes import spectrogram_note
    from rangekit.plot.jobs import spectrogram_figure

    check_figure(output)
    probe = load_template(template)
    if probe is not None:
        refuse_beep_options(beep_kw)
        if click.get_current_context().get_parameter_source("detector") == (
            click.core.ParameterSource.COMMANDLINE
        ):
            raise click.UsageError(
                "--detector applies to the built-in beep; --template uses the matched filter"
            )
    method = "template" if probe is not None else detector
    detail(f"rangekit: plot spectrogram: {recording}#{channel}, onsets by {method}")
    fig = spectrogram_figure(
        recording, output, channel=channel, beep=make_beep(beep_kw), detector=detector,
        probe=probe, t0_s=t0_s, t1_s=t1_s, fmin_hz=fmin_hz, fmax_hz=fmax_hz,
    )  # fmt: skip
    note(spectrogram_note(output, fig))


@click.command("matched")
@click.argument("recording", type=click.Path(dir_okay=True), metavar="REC.wav")
@click.option(
    "--scheme",
    type=click.Choice(["oneway", "echo"]),
    required=True,
    help="oneway = RF-synchronised beacons (sample 0 = trigger); echo = SRF02 pulse-echo.",
)
@channel_option
@click.option(
    "--window",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Activation window (oneway) or ranging cycle (echo) to show, from 0 (see --period).",
)
@temperature_option
@speed_of_sound_option()
@ultrasonic_options
@figure_output
@verbosity_options
@debug_option
def matched_cmd(recording, scheme, channel, window, temp_c, speed, output, **kw):
    """Matched-filter envelope of one channel and window, with the chosen first path.

    The options are those of `rangekit range --scheme oneway|echo`; the marked path is
    the one that command reports for this channel and window (its distance in the title).
    """
    from rangekit.io.notes import matched_note
    from rangekit.plot.jobs import matched_figure
    from rangekit.ranging.config import Medium

    check_figure(output)
    setup = ultrasonic_setup(kw, scheme=scheme)
    medium = Medium(temp_c=temp_c, speed_m_s=speed)
    trace = matched_figure(
        recording, output, setup=setup, medium=medium, channel=channel, window=window
    )
    note(matched_note(output, trace, channel=channel, window=window))
