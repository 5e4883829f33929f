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
    write_report,
)

from rangekit.localize.duhl import DUHLConfig

_DEFAULTS = {f.name: f.default for f in dataclasses.fields(DUHLConfig)}


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
    from rangekit.io.duhllog import read_beacons, read_duhl_log
    from rangekit.localize.duhl import rig_inputs, track_log, track_report

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
    trk = track_log(dlog, bcn, config=config, initial_pose=pose0, name=name,
                    beacon_file=str(beacons))  # fmt: skip
    write_report(track_report(trk, log=name, beacons=str(beacons), initial_pose=pose0),
                 fmt, output)  # fmt: skip
