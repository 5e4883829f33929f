"""``rangekit synth``: simulated recordings with their ground truth."""

from __future__ import annotations

from pathlib import Path

import click
from rangekit_cli._options import (
    FiniteRange,
    beep_options,
    check_outputs,
    debug_option,
    detail,
    float_list,
    heartbeat,
    load_template,
    make_beep,
    note,
    refuse_beep_options,
    temperature_option,
    transducer_q_options,
    verbosity_options,
)


@click.group("synth")
def synth():
    """Render simulated recordings plus a JSON sidecar with the ground truth."""


def _impair_spec(ctx, param, value):
    """--impair SPEC parsed now, before anything is rendered or written."""
    if value is None:
        return None
    from rangekit.errors import InvalidParameterError
    from rangekit.sim.impair import parse_impairments

    try:
        return parse_impairments(value)
    except InvalidParameterError as e:
        raise click.BadParameter(str(e), ctx=ctx, param=param) from None


impair_option = click.option(
    "--impair",
    "impairments",
    metavar="SPEC",
    default=None,
    callback=_impair_spec,
    help="Impair the rendered recording before writing it: KEY=VALUE[,...] with keys dc, "
    "clip_db, lf_db, hum_db, hum_hz, pink_db, interference (speech|music), interference_db, "
    "interference_max_hz, agc_db, agc_steps, silence_s, lp_hz, hp_hz; levels in dB over "
    "the rendered noise floor (impairments.md of the documentation).",
)


def _impair(imp, recordings, *, fs, seed, floor_psd, truth):
    """Apply --impair to each array of ``recordings`` (one WAV's samples each) and clip at
    full scale as a 16-bit ADC would; returns the arrays and ``truth`` moved by the
    silence padding with its ``impairments`` record. ``floor_psd``: per recording, the
    simulator's noise floor (one value or one per channel)."""
    import numpy as np

    from rangekit.sim.impair import impair, shift_truth

    if imp is None:
        return recordings, truth
    # Draws apart from the render's: the same --seed renders the same recording.
    rng = np.random.default_rng(None if seed is None else [seed, 1])
    out, clipped, full, floors, shift = [], [], [], [], 0
    for x, floor in zip(recordings, floor_psd, strict=True):
        r = impair(x, fs=fs, impairments=imp, rng=rng, floor_psd=floor)
        over = np.abs(r.x) > 1.0
        full += np.atleast_1d(over.mean(axis=0)).tolist()
        out.append(np.clip(r.x, -1.0, 1.0))
        clipped += r.clipped_fraction.tolist()
        floors += r.floor_psd.tolist()
        shift = r.shift_samples
    truth = shift_truth(truth, shift)
    truth["impairments"] = {
        **imp.as_dict(),
        "spec": imp.spec(),
        "shift_samples": shift,
        "shift_s": shift / fs,
        "clipped_fraction": clipped,
        "full_scale_clipped_fraction": full,
        "floor_psd": floors,
    }
    return out, truth


