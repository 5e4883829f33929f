"""``rangekit track dead-reckoning`` and ``rangekit track lmax`` (Ahn & Yu 2007)."""

from __future__ import annotations

import click
from rangekit_cli._options import FiniteRange
from rangekit_cli.track_common import (
    default,
    gate_options,
    gate_value,
    log_argument,
    output_options,
    smooth_option,
    write_report,
)

from rangekit.io.tracks import TrackReport
from rangekit.localize.deadreckoning import dead_reckon


@click.command("dead-reckoning")
@log_argument()
@smooth_option
@gate_options(default(dead_reckon, "gate"))
@output_options
def dead_reckoning_cmd(log, smooth, gate, no_gate, fmt, output):
    """A robot's position, velocity and accelerometer bias (Ahn & Yu 2007 §2).

    LOG.csv is an IMU log t_s, ax_mps2, ay_mps2, speed_mps (theory/ahn2007.md of the
    documentation).
    Prints one row per log row as CSV, or JSON with "columns" and "rows".

    \b
    Example:
      rangekit track dead-reckoning imu.csv --smooth
    """
    from rangekit.localize.deadreckoning import track_log

    kw = gate_value(gate, no_gate)
    columns, rows = track_log(log, smooth=bool(smooth), **kw)
    chosen = {"gate": kw.get("gate", default(dead_reckon, "gate")), "smooth": bool(smooth)}
    report = TrackReport("dead-reckoning", str(log), columns, rows, smoothed=bool(smooth),
                         parameters=chosen)  # fmt: skip
    write_report(report, fmt, output)


@click.command("lmax")
@log_argument()
@click.option(
    "--l-max",
    "l_max",
    type=FiniteRange(0.0, None, min_open=True),
    required=True,
    metavar="FLOAT",
    help="Largest move between two fixes, m (e.g. the mean step length).",
)
@click.option(
    "--i-star",
    "i_star",
    type=click.IntRange(min=1),
    default=None,
    metavar="INT",
    help="1-based row number (among the data rows) of the most accurate fix, as the "
    "paper's i*: runs the offline filter, backward and forward from it. Without it: the "
    "online filter, anchored at the first fix.",
)
@output_options
def lmax_cmd(log, l_max, i_star, fmt, output):
    """A pedestrian's positions from noisy fixes (the l_max filter, Ahn & Yu 2007 §3).

    LOG.csv is a position log t_s, x_m, y_m (theory/ahn2007.md of the documentation). Prints the
    estimates, one row per fix.

    \b
    Examples:
      rangekit track lmax fixes.csv --l-max 0.5
      rangekit track lmax fixes.csv --l-max 0.5 --i-star 40
    """
    from rangekit.localize.lmax import read_position_log, track_fixes

    t, fixes = read_position_log(log, name=str(log))
    if i_star is not None and i_star > t.size:
        raise click.BadParameter(
            f"{i_star} is beyond the {t.size} fixes of {log} (1-based: 1..{t.size})",
            param_hint="--i-star",
        )
    columns, rows = track_fixes(
        t, fixes, l_max_m=l_max, i_star=None if i_star is None else i_star - 1
    )
    chosen = {"l_max_m": l_max, "filter": "online" if i_star is None else f"offline from {i_star}"}
    write_report(TrackReport("lmax", str(log), columns, rows, parameters=chosen), fmt, output)
