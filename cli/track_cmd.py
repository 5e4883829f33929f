"""``rangekit track``: run a tracking filter over a measurement, IMU or position log."""

from __future__ import annotations

import json
import math

import click
from rangekit_cli._options import FiniteRange, debug_option, emit, format_choice, output_option

FILTERS = ("range-ekf", "dead-reckoning", "lmax")

#: Which filters each filter-specific option applies to (option name -> filters).
_APPLIES = {
    "--accel-psd": ("range-ekf",),
    "--gate": ("range-ekf", "dead-reckoning"),
    "--no-gate": ("range-ekf", "dead-reckoning"),
    "--cross-sign": ("range-ekf",),
    "--smooth": ("range-ekf", "dead-reckoning"),
    "--l-max": ("lmax",),
    "--i-star": ("lmax",),
}

#: Track columns that hold whole numbers (written as integers).
_INT_COLUMNS = frozenset({"target"})


@click.command("track")
@click.argument("log", type=click.Path(dir_okay=True), metavar="LOG.csv")
@click.option(
    "--filter",
    "filter_",
    type=click.Choice(FILTERS),
    required=True,
    help="range-ekf: people from acoustic ranges (Jiang 2018), LOG is a measurement log; "
    "dead-reckoning: robot from accelerometer + odometer with bias states (Ahn & Yu 2007), "
    "LOG is an IMU log; lmax: pedestrian position fixes through the l_max filter (Ahn & Yu "
    "2007), LOG is a position log.",
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
    "quantile are rejected [range-ekf: 0.999 per range; dead-reckoning: no gate].",
)
@click.option(
    "--no-gate",
    "no_gate",
    is_flag=True,
    help="range-ekf, dead-reckoning: use every measurement (no innovation gate).",
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
@format_choice(("csv", "json"), "csv")
@output_option
@debug_option
def track_cmd(
    log, filter_, smooth, accel_psd, gate, no_gate, cross_sign, l_max, i_star, fmt, output
):
    """Track from a log: people from ranges, a robot from its IMU, or a walker's fixes.

    LOG.csv is a measurement log (range-ekf), an IMU log (dead-reckoning) or a position log
    (lmax), formats in docs/formats.md. Prints one row per epoch (and per target for
    range-ekf) as CSV with a header, or JSON with "columns" and "rows". range-ekf also
    prints a one-line summary on stderr (epochs, targets, rejected ranges, re-opened
    targets, skipped epochs).

    \b
    Examples:
      rangekit track --filter range-ekf log.csv --smooth -o track.csv
      rangekit track --filter dead-reckoning imu.csv --format json
      rangekit track --filter lmax fixes.csv --l-max 0.5 --i-star 1
    """
    given = {
        "--accel-psd": accel_psd is not None,
        "--gate": gate is not None,
        "--no-gate": no_gate,
        "--cross-sign": cross_sign is not None,
        "--smooth": smooth,
        "--l-max": l_max is not None,
        "--i-star": i_star is not None,
    }
    for opt, used in given.items():
        if used and filter_ not in _APPLIES[opt]:
            raise click.UsageError(
                f"{opt} does not apply to --filter {filter_} (only to {', '.join(_APPLIES[opt])})"
            )
    if gate is not None and no_gate:
        raise click.UsageError("--gate and --no-gate exclude each other")

    extra: dict = {}
    summary = None
    if filter_ == "range-ekf":
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
    else:
        columns, rows = _lmax(log, l_max, i_star)

    table = [_row(columns, r) for r in rows]
    if fmt == "csv":
        from rangekit.io.csvlog import write_table

        text = write_table(columns, table)
    else:
        obj = {
            "filter": filter_,
            "log": str(log),
            "smoothed": bool(smooth),
            "columns": list(columns),
            "rows": table,
            **extra,
        }
        text = json.dumps(obj, indent=2) + "\n"
    emit(text, output)
    if summary:
        click.echo(summary, err=True)


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
