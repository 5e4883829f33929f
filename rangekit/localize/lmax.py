"""The l_max pedestrian localization filter (Ahn & Yu, §3).

Noisy position fixes ``P̃_i`` from a wireless network are smoothed without any noise
model: each estimate moves from the previous estimate towards the next fix, by the full
distance if it is at most ``l_max`` and by ``l_max`` otherwise. Offline, the pass starts
at the fix ``i*`` closest to the truth (assumed known) and runs backwards to the first
fix, then forwards to the last one; online, ``i* = 1`` (the known start) and only the
forward pass runs, one step per new fix (:func:`lmax_step`).

Indices are zero-based: the paper's ``i*`` is ``i_star + 1``, and the online filter is
``i_star = 0``. The estimate at ``i*`` is the anchor: the fix ``P̃_{i*}`` itself (the
paper's premise that it is the most accurate one) unless ``anchor_m`` is given (e.g. a
known starting position).

Position log format (CSV, ``#`` lines are comments)::

    t_s  time of the fix (s), required, non-decreasing
    x_m  measured x (m), required
    y_m  measured y (m), required

Examples
--------
Fixes 0.5 m apart are followed exactly; a 5 m jump is cut to l_max = 1 m:

>>> lmax_online([[0.0, 0.0], [0.3, 0.4], [3.3, 4.4]], l_max_m=1.0).round(12).tolist()
[[0.0, 0.0], [0.3, 0.4], [0.9, 1.2]]
"""

from __future__ import annotations

import functools
import math
import os
from typing import IO

import numpy as np

from rangekit import _validate as V
from rangekit.errors import InvalidParameterError
from rangekit.io.csvlog import Column, read_table

__all__ = [
    "NUMBA_MIN_POINTS",
    "POSITION_LOG_COLUMNS",
    "TRACK_COLUMNS",
    "best_index",
    "lmax_offline",
    "lmax_online",
    "lmax_step",
    "read_position_log",
    "track_fixes",
    "track_log",
]

#: The position log's columns (see the module docstring).
POSITION_LOG_COLUMNS = {"t_s": Column(kind="time"), "x_m": Column(), "y_m": Column()}
#: The columns of the array :func:`track_log` returns.
TRACK_COLUMNS = ("t_s", "x_m", "y_m")
#: Paths with at least this many fixes use the numba-compiled loop (same numbers, tested);
#: below it the plain loop is faster than importing numba.
NUMBA_MIN_POINTS = 200_000


# --------------------------------------------------------------------------- kernels
def _lmax_loop(mx, my, i_star, x0, y0, l_max, out):
    """Backward pass from ``i_star`` then forward pass, into ``out`` (n, 2) (numba-able).

    ``Δ = (P̃ - P̂_prev) * min(1, l_max / l)``, which equals the paper's
    ``min(l, l_max) (cos θ, sin θ)`` with ``θ = atan2(ỹ - ŷ, x̃ - x̂)`` and is exact when
    ``l <= l_max`` (the estimate is then the fix itself).
    """
    n = mx.shape[0]
    out[i_star, 0] = x0
    out[i_star, 1] = y0
    for i in range(i_star - 1, -1, -1):
        px, py = out[i + 1, 0], out[i + 1, 1]
        dx, dy = mx[i] - px, my[i] - py
        dist = math.sqrt(dx * dx + dy * dy)
        if dist > l_max:
            dx, dy = dx * l_max / dist, dy * l_max / dist
        out[i, 0], out[i, 1] = px + dx, py + dy
    for i in range(i_star + 1, n):
        px, py = out[i - 1, 0], out[i - 1, 1]
        dx, dy = mx[i] - px, my[i] - py
        dist = math.sqrt(dx * dx + dy * dy)
        if dist > l_max:
            dx, dy = dx * l_max / dist, dy * l_max / dist
        out[i, 0], out[i, 1] = px + dx, py + dy
    return out


@functools.cache
def _compiled_loop():
    """The numba-compiled :func:`_lmax_loop` (numba is imported on first use only)."""
    import numba

    return numba.njit(cache=True, nogil=True)(_lmax_loop)


def _lmax_paper(meas: np.ndarray, i_star_1: int, l_max: float, anchor: np.ndarray) -> np.ndarray:
    """Literal transcription of the §3 algorithm (1-based ``i*``, θ, cos, sin): the oracle."""
    n = len(meas)
    P_t = {i + 1: (float(meas[i, 0]), float(meas[i, 1])) for i in range(n)}  # P̃_i
    P_h = {i_star_1: (float(anchor[0]), float(anchor[1]))}  # P̂_i

    def toward(target, prev):
        theta = math.atan2(target[1] - prev[1], target[0] - prev[0])
        dist = math.hypot(target[0] - prev[0], target[1] - prev[1])
        if dist <= l_max:
            dx, dy = dist * math.cos(theta), dist * math.sin(theta)
        else:
            dx, dy = l_max * math.cos(theta), l_max * math.sin(theta)
        return (prev[0] + dx, prev[1] + dy)

    for i in range(1, i_star_1):  # for i = 1 : i* - 1
        P_h[i_star_1 - i] = toward(P_t[i_star_1 - i], P_h[i_star_1 - i + 1])
    for i in range(i_star_1 + 1, n + 1):  # for i = i* + 1 : N
        P_h[i] = toward(P_t[i], P_h[i - 1])
    return np.array([P_h[i] for i in range(1, n + 1)], dtype=np.float64).reshape(n, 2)


