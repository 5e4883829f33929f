"""``rangekit synth oneway`` and ``synth echo``: simulated ultrasonic recordings."""

from __future__ import annotations

import math

import click
from rangekit_cli._options import FiniteRange, float_list, note
from rangekit_cli._synth_options import (
    describe_seed,
    parse_point,
    parse_pose,
    scenario_default,
    ultrasonic_synth_options,
    write,
)


@click.command("oneway")
@click.option(
    "--tx",
    "txs",
    multiple=True,
    metavar="X,Y",
    help="A ceiling transmitter's position in metres (repeat; fired in this order) "
    "[default: six Txs on a 1.5 m grid around the origin].",
)
@click.option(
    "--ceiling",
    type=FiniteRange(0.1, 100.0),
    help="Transmitter height z_T above the receivers' plane, m (Kim & Kim 2013 §V).",
    **scenario_default("synth_oneway", "ceiling_m"),
)
@click.option(
    "--pose",
    default="0,0,0",
    show_default=True,
    metavar="X,Y,DEG",
    help="Robot pose: position in metres, heading in degrees.",
)
@click.option(
    "--radius",
    type=FiniteRange(0.0, 10.0),
    help="Receiver circle radius r_R, m (receivers at 0, 120, 240 degrees).",
    **scenario_default("synth_oneway", "radius_m"),
)
@click.option(
    "--windows",
    "n_windows",
    type=click.IntRange(1, 100000),
    default=None,
    help="Activation windows to render [default: one per Tx].",
)
@click.option(
    "--period",
    type=FiniteRange(0.001, 60.0),
    help="Activation period, s (5 Hz).",
    **scenario_default("synth_oneway", "period_s"),
)
@click.option(
    "--latency",
    type=FiniteRange(0.0, 1.0),
    help="Trigger-to-drive latency, s.",
    **scenario_default("synth_oneway", "latency_s"),
)
@click.option(
    "--snr-db",
    type=FiniteRange(-60.0, 200.0),
    help="In-band SNR of the weakest direct arrival, dB (band: the code's main lobe).",
    **scenario_default("synth_oneway", "snr_db"),
)
@click.option(
    "--room", default=None, metavar="LX,LY,LZ", help="Shoebox room (reflections); positions inside."
)
@click.option(
    "--absorption",
    type=FiniteRange(0.0, 1.0),
    help="Wall energy absorption.",
    **scenario_default("ShoeboxRoom", "absorption"),
)
@click.option(
    "--order",
    type=click.IntRange(0, 6),
    help="Image-source reflection order.",
    **scenario_default("ShoeboxRoom", "max_order"),
)
@click.option(
    "--reflection",
    "reflections",
    multiple=True,
    metavar="DELAY_MS,GAIN",
    help="An extra path for every arrival: DELAY_MS after the direct one, GAIN times it (repeat).",
)
@ultrasonic_synth_options("synth_oneway")
def synth_oneway(
    txs, ceiling, pose, radius, n_windows, period, latency, snr_db, no_noise, room, absorption,
    order, reflections, temp_c, q, fs, seed, impairments, output,
):  # fmt: skip
    """Ceiling beacons fired in turn, heard by a robot's three receivers (Kim & Kim 2013).

    Each activation window (--period) starts with the RF trigger; the window's Tx drives
    a Barker-7 burst on 40 kHz --latency later. Writes OUTPUT (one channel per receiver,
    16-bit PCM, sample 0 = the first trigger), OUTPUT with suffix .json (the geometry,
    each window's Tx and its true distance to every receiver) and OUTPUT with suffix
    .beacons.json: the beacon file of `locate` and `track duhl` (Tx ids 0, 1, ...
    in firing order, z = --ceiling above the receivers).

    \b
    Examples:
      rangekit synth oneway --tx 1,0.5 --tx -1,2 --pose 0.2,0.1,30 --seed 1 -o ow.wav
      rangekit range --scheme oneway ow.wav --period 0.2
      rangekit range --scheme oneway ow.wav --period 0.2 --tx-order 0,1 --format csv -o r.csv
      rangekit locate --beacons ow.beacons.json --ranges r.csv
    """
    from rangekit.io.notes import synthesis_note
    from rangekit.sim import ShoeboxRoom
    from rangekit.sim.scenarios import synth_oneway

    pts = []
    for t in txs:
        v = float_list(t, name="--tx")
        if len(v) != 2:
            raise click.BadParameter(f"{t!r} must be X,Y in metres", param_hint="--tx")
        pts.append(v)
    px, py, deg = parse_pose(pose)
    room_obj = None
    if room is not None:
        room_obj = ShoeboxRoom(tuple(parse_point(room, "--room")), absorption, order)
    extra = []
    for r in reflections:
        v = float_list(r, name="--reflection", lo=0.0)
        if len(v) != 2 or v[0] <= 0:
            raise click.BadParameter(
                f"{r!r} must be DELAY_MS,GAIN (> 0)", param_hint="--reflection"
            )
        extra.append((v[0] * 1e-3, v[1]))
    given = {"txs_m": pts} if pts else {}  # else the library's six transmitters
    syn = synth_oneway(
        ceiling_m=ceiling, pose=(px, py, math.radians(deg)), radius_m=radius,
        n_windows=n_windows, period_s=period, latency_s=latency,
        snr_db=None if no_noise else snr_db, room=room_obj, extra_paths=extra, temp_c=temp_c,
        q=q, fs=fs, seed=seed, impairments=impairments, name=output, **given,
    )  # fmt: skip
    write(syn, output)
    describe_seed(seed)
    note(synthesis_note(syn, output))


