"""Compiled ray casting and segment crossing against wall segments (private).

Two operations on a set of wall segments ``seg`` (float64, shape ``(m, 4)``, rows
``x0, y0, x1, y1``), each written twice:

* a loop version (``_cast_rays_loop``, ``_crosses_loop``) that numba compiles: one pass
  over the rays (or moves), an inner brute-force pass over the segments, no Python
  overhead per ray;
* a plain-numpy reference (``_cast_rays_reference``, ``_crosses_reference``), the test
  oracle, evaluated on ``(rays, segments)`` blocks of bounded size.

Both versions evaluate the same expressions in the same order, so they agree to the last
bit in practice (the tests allow 1e-12 relative).  Small problems take the numpy path
because importing numba costs more (~0.3 s) than the work; :data:`NUMBA_MIN_PAIRS` sets
the switch.  The public wrappers are in :mod:`rangekit.floorplan`.

Geometry (both operations)
--------------------------
A ray ``o + t d`` (``d`` a unit vector, ``t >= 0`` the distance in metres) and a segment
``a + u e`` (``e = b - a``, ``0 <= u <= 1``) meet where ``t = (w x e) / (d x e)`` and
``u = (w x d) / (d x e)``, with ``w = a - o`` and ``p x q = p_x q_y - p_y q_x``.
Parallel pairs (``d x e == 0``) never hit.  The incidence angle is
``theta = atan2(|d x e|, |d . e|)`` in ``[0, pi/2]``: the acute angle between the ray
and the wall, ``pi/2`` for a perpendicular hit.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["NUMBA_MIN_PAIRS", "cast", "crosses"]

#: Problems with fewer ray-segment pairs than this run the numpy reference (same numbers).
NUMBA_MIN_PAIRS = 200_000

#: Ray-segment pairs evaluated per block by the numpy references (bounds their memory).
_BLOCK_PAIRS = 1 << 18


# ----------------------------------------------------------------------------- rays


def _cast_rays_loop(ox, oy, dx, dy, rmax, seg, exclude):
    """First wall hit of each ray (compiled by numba; see :func:`cast`)."""
    n = ox.shape[0]
    m = seg.shape[0]
    dist = np.full(n, np.nan)
    hit = np.full(n, -1, dtype=np.int64)
    theta = np.full(n, np.nan)
    for i in range(n):
        best = np.inf
        best_k = -1
        for k in range(m):
            if k == exclude[i]:
                continue
            ex = seg[k, 2] - seg[k, 0]
            ey = seg[k, 3] - seg[k, 1]
            denom = dx[i] * ey - dy[i] * ex
            if denom == 0.0:
                continue
            wx = seg[k, 0] - ox[i]
            wy = seg[k, 1] - oy[i]
            t = (wx * ey - wy * ex) / denom
            if t < 0.0 or t > rmax[i] or t >= best:
                continue
            u = (wx * dy[i] - wy * dx[i]) / denom
            if u < 0.0 or u > 1.0:
                continue
            best = t
            best_k = k
        if best_k >= 0:
            ex = seg[best_k, 2] - seg[best_k, 0]
            ey = seg[best_k, 3] - seg[best_k, 1]
            dist[i] = best
            hit[i] = best_k
            theta[i] = np.arctan2(abs(dx[i] * ey - dy[i] * ex), abs(dx[i] * ex + dy[i] * ey))
    return dist, hit, theta


def _cast_rays_reference(ox, oy, dx, dy, rmax, seg, exclude):
    """Plain-numpy first wall hit of each ray: the oracle for :func:`_cast_rays_loop`."""
    n = ox.shape[0]
    m = seg.shape[0]
    dist = np.full(n, np.nan)
    hit = np.full(n, -1, dtype=np.int64)
    theta = np.full(n, np.nan)
    if n == 0 or m == 0:
        return dist, hit, theta
    ex = seg[:, 2] - seg[:, 0]
    ey = seg[:, 3] - seg[:, 1]
    ks = np.arange(m)
    step = max(1, _BLOCK_PAIRS // m)
    for s in range(0, n, step):
        sl = slice(s, min(n, s + step))
        rdx = dx[sl, None]
        rdy = dy[sl, None]
        denom = rdx * ey - rdy * ex
        wx = seg[:, 0] - ox[sl, None]
        wy = seg[:, 1] - oy[sl, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (wx * ey - wy * ex) / denom
            u = (wx * rdy - wy * rdx) / denom
        ok = (
            (denom != 0.0)
            & (t >= 0.0)
            & (t <= rmax[sl, None])
            & (u >= 0.0)
            & (u <= 1.0)
            & (ks != exclude[sl, None])
        )
        tt = np.where(ok, t, np.inf)
        k = np.argmin(tt, axis=1)
        rows = np.arange(k.size)
        best = tt[rows, k]
        found = np.isfinite(best)
        idx = np.flatnonzero(found) + s
        kf = k[found]
        dist[idx] = best[found]
        hit[idx] = kf
        cross = dx[idx] * ey[kf] - dy[idx] * ex[kf]
        dot = dx[idx] * ex[kf] + dy[idx] * ey[kf]
        theta[idx] = np.arctan2(np.abs(cross), np.abs(dot))
    return dist, hit, theta


# ---------------------------------------------------------------------------- moves


def _crosses_loop(ax, ay, bx, by, seg):
    """Whether each move a -> b meets any segment (compiled by numba; see :func:`crosses`)."""
    n = ax.shape[0]
    m = seg.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        dx = bx[i] - ax[i]
        dy = by[i] - ay[i]
        dd = dx * dx + dy * dy
        if dd == 0.0:
            continue
        for k in range(m):
            ex = seg[k, 2] - seg[k, 0]
            ey = seg[k, 3] - seg[k, 1]
            wx = seg[k, 0] - ax[i]
            wy = seg[k, 1] - ay[i]
            denom = dx * ey - dy * ex
            if denom != 0.0:
                t = (wx * ey - wy * ex) / denom
                u = (wx * dy - wy * dx) / denom
                if t >= 0.0 and t <= 1.0 and u >= 0.0 and u <= 1.0:
                    out[i] = True
                    break
            elif wx * dy - wy * dx == 0.0:
                # Collinear: overlap of the parameter intervals along the move.
                s0 = (wx * dx + wy * dy) / dd
                s1 = ((seg[k, 2] - ax[i]) * dx + (seg[k, 3] - ay[i]) * dy) / dd
                if min(s0, s1) <= 1.0 and max(s0, s1) >= 0.0:
                    out[i] = True
                    break
    return out


def _crosses_reference(ax, ay, bx, by, seg):
    """Plain-numpy move/segment test: the oracle for :func:`_crosses_loop`."""
    n = ax.shape[0]
    m = seg.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    if n == 0 or m == 0:
        return out
    ex = seg[:, 2] - seg[:, 0]
    ey = seg[:, 3] - seg[:, 1]
    step = max(1, _BLOCK_PAIRS // m)
    for s in range(0, n, step):
        sl = slice(s, min(n, s + step))
        dx = (bx[sl] - ax[sl])[:, None]
        dy = (by[sl] - ay[sl])[:, None]
        dd = dx * dx + dy * dy
        wx = seg[:, 0] - ax[sl, None]
        wy = seg[:, 1] - ay[sl, None]
        denom = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (wx * ey - wy * ex) / denom
            u = (wx * dy - wy * dx) / denom
            s0 = (wx * dx + wy * dy) / dd
            s1 = ((seg[:, 2] - ax[sl, None]) * dx + (seg[:, 3] - ay[sl, None]) * dy) / dd
        proper = (denom != 0.0) & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
        collinear = (
            (denom == 0.0)
            & (wx * dy - wy * dx == 0.0)
            & (np.minimum(s0, s1) <= 1.0)
            & (np.maximum(s0, s1) >= 0.0)
        )
        out[sl] = np.any((proper | collinear) & (dd != 0.0), axis=1)
    return out


# -------------------------------------------------------------------------- dispatch


@functools.cache
def _compiled(name: str, cache: bool = True):
    """The numba-compiled loop ``name`` (numba is imported on first use only)."""
    import numba

    func = {"cast": _cast_rays_loop, "crosses": _crosses_loop}[name]
    return numba.njit(cache=cache, nogil=True)(func)


def _run_compiled(name: str, *args):
    """Run the compiled loop ``name``, without the disk cache if that cannot be loaded."""
    try:
        return _compiled(name)(*args)
    except ModuleNotFoundError:
        # numba's disk cache records the defining module's *name* and re-imports it on
        # load; an entry written while this file was imported under another name (a
        # prepend-mode doctest run) cannot be loaded: compile an uncached copy instead.
        return _compiled(name, cache=False)(*args)


def cast(ox, oy, dx, dy, rmax, seg, exclude):
    """First hit of each ray ``o + t d``, ``0 <= t <= rmax``, skipping segment ``exclude``.

    All inputs are C-contiguous: float64 ``(n,)`` for ``ox, oy, dx, dy, rmax`` (``d`` of
    unit length), float64 ``(m, 4)`` for ``seg`` and int64 ``(n,)`` for ``exclude``
    (``-1`` excludes nothing).  Returns ``(dist, hit, theta)``: float64 distance (NaN for
    no hit), int64 segment index (-1) and float64 incidence angle in ``[0, pi/2]`` (NaN).
    """
    if ox.shape[0] * seg.shape[0] >= NUMBA_MIN_PAIRS:
        return _run_compiled("cast", ox, oy, dx, dy, rmax, seg, exclude)
    return _cast_rays_reference(ox, oy, dx, dy, rmax, seg, exclude)


def crosses(ax, ay, bx, by, seg):
    """Whether each closed move ``a -> b`` meets any closed segment of ``seg`` (bool ``(n,)``).

    Touching counts (an end point on a wall, a move along a wall line overlapping it); a
    zero-length move never crosses.  Inputs as for :func:`cast`.
    """
    if ax.shape[0] * seg.shape[0] >= NUMBA_MIN_PAIRS:
        return _run_compiled("crosses", ax, ay, bx, by, seg)
    return _crosses_reference(ax, ay, bx, by, seg)
