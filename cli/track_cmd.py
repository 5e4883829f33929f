"""``rangekit track``: run a tracking filter over a measurement, IMU or position log."""

from __future__ import annotations

import json
import math

import click
from rangekit_cli._options import (
    FiniteRange,
    debug_option,
    emit,
    float_list,
    format_choice,
    output_option,
)

FILTERS = ("range-ekf", "dead-reckoning", "lmax", "duhl", "duhl-ranges", "particle")
_DUHL = ("duhl", "duhl-ranges")
_PF = ("particle",)

#: Which filters each filter-specific option applies to (option name -> filters).
_APPLIES = {
    "--accel-psd": ("range-ekf",),
    "--gate": ("range-ekf", "dead-reckoning", *_DUHL),
    "--no-gate": ("range-ekf", "dead-reckoning", *_DUHL),
    "--cross-sign": ("range-ekf",),
    "--smooth": ("range-ekf", "dead-reckoning"),
    "--l-max": ("lmax",),
    "--i-star": ("lmax",),
    "--beacons": _DUHL,
    "--initial-pose": ("range-ekf", *_DUHL),
    "--rig": ("range-ekf", *_DUHL),
    "--robust": ("range-ekf",),
    "--wheel-base": _DUHL,
    "--sigma-d": _DUHL,
    "--k-v": _DUHL,
    "--map": _PF,
    "--steps": (*_PF, "range-ekf"),
    "--ranges": _PF,
    "--start": _PF,
    "--method": _PF,
    "--mode": _PF,
    "--particles": _PF,
    "--mounts": _PF,
    "--seed": _PF,
}

#: Defaults of the duhl options, for the help text only (the values used are those of
#: :class:`rangekit.localize.duhl.DUHLConfig`, not imported here to keep start-up fast;
#: tests check that the two agree).
DUHL_DEFAULTS = {"wheel_base_m": 0.33, "sigma_d_m": 0.01, "k_v_m": 4e-4}

#: Track columns that hold whole numbers (written as integers).
_INT_COLUMNS = frozenset({"target", "status", "n_particles", "n_hypotheses"})

#: Columns of the particle filter's track.
PARTICLE_COLUMNS = ("t_s", "x_m", "y_m", "n_particles", "spread_m")

#: Columns of the duhl and duhl-ranges tracks.
DUHL_COLUMNS = (
    "t_s",
    "x_m",
    "y_m",
    "heading_rad",
    "var_x_m2",
    "var_y_m2",
    "var_heading_rad2",
    "status",
)