# --------------------------------------------------------------------------- validation
def _fixes(name: str, a) -> np.ndarray:
    m = np.asarray(a, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] != 2:
        raise InvalidParameterError(f"{name} must have shape (n, 2), got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        k = int(np.argmax(~np.all(np.isfinite(m), axis=1)))
        raise InvalidParameterError(f"{name}[{k}]={m[k].tolist()!r} is not finite")
    return np.ascontiguousarray(m)


def _point(name: str, p) -> np.ndarray:
    a = np.asarray(p, dtype=np.float64)
    if a.shape != (2,) or not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"{name}={p!r} must be two finite numbers (x, y) in m")
    return a


def _run(meas: np.ndarray, i_star: int, anchor: np.ndarray, l_max: float) -> np.ndarray:
    out = np.empty_like(meas)
    loop = _compiled_loop() if len(meas) >= NUMBA_MIN_POINTS else _lmax_loop
    return loop(meas[:, 0].copy(), meas[:, 1].copy(), i_star, anchor[0], anchor[1], l_max, out)


# --------------------------------------------------------------------------- public
def lmax_step(previous_m, measured_m, *, l_max_m: float) -> np.ndarray:
    """One step of the l_max filter: move from the last estimate towards a new fix.

    Parameters
    ----------
    previous_m : array_like, shape (2,)
        The previous estimate ``P̂_{i-1}`` (m).
    measured_m : array_like, shape (2,)
        The new fix ``P̃_i`` (m).
    l_max_m : float
        Largest move per step (m), > 0.

    Returns
    -------
    ndarray, shape (2,)
        ``P̂_i = P̂_{i-1} + min(l, l_max) (cos θ, sin θ)`` with ``l = |P̃_i - P̂_{i-1}|``
        and ``θ = ∠(P̃_i - P̂_{i-1})`` (Ahn & Yu §3, forward loop).

    Examples
    --------
    >>> lmax_step([0.0, 0.0], [3.0, 4.0], l_max_m=1.0).tolist()
    [0.6, 0.8]
    >>> lmax_step([0.0, 0.0], [0.3, 0.4], l_max_m=1.0).tolist()
    [0.3, 0.4]
    """
    prev = _point("previous_m", previous_m)
    meas = _point("measured_m", measured_m)
    l_max = V.positive("l_max_m", l_max_m)
    return _run(np.stack([prev, meas]), 0, prev, l_max)[1]


def lmax_offline(measured_m, *, l_max_m: float, i_star: int, anchor_m=None) -> np.ndarray:
    """The offline l_max filter: backward from ``i_star``, then forward (Ahn & Yu §3).

    Parameters
    ----------
    measured_m : array_like, shape (n, 2)
        Position fixes ``P̃_i`` (m), in time order.
    l_max_m : float
        Largest move per step (m), > 0; the paper recommends the maximum or average
        distance a person moves in one sampling interval.
    i_star : int
        Zero-based index of the fix closest to the truth (the paper's ``i*`` minus 1),
        ``0 <= i_star < n``.
    anchor_m : array_like, shape (2,), optional
        The estimate at ``i_star``; default the fix ``measured_m[i_star]``.

    Returns
    -------
    ndarray, shape (n, 2)
        Estimates ``P̂_i`` (m).

    Raises
    ------
    InvalidParameterError
        ``l_max_m <= 0``, ``i_star`` outside ``[0, n)``, or non-finite fixes.

    Examples
    --------
    >>> fixes = [[5.0, 0.0], [0.0, 0.0], [0.5, 0.0], [0.5, 3.0]]
    >>> lmax_offline(fixes, l_max_m=1.0, i_star=1).tolist()
    [[1.0, 0.0], [0.0, 0.0], [0.5, 0.0], [0.5, 1.0]]
    """
    meas = _fixes("measured_m", measured_m)
    l_max = V.positive("l_max_m", l_max_m)
    n = len(meas)
    if isinstance(i_star, bool) or not isinstance(i_star, (int, np.integer)):
        raise InvalidParameterError(f"i_star={i_star!r} must be an integer index")
    if not 0 <= int(i_star) < n:
        raise InvalidParameterError(
            f"i_star={i_star!r} must be an index of the {n} fixes, within [0, {n - 1}]"
            if n
            else f"i_star={i_star!r}: there are no fixes"
        )
    anchor = meas[int(i_star)] if anchor_m is None else _point("anchor_m", anchor_m)
    return _run(meas, int(i_star), anchor, l_max)


