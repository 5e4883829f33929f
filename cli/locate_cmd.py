"""``rangekit locate``: one static robot pose from ceiling transmitters (UHL, Kim & Kim 2013)."""

from __future__ import annotations

import math

import click
from rangekit_cli._options import (
    FiniteRange,
    debug_option,
    detail,
    emit,
    format_option,
    output_option,
    verbosity_options,
    warn,
)

#: Output fields, in order.
FIELDS = ("x_m", "y_m", "heading_deg", "method_used", "residual_m")
#: Added when the distances' sigma is known (--ranges or --sigma).
SIGMA_FIELDS = ("sigma_x_m", "sigma_y_m", "sigma_heading_deg")

#: Header of the --distances CSV file.
DISTANCE_COLUMNS = ("tx", "d1_m", "d2_m", "d3_m")


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
@click.option(
    "--sigma",
    type=FiniteRange(0.0, None, min_open=True),
    default=None,
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
    from rangekit.errors import IncompatibleInputError, InvalidParameterError
    from rangekit.io.duhllog import read_beacons
    from rangekit.io.results import format_rows
    from rangekit.localize.uhl import solve_pose

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
    sig = None
    if distances is not None:
        ids, d, source = _read_distances(distances)
    elif ranges is not None:
        ids, d, sig, source = _read_ranges(ranges)
    else:
        ids, d = _parse_tx(tx_items)
        source = "--tx"
    if sigma is not None:
        sig = [[sigma] * 3 for _ in ids]
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
    detail(
        f"rangekit: locate: {len(ids)} transmitters ({', '.join(map(str, ids))}) from "
        f"{source}, method {method}, distance sigma "
        f"{f'{sigma:g} m' if sigma is not None else 'per range' if sig is not None else 'none'}"
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
    fields = FIELDS
    if sig is not None:
        import numpy as np

        from rangekit.localize.uhl_cov import pose_covariance

        s = np.asarray(sig, dtype=float)
        if not np.all(np.isfinite(s)):
            raise IncompatibleInputError(f"{source}: a distance without sigma_m")
        cov = pose_covariance(bcn.position(ids), d, s, r_R=r_r, method=method, d_th=d_th)
        sd = np.sqrt(np.diag(cov))
        row.update(sigma_x_m=sd[0], sigma_y_m=sd[1], sigma_heading_deg=math.degrees(sd[2]))
        fields = FIELDS + SIGMA_FIELDS
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
        if sig is not None:
            obj["covariance"] = cov.tolist()
        text = json.dumps(obj, indent=2) + "\n"
    else:
        text = format_rows([row], fields, fmt)
    emit(text, output)


def _read_distances(path) -> tuple[list[int], list[list[float]], str]:
    """Ids and (n, 3) distances from a ``tx,d1_m,d2_m,d3_m`` CSV file."""
    from rangekit.errors import LogFormatError
    from rangekit.io.csvlog import Column, read_table

    spec = {"tx": Column(kind="int", nonneg=True)}
    spec.update({c: Column(nonneg=True) for c in DISTANCE_COLUMNS[1:]})
    name = "standard input" if str(path) == "-" else str(path)
    tab = read_table(path, spec, name=name, allow_extra=False)
    ids = [int(t) for t in tab["tx"].tolist()]
    seen: set[int] = set()
    for t in ids:
        if t in seen:
            raise LogFormatError(f"{name}, column 'tx': transmitter {t} appears more than once")
        seen.add(t)
    d = [[float(tab[c][i]) for c in DISTANCE_COLUMNS[1:]] for i in range(len(ids))]
    return ids, d, name


def _read_ranges(path):
    """Ids, (n, 3) distances and sigmas from `range --scheme oneway` output (CSV or JSON)."""

    from rangekit.errors import LogFormatError
    from rangekit.io.csvlog import Column, read_table
    from rangekit.io.guard import MAX_TABLE_BYTES, is_stdin, read_stdin
    from rangekit.localize.uhl_cov import uhl_inputs

    name = "standard input" if is_stdin(path) else str(path)
    # Standard input is JSON when it starts with an object, else CSV.
    stdin_json = is_stdin(path) and read_stdin(MAX_TABLE_BYTES).lstrip().startswith(b"{")
    if name.endswith(".json") or stdin_json:
        from rangekit.io.sidecar import read_json

        obj = read_json(path)  # guarded: regular file, size, nesting, finite numbers
        try:
            rows = obj["ranges"]
            cols = {k: [r[k] for r in rows] for k in ("tx", "channel", "distance_m", "sigma_m")}
        except (ValueError, KeyError, TypeError) as e:
            raise LogFormatError(
                f'{name}: not the JSON of `rangekit range --scheme oneway` (a "ranges" list '
                f"of objects with tx, channel, distance_m, sigma_m): {e}"
            ) from None
        tx = [-1 if v is None else v for v in cols["tx"]]
        dist = [math.nan if v is None else v for v in cols["distance_m"]]
        sig = [math.nan if v is None else v for v in cols["sigma_m"]]
        bad = [v for v in (*tx, *cols["channel"]) if isinstance(v, bool) or not isinstance(v, int)]
        if bad:
            raise LogFormatError(f"{name}: tx and channel must be integers, got {bad[0]!r}")
        channel = cols["channel"]
    else:
        spec = {
            "tx": Column(kind="str", empty_ok=True),
            "channel": Column(kind="int", nonneg=True),
            "distance_m": Column(empty_ok=True, nonneg=True),
            "sigma_m": Column(empty_ok=True, nonneg=True),
        }
        tab = read_table(path, spec, name=name)
        tx = []
        for i, v in enumerate(tab["tx"].tolist()):
            try:
                tx.append(-1 if v in ("", "-") else int(v))
            except ValueError:
                raise LogFormatError(
                    f"{name} row {i + 1}, column 'tx': {v!r} is not an id"
                ) from None
        channel, dist, sig = tab["channel"], tab["distance_m"], tab["sigma_m"]
    r = uhl_inputs(tx, channel, dist, sig, what=name)
    if r.dropped:
        warn(
            f"rangekit: {name}: transmitter(s) {', '.join(map(str, r.dropped))} left out "
            "(not heard on every receiver)"
        )
    return r.ids, r.distances_m.tolist(), r.sigma_m.tolist(), name


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