@click.command("track")
@click.argument("log", type=click.Path(dir_okay=True), metavar="LOG.csv", required=False)
@click.option(
    "--filter",
    "filter_",
    type=click.Choice(FILTERS),
    required=True,
    help="range-ekf: people from acoustic ranges (Jiang 2018), LOG is a measurement log; "
    "dead-reckoning: robot from accelerometer + odometer with bias states (Ahn & Yu 2007), "
    "LOG is an IMU log; lmax: pedestrian position fixes through the l_max filter (Ahn & Yu "
    "2007), LOG is a position log; duhl: robot pose from wheel odometry and ceiling "
    "ultrasonic transmitters (Kim & Kim 2013), LOG is a DUHL log, needs --beacons; "
    "duhl-ranges: the same with each Tx's distances fed straight to the EKF (the "
    "comparison filter, no UHL); particle: a walker on a floor plan from IMU step events "
    "and two body-worn ultrasonic range finders (Girard 2011), needs --steps (or LOG) "
    "and --start.",
)
@click.option(
    "--smooth",
    is_flag=True,
    help="range-ekf, dead-reckoning: output the RTS-smoothed (offline) track instead of the "
    "causal filter's.",
)
@click.option(
    "--accel-psd",
    "accel_psd",
    type=FiniteRange(0.0, None, min_open=True),
    default=None,
    metavar="FLOAT",
    help="range-ekf: spectral density of the targets' white acceleration, m²/s³ per axis "
    "[0.05, walking people].",
)
@click.option(
    "--gate",
    type=FiniteRange(0.0, 1.0, min_open=True, max_open=True),
    default=None,
    metavar="FLOAT",
    help="Innovation gate probability in (0, 1): measurements beyond this chi-square "
    "quantile are rejected [range-ekf: 0.999 per range; dead-reckoning, duhl, duhl-ranges: "
    "no gate].",
)
@click.option(
    "--no-gate",
    "no_gate",
    is_flag=True,
    help="range-ekf, dead-reckoning, duhl, duhl-ranges: use every measurement (no "
    "innovation gate).",
)
@click.option(
    "--cross-sign",
    "cross_sign",
    type=click.Choice(["physical", "paper"]),
    default=None,
    help="range-ekf: sign of the robot-pose cross-covariance of Jiang 2018 eq (12): the "
    "derived one, or the one the paper prints [physical].",
)
@click.option(
    "--rig",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="RIG.json",
    help="range-ekf: track a body against the fixed anchors of this rig file (docs/rigs.md); "
    "LOG is then a DUHL-format log of odometry and anchor ranges. duhl, duhl-ranges: the "
    "rig instead of --beacons (three receivers on a circle, Kim & Kim 2013).",
)
@click.option(
    "--robust",
    type=click.Choice(["huber", "student-t", "none"]),
    default=None,
    help="range-ekf with --rig: weighting of ranges by their normalised innovation [huber].",
)
@click.option(
    "--l-max",
    "l_max",
    type=FiniteRange(0.0, None, min_open=True),
    default=None,
    metavar="FLOAT",
    help="lmax (required): largest move between two fixes, m (e.g. the mean step length).",
)
@click.option(
    "--i-star",
    "i_star",
    type=click.IntRange(min=1),
    default=None,
    metavar="INT",
    help="lmax: 1-based row number (among the data rows) of the most accurate fix, as the "
    "paper's i*: runs the offline filter, backward and forward from it. Without it: the "
    "online filter, anchored at the first fix.",
)
@click.option(
    "--beacons",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="FILE",
    help="duhl, duhl-ranges (required): beacon file, the ceiling transmitters' ids and "
    "positions (JSON, docs/formats.md).",
)
@click.option(
    "--initial-pose",
    "initial_pose",
    default=None,
    metavar="X,Y,DEG",
    help="duhl, duhl-ranges, range-ekf with --rig: the robot's pose at the first odometry "
    "row (m, m, degrees; X,Y for a rig without odometry). Without it the filter starts "
    "from the first ranges (UHL solve or multilateration).",
)
@click.option(
    "--wheel-base",
    "wheel_base",
    type=FiniteRange(0.0, None, min_open=True),
    default=None,
    metavar="M",
    help="duhl, duhl-ranges: distance between the drive wheels, m "
    f"[{DUHL_DEFAULTS['wheel_base_m']:g}, a Pioneer P3-DX].",
)
@click.option(
    "--sigma-d",
    "sigma_d",
    type=FiniteRange(0.0, None, min_open=True),
    default=None,
    metavar="M",
    help=f"duhl, duhl-ranges: 1-sigma of a measured distance, m [{DUHL_DEFAULTS['sigma_d_m']:g}].",
)
@click.option(
    "--k-v",
    "k_v",
    type=FiniteRange(0.0, None),
    default=None,
    metavar="M",
    help="duhl, duhl-ranges: odometry noise, variance k_v |v| / dt per wheel, m "
    f"[{DUHL_DEFAULTS['k_v_m']:g}].",
)
@click.option(
    "--map",
    "map_path",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="PLAN.json",
    help="particle: the floor plan (docs/floorplan.md); needed by --mode model and ranging.",
)
@click.option(
    "--steps",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="STEPS.csv",
    help="particle, range-ekf with a step-odometry --rig: step events "
    "t_s,length_m,heading_rad,heading_sigma_rad (docs/formats.md); particle: may be given "
    "as LOG instead.",
)
@click.option(
    "--ranges",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="RANGES.csv",
    help="particle: range readings t_s,sensor,range_m (empty = no echo; docs/formats.md).",
)
@click.option(
    "--start",
    default=None,
    metavar="X,Y",
    help="particle (required): the walker's position at the first step, m (Girard 2011 "
    "§3.2 step 1).",
)
@click.option(
    "--method",
    type=click.Choice(["girard", "sir"]),
    default=None,
    help="particle: the paper's filter (κ motion vectors, wall elimination, merging, "
    "eq. (1), keep the ν best) or sequential importance resampling with the SRF02 error "
    "model [girard].",
)
@click.option(
    "--mode",
    type=click.Choice(["imu", "model", "ranging"]),
    default=None,
    help="particle: steps only; steps + floor plan; steps + plan + range readings "
    "(Girard 2011 Table 1) [ranging with --ranges, else model with --map, else imu].",
)
@click.option(
    "--particles",
    type=click.IntRange(min=1, max=10_000_000),
    default=None,
    metavar="N",
    help="particle: ν, the number of particles kept [150, the paper's].",
)
@click.option(
    "--mounts",
    default=None,
    metavar="DEG[,DEG...]",
    help="particle: each range sensor's axis relative to the walking direction, degrees, "
    "sensor 0 first [90,-90: back to back, sensor 0 facing left].",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=None,
    metavar="S",
    help="particle: random seed (>= 0); the same seed gives the same track [fresh entropy].",
)
@format_choice(("csv", "json"), "csv")
@output_option
@debug_option
def track_cmd(
    log,
    filter_,
    smooth,
    accel_psd,
    gate,
    no_gate,
    cross_sign,
    rig,
    robust,
    l_max,
    i_star,
    beacons,
    initial_pose,
    wheel_base,
    sigma_d,
    k_v,
    map_path,
    steps,
    ranges,
    start,
    method,
    mode,
    particles,
    mounts,
    seed,
    fmt,
    output,
):
    """Track from a log: people from ranges, a robot from its IMU, or a walker's fixes.

    LOG.csv is a measurement log (range-ekf; with --rig a DUHL log of odometry and ranges
    to the rig's fixed anchors, docs/rigs.md), an IMU log (dead-reckoning), a position log
    (lmax) or a DUHL log of wheel odometry and ultrasonic distances (duhl, duhl-ranges),
    formats in docs/formats.md. Prints one row per epoch (and per target for range-ekf)
    as CSV with a header, or JSON with "columns" and "rows". range-ekf also prints a
    one-line summary on stderr (epochs, targets, rejected ranges, re-opened targets,
    skipped epochs); duhl and duhl-ranges print a summary (observations used and
    rejected, warnings) and then each warning. particle reads --steps (and --map,
    --ranges) and prints t_s, x_m, y_m, n_particles, spread_m per step; each
    re-initialisation (walker left the map, all particles died) is a warning.

    \b
    Examples:
      rangekit track --filter range-ekf log.csv --smooth -o track.csv
      rangekit track --filter dead-reckoning imu.csv --format json
      rangekit track --filter lmax fixes.csv --l-max 0.5 --i-star 1
      rangekit track --filter range-ekf --rig rig.json robot.csv -o track.csv
      rangekit track --filter duhl run.csv --beacons beacons.json -o pose.csv
      rangekit track --filter particle --map plan.json --steps steps.csv \\
          --ranges ranges.csv --start 1.0,1.0 -o track.csv
    """
    given = {
        "--accel-psd": accel_psd is not None,
        "--gate": gate is not None,
        "--no-gate": no_gate,
        "--cross-sign": cross_sign is not None,
        "--rig": rig is not None,
        "--robust": robust is not None,
        "--smooth": smooth,
        "--l-max": l_max is not None,
        "--i-star": i_star is not None,
        "--beacons": beacons is not None,
        "--initial-pose": initial_pose is not None,
        "--wheel-base": wheel_base is not None,
        "--sigma-d": sigma_d is not None,
        "--k-v": k_v is not None,
        "--map": map_path is not None,
        "--steps": steps is not None,
        "--ranges": ranges is not None,
        "--start": start is not None,
        "--method": method is not None,
        "--mode": mode is not None,
        "--particles": particles is not None,
        "--mounts": mounts is not None,
        "--seed": seed is not None,
    }
    for opt, used in given.items():
        if used and filter_ not in _APPLIES[opt]:
            raise click.UsageError(
                f"{opt} does not apply to --filter {filter_} (only to {', '.join(_APPLIES[opt])})"
            )
    if gate is not None and no_gate:
        raise click.UsageError("--gate and --no-gate exclude each other")
    if filter_ != "particle" and log is None:
        raise click.UsageError(f"--filter {filter_} needs LOG.csv (missing argument)")

    extra: dict = {}
    summary = None
    notes: list[str] = []
    if filter_ == "range-ekf" and rig is not None:
        for opt in ("--accel-psd", "--gate", "--no-gate", "--cross-sign"):
            if given[opt]:
                raise click.UsageError(f"{opt} does not apply with --rig (robust weights, no gate)")
        columns, rows, extra, summary = _range_ekf_rig(
            log,
            rig,
            initial_pose=initial_pose,
            robust=robust or "huber",
            smooth=smooth,
            steps=steps,
        )
    elif filter_ == "range-ekf":
        for opt in ("--initial-pose", "--robust", "--steps"):
            if given[opt]:
                raise click.UsageError(f"{opt} applies to --filter range-ekf only with --rig")
        columns, rows, extra, summary = _range_ekf(
            log,
            accel_psd=0.05 if accel_psd is None else accel_psd,
            gate=None if no_gate else (0.999 if gate is None else gate),
            cross_sign=cross_sign or "physical",
            smooth=smooth,
        )
    elif filter_ == "dead-reckoning":
        from rangekit.localize.deadreckoning import track_log

        columns, rows = track_log(log, smooth=smooth, gate=gate)
    elif filter_ == "lmax":
        columns, rows = _lmax(log, l_max, i_star)
    elif filter_ == "particle":
        if log is not None and steps is not None:
            raise click.UsageError("give the step log once: as LOG or as --steps, not both")
        columns, rows, extra, summary, notes = _particle(
            log if steps is None else steps,
            map_path=map_path,
            ranges=ranges,
            start=start,
            method=method,
            mode=mode,
            particles=particles,
            mounts=mounts,
            seed=seed,
        )
    else:
        columns, rows, extra, summary, notes = _duhl(
            log,
            filter_,
            beacons=beacons,
            initial_pose=initial_pose,
            wheel_base=wheel_base,
            sigma_d=sigma_d,
            k_v=k_v,
            gate=gate,
            rig=rig,
        )

    table = [_row(columns, r) for r in rows]
    if fmt == "csv":
        from rangekit.io.csvlog import write_table

        text = write_table(columns, table)
    else:
        obj = {
            "filter": filter_,
            "log": str(log if (steps is None or filter_ != "particle") else steps),
            "smoothed": bool(smooth),
            "columns": list(columns),
            "rows": table,
            **extra,
        }
        text = json.dumps(obj, indent=2) + "\n"
    emit(text, output)
    if summary:
        click.echo(summary, err=True)
    for note in notes:
        click.echo(f"warning: {note}", err=True)