def lmax_online(measured_m, *, l_max_m: float, anchor_m=None) -> np.ndarray:
    """The online (real-time) l_max filter: ``i* = 1``, forward pass only (Ahn & Yu §3).

    Row i of the result depends only on fixes 0..i, so it equals feeding the fixes one at
    a time to :func:`lmax_step`.

    Parameters
    ----------
    measured_m : array_like, shape (n, 2)
        Position fixes (m). An empty array gives an empty result.
    l_max_m : float
        Largest move per step (m), > 0.
    anchor_m : array_like, shape (2,), optional
        The known starting position; default the first fix.

    Returns
    -------
    ndarray, shape (n, 2)

    Examples
    --------
    >>> lmax_online([[0.0, 0.0], [2.0, 0.0], [2.0, 0.0]], l_max_m=1.5).tolist()
    [[0.0, 0.0], [1.5, 0.0], [2.0, 0.0]]
    """
    meas = _fixes("measured_m", measured_m)
    l_max = V.positive("l_max_m", l_max_m)
    if len(meas) == 0:
        return meas.copy()
    anchor = meas[0] if anchor_m is None else _point("anchor_m", anchor_m)
    return _run(meas, 0, anchor, l_max)


def best_index(measured_m, truth_m) -> int:
    """The zero-based ``i*``: index of the fix closest to the truth (Ahn & Yu §3).

    Examples
    --------
    >>> best_index([[0.0, 1.0], [1.0, 1.1], [2.0, 3.0]], [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    1
    """
    meas = _fixes("measured_m", measured_m)
    truth = _fixes("truth_m", truth_m)
    if meas.shape != truth.shape or len(meas) == 0:
        raise InvalidParameterError(
            f"measured_m {meas.shape} and truth_m {truth.shape} must have the same non-empty shape"
        )
    return int(np.argmin(np.hypot(*(meas - truth).T)))


# --------------------------------------------------------------------------- logs
def read_position_log(
    path: str | os.PathLike | IO[str], *, name: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Read a position log ``t_s, x_m, y_m``.

    Returns
    -------
    t_s : ndarray, shape (n,)
    measured_m : ndarray, shape (n, 2)

    Raises
    ------
    InputFileError
        The file cannot be opened.
    LogFormatError
        A missing column, an empty, non-numeric, NaN or infinite cell, or time going
        backwards; the message names the row and the column.

    Examples
    --------
    >>> import io
    >>> t, p = read_position_log(io.StringIO("t_s,x_m,y_m\\n0,1.5,-2\\n1,1.0,-2.5\\n"))
    >>> t.tolist(), p.tolist()
    ([0.0, 1.0], [[1.5, -2.0], [1.0, -2.5]])
    """
    tab = read_table(path, POSITION_LOG_COLUMNS, name=name)
    return tab["t_s"], np.stack([tab["x_m"], tab["y_m"]], axis=1).reshape(-1, 2)


def track_log(
    path: str | os.PathLike | IO[str], *, l_max_m: float, i_star: int | None = None
) -> tuple[list[str], np.ndarray]:
    """Run the l_max filter on a position log file.

    Parameters
    ----------
    path : path or text stream
        Position log (:func:`read_position_log`).
    l_max_m : float
        Largest move per step (m), > 0.
    i_star : int, optional
        Zero-based index of the most accurate fix: the offline filter
        (:func:`lmax_offline`). None (default): the online filter (:func:`lmax_online`),
        anchored at the first fix.

    Returns
    -------
    columns : list of str
        ``["t_s", "x_m", "y_m"]`` (the estimates).
    rows : ndarray, shape (n, 3)

    Examples
    --------
    >>> import io
    >>> cols, rows = track_log(io.StringIO("t_s,x_m,y_m\\n0,0,0\\n1,3,4\\n"), l_max_m=1.0)
    >>> cols, rows.tolist()
    (['t_s', 'x_m', 'y_m'], [[0.0, 0.0, 0.0], [1.0, 0.6, 0.8]])
    """
    t, meas = read_position_log(path)
    return track_fixes(t, meas, l_max_m=l_max_m, i_star=i_star)


def track_fixes(
    t_s: np.ndarray, measured_m: np.ndarray, *, l_max_m: float, i_star: int | None = None
) -> tuple[list[str], np.ndarray]:
    """:func:`track_log` on fixes already read (``t_s`` (n,), ``measured_m`` (n, 2)).

    Examples
    --------
    >>> cols, rows = track_fixes([0.0, 1.0], [[0.0, 0.0], [3.0, 4.0]], l_max_m=1.0, i_star=0)
    >>> rows.tolist()
    [[0.0, 0.0, 0.0], [1.0, 0.6, 0.8]]
    """
    if i_star is None:
        est = lmax_online(measured_m, l_max_m=l_max_m)
    else:
        est = lmax_offline(measured_m, l_max_m=l_max_m, i_star=i_star)
    return list(TRACK_COLUMNS), np.column_stack([t_s, est]).reshape(-1, 3)
