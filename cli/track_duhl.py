"""``rangekit track duhl`` and ``rangekit track duhl-ranges`` (Kim & Kim 2013)."""

from __future__ import annotations

import dataclasses

import click
from rangekit_cli._options import FiniteRange, doc_page, shown_default
from rangekit_cli.track_common import (
    gate_options,
    gate_value,
    initial_pose_option,
    log_argument,
    output_options,
    parse_pose,
    rig_option,
    write_track,
)

from rangekit.localize.duhl import DUHLConfig

_DEFAULTS = {f.name: f.default for f in dataclasses.fields(DUHLConfig)}

#: Columns of the duhl and duhl-ranges tracks.
DUHL_COLUMNS = (
    "t_s", "x_m", "y_m", "heading_rad", "var_x_m2", "var_y_m2", "var_heading_rad2", "status",
)  # fmt: skip


def duhl_options(f):
    """The options of both DUHL variants (written once)."""
    opts = [
        log_argument(),
        click.option(
            "--beacons",
            type=click.Path(dir_okay=True),
            default=None,
            metavar="FILE",
            help="Beacon file, the ceiling transmitters' ids and positions (JSON, "
            f"{doc_page('formats.md')}); or --rig.",
        ),
        rig_option(
            f"Rig file ({doc_page('rigs.md')}) instead of --beacons: Kim & Kim's three "
            "receivers on a circle; its anchors are the transmitters."
        ),
        initial_pose_option(
            "The robot's pose at the first odometry row (m, m, degrees). Without it the "
            "filter starts from a UHL solve of the first two transmitters heard."
        ),
        click.option(
            "--wheel-base",
            "wheel_base_m",
            type=FiniteRange(0.0, None, min_open=True),
            default=None,
            metavar="M",
            help="Distance between the drive wheels, m "
            "(the default is a Pioneer P3-DX's, the paper's robot) "
            f"{shown_default(_DEFAULTS['wheel_base_m'])}.",
        ),
        click.option(
            "--sigma-d",
            "sigma_d_m",
            type=FiniteRange(0.0, None, min_open=True),
            default=None,
            metavar="M",
            help=f"1-sigma of a measured distance, m {shown_default(_DEFAULTS['sigma_d_m'])}.",
        ),
        click.option(
            "--k-v",
            "k_v_m",
            type=FiniteRange(0.0, None),
            default=None,
            metavar="M",
            help="Odometry noise, variance k_v |v| / dt per wheel, m "
            f"{shown_default(_DEFAULTS['k_v_m'])}.",
        ),
        gate_options(_DEFAULTS["gate_prob"]),
        output_options,
    ]
    for o in reversed(opts):
        f = o(f)
    return f


@click.command("duhl")
@duhl_options
def duhl_cmd(**kw):
    """A differential-drive robot's pose from wheel odometry and ceiling ultrasonic
    transmitters (the DUHL filter of Kim & Kim 2013 §III-IV).

    LOG.csv is a DUHL log of wheel odometry and ultrasonic distances (formats.md of the
    documentation).
    Prints one pose per odometry row, a summary on stderr, then each warning.

    \b
    Example:
      rangekit track duhl run.csv --beacons beacons.json -o pose.csv
    """
    _run("duhl", **kw)


@click.command("duhl-ranges")
@duhl_options
def duhl_ranges_cmd(**kw):
    """The DUHL prediction with each transmitter's distances fed straight to the EKF
    (the comparison filter, no UHL; not in the paper).

    \b
    Example:
      rangekit track duhl-ranges run.csv --beacons beacons.json --initial-pose 0,0,0
    """
    _run("duhl-ranges", **kw)


def _run(filter_, *, log, beacons, rig, initial_pose, gate, no_gate, fmt, output, **given):
    import numpy as np

    from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError
    from rangekit.io.duhllog import read_beacons, read_duhl_log
    from rangekit.localize import _duhl_kernels as S
    from rangekit.localize.duhl import rig_inputs, track_log

    gate_kw = {"gate_prob": g["gate"]} if "gate" in (g := gate_value(gate, no_gate)) else {}
    if beacons is None and rig is None:
        raise click.UsageError(
            f"{filter_} needs --beacons FILE (the transmitters' positions) or --rig"
        )
    if beacons is not None and rig is not None:
        raise click.UsageError("give the transmitters once: --beacons or --rig, not both")
    pose0 = parse_pose(initial_pose, 3)
    name = str(log)
    dlog = read_duhl_log(log, name=name)
    from_rig: dict = {}
    if rig is not None:
        from rangekit.rig import read_rig

        bcn, dlog, from_rig = rig_inputs(read_rig(rig), dlog, name=str(rig))
        beacons = rig
    else:
        bcn = read_beacons(beacons)
    config = DUHLConfig(
        **(from_rig | {k: v for k, v in given.items() if v is not None}),
        variant="ranges" if filter_ == "duhl-ranges" else "duhl",
        **gate_kw,
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
        [trk.t_s[k0:], trk.pose[k0:], cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2], trk.status[k0:]]
    )
    st = trk.obs_status
    m = int(st.size)
    used = int(np.count_nonzero(st == S.OBS_USED))
    # Rejected as status bit 4 counts them: UHL undefined, residual too large, gated.
    rejected = int(np.count_nonzero(np.isin(st, (S.OBS_DEGENERATE, S.OBS_RESIDUAL, S.OBS_GATED))))
    before = int(np.count_nonzero(st == S.OBS_BEFORE_START))
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
        "initial_pose": pose0,
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
    write_track(DUHL_COLUMNS, rows, filter_name=filter_, log=name, fmt=fmt, output=output,
                extra=extra, summary=summary, notes=warnings, chosen=extra["config"])  # fmt: skip