def _parse_point(text: str, name: str) -> list[float]:
    v = float_list(text, name=name)
    if v is None or len(v) != 3:
        raise click.BadParameter(f"{text!r} must be X,Y,Z in metres", param_hint=name)
    return v


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
    default=0.1,
    show_default=True,
    help="Speaker-to-mic distance, m.",
)
@click.option(
    "--snr-db",
    type=float,
    default=20.0,
    show_default=True,
    help="SNR of the weakest direct beep, dB.",
)
@click.option("--no-noise", is_flag=True, help="Render without noise.")
@click.option("--noise", type=click.Choice(["white", "pink"]), default="white", show_default=True)
@click.option(
    "--room", default=None, metavar="LX,LY,LZ", help="Shoebox room size in metres (reflections)."
)
@click.option(
    "--absorption", type=float, default=0.3, show_default=True, help="Wall energy absorption."
)
@click.option(
    "--order",
    type=click.IntRange(0, 12),
    default=1,
    show_default=True,
    help="Image-source reflection order, at most 12 (the images grow as (2 order + 1)^3).",
)
@temperature_option
@click.option(
    "--ppm",
    default=None,
    metavar="E[,E...]",
    help="Sample-clock error per device, ppm [default: 0].",
)
@click.option(
    "--fs", type=float, default=44100.0, show_default=True, help="Recording sample rate, Hz."
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
    import numpy as np

    from rangekit.io.audio import write_audio
    from rangekit.io.sidecar import write_json
    from rangekit.sim import Device, ShoeboxRoom, pair_devices, render_beepbeep
    from rangekit.sim.impair import noise_floor_psd

    rng = np.random.default_rng(seed)
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
        room_obj = ShoeboxRoom(tuple(_parse_point(room, "--room")), absorption, order)
    if positions:
        pts = [np.array(_parse_point(p, "--position")) for p in positions]
        if len(pts) < 2:
            raise click.UsageError("give --position at least twice (one per device)")
    elif distance is None:
        raise click.UsageError("give --distance M (two devices) or --position X,Y,Z per device")
    n = len(pts) if positions else 2
    clock = float_list(ppm, name="--ppm") if ppm else [0.0]
    if len(clock) not in (1, n):
        raise click.BadParameter(f"{len(clock)} values for {n} devices", param_hint="--ppm")
    clock = np.broadcast_to(np.asarray(clock), (n,))
    starts = rng.uniform(0.0, 0.1, n)
    if positions:
        up = np.array([0.0, 0.0, 0.5 * self_distance])
        devices = [
            Device(p - up, p + up, rec_start_s=float(starts[i]), clock_ppm=float(clock[i]), fs=fs)
            for i, p in enumerate(pts)
        ]
    else:
        center = (0.0, 0.0, 1.2) if room_obj is None else tuple(0.5 * np.array(room_obj.size_m))
        devices = pair_devices(
            distance,
            self_distance_m=self_distance,
            center_m=center,
            rec_start_s=tuple(float(s) for s in starts),
            clock_ppm=tuple(float(c) for c in clock),
            fs=fs,
        )
    common = {
        "temp_c": temp_c,
        "snr_db": None if no_noise else snr_db,
        "noise": noise,
        "room": room_obj,
        "rng": rng,
    }
    if exchanges == 1:
        sim = render_beepbeep(devices, beep=beep, **common)
    else:
        from rangekit.sim.exchanges import render_exchanges

        source = beep.as_probe()
        with heartbeat(f"synth: {exchanges} exchanges"):
            sim = render_exchanges(
                devices,
                source=source.samples,
                source_fs=source.fs,
                n_exchanges=exchanges,
                period_s=3.0 if period is None else period,
                jitter_s=0.0 if jitter is None else jitter,
                **common,
            )
    out = Path(output)
    floors = [
        noise_floor_psd(d["noise_sigma"], fs=fs, kind=noise, n_samples=len(x))
        for d, x in zip(sim.truth["devices"], sim.recordings, strict=True)
    ]
    if mono:
        recordings = sim.recordings
    else:
        length = min(len(x) for x in sim.recordings)
        recordings, floors = [np.stack([x[:length] for x in sim.recordings], axis=1)], [floors]
    recordings, truth = _impair(
        impairments, recordings, fs=fs, seed=seed, floor_psd=floors, truth=dict(sim.truth)
    )
    truth["seed"] = seed
    _describe_seed(seed)
    truth["setup"] = {  # what a user knows before measuring (rangekit.io.setup)
        "scheme": "beepbeep",
        "self_distance_m": [float(d["self_distance_m"]) for d in truth["devices"]],
        "temp_c": temp_c,
        "signal": {"probe": str(template)} if template is not None else {"beep": truth.get("beep")},
    }
    if mono:
        files = [out.with_name(f"{out.stem}_dev{i}{out.suffix or '.wav'}") for i in range(n)]
    else:
        files = [out]
    check_outputs([*files, out.with_suffix(".json")])
    for f, x in zip(files, recordings, strict=True):
        write_audio(f, x, fs=fs)
    truth["files"] = [f.name for f in files]
    write_json(out.with_suffix(".json"), truth)
    pairs = ", ".join(f"{p['a']}-{p['b']}: {p['distance_m']:.4f} m" for p in truth["pairs"])
    note(f"wrote {', '.join(truth['files'])} and {out.with_suffix('.json').name} ({pairs})")


def _ultrasonic_output(x, truth, *, peak, fs, seed, imp):
    """The WAV samples of an ultrasonic render (scaled to ``peak``, then --impair with the
    render's white-noise floor) and a copy of its truth."""
    import numpy as np

    from rangekit.sim.impair import noise_floor_psd

    scale = peak / float(np.max(np.abs(x)))
    floor = noise_floor_psd(truth["noise_sigma"] * scale, fs=fs)
    (x,), truth = _impair(imp, [x * scale], fs=fs, seed=seed, floor_psd=[floor], truth=truth)
    return x, dict(truth)


def _describe_seed(seed) -> None:
    """--verbose: the seed of the noise and draws (none: a fresh one, not reproducible)."""
    what = f"seed {seed}" if seed is not None else "no --seed: fresh randomness, not reproducible"
    detail(f"rangekit: synth: {what}")


def _parse_pose(text: str, name: str = "--pose") -> list[float]:
    v = float_list(text, name=name)
    if v is None or len(v) != 3:
        raise click.BadParameter(f"{text!r} must be X,Y,HEADING (m, m, degrees)", param_hint=name)
    return v


def _ultrasonic_synth_options(f):
    """--temperature, --transducer-q, --fs, --seed, -o, -q/-v and --debug of the ultrasonic
    synth commands."""
    opts = [
        transducer_q_options(
            FiniteRange(0.5, 100.0),
            4.0,
            "Q of the transducers (Tx and Rx; the echo sensor has one).",
        ),
        click.option(
            "--fs",
            type=FiniteRange(1000.0, 1e7),
            default=192000.0,
            show_default=True,
            help="Sample rate, Hz.",
        ),
        click.option(
            "--seed", type=click.IntRange(0, 2**63 - 1), default=None, help="Random seed, >= 0."
        ),
        click.option("--no-noise", is_flag=True, help="Render without noise."),
        impair_option,
        click.option(
            "-o",
            "--output",
            type=click.Path(dir_okay=False),
            required=True,
            help="WAV file to write.",
        ),
    ]
    for o in reversed(opts):
        f = o(f)
    return verbosity_options(debug_option(temperature_option(f)))


@synth.command("oneway")
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
    default=2.011,
    show_default=True,
    help="Transmitter height z_T above the receivers' plane, m (Kim & Kim 2013 §V).",
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
    default=0.19,
    show_default=True,
    help="Receiver circle radius r_R, m (receivers at 0, 120, 240 degrees).",
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
    default=0.2,
    show_default=True,
    help="Activation period, s (5 Hz).",
)
@click.option(
    "--latency",
    type=FiniteRange(0.0, 1.0),
    default=0.0,
    show_default=True,
    help="Trigger-to-drive latency, s.",
)
@click.option(
    "--snr-db",
    type=FiniteRange(-60.0, 200.0),
    default=20.0,
    show_default=True,
    help="In-band SNR of the weakest direct arrival, dB (band: the code's main lobe).",
)
@click.option(
    "--room", default=None, metavar="LX,LY,LZ", help="Shoebox room (reflections); positions inside."
)
@click.option(
    "--absorption",
    type=FiniteRange(0.0, 1.0),
    default=0.3,
    show_default=True,
    help="Wall energy absorption.",
)
@click.option(
    "--order",
    type=click.IntRange(0, 6),
    default=1,
    show_default=True,
    help="Image-source reflection order.",
)
@click.option(
    "--reflection",
    "reflections",
    multiple=True,
    metavar="DELAY_MS,GAIN",
    help="An extra path for every arrival: DELAY_MS after the direct one, GAIN times it (repeat).",
)
@_ultrasonic_synth_options
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
    import math

    import numpy as np

    from rangekit.io.audio import write_audio
    from rangekit.io.sidecar import write_json
    from rangekit.signals.transducer import Transducer
    from rangekit.sim import ShoeboxRoom
    from rangekit.sim.ultrasonic import render_oneway

    if txs:
        pts = []
        for t in txs:
            v = float_list(t, name="--tx")
            if len(v) != 2:
                raise click.BadParameter(f"{t!r} must be X,Y in metres", param_hint="--tx")
            pts.append([v[0], v[1], ceiling])
    else:
        pts = [[x, y, ceiling] for y in (-0.75, 0.75) for x in (-1.5, 0.0, 1.5)]
    px, py, deg = _parse_pose(pose)
    room_obj = None
    if room is not None:
        room_obj = ShoeboxRoom(tuple(_parse_point(room, "--room")), absorption, order)
    extra = []
    for r in reflections:
        v = float_list(r, name="--reflection", lo=0.0)
        if len(v) != 2 or v[0] <= 0:
            raise click.BadParameter(
                f"{r!r} must be DELAY_MS,GAIN (> 0)", param_hint="--reflection"
            )
        extra.append((v[0] * 1e-3, v[1]))
    from rangekit.io.audio import check_memory

    n_tx = len(pts)
    frames = int((n_windows or n_tx) * period * fs)
    check_memory(output, frames, 3, hint="render fewer --windows")  # before rendering
    t = Transducer(q=q)
    sim = render_oneway(
        pts,
        (px, py, math.radians(deg)),
        fs=fs,
        tx=t,
        rx=t,
        n_windows=n_windows,
        period_s=period,
        latency_s=latency,
        temp_c=temp_c,
        snr_db=None if no_noise else snr_db,
        radius_m=radius,
        room=room_obj,
        extra_paths=extra,
        rng=np.random.default_rng(seed),
    )
    out = Path(output)
    x, truth = _ultrasonic_output(sim.x.T, sim.truth, peak=0.5, fs=fs, seed=seed, imp=impairments)
    from rangekit.io.duhllog import Beacons

    beacons = out.with_suffix(".beacons.json")
    check_outputs([out, out.with_suffix(".json"), beacons])
    write_audio(out, x, fs=fs)
    truth["seed"] = seed
    _describe_seed(seed)
    truth["files"] = [out.name]
    truth["beacons"] = beacons.name
    truth["setup"] = {
        "scheme": "oneway",
        "temp_c": temp_c,
        "period_s": period,
        "latency_s": latency,
        "tx_order": list(range(len(pts))),
    }
    write_json(out.with_suffix(".json"), truth)
    write_json(beacons, Beacons(np.arange(len(pts)), pts).to_json())
    note(
        f"wrote {out.name} ({len(truth['windows'])} windows x {x.shape[1]} receivers), "
        f"{out.with_suffix('.json').name} and {beacons.name} (Tx ids 0-{len(pts) - 1} in "
        "firing order: range with --tx-order "
        f"{','.join(str(i) for i in range(len(pts)))})"
    )


