"""One static robot pose from ceiling transmitters: what ``rangekit locate`` computes.

The inputs are a beacon file (:func:`rangekit.io.duhllog.read_beacons`) and, per heard
transmitter, its distances to the robot's three receivers, from a ``tx,d1_m,d2_m,d3_m``
table (:func:`read_distance_table`), from the output of ``rangekit range --scheme oneway
--tx-order ...`` (:func:`read_range_rows`: the median over windows, with sigma), or given
directly. :func:`locate_pose` checks them against the beacons and solves the pose with UHL
(Kim & Kim 2013 §II-B, :func:`rangekit.localize.uhl.solve_pose`), with its covariance when
the distances' sigma is known (:func:`rangekit.localize.uhl_cov.pose_covariance`).

Examples
--------
>>> import numpy as np
>>> from rangekit.io.duhllog import Beacons
>>> from rangekit.sim.ultrasonic import receiver_positions
>>> b = Beacons([1, 2], [[0.0, 0.0, 2.0], [3.0, 0.0, 2.0]])
>>> rx = receiver_positions((1.2, 0.7, np.radians(30.0)))
>>> d = [np.linalg.norm(rx - b.position(i), axis=1).tolist() for i in (1, 2)]
>>> p = locate_pose(b, [1, 2], d, sigma_m=0.01)
>>> round(p.x_m, 6), round(p.y_m, 6), round(p.heading_deg, 4), p.method_used
(1.2, 0.7, 30.0, 'indirect')
>>> bool(p.covariance[0, 0] > 0)
True
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import IO

import numpy as np

from rangekit.errors import IncompatibleInputError, InvalidParameterError, LogFormatError

__all__ = [
    "DISTANCE_COLUMNS",
    "FIELDS",
    "SIGMA_FIELDS",
    "Located",
    "locate_pose",
    "read_distance_table",
    "read_range_rows",
]

#: Header of a distance table.
DISTANCE_COLUMNS = ("tx", "d1_m", "d2_m", "d3_m")
#: The fields of :meth:`Located.row`, in order (the ``rangekit locate`` table).
FIELDS = ("x_m", "y_m", "heading_deg", "method_used", "residual_m")
#: Added when the covariance is known (the distances' sigma given).
SIGMA_FIELDS = ("sigma_x_m", "sigma_y_m", "sigma_heading_deg")


@dataclass(frozen=True)
class Located:
    """A solved pose: position (m), heading, the UHL branch used, the fit residual (m),
    and the 3 x 3 covariance of ``(x_m, y_m, heading_rad)`` (None without sigmas); and
    how it was solved: the method asked for, the hybrid threshold and receiver radius
    used (m), the transmitter ids in order, the beacon file's name (what
    :func:`locate_pose` was given, its defaults filled in)."""

    x_m: float
    y_m: float
    heading_rad: float
    method_used: str
    residual_m: float
    covariance: np.ndarray | None = None
    method: str = "hybrid"
    d_th_m: float | None = None
    r_R_m: float | None = None
    tx: tuple[int, ...] = ()
    beacon_file: str = ""

    @property
    def heading_deg(self) -> float:
        return math.degrees(self.heading_rad)

    def row(self) -> dict:
        """The result row of ``rangekit locate`` (sigmas when the covariance is known)."""
        out = {
            "x_m": self.x_m,
            "y_m": self.y_m,
            "heading_deg": self.heading_deg,
            "method_used": self.method_used,
            "residual_m": self.residual_m,
        }
        if self.covariance is not None:
            sd = np.sqrt(np.diag(self.covariance))
            out.update(
                sigma_x_m=float(sd[0]),
                sigma_y_m=float(sd[1]),
                sigma_heading_deg=math.degrees(float(sd[2])),
            )
        return out

    def fields(self) -> tuple[str, ...]:
        """The keys of :meth:`row`: :data:`FIELDS`, and :data:`SIGMA_FIELDS` with a
        covariance."""
        return FIELDS + (SIGMA_FIELDS if self.covariance is not None else ())

    def to_json(self) -> dict:
        """The JSON object of ``rangekit locate --format json``: :meth:`row`, then
        ``heading_rad``, ``method``, ``d_th_m``, ``r_R_m``, ``beacons`` (the file's name),
        ``tx`` (the ids used, in order) and with sigmas ``covariance`` (3 x 3 lists)."""
        obj = {
            **self.row(),
            "heading_rad": self.heading_rad,
            "method": self.method,
            "d_th_m": self.d_th_m,
            "r_R_m": self.r_R_m,
            "beacons": self.beacon_file,
            "tx": list(self.tx),
        }
        if self.covariance is not None:
            obj["covariance"] = self.covariance.tolist()
        return obj

    def format(self, fmt: str) -> str:
        """The result as ``rangekit locate`` prints it: ``"json"`` (:meth:`to_json`,
        indented), or ``"table"`` / ``"csv"`` of :meth:`row`
        (:func:`rangekit.io.results.format_rows`, the number rules of every verb)."""
        if fmt == "json":
            import json

            return json.dumps(self.to_json(), indent=2) + "\n"
        from rangekit.io.results import format_rows

        return format_rows([self.row()], self.fields(), fmt)


def locate_pose(
    beacons,
    ids: Sequence[int],
    distances_m,
    *,
    sigma_m=None,
    r_R: float | None = None,
    method: str = "hybrid",
    d_th: float | None = None,
    source: str = "the distances",
    beacon_file: str = "",
) -> Located:
    """The UHL pose of a robot whose receivers heard transmitters ``ids`` at ``distances_m``.

    Parameters
    ----------
    beacons : rangekit.io.duhllog.Beacons
    ids : sequence of int
        Transmitter ids, distinct, at least 2 (Kim & Kim 2013 eq (3)).
    distances_m : array_like, shape (n, 3)
        Distances to receivers 1-3 (at 0, 120, 240 degrees from the heading), m.
    sigma_m : float or array_like (n, 3), optional
        1-sigma of the distances; gives the pose covariance.
    r_R, method, d_th
        As in :func:`rangekit.localize.uhl.solve_pose` (None: its defaults).
    source : str
        Where the distances came from, for error messages.
    beacon_file : str
        The beacon file's name, for error messages.

    Raises
    ------
    IncompatibleInputError
        A transmitter the beacon file lacks, fewer than 2 transmitters, a geometry UHL
        cannot solve (transmitters at one x-y point), a distance without a sigma.
    """
    from rangekit.localize.uhl import solve_pose

    ids = [int(t) for t in ids]
    known = set(beacons.ids.tolist())
    for t in ids:
        if t not in known:
            raise IncompatibleInputError(
                f"{source}: transmitter {t} is not in the beacon file"
                f"{f' {beacon_file!r}' if beacon_file else ''} (ids: {sorted(known)})"
            )
    if len(ids) < 2:
        raise IncompatibleInputError(
            f"{source}: {len(ids)} transmitter(s) heard; UHL needs at least 2 (Kim & Kim "
            "2013, eq (3))"
        )
    from rangekit.localize.uhl import DEFAULT_D_TH_M, R_R_M

    kw = {
        "method": method,
        "r_R": R_R_M if r_R is None else r_R,
        "d_th": DEFAULT_D_TH_M if d_th is None else d_th,
    }
    xyz = beacons.position(ids)
    try:
        pose = solve_pose(xyz, distances_m, **kw)
    except InvalidParameterError as e:
        # Shapes and values are the caller's to check: what is left is the geometry.
        raise IncompatibleInputError(
            f"transmitters {', '.join(str(t) for t in ids)}: {e}".replace("tx_xyz: ", "")
        ) from e
    cov = None
    if sigma_m is not None:
        from rangekit.localize.uhl_cov import pose_covariance

        s = np.broadcast_to(np.asarray(sigma_m, dtype=float), np.shape(distances_m))
        if not np.all(np.isfinite(s)):
            raise IncompatibleInputError(f"{source}: a distance without sigma_m")
        cov = pose_covariance(xyz, np.asarray(distances_m, dtype=float), s, **kw)
    return Located(
        float(pose.x_m),
        float(pose.y_m),
        float(pose.phi_rad),
        str(pose.method_used),
        float(pose.residual_m),
        cov,
        method=method,
        d_th_m=kw["d_th"],
        r_R_m=kw["r_R"],
        tx=tuple(ids),
        beacon_file=beacon_file,
    )


def read_distance_table(
    path: str | os.PathLike | IO[str], *, name: str | None = None
) -> tuple[list[int], list[list[float]]]:
    """Ids and (n, 3) distances from a ``tx,d1_m,d2_m,d3_m`` CSV table.

    Raises
    ------
    LogFormatError
        Another header, an empty, NaN or negative distance, a transmitter listed twice
        (the row and column named).
    """
    from rangekit.io.csvlog import Column, read_table

    spec = {"tx": Column(kind="int", nonneg=True)}
    spec.update({c: Column(nonneg=True) for c in DISTANCE_COLUMNS[1:]})
    name = name or str(path)
    tab = read_table(path, spec, name=name, allow_extra=False)
    ids = [int(t) for t in tab["tx"].tolist()]
    seen: set[int] = set()
    for t in ids:
        if t in seen:
            raise LogFormatError(f"{name}, column 'tx': transmitter {t} appears more than once")
        seen.add(t)
    return ids, [[float(tab[c][i]) for c in DISTANCE_COLUMNS[1:]] for i in range(len(ids))]


def read_range_rows(path: str | os.PathLike, *, name: str | None = None, json: bool | None = None):
    """Per transmitter, the distances and sigmas of ``rangekit range --scheme oneway
    --tx-order ...`` output (CSV or JSON: ``json=None`` decides by the ``.json`` suffix),
    as :class:`rangekit.localize.uhl_cov.UHLInputs` (median over the windows; the
    transmitters a receiver never heard listed in ``dropped``). Standard input (``-``)
    is JSON when it starts with ``{``, else CSV, unless ``json`` says.

    Raises
    ------
    LogFormatError
        Not that output (the columns or keys named).
    """
    from rangekit.io.csvlog import Column, read_table
    from rangekit.io.guard import MAX_TABLE_BYTES, is_stdin, read_stdin
    from rangekit.localize.uhl_cov import uhl_inputs

    name = name or str(path)
    if json is None and is_stdin(path):
        json = read_stdin(MAX_TABLE_BYTES).lstrip().startswith(b"{")
    elif json is None:
        json = name.endswith(".json")
    if json:
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
    return uhl_inputs(tx, channel, dist, sig, what=name)
