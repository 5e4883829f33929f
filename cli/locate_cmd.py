"""``rangekit locate``: one static robot pose from ceiling transmitters (UHL, Kim & Kim 2013)."""

from __future__ import annotations

import math

import click
from rangekit_cli._options import (
    LazyHelpOption,
    debug_option,
    detail,
    emit,
    format_option,
    number_option,
    output_option,
    verbosity_options,
    warn,
)


def _uhl_default(name: str) -> dict:
    """``default``, ``show_default`` and ``cls`` of an option whose default is keyword
    ``name`` of :func:`rangekit.localize.uhl.solve_pose`, read when the command runs or
    shows help (:class:`LazyHelpOption`), not copied."""

    def read():
        import inspect

        from rangekit.localize.uhl import solve_pose

        return inspect.signature(solve_pose).parameters[name].default

    return {"default": read, "show_default": True, "cls": LazyHelpOption}


@click.command("locate")
@click.option(
    "--beacons",
    type=click.Path(dir_okay=True),
    required=True,
    metavar="FILE",
    help="Beacon file: the ceiling transmitters' ids and positions (JSON, formats.md of "
    "the documentation).",
)
@click.option(
    "--distances",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="FILE.csv",
    help="CSV with header tx,d1_m,d2_m,d3_m: one row per transmitter heard, its distances "
    "(m) to receivers 1, 2, 3 (at 0, 120, 240 degrees from the heading); - reads standard "
    "input.",
)
@click.option(
    "--ranges",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="FILE.csv|json",
    help="The output of `rangekit range --scheme oneway --tx-order ...` (CSV or JSON): per "
    "transmitter the median distance to each receiver (channel 0, 1, 2 = receiver 1, 2, 3) "
    "and the median sigma, which gives the pose's sigma; - reads standard input (JSON when "
    "it starts with {).",
)
@number_option(
    "--sigma",
    lo=0.0,
    hi=None,
    min_open=True,
    metavar="M",
    help="1-sigma of every distance of --distances or --tx, m: adds the pose's sigma.",
)
@click.option(
    "--tx",
    "tx_items",
    multiple=True,
    metavar="ID:D1,D2,D3",
    help="One transmitter heard and its three distances (m), instead of --distances; "
    "repeat for each transmitter (at least 2).",
)
@click.option(
    "--method",
    type=click.Choice(["hybrid", "direct", "indirect"]),
    **_uhl_default("method"),
    help="Position by the direct method, the indirect method using ranges, or the hybrid "
    "rule of Kim & Kim 2013 Table I.",
)
@number_option(
    "--d-th",
    "d_th",
    lo=0.0,
    hi=None,
    **_uhl_default("d_th"),
    metavar="M",
    help="Hybrid threshold, m: with collinear transmitters, the direct position is kept "
    "within this distance of their line.",
)
@number_option(
    "--r-r",
    "r_r",
    lo=0.0,
    hi=None,
    min_open=True,
    **_uhl_default("r_R"),
    metavar="M",
    help="Radius of the receiver circle on the robot, m.",
)
@format_option
@output_option
@verbosity_options
@debug_option
def locate_cmd(beacons, ranges, sigma, distances, tx_items, method, d_th, r_r, fmt, output):
    """One robot pose from the distances of ceiling transmitters to its three receivers.

    The UHL solve of Kim & Kim 2013 §II-B: the transmitters' positions come from the
    beacon file, the distances from a CSV file (--distances), the command line (--tx,
    repeated) or one-way ranging output (--ranges). Prints x_m, y_m, heading_deg (in
    (-180, 180]), the method that gave the position and the RMS distance residual at the
    solution (m); with --ranges or --sigma also the pose's 1-sigma (the distances' sigma
    propagated through the solve to first order).

    \b
    Examples:
      rangekit locate --beacons beacons.json --distances d.csv
      rangekit locate --beacons beacons.json --tx 1:2.11,2.05,2.20 --tx 2:2.42,2.37,2.51
      rangekit locate --beacons beacons.json --distances d.csv --method direct --format json
      rangekit synth oneway --seed 1 -o ow.wav
      rangekit range --scheme oneway ow.wav --period 0.2 --tx-order 0,1,2,3,4,5 -o r.csv \\
          --format csv
      rangekit locate --beacons ow.beacons.json --ranges r.csv
    """
    from rangekit.io.duhllog import read_beacons
    from rangekit.io.guard import is_stdin
    from rangekit.io.notes import locate_detail
    from rangekit.localize.locate import locate_pose, read_distance_table, read_range_rows

    given = [
        o for o, v in (("--distances", distances), ("--tx", tx_items), ("--ranges", ranges)) if v
    ]
    if len(given) > 1:
        raise click.UsageError(f"{' and '.join(given)} exclude each other")
    if not given:
        raise click.UsageError(
            "give the distances: --distances FILE.csv, --tx ID:D1,D2,D3 or --ranges FILE"
        )
    if ranges is not None and sigma is not None:
        raise click.UsageError("--sigma applies to --distances and --tx (--ranges has sigma_m)")
    sig = sigma
    if distances is not None:
        source = "standard input" if is_stdin(distances) else str(distances)
        ids, d = read_distance_table(distances, name=source)
    elif ranges is not None:
        source = "standard input" if is_stdin(ranges) else str(ranges)
        r = read_range_rows(ranges, name=source)  # standard input: JSON if it starts with {
        if r.dropped:
            warn(
                f"rangekit: {source}: transmitter(s) {', '.join(map(str, r.dropped))} left out "
                "(not heard on every receiver)"
            )
        ids, d, sig = r.ids, r.distances_m.tolist(), r.sigma_m
    else:
        ids, d = _parse_tx(tx_items)
        source = "--tx"
    detail("rangekit: locate: " + locate_detail(ids, source=source, method=method, sigma_m=sig))
    pose = locate_pose(
        read_beacons(beacons), ids, d, sigma_m=sig, r_R=r_r, method=method, d_th=d_th,
        source=source, beacon_file=str(beacons),
    )  # fmt: skip
    emit(pose.format(fmt), output)


def _parse_tx(items) -> tuple[list[int], list[list[float]]]:
    """Ids and (n, 3) distances from repeated ``--tx ID:D1,D2,D3``."""
    ids: list[int] = []
    d: list[list[float]] = []
    for item in items:
        head, sep, tail = item.partition(":")
        try:
            if not sep:
                raise ValueError
            t = int(head.strip())
            vals = [float(v) for v in tail.split(",")]
        except ValueError:
            raise click.BadParameter(
                f"{item!r} must be ID:D1,D2,D3 (an integer id, three distances in m)",
                param_hint="--tx",
            ) from None
        if t < 0:
            raise click.BadParameter(f"{item!r}: the id {t} is negative", param_hint="--tx")
        if len(vals) != 3:
            raise click.BadParameter(
                f"{item!r} has {len(vals)} distance(s); give three, D1,D2,D3", param_hint="--tx"
            )
        for v in vals:
            if not math.isfinite(v) or v < 0.0:
                raise click.BadParameter(
                    f"{item!r}: the distance {v:g} is not a finite number >= 0",
                    param_hint="--tx",
                )
        if t in ids:
            raise click.BadParameter(f"transmitter {t} is given more than once", param_hint="--tx")
        ids.append(t)
        d.append(vals)
    return ids, d
