"""``rangekit synth``: simulated recordings with their ground truth.

The group and ``synth beepbeep``; ``synth oneway`` and ``synth echo`` live in
:mod:`rangekit_cli.synth_ultrasonic_cmd`. Each command parses its options and calls
:mod:`rangekit.sim.scenarios` (scene, render, impairments, sidecar).
"""

from __future__ import annotations

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    debug_option,
    float_list,
    load_template,
    make_beep,
    note,
    progress,
    refuse_beep_options,
    temperature_option,
    verbosity_options,
)
from rangekit_cli._synth_options import (
    describe_seed,
    impair_option,
    parse_point,
    scenario_default,
    write,
)
from rangekit_cli.synth_ultrasonic_cmd import synth_echo, synth_oneway


@click.group("synth")
def synth():
    """Render simulated recordings plus a JSON sidecar with the ground truth."""


synth.add_command(synth_oneway)
synth.add_command(synth_echo)


@synth.command("beepbeep")
@click.option("--distance", type=float, default=None, help="Distance between two devices, m.")
@click.option(
    "--position",
    "positions",
    multiple=True,
    metavar="X,Y,Z",
    help="A device position in metres (repeat once per device; replaces --distance).",
)
@click.option(
    "--self-distance",
    type=float,
    help="Speaker-to-mic distance, m.",
    **scenario_default("synth_beepbeep", "self_distance_m"),
)
@click.option(
    "--snr-db",
    type=float,
    help="SNR of the weakest direct beep, dB.",
    **scenario_default("synth_beepbeep", "snr_db"),
)
@click.option("--no-noise", is_flag=True, help="Render without noise.")
@click.option("--noise", type=click.Choice(["white", "pink"]), default="white", show_default=True)
@click.option(
    "--room", default=None, metavar="LX,LY,LZ", help="Shoebox room size in metres (reflections)."
)
@click.option(
    "--absorption",
    type=float,
    help="Wall energy absorption.",
    **scenario_default("ShoeboxRoom", "absorption"),
)
@click.option(
    "--order",
    type=click.IntRange(0, 12),
    help="Image-source reflection order, at most 12 (the images grow as (2 order + 1)^3).",
    **scenario_default("ShoeboxRoom", "max_order"),
)
@temperature_option
@click.option(
    "--ppm",
    default=None,
    metavar="E[,E...]",
    help="Sample-clock error per device, ppm [default: 0].",
)
@click.option(
    "--fs",
    type=float,
    help="Recording sample rate, Hz.",
    **scenario_default("synth_beepbeep", "fs"),
)
@click.option("--mono", is_flag=True, help="Write one mono WAV per device (NAME_devI.wav).")
@click.option(
    "--exchanges",
    type=click.IntRange(1, 100000),
    default=1,
    show_default=True,
    help="Exchanges in the recording, --period apart: a series for `range --series` and "
    "`--clock-rate` (at most 100000).",
)
@click.option(
    "--period",
    type=FiniteRange(min=0.0, min_open=True),
    default=None,
    metavar="S",
    help="With --exchanges: seconds between the starts of consecutive exchanges [default: 3].",
)
@click.option(
    "--jitter",
    type=FiniteRange(min=0.0),
    default=None,
    metavar="S",
    help="With --exchanges: each gap between two devices' plays is lengthened by a uniform "
    "random time in [0, S] seconds [default: 0].",
)
@click.option(
    "--seed",
    type=click.IntRange(0, 2**63 - 1),
    default=None,
    help="Random seed, >= 0 (recording starts, noise).",
)
@beep_options
@click.option(
    "--template",
    "template",
    type=click.Path(),
    default=None,
    metavar="FILE",
    help="A probe file (e.g. from `rangekit design sweep`) every device plays instead of the "
    "beep; range the result with `range --template FILE`.",
)
@impair_option
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False), required=True, help="WAV file to write."
)
@verbosity_options
@debug_option
def synth_beepbeep(
    distance, positions, self_distance, snr_db, no_noise, noise, room, absorption, order,
    temp_c, ppm, fs, mono, exchanges, period, jitter, seed, template, impairments, output,
    **beep_kw,
):  # fmt: skip
    """An exchange in which every device plays the beep in turn (device 0 first).

    Two devices --distance apart, or one device per --position. Each device records from
    a random start (0-0.1 s, seeded) at --fs with its --ppm clock error. Writes OUTPUT
    (one channel per device, 16-bit PCM) and OUTPUT with suffix .json: positions, every
    device's true onsets in its own samples, and each pair's true distance. --impair
    adds real recordings' impairments (the truth moves with silence_s). With --exchanges N
    the recording holds N exchanges --period apart (the sidecar's "exchanges" lists each
    one's play times): a series for `range --series`, with --ppm for `--clock-rate`.

    \b
    Examples:
      rangekit synth beepbeep --distance 2.0 --snr-db 20 --seed 1 -o x.wav
      rangekit synth beepbeep --position 1,1,1.2 --position 4,2,1.2 --position 2,4,1.2 \\
          --room 6,5,3 --seed 2 -o three.wav
      rangekit synth beepbeep --distance 2 --seed 1 --impair dc=0.02,clip_db=10,hum_db=30 \\
          -o x.wav
      rangekit design sweep --f0 2000 --f1 6000 --duration 0.1 -o sweep.wav
      rangekit synth beepbeep --distance 2 --template sweep.wav --seed 1 -o sw.wav
      rangekit synth beepbeep --distance 2 --exchanges 20 --period 2 --ppm 0,40 \\
          --mono --seed 1 -o series.wav
    """
    from rangekit.io.notes import synthesis_note
    from rangekit.sim import ShoeboxRoom
    from rangekit.sim.scenarios import synth_beepbeep

    if exchanges == 1:
        for opt, v in (("--period", period), ("--jitter", jitter)):
            if v is not None:
                raise click.UsageError(f"{opt} applies with --exchanges N (N > 1) only")
    if template is not None:
        refuse_beep_options(beep_kw)
    beep = load_template(template) if template is not None else make_beep(beep_kw)
    if positions and distance is not None:
        raise click.UsageError("give --distance or --position, not both")
    room_obj = None
    if room is not None:
        room_obj = ShoeboxRoom(tuple(parse_point(room, "--room")), absorption, order)
    pts = None
    if positions:
        pts = [parse_point(p, "--position") for p in positions]
        if len(pts) < 2:
            raise click.UsageError("give --position at least twice (one per device)")
    elif distance is None:
        raise click.UsageError("give --distance M (two devices) or --position X,Y,Z per device")
    n = len(pts) if positions else 2
    clock = float_list(ppm, name="--ppm") if ppm else [0.0]
    if len(clock) not in (1, n):
        raise click.BadParameter(f"{len(clock)} values for {n} devices", param_hint="--ppm")
    signal = {"probe": beep} if template is not None else {"beep": beep}
    series = {k: v for k, v in (("period_s", period), ("jitter_s", jitter)) if v is not None}
    with progress(0, "synth", unit="signals") as bar:
        syn = synth_beepbeep(
            distance_m=distance, positions_m=pts, self_distance_m=self_distance,
            snr_db=None if no_noise else snr_db, noise=noise, room=room_obj, temp_c=temp_c,
            clock_ppm=clock, fs=fs, mono=mono, exchanges=exchanges, seed=seed,
            impairments=impairments, progress=bar.report, **series, **signal,
        )  # fmt: skip
    describe_seed(seed)
    write(syn, output)
    note(synthesis_note(syn, output))