def _row(columns, values) -> list:
    """One track row as Python values: ints for id columns, None for NaN (an empty cell)."""
    out = []
    for c, v in zip(columns, values, strict=True):
        f = float(v)
        if not math.isfinite(f):
            out.append(None)
        elif c in _INT_COLUMNS:
            out.append(int(f))
        else:
            out.append(f)
    return out


def _num(v: float) -> float | None:
    """A float for JSON (NaN and infinities as null)."""
    f = float(v)
    return f if math.isfinite(f) else None


def _range_ekf(log, *, accel_psd, gate, cross_sign, smooth):
    from rangekit.io.tracklog import read_measurement_log
    from rangekit.localize.range_ekf import track_ranges, track_rows

    name = str(log)
    mlog = read_measurement_log(log, name=name)
    trk = track_ranges(
        mlog, accel_psd=accel_psd, gate=gate, cross_sign=cross_sign, smooth=smooth, name=name
    )
    columns, rows = track_rows(trk, smoothed=smooth)
    n_reinit = int(trk.n_reinit.sum())
    summary = (
        f"range-ekf: {trk.t_s.size} epochs, {trk.n_targets} targets, "
        f"{len(trk.rejected)} ranges rejected by the gate, {n_reinit} targets re-opened, "
        f"{trk.n_skipped} epochs skipped before the start"
    )
    extra = {
        "rejected": [
            {"t_s": r.t_s, "a": r.a, "b": r.b, "range_m": _num(r.range_m), "nis": _num(r.nis)}
            for r in trk.rejected
        ],
        "n_targets": int(trk.n_targets),
        "n_reinit": n_reinit,
        "n_skipped": int(trk.n_skipped),
        # one per row: the probability that the target is near the filtered position
        # rather than on another branch of the bank (its mirror image)
        "p_branch": [float(p) for p in trk.p_branch.reshape(-1)],
    }
    if smooth:
        other = int(trk.same_line.size - trk.same_line.sum())
        extra["n_epochs_other_branch"] = other
        summary += (
            f"; smoothed along the final best branch ({other} epochs where the causal "
            "filter reported another)"
        )
    return columns, rows, extra, summary