@synth.command("echo")
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
    default=0.0,
    show_default=True,
    help="Sensor axis relative to the heading, degrees (+90 = left).",
)
@click.option(
    "--snr-db",
    type=FiniteRange(-60.0, 200.0),
    default=20.0,
    show_default=True,
    help="In-band SNR of an on-axis echo at the 6 m maximum range, dB.",
)
@_ultrasonic_synth_options
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
    import math

    import numpy as np

    from rangekit.floorplan import load_floorplan
    from rangekit.io.audio import write_audio
    from rangekit.io.sidecar import write_json
    from rangekit.signals.transducer import Transducer
    from rangekit.sim.ultrasonic import render_echo

    plan = load_floorplan(map_path)
    pts = []
    for p in poses:
        x, y, deg = _parse_pose(p)
        pts.append((x, y, math.radians(deg)))
    sim = render_echo(
        plan,
        pts,
        mount_angle_rad=math.radians(mount),
        fs=fs,
        transducer=Transducer(q=q),
        temp_c=temp_c,
        snr_db=None if no_noise else snr_db,
        rng=np.random.default_rng(seed),
    )
    out = Path(output)
    x, truth = _ultrasonic_output(sim.x[0], sim.truth, peak=0.9, fs=fs, seed=seed, imp=impairments)
    check_outputs([out, out.with_suffix(".json")])
    write_audio(out, x, fs=fs)
    truth["seed"] = seed
    _describe_seed(seed)
    truth["map"] = str(map_path)
    truth["files"] = [out.name]
    truth["setup"] = {"scheme": "echo", "temp_c": temp_c, "period_s": truth.get("period_s")}
    write_json(out.with_suffix(".json"), truth)
    ranges = ", ".join(
        "-" if w["distance_m"] is None else f"{w['distance_m']:.3f} m" for w in truth["windows"]
    )
    note(f"wrote {out.name} and {out.with_suffix('.json').name} (model: {ranges})")
