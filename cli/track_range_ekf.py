"""``rangekit track range-ekf``: people from acoustic ranges (Jiang 2018), or a body
against the fixed anchors of a rig file (``--rig``, rigs.md of the documentation)."""

from __future__ import annotations

import click
from rangekit_cli._options import FiniteRange, doc_page, shown_default
from rangekit_cli.track_common import (
    default,
    gate_options,
    gate_value,
    initial_pose_option,
    log_argument,
    output_options,
    parse_pose,
    rig_option,
    smooth_option,
    write_report,
)

from rangekit.localize.anchor_ekf import track_anchors
from rangekit.localize.range_ekf import track_ranges

#: Options that apply only without / only with --rig.
_NO_RIG = ("--accel-psd", "--gate", "--no-gate", "--cross-sign", "--iterations", "--engine")
_RIG_ONLY = ("--initial-pose", "--robust", "--steps")


@click.command("range-ekf")
@log_argument()
@smooth_option
@click.option(
    "--accel-psd",
    "accel_psd",
    type=FiniteRange(0.0, None, min_open=True),
    default=None,
    metavar="FLOAT",
    help="Spectral density of the targets' white acceleration, m²/s³ per axis "
    f"(the default suits walking people) {shown_default(default(track_ranges, 'accel_psd'))}.",
)
@gate_options(default(track_ranges, "gate"), " per range")
@click.option(
    "--cross-sign",
    "cross_sign",
    type=click.Choice(["physical", "paper"]),
    default=None,
    help="Sign of the robot-pose cross-covariance of Jiang 2018 eq (12): the derived one, "
    f"or the one the paper prints {shown_default(default(track_ranges, 'cross_sign'))}.",
)
@click.option(
    "--iterations",
    type=click.IntRange(1, 100),
    default=None,
    metavar="N",
    help="Gauss-Newton steps of each update (the iterated EKF, started where the epoch's "
    "fixes put the fixed targets); 1 is the plain EKF, linearised at the prediction "
    f"{shown_default(default(track_ranges, 'iterations'))}.",
)
@click.option(
    "--engine",
    type=click.Choice(["compiled", "python", "numpy"]),
    default=None,
    help="How the hypothesis bank runs: one compiled call, driven from Python, or the "
    "plain numpy reference (slow); the same track to rounding "
    f"{shown_default(default(track_ranges, 'engine'))}.",
)
@rig_option(
    f"Track a body against the fixed anchors of this rig file ({doc_page('rigs.md')}); LOG "
    "is then a "
    "DUHL-format log of odometry and anchor ranges."
)
@click.option(
    "--robust",
    type=click.Choice(["huber", "student-t", "none"]),
    default=None,
    help="With --rig: weighting of ranges by their normalised innovation "
    f"{shown_default(default(track_anchors, 'robust'))}.",
)
@initial_pose_option(
    "With --rig: the body's pose at the first odometry row (m, m, degrees; X,Y for a rig "
    "without odometry). Without it the filter starts from the first ranges "
    "(multilateration and a heading bank)."
)
@click.option(
    "--steps",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="STEPS.csv",
    help="With a step-odometry --rig: the step events t_s,length_m,heading_rad,"
    f"heading_sigma_rad ({doc_page('formats.md')}).",
)
@output_options
def range_ekf_cmd(log, smooth, accel_psd, gate, no_gate, cross_sign, iterations, engine, rig,
                  robust, initial_pose, steps, fmt, output):  # fmt: skip
    """Positions of people from acoustic ranges (the EKF of Jiang 2018 §4.4).

    LOG.csv is a measurement log (robot poses, relative fixes, ranges; formats.md of the
    documentation).
    With --rig, LOG.csv is a DUHL-format log of odometry and ranges to the rig's fixed
    anchors, and the body carrying the rig's tags is tracked (rigs.md). Prints one
    row per epoch (and target) as CSV, or JSON with "columns" and "rows", then a
    one-line summary on stderr.

    \b
    Examples:
      rangekit track range-ekf walk.csv --smooth -o track.csv
      rangekit track range-ekf walk.csv --format json --no-gate
      rangekit track range-ekf walk.csv --iterations 1
    """
    given = {
        "--accel-psd": accel_psd is not None,
        "--gate": gate is not None,
        "--no-gate": bool(no_gate),
        "--cross-sign": cross_sign is not None,
        "--iterations": iterations is not None,
        "--engine": engine is not None,
        "--initial-pose": initial_pose is not None,
        "--robust": robust is not None,
        "--steps": steps is not None,
    }
    if rig is not None:
        for opt in _NO_RIG:
            if given[opt]:
                raise click.UsageError(f"{opt} does not apply with --rig (robust weights, no gate)")
        _with_rig(log, rig, initial_pose, robust, bool(smooth), steps, fmt, output)
        return
    for opt in _RIG_ONLY:
        if given[opt]:
            raise click.UsageError(f"{opt} applies to range-ekf only with --rig")
    kw = gate_value(gate, no_gate)
    if accel_psd is not None:
        kw["accel_psd"] = accel_psd
    for key, val in (("cross_sign", cross_sign), ("iterations", iterations), ("engine", engine)):
        if val is not None:
            kw[key] = val
    _jiang(log, kw, bool(smooth), fmt, output)


def _jiang(log, kw: dict, smooth: bool, fmt: str, output) -> None:
    from rangekit.io.tracklog import read_measurement_log
    from rangekit.localize.range_ekf import track_report

    name = str(log)
    trk = track_ranges(read_measurement_log(log, name=name), smooth=smooth, name=name, **kw)
    write_report(track_report(trk, log=name, smoothed=smooth, options=kw), fmt, output)


def _with_rig(log, rig_path, initial_pose, robust, smooth, steps, fmt, output) -> None:
    """Fixed-anchor tracking (rangekit.localize.anchor_ekf) of a DUHL-format log."""
    from rangekit.io.duhllog import read_duhl_log
    from rangekit.localize.anchor_ekf import track_report
    from rangekit.rig import read_rig

    rig = read_rig(rig_path)
    rig.require_anchors("the anchor EKF (track range-ekf --rig)", source=str(rig_path))
    pose0 = parse_pose(initial_pose, 3 if rig.odometry.kind == "differential-drive" else 2)
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
    kw = {} if robust is None else {"robust": robust}
    trk = track_anchors(dlog, rig, initial_pose=pose0, smooth=smooth, steps=slog, name=name, **kw)
    rep = track_report(trk, log=name, rig=rig_path, robust=robust, initial_pose=pose0,
                       smoothed=smooth)  # fmt: skip
    write_report(rep, fmt, output)