def _range_ekf_rig(log, rig_path, *, initial_pose, robust, smooth, steps=None):
    """Fixed-anchor tracking (rangekit.localize.anchor_ekf) of a DUHL-format log."""
    from rangekit.io.duhllog import read_duhl_log
    from rangekit.localize.anchor_ekf import track_anchors, track_rows
    from rangekit.rig import read_rig

    rig = read_rig(rig_path)
    pose0 = None
    if initial_pose is not None:
        vals = float_list(initial_pose, name="--initial-pose")
        want = 3 if rig.odometry.kind == "differential-drive" else 2  # none, steps: X,Y
        if len(vals) != want:
            raise click.BadParameter(
                f"{initial_pose!r} must be {'X,Y,DEG' if want == 3 else 'X,Y'} for this rig "
                f"({rig.odometry.kind} odometry), got {len(vals)} numbers",
                param_hint="--initial-pose",
            )
        pose0 = [vals[0], vals[1], math.radians(vals[2])] if want == 3 else vals
    name = str(log)
    dlog = read_duhl_log(log, name=name)
    slog = None
    if rig.odometry.kind == "steps":
        if steps is None:
            raise click.UsageError(
                f"the rig {rig_path} has step odometry: give the step log (--steps STEPS.csv)"
            )
        from rangekit.io.steplog import read_step_log

        slog = read_step_log(steps, name=str(steps))
    elif steps is not None:
        raise click.UsageError(
            f"--steps needs a rig with step odometry ({rig_path} has {rig.odometry.kind!r})"
        )
    trk = track_anchors(
        dlog, rig, initial_pose=pose0, robust=robust, smooth=smooth, steps=slog, name=name
    )
    columns, rows = track_rows(trk, smoothed=smooth)
    n_down = len(trk.downweighted)
    bias_txt = ", ".join(
        f"{int(a)}: {b:+.3f}±{s:.3f}"
        for a, b, s in zip(trk.anchor_ids, trk.bias_m, trk.bias_sigma_m, strict=True)
    )
    summary = (
        f"range-ekf (rig {rig_path}): {trk.t_s.size} distance rows from t_s={trk.t_s[0]:g} "
        f"(start: {trk.start}), {n_down} ranges down-weighted ({robust}); range bias m "
        f"per anchor {bias_txt}"
    )
    extra = {
        "rig": str(rig_path),
        "robust": robust,
        "start": trk.start,
        "start_t_s": float(trk.start_t_s),
        "initial_pose": pose0,
        "biases": [
            {"anchor": int(a), "bias_m": float(b), "sigma_m": float(s)}
            for a, b, s in zip(trk.anchor_ids, trk.bias_m, trk.bias_sigma_m, strict=True)
        ],
        "downweighted": [
            {
                "t_s": d.t_s,
                "anchor": d.anchor,
                "tag": d.tag,
                "range_m": d.range_m,
                "residual_m": d.residual_m,
                "nu": d.nu,
                "weight": d.weight,
            }
            for d in trk.downweighted
        ],
    }
    return columns, rows, extra, summary


