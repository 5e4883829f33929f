"""Step-event and range-reading logs of pedestrian tracking (Girard et al. 2011 §3.2).

Two CSV files, both read through :func:`rangekit.io.csvlog.read_table` (row and column
named in every error, ``#`` lines are comments, rows in time order):

**Step log** -- one row per step event (Girard §3.2 step 2: the foot-mounted IMU detects a
step and measures its length and orientation)::

    t_s,length_m,heading_rad,heading_sigma_rad
    1.0,1.25,0.0,0.035

``t_s`` is when the foot lands (s), ``length_m`` the measured step length (>= 0),
``heading_rad`` the walking direction counter-clockwise from +x (compass, rad),
``heading_sigma_rad`` the 1-sigma of that heading (>= 0; empty = unknown, NaN).

**Range log** -- one row per reading of a body-worn range finder (SRF02)::

    t_s,sensor,range_m
    0.072,0,1.02
    0.144,1,

``sensor`` is the sensor index (0, 1, ...: the order of the filter's sensor mounts),
``range_m`` the reading in m (>= 0), an empty cell = out of range (no echo).

Examples
--------
>>> import io
>>> steps = read_step_log(io.StringIO("t_s,length_m,heading_rad,heading_sigma_rad\\n"
...                                   "1.0,1.25,0.5,0.03\\n"), name="steps.csv")
>>> steps.length_m.tolist(), steps.heading_rad.tolist()
([1.25], [0.5])
>>> ranges = read_range_log(io.StringIO("t_s,sensor,range_m\\n0.1,0,1.5\\n0.2,1,\\n"))
>>> ranges.sensor.tolist(), ranges.range_m.tolist()
([0, 1], [1.5, nan])
>>> read_range_log(io.StringIO("t_s,sensor,range_m\\n0.1,-1,1.5\\n"), name="r.csv")
Traceback (most recent call last):
...
rangekit.errors.LogFormatError: r.csv row 2, column 'sensor': -1 is negative
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import IO

import numpy as np

from rangekit.errors import InvalidParameterError
from rangekit.io.csvlog import Column, read_table, write_table

__all__ = [
    "RANGE_COLUMNS",
    "STEP_COLUMNS",
    "RangeLog",
    "StepLog",
    "read_range_log",
    "read_step_log",
]

#: Header of a step log, in order.
STEP_COLUMNS = ("t_s", "length_m", "heading_rad", "heading_sigma_rad")
#: Header of a range log, in order.
RANGE_COLUMNS = ("t_s", "sensor", "range_m")

_STEP_SPEC = {
    "t_s": Column(kind="time"),
    "length_m": Column(nonneg=True),
    "heading_rad": Column(),
    "heading_sigma_rad": Column(nonneg=True, empty_ok=True),
}
_RANGE_SPEC = {
    "t_s": Column(kind="time"),
    "sensor": Column(kind="int", nonneg=True),
    "range_m": Column(nonneg=True, empty_ok=True),
}


def _arr(name: str, v, n: int | None, dtype=np.float64) -> np.ndarray:
    a = np.array(v, dtype=dtype).reshape(-1)
    if n is not None and a.size != n:
        raise InvalidParameterError(f"{name} has {a.size} values, t_s has {n}")
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class StepLog:
    """Step events (Girard 2011 §3.2 step 2), arrays of equal length ``(n,)``.

    Attributes
    ----------
    t_s : numpy.ndarray
        Time the foot lands, s, non-decreasing.
    length_m : numpy.ndarray
        Measured step length, m (>= 0).
    heading_rad : numpy.ndarray
        Measured walking direction, rad, counter-clockwise from +x.
    heading_sigma_rad : numpy.ndarray
        1-sigma of the heading, rad (NaN: unknown).

    Raises
    ------
    InvalidParameterError
        On arrays of different lengths, NaN or infinite values, negative lengths or
        sigmas, or times going backwards.
    """

    t_s: np.ndarray
    length_m: np.ndarray
    heading_rad: np.ndarray
    heading_sigma_rad: np.ndarray

    def __post_init__(self) -> None:
        t = _arr("t_s", self.t_s, None)
        n = t.size
        vals = {
            "t_s": t,
            "length_m": _arr("length_m", self.length_m, n),
            "heading_rad": _arr("heading_rad", self.heading_rad, n),
            "heading_sigma_rad": _arr("heading_sigma_rad", self.heading_sigma_rad, n),
        }
        for k in ("t_s", "length_m", "heading_rad"):
            if not np.all(np.isfinite(vals[k])):
                raise InvalidParameterError(f"{k} contains NaN or infinite values")
        if np.any(np.diff(t) < 0):
            raise InvalidParameterError("t_s must not decrease")
        if np.any(vals["length_m"] < 0) or np.any(vals["heading_sigma_rad"] < 0):
            raise InvalidParameterError("length_m and heading_sigma_rad must be >= 0")
        for k, v in vals.items():
            object.__setattr__(self, k, v)

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def vectors_m(self) -> np.ndarray:
        """Measured step vectors ``(n, 2)`` in m."""
        return self.length_m[:, None] * np.column_stack(
            [np.cos(self.heading_rad), np.sin(self.heading_rad)]
        )

    def to_csv(self, *, comment: str = "") -> str:
        """The log as CSV text (empty cell for an unknown sigma)."""
        rows = zip(self.t_s, self.length_m, self.heading_rad, self.heading_sigma_rad, strict=True)
        return write_table(STEP_COLUMNS, list(rows), header_comment=comment)


@dataclass(frozen=True)
class RangeLog:
    """Range readings of body-worn sensors, arrays of equal length ``(n,)``.

    Attributes
    ----------
    t_s : numpy.ndarray
        Reading time, s, non-decreasing.
    sensor : numpy.ndarray
        int64 sensor index (>= 0).
    range_m : numpy.ndarray
        Reading in m, NaN when out of range (no echo).

    Raises
    ------
    InvalidParameterError
        On arrays of different lengths, non-finite times, negative sensors or ranges,
        infinite ranges or times going backwards.
    """

    t_s: np.ndarray
    sensor: np.ndarray
    range_m: np.ndarray

    def __post_init__(self) -> None:
        t = _arr("t_s", self.t_s, None)
        n = t.size
        s = _arr("sensor", self.sensor, n, np.int64)
        r = _arr("range_m", self.range_m, n)
        if not np.all(np.isfinite(t)):
            raise InvalidParameterError("t_s contains NaN or infinite values")
        if np.any(np.diff(t) < 0):
            raise InvalidParameterError("t_s must not decrease")
        if np.any(s < 0):
            raise InvalidParameterError("sensor indices must be >= 0")
        if np.any(np.isinf(r)) or np.any(r < 0):
            raise InvalidParameterError("range_m must be >= 0 and finite (NaN = out of range)")
        for k, v in (("t_s", t), ("sensor", s), ("range_m", r)):
            object.__setattr__(self, k, v)

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def n_sensors(self) -> int:
        """Largest sensor index + 1 (0 for an empty log)."""
        return int(self.sensor.max()) + 1 if self.sensor.size else 0

    def to_csv(self, *, comment: str = "") -> str:
        """The log as CSV text (empty cell for out of range)."""
        rows = zip(self.t_s, self.sensor, self.range_m, strict=True)
        return write_table(RANGE_COLUMNS, list(rows), header_comment=comment)


def _label(source, name: str | None) -> str:
    return name or (str(source) if not hasattr(source, "read") else "<stream>")


def read_step_log(source: str | os.PathLike | IO[str], *, name: str | None = None) -> StepLog:
    """Read and validate a step log (format in the module docstring).

    Parameters
    ----------
    source : path or text stream
    name : str, optional
        How the file is named in error messages.

    Returns
    -------
    StepLog
        Empty (zero rows) for a file with only a header.

    Raises
    ------
    LogFormatError
        Missing column, a cell that is not a number, NaN or infinite, a negative length
        or sigma, time going backwards; the message names file, row and column.
    InputFileError
        The file cannot be opened.
    """
    label = _label(source, name)
    tab = read_table(source, _STEP_SPEC, name=label)
    return StepLog(tab["t_s"], tab["length_m"], tab["heading_rad"], tab["heading_sigma_rad"])


def read_range_log(source: str | os.PathLike | IO[str], *, name: str | None = None) -> RangeLog:
    """Read and validate a range log (format in the module docstring).

    Parameters
    ----------
    source : path or text stream
    name : str, optional
        How the file is named in error messages.

    Returns
    -------
    RangeLog

    Raises
    ------
    LogFormatError
        Missing column, a sensor that is not a non-negative integer, a range that is not
        a number, negative or infinite (leave it empty for out of range), time going
        backwards; the message names file, row and column.
    InputFileError
        The file cannot be opened.
    """
    label = _label(source, name)
    tab = read_table(source, _RANGE_SPEC, name=label)
    return RangeLog(tab["t_s"], tab["sensor"], tab["range_m"])
