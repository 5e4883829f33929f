"""``rangekit locate``: one static robot pose from ceiling transmitters (UHL, Kim & Kim 2013)."""

from __future__ import annotations

import math

import click
from rangekit_cli._options import FiniteRange, debug_option, emit, format_choice, output_option

#: Output fields, in order.
FIELDS = ("x_m", "y_m", "heading_deg", "method_used", "residual_m")

#: Header of the --distances CSV file.
DISTANCE_COLUMNS = ("tx", "d1_m", "d2_m", "d3_m")


@click.command("locate")
@click.option(
    "--beacons",
    type=click.Path(dir_okay=True),
    required=True,
    metavar="FILE",
    help="Beacon file: the ceiling transmitters' ids and positions (JSON, docs/formats.md).",
)
@click.option(
    "--distances",
    type=click.Path(dir_okay=True),
    default=None,
    metavar="FILE.csv",
    help="CSV with header tx,d1_m,d2_m,d3_m: one row per transmitter heard, its distances "
    "(m) to receivers 1, 2, 3 (at 0, 120, 240 degrees from the heading).",
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
    default="hybrid",
    show_default=True,
    help="Position by the direct method, the indirect method using ranges, or the hybrid "
    "rule of Kim & Kim 2013 Table I.",
)
@click.option(
    "--d-th",
    "d_th",
    type=FiniteRange(0.0, None),
    default=0.2,
    show_default=True,
    metavar="M",
    help="Hybrid threshold, m: with collinear transmitters, the direct position is kept "
    "within this distance of their line.",
)
@click.option(
    "--r-r",
    "r_r",
    type=FiniteRange(0.0, None, min_open=True),
    default=0.19,
    show_default=True,
    metavar="M",
    help="Radius of the receiver circle on the robot, m.",
)
@format_choice(("table", "json"), "table")
@output_option
@debug_option
def locate_cmd(beacons, distances, tx_items, method, d_th, r_r, fmt, output):
    """One robot pose from the distances of ceiling transmitters to its three receivers.

    The UHL solve of Kim & Kim 2013 §II-B: the transmitters' positions come from the
    beacon file, the distances from a CSV file (--distances) or the command line (--tx,
    repeated). Prints x_m, y_m, heading_deg (in (-180, 180]), the method that gave the
    position and the RMS distance residual at the solution (m).

    \b
    Examples:
      rangekit locate --beacons beacons.json --distances d.csv
      rangekit locate --beacons beacons.json --tx 1:2.11,2.05,2.20 --tx 2:2.42,2.37,2.51
      rangekit locate --beacons beacons.json --distances d.csv --method direct --format json
    """
    from rangekit.errors import IncompatibleInputError, InvalidParameterError
    from rangekit.io.duhllog import read_beacons
    from rangekit.io.results import format_rows
    from rangekit.localize.uhl import solve_pose

    if distances is not None and tx_items:
        raise click.UsageError("--distances and --tx exclude each other")
    if distances is None and not tx_items:
        raise click.UsageError("give the distances: --distances FILE.csv or --tx ID:D1,D2,D3")
    if distances is not None:
        ids, d, source = _read_distances(distances)
    else:
        ids, d = _parse_tx(tx_items)
        source = "--tx"
    bcn = read_beacons(beacons)
    known = set(bcn.ids.tolist())
    for t in ids:
        if t not in known:
            raise IncompatibleInputError(
                f"{source}: transmitter {t} is not in the beacon file {str(beacons)!r} "
                f"(ids: {sorted(known)})"
            )
    if len(ids) < 2:
        raise IncompatibleInputError(
            f"{source}: {len(ids)} transmitter(s) heard; UHL needs at least 2 (Kim & Kim "
            "2013, eq (3))"
        )
    try:
        pose = solve_pose(bcn.position(ids), d, r_R=r_r, method=method, d_th=d_th)
    except InvalidParameterError as e:
        # Shapes, values and options are checked above: what is left is the geometry.
        raise IncompatibleInputError(
            f"transmitters {', '.join(str(t) for t in ids)}: {e}".replace("tx_xyz: ", "")
        ) from e
    heading = math.degrees(pose.phi_rad)
    row = {
        "x_m": pose.x_m,
        "y_m": pose.y_m,
        "heading_deg": heading,
        "method_used": pose.method_used,
        "residual_m": pose.residual_m,
    }
    if fmt == "json":
        import json

        obj = {
            **row,
            "heading_rad": pose.phi_rad,
            "method": method,
            "d_th_m": d_th,
            "r_R_m": r_r,
            "beacons": str(beacons),
            "tx": ids,
        }
        text = json.dumps(obj, indent=2) + "\n"
    else:
        text = format_rows([row], FIELDS, "table")
    emit(text, output)


def _read_distances(path) -> tuple[list[int], list[list[float]], str]:
    """Ids and (n, 3) distances from a ``tx,d1_m,d2_m,d3_m`` CSV file."""
    from rangekit.errors import LogFormatError
    from rangekit.io.csvlog import Column, read_table

    spec = {"tx": Column(kind="int", nonneg=True)}
    spec.update({c: Column(nonneg=True) for c in DISTANCE_COLUMNS[1:]})
    name = str(path)
    tab = read_table(path, spec, name=name, allow_extra=False)
    ids = [int(t) for t in tab["tx"].tolist()]
    seen: set[int] = set()
    for t in ids:
        if t in seen:
            raise LogFormatError(f"{name}, column 'tx': transmitter {t} appears more than once")
        seen.add(t)
    d = [[float(tab[c][i]) for c in DISTANCE_COLUMNS[1:]] for i in range(len(ids))]
    return ids, d, name


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