def _lmax(log, l_max, i_star):
    from rangekit.localize.lmax import read_position_log, track_fixes

    if l_max is None:
        raise click.UsageError("--filter lmax needs --l-max (largest move per step, m)")
    t, fixes = read_position_log(log, name=str(log))
    if i_star is not None and i_star > t.size:
        raise click.BadParameter(
            f"{i_star} is beyond the {t.size} fixes of {log} (1-based: 1..{t.size})",
            param_hint="--i-star",
        )
    return track_fixes(t, fixes, l_max_m=l_max, i_star=None if i_star is None else i_star - 1)


def _initial_pose(text: str | None) -> list[float] | None:
    """``X,Y,DEG`` of --initial-pose as ``[x_m, y_m, phi_rad]``."""
    vals = float_list(text, name="--initial-pose")
    if vals is None:
        return None
    if len(vals) != 3:
        raise click.BadParameter(
            f"{text!r} must be three numbers X,Y,DEG (m, m, degrees), got {len(vals)}",
            param_hint="--initial-pose",
        )
    return [vals[0], vals[1], math.radians(vals[2])]


def _duhl(log, filter_, *, beacons, initial_pose, wheel_base, sigma_d, k_v, gate, rig=None):
    import numpy as np

    from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError
    from rangekit.io.duhllog import read_beacons, read_duhl_log
    from rangekit.localize._duhl_kernels import (
        OBS_BEFORE_START,
        OBS_DEGENERATE,
        OBS_GATED,
        OBS_RESIDUAL,
        OBS_USED,
    )
    from rangekit.localize.duhl import DUHLConfig, track_log

    if beacons is None and rig is None:
        raise click.UsageError(
            f"--filter {filter_} needs --beacons FILE (the transmitters' positions) or --rig"
        )
    if beacons is not None and rig is not None:
        raise click.UsageError("give the transmitters once: --beacons or --rig, not both")
    pose0 = _initial_pose(initial_pose)
    name = str(log)
    dlog = read_duhl_log(log, name=name)
    from_rig: dict = {}
    if rig is not None:
        from rangekit.localize.duhl import rig_inputs
        from rangekit.rig import read_rig

        bcn, dlog, from_rig = rig_inputs(read_rig(rig), dlog, name=str(rig))
        beacons = rig
    else:
        bcn = read_beacons(beacons)
    given = {"wheel_base_m": wheel_base, "sigma_d_m": sigma_d, "k_v_m": k_v}
    config = DUHLConfig(
        **(from_rig | {k: v for k, v in given.items() if v is not None}),
        variant="ranges" if filter_ == "duhl-ranges" else "duhl",
        gate_prob=gate,
    )
    known = {int(i) for i in bcn.ids.tolist()}
    d = dlog.distances
    for t_s, tx in zip(d.t_s.tolist(), d.tx.tolist(), strict=True):
        if int(tx) not in known:
            raise IncompatibleInputError(
                f"{name}: the distance row at t_s={t_s:g} names transmitter {int(tx)}, which "
                f"is not in the beacon file {str(beacons)!r} (ids: {sorted(known)})"
            )
    try:
        trk = track_log(dlog, bcn, config=config, initial_pose=pose0)
    except InvalidParameterError as e:
        # The options are checked above, so what is left is the log itself (no odometry,
        # never two transmitters heard to start from).
        msg = str(e).replace("initial_pose not given", "--initial-pose not given")
        raise LogFormatError(f"{name}: the filter cannot run on this log: {msg}") from e

    k0 = trk.start_index
    cov = trk.cov[k0:]
    rows = np.column_stack(
        [
            trk.t_s[k0:],
            trk.pose[k0:],
            cov[:, 0, 0],
            cov[:, 1, 1],
            cov[:, 2, 2],
            trk.status[k0:],
        ]
    )
    st = trk.obs_status
    m = int(st.size)
    used = int(np.count_nonzero(st == OBS_USED))
    # Rejected as status bit 4 counts them: UHL undefined, residual too large, gated.
    rejected = int(np.count_nonzero(np.isin(st, (OBS_DEGENERATE, OBS_RESIDUAL, OBS_GATED))))
    before = int(np.count_nonzero(st == OBS_BEFORE_START))
    none = m - used - rejected - before
    warnings = list(trk.warnings)
    summary = (
        f"{filter_}: {rows.shape[0]} poses from t_s={trk.t_s[k0]:g}, {m} distance rows: "
        f"{used} observations used, {rejected} rejected, {none} without an observation, "
        f"{before} before the start; {len(warnings)} warnings"
    )
    extra = {
        "beacons": str(beacons),
        "start_t_s": float(trk.t_s[k0]),
        "initial_pose": None if pose0 is None else pose0,
        "config": {
            "wheel_base_m": config.wheel_base_m,
            "sigma_d_m": config.sigma_d_m,
            "k_v_m": config.k_v_m,
            "gate": config.gate_prob,
        },
        "n_distance_rows": m,
        "n_observations": used,
        "n_rejected": rejected,
        "n_without_observation": none,
        "n_before_start": before,
        "warnings": warnings,
    }
    return DUHL_COLUMNS, rows, extra, summary, warnings


