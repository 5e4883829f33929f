"""Measurement logs for range tracking (Jiang 2018 §4.4): robot poses, relative fixes, ranges.

One CSV file, one measurement per row, rows in time order, typed by ``kind``:

========  ======================================================================================
kind      columns used
========  ======================================================================================
robot     ``t_s, x_m, y_m, heading_rad, var_x_m2, var_y_m2, cov_xy_m2``: the robot's
          self-localised pose and the covariance P_r of its position (world frame).
fix       ``t_s, b, x_m, y_m, var_x_m2, var_y_m2, cov_xy_m2``: position of target ``b``
          relative to the robot in the robot's frame (x forward, y left), as a depth
          camera gives it, and its covariance R_f in that frame.
range     ``t_s, a, b, range_m, sigma_m``: a distance between ``a`` and ``b`` (0 = the
          robot, 1..N = targets) with its 1-sigma; an empty ``range_m`` is a failed
          ranging (no measurement).
========  ======================================================================================

Column header: ``t_s,kind,a,b,x_m,y_m,heading_rad,var_x_m2,var_y_m2,cov_xy_m2,range_m,sigma_m``
(cells a kind does not use are left empty). ``#`` lines are comments. The format is
documented in ``docs/formats.md``; :func:`read_measurement_log` checks every row and names
the row and column of the first problem.

Examples
--------
>>> import io
>>> text = '''t_s,kind,a,b,x_m,y_m,heading_rad,var_x_m2,var_y_m2,cov_xy_m2,range_m,sigma_m
... 0.0,robot,,,1.0,2.0,0.0,0.0036,0.0036,0,,
... 0.0,fix,,1,1.2,0.1,,0.01,0.01,0,,
... 0.0,range,0,2,,,,,,,3.1,0.1
... 0.0,range,1,2,,,,,,,2.5,0.1
... '''
>>> log = read_measurement_log(io.StringIO(text), name="log.csv")
>>> log.n_targets, log.ranges.range_m.tolist(), log.fixes.target.tolist()
(2, [3.1, 2.5], [1])
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import IO

import numpy as np

from rangekit.errors import LogFormatError
from rangekit.io.csvlog import Column, read_table, write_table

__all__ = [
    "LOG_COLUMNS",
    "FixRows",
    "MeasurementLog",
    "RangeRows",
    "RobotRows",
    "read_measurement_log",
]

#: The header of a measurement log, in order.
LOG_COLUMNS = (
    "t_s",
    "kind",
    "a",
    "b",
    "x_m",
    "y_m",
    "heading_rad",
    "var_x_m2",
    "var_y_m2",
    "cov_xy_m2",
    "range_m",
    "sigma_m",
)

_SPEC = {
    "t_s": Column(kind="time"),
    "kind": Column(kind="str"),
    "a": Column(kind="int", empty_ok=True),
    "b": Column(kind="int", empty_ok=True),
    "x_m": Column(empty_ok=True),
    "y_m": Column(empty_ok=True),
    "heading_rad": Column(empty_ok=True, required=False),
    "var_x_m2": Column(empty_ok=True, nonneg=True),
    "var_y_m2": Column(empty_ok=True, nonneg=True),
    "cov_xy_m2": Column(empty_ok=True),
    "range_m": Column(empty_ok=True, nonneg=True),
    "sigma_m": Column(empty_ok=True, nonneg=True),
}

#: Columns each kind must fill.
_NEEDS = {
    "robot": ("x_m", "y_m", "var_x_m2", "var_y_m2"),
    "fix": ("b", "x_m", "y_m", "var_x_m2", "var_y_m2"),
    "range": ("a", "b", "sigma_m"),
}


@dataclass(frozen=True)
class RobotRows:
    """Robot poses: ``t_s`` (n,), ``xy_m`` (n, 2), ``heading_rad`` (n,), ``cov_m2`` (n, 2, 2)."""

    t_s: np.ndarray
    xy_m: np.ndarray
    heading_rad: np.ndarray
    cov_m2: np.ndarray


@dataclass(frozen=True)
class FixRows:
    """Relative fixes: ``t_s`` (n,), ``target`` (n,) ids 1..N, ``rel_m`` (n, 2) in the robot
    frame, ``cov_m2`` (n, 2, 2) in the robot frame."""

    t_s: np.ndarray
    target: np.ndarray
    rel_m: np.ndarray
    cov_m2: np.ndarray


@dataclass(frozen=True)
class RangeRows:
    """Ranges: ``t_s`` (n,), ``a``, ``b`` (n,) ids (0 = robot), ``range_m`` (n,) with NaN for a
    failed ranging, ``sigma_m`` (n,)."""

    t_s: np.ndarray
    a: np.ndarray
    b: np.ndarray
    range_m: np.ndarray
    sigma_m: np.ndarray


@dataclass(frozen=True)
class MeasurementLog:
    """A parsed measurement log (rows of each kind, in time order).

    Attributes
    ----------
    robot : RobotRows
    fixes : FixRows
    ranges : RangeRows
    n_targets : int
        The largest target id that appears (targets are 1..n_targets).
    """

    robot: RobotRows
    fixes: FixRows
    ranges: RangeRows
    n_targets: int

    def to_csv(self, *, comment: str = "") -> str:
        """The log as CSV text in the documented format (rows merged in time order;
        at equal times robot rows first, then fixes, then ranges)."""
        rows: list[tuple[float, int, int, list]] = []
        r, f, g = self.robot, self.fixes, self.ranges
        for i in range(r.t_s.size):
            c = r.cov_m2[i]
            cells = [r.t_s[i], "robot", None, None, *r.xy_m[i], r.heading_rad[i]]
            rows.append((r.t_s[i], 0, i, [*cells, c[0, 0], c[1, 1], c[0, 1], None, None]))
        for i in range(f.t_s.size):
            c = f.cov_m2[i]
            cells = [f.t_s[i], "fix", None, f.target[i], *f.rel_m[i], None]
            rows.append((f.t_s[i], 1, i, [*cells, c[0, 0], c[1, 1], c[0, 1], None, None]))
        for i in range(g.t_s.size):
            cells = [g.t_s[i], "range", g.a[i], g.b[i], *([None] * 6)]
            rows.append((g.t_s[i], 2, i, [*cells, g.range_m[i], g.sigma_m[i]]))
        rows.sort(key=lambda r: (r[0], r[1], r[2]))
        return write_table(LOG_COLUMNS, [r[3] for r in rows], header_comment=comment)


def _cov(vx: np.ndarray, vy: np.ndarray, cxy: np.ndarray) -> np.ndarray:
    cxy = np.where(np.isnan(cxy), 0.0, cxy)
    out = np.empty((vx.size, 2, 2))
    out[:, 0, 0], out[:, 1, 1], out[:, 0, 1], out[:, 1, 0] = vx, vy, cxy, cxy
    return out


def read_measurement_log(
    source: str | os.PathLike | IO[str], *, name: str | None = None
) -> MeasurementLog:
    """Read and validate a measurement log (format in the module docstring).

    Parameters
    ----------
    source : path or text stream
    name : str, optional
        How the file is named in error messages.

    Returns
    -------
    MeasurementLog

    Raises
    ------
    LogFormatError
        Missing column, unknown ``kind``, a cell a kind needs left empty, a NaN, a
        negative sigma or variance, time going backwards, a target id < 1, a range whose
        ``a`` is not 0 or a target, ``a == b``, a covariance that is not positive
        semidefinite, or a log without ranges. The message names row and column.
    InputFileError
        The file cannot be opened.
    """
    label = name or (str(source) if not hasattr(source, "read") else "<stream>")
    tab = read_table(source, _SPEC, name=label)
    kind = tab["kind"]
    n = kind.size
    rownum = np.arange(n) + 2  # 1-based, header is row 1 (comments are not counted)
    for i in range(n):
        k = kind[i]
        if k not in _NEEDS:
            raise LogFormatError(
                f"{label} row {rownum[i]}, column 'kind': unknown kind {k!r} "
                f"(use {', '.join(_NEEDS)})"
            )
        for c in _NEEDS[k]:
            v = tab[c][i]
            if (c in ("a", "b") and v < 0) or (c not in ("a", "b") and np.isnan(v)):
                raise LogFormatError(
                    f"{label} row {rownum[i]}, column {c!r}: a {k} row needs a value here"
                )
        if k == "fix" and tab["b"][i] < 1:
            raise LogFormatError(
                f"{label} row {rownum[i]}, column 'b': target ids start at 1 (0 is the robot)"
            )
        if k == "range":
            a, b = tab["a"][i], tab["b"][i]
            if b < 1:
                raise LogFormatError(
                    f"{label} row {rownum[i]}, column 'b': a range's b must be a target (>= 1)"
                )
            if a == b:
                raise LogFormatError(
                    f"{label} row {rownum[i]}, column 'a': a range from {a} to itself"
                )
        if k in ("robot", "fix"):
            vx, vy = tab["var_x_m2"][i], tab["var_y_m2"][i]
            cxy = 0.0 if np.isnan(tab["cov_xy_m2"][i]) else tab["cov_xy_m2"][i]
            if cxy * cxy > vx * vy * (1 + 1e-9):
                raise LogFormatError(
                    f"{label} row {rownum[i]}, column 'cov_xy_m2': {cxy:g} makes the "
                    "covariance indefinite (cov_xy^2 > var_x var_y)"
                )
    sel = {k: np.flatnonzero(kind == k) for k in _NEEDS}
    if sel["range"].size == 0:
        raise LogFormatError(f"{label}: the log has no 'range' rows (nothing to track from)")
    ri, fi, gi = sel["robot"], sel["fix"], sel["range"]
    heading = tab["heading_rad"][ri]
    robot = RobotRows(
        tab["t_s"][ri],
        np.column_stack([tab["x_m"][ri], tab["y_m"][ri]]),
        np.where(np.isnan(heading), 0.0, heading),
        _cov(tab["var_x_m2"][ri], tab["var_y_m2"][ri], tab["cov_xy_m2"][ri]),
    )
    fixes = FixRows(
        tab["t_s"][fi],
        tab["b"][fi].astype(np.int64),
        np.column_stack([tab["x_m"][fi], tab["y_m"][fi]]).reshape(-1, 2),
        _cov(tab["var_x_m2"][fi], tab["var_y_m2"][fi], tab["cov_xy_m2"][fi]),
    )
    ranges = RangeRows(
        tab["t_s"][gi],
        tab["a"][gi].astype(np.int64),
        tab["b"][gi].astype(np.int64),
        tab["range_m"][gi],
        tab["sigma_m"][gi],
    )
    if np.any(ranges.a == 0) and robot.t_s.size == 0:
        raise LogFormatError(f"{label}: ranges to the robot (a = 0) but no 'robot' rows")
    if fixes.t_s.size and robot.t_s.size == 0:
        raise LogFormatError(f"{label}: 'fix' rows need 'robot' rows (fixes are robot-relative)")
    n_targets = int(max(ranges.b.max(), ranges.a.max(), fixes.target.max(initial=0)))
    return MeasurementLog(robot, fixes, ranges, n_targets)