@click.command("echo")
@click.option(
    "--map",
    "map_path",
    type=click.Path(dir_okay=False),
    required=True,
    help="Floor plan JSON (floorplan.md of the documentation).",
)
@click.option(
    "--pose",
    "poses",
    multiple=True,
    required=True,
    metavar="X,Y,DEG",
    help="Carrier pose for one ranging cycle: metres and heading in degrees (repeat).",
)
@click.option(
    "--mount",
    type=FiniteRange(-360.0, 360.0),
    help="Sensor axis relative to the heading, degrees (+90 = left).",
    **scenario_default("synth_echo", "mount_angle_rad", math.degrees),
)
@click.option(
    "--snr-db",
    type=FiniteRange(-60.0, 200.0),
    help="In-band SNR of an on-axis echo at the 6 m maximum range, dB.",
    **scenario_default("synth_echo", "snr_db"),
)
@ultrasonic_synth_options("synth_echo")
def synth_echo(map_path, poses, mount, snr_db, no_noise, temp_c, q, fs, seed, impairments, output):
    """SRF02 echo recording in a floor plan: one 70 ms ranging cycle per --pose.

    Sample 0 of each cycle is the ping (8 cycles of 40 kHz). The recording holds the
    ring-down and every first-order specular wall echo within the beam, with the beam
    pattern's two-way gain and 1/(2d) spreading. Writes OUTPUT (mono, 16-bit PCM) and
    OUTPUT with suffix .json: per cycle the pose, the SRF02 model's range (null = out of
    range) and the rendered echoes.

    \b
    Examples:
      rangekit synth echo --map plan.json --pose 1,1,90 --pose 1,1.5,90 -o echo.wav
      rangekit range --scheme echo echo.wav --period 0.07
    """
    from rangekit.floorplan import load_floorplan
    from rangekit.io.notes import synthesis_note
    from rangekit.sim.scenarios import synth_echo

    plan = load_floorplan(map_path)
    pts = []
    for p in poses:
        x, y, deg = parse_pose(p)
        pts.append((x, y, math.radians(deg)))
    syn = synth_echo(
        plan, pts, mount_angle_rad=math.radians(mount), snr_db=None if no_noise else snr_db,
        temp_c=temp_c, q=q, fs=fs, seed=seed, impairments=impairments, map_name=str(map_path),
    )  # fmt: skip
    write(syn, output)
    describe_seed(seed)
    note(synthesis_note(syn, output))