def _particle(steps, *, map_path, ranges, start, method, mode, particles, mounts, seed):
    """Girard 2011 particle filter over a step log (and floor plan, range log)."""
    import numpy as np

    from rangekit.errors import IncompatibleInputError
    from rangekit.floorplan import load_floorplan
    from rangekit.io.steplog import read_range_log, read_step_log
    from rangekit.localize.particle import ParticleConfig, track_particles

    if steps is None:
        raise click.UsageError("--filter particle needs the step log (--steps STEPS.csv)")
    if start is None:
        raise click.UsageError("--filter particle needs --start X,Y (the first position, m)")
    xy0 = float_list(start, name="--start")
    if len(xy0) != 2:
        raise click.BadParameter(
            f"{start!r} must be two numbers X,Y (m), got {len(xy0)}", param_hint="--start"
        )
    if mode is None:
        mode = "ranging" if ranges is not None else ("model" if map_path is not None else "imu")
    if mode in ("model", "ranging") and map_path is None:
        raise click.UsageError(f"--mode {mode} needs --map PLAN.json (the floor plan)")
    if mode == "ranging" and ranges is None:
        raise click.UsageError("--mode ranging needs --ranges RANGES.csv (the range readings)")
    if mode != "ranging" and ranges is not None:
        raise click.UsageError(f"--ranges is not used by --mode {mode} (only by ranging)")
    cfg: dict = {"method": method or "girard", "mode": mode}
    if particles is not None:
        cfg["n_particles"] = particles
    if mounts is not None:
        cfg["mount_angles_rad"] = tuple(
            math.radians(a) for a in float_list(mounts, name="--mounts", lo=-360.0, hi=360.0)
        )
    config = ParticleConfig(**cfg)
    slog = read_step_log(steps, name=str(steps))
    rlog = None if ranges is None else read_range_log(ranges, name=str(ranges))
    plan = None if map_path is None else load_floorplan(map_path)
    if rlog is not None and rlog.n_sensors > len(config.mount_angles_rad):
        n = len(config.mount_angles_rad)
        raise IncompatibleInputError(
            f"{ranges}: has readings of sensor {rlog.n_sensors - 1} but --mounts gives "
            f"{n} sensor(s) (sensor indices 0..{n - 1})"
        )
    if plan is not None:
        x0, y0, x1, y1 = plan.bounds
        if not (x0 <= xy0[0] <= x1 and y0 <= xy0[1] <= y1):
            raise IncompatibleInputError(
                f"--start {xy0[0]:g},{xy0[1]:g} is outside the floor plan {map_path} "
                f"(x {x0:g}..{x1:g}, y {y0:g}..{y1:g})"
            )
    trk = track_particles(plan, slog, rlog, xy0, config, rng=seed)
    rows = np.column_stack([trk.t_s, trk.xy_m, trk.n_particles, trk.spread_m])
    notes = [f"step {e.step} (t_s={e.t_s:g}): {e.message}" for e in trk.events]
    summary = (
        f"particle ({config.method}, {mode}): {rows.shape[0]} steps, "
        f"nu={config.n_particles}, {len(trk.events)} re-initialisations"
    )
    extra = {
        "method": config.method,
        "mode": mode,
        "map": None if map_path is None else str(map_path),
        "ranges": None if ranges is None else str(ranges),
        "start_m": list(xy0),
        "n_particles": config.n_particles,
        "seed": seed,
        "events": [
            {"step": e.step, "t_s": e.t_s, "kind": e.kind, "message": e.message} for e in trk.events
        ],
    }
    return PARTICLE_COLUMNS, rows, extra, summary, notes
