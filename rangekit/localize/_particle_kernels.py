"""Compiled kernels of the floor-plan particle filters (Girard et al. 2011 §3), private.

A uniform grid over the wall segments (:class:`SegmentGrid`, built by :func:`build_grid`)
lets ray casting and wall-crossing tests look only at the segments of the cells a ray or a
move passes through (Girard §3 used 2 m tiles; the cell here defaults to 1 m). Kernels:

* :func:`cast_rays_grid`: first wall hit of each ray (distance, segment, incidence angle),
  the same numbers as the brute-force :func:`rangekit._raycast.cast` (tested against its
  plain-numpy reference ``_raycast._cast_rays_reference``);
* :func:`crosses_grid`: whether each move ``a -> b`` meets a wall (same as
  :func:`rangekit._raycast.crosses`);
* :func:`ray_model_grid`: Girard's ray model (§3.2, eq. (3)) for many particles and
  sensors at once, the numbers of :func:`rangekit.sensors.srf02.model_range` with
  ``method="rays"`` (inf where that function gives NaN). When all particles share the
  heading, a ray is cast from a cell only if some wall within its range is close enough
  to perpendicular to send it back (exact; in axis-parallel plans about one ray in seven);
* :func:`merge_close`: step 5 of Girard §3.2, merging particles closer than tau (greedy,
  heaviest first, spatial hash); :func:`merge_close_reference` is its O(n^2) oracle.

Exactness: each ray/segment and move/segment pair is evaluated with the expressions of
:mod:`rangekit._raycast` in the same order, and ties between segments hit at the same
distance go to the lower segment index, as in the brute-force loop; segments are
registered in every cell their bounding box (padded by ``_PAD_M``) touches, and a ray
stops only once its best hit lies inside the cells already visited. So the grid answers
equal the brute-force answers bit for bit (tested).

Traversal is Amanatides & Woo's 3-D-DDA in 2-D: from the ray's entry into the grid box,
step to the next cell boundary in x or y, whichever comes first.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "SegmentGrid",
    "build_grid",
    "cast_rays_grid",
    "crosses_grid",
    "merge_close",
    "merge_close_reference",
    "ray_model_grid",
    "useful_rays",
]

#: Segments are registered in the cells within this distance (m) of their bounding box.
_PAD_M = 1e-7


class SegmentGrid(NamedTuple):
    """A uniform grid of square cells over the wall segments.

    Cell ``(ix, iy)`` covers ``[x0 + ix h, x0 + (ix + 1) h] x [y0 + iy h, ...]``, its
    segments are ``items[start[c]:start[c + 1]]`` with ``c = iy * nx + ix``.
    """

    seg: np.ndarray  # float64 (m, 4): x0, y0, x1, y1
    x0: float
    y0: float
    cell_m: float
    nx: int
    ny: int
    start: np.ndarray  # int64 (nx * ny + 1,)
    items: np.ndarray  # int64: segment indices, cell by cell
    cseg: np.ndarray  # float64 (len(items), 4): x0, y0, ex, ey of each item (contiguous)
    orient: np.ndarray  # float64: distinct wall directions in [0, pi), rad, sorted


def build_grid(seg: np.ndarray, cell_m: float = 1.0) -> SegmentGrid:
    """Register each segment in the cells its padded bounding box touches.

    Parameters
    ----------
    seg : numpy.ndarray
        float64 ``(m, 4)`` segments ``x0, y0, x1, y1`` in m.
    cell_m : float
        Cell side in m, > 0.

    Returns
    -------
    SegmentGrid
        The grid box is the segments' bounding box grown by one cell on each side (a
        1 x 1 grid around the origin for no segments).
    """
    seg = np.ascontiguousarray(seg, dtype=np.float64).reshape(-1, 4)
    h = float(cell_m)
    if seg.shape[0] == 0:
        z = np.zeros(0, np.int64)
        e = np.zeros((0, 4))
        return SegmentGrid(seg, -h, -h, h, 2, 2, np.zeros(5, np.int64), z, e, np.zeros(0))
    xs = np.concatenate([seg[:, 0], seg[:, 2]])
    ys = np.concatenate([seg[:, 1], seg[:, 3]])
    x0 = float(xs.min()) - h
    y0 = float(ys.min()) - h
    nx = int(math.floor((xs.max() - x0) / h)) + 2
    ny = int(math.floor((ys.max() - y0) / h)) + 2
    lo_x = np.floor((np.minimum(seg[:, 0], seg[:, 2]) - _PAD_M - x0) / h).astype(np.int64)
    hi_x = np.floor((np.maximum(seg[:, 0], seg[:, 2]) + _PAD_M - x0) / h).astype(np.int64)
    lo_y = np.floor((np.minimum(seg[:, 1], seg[:, 3]) - _PAD_M - y0) / h).astype(np.int64)
    hi_y = np.floor((np.maximum(seg[:, 1], seg[:, 3]) + _PAD_M - y0) / h).astype(np.int64)
    lo_x, hi_x = np.clip(lo_x, 0, nx - 1), np.clip(hi_x, 0, nx - 1)
    lo_y, hi_y = np.clip(lo_y, 0, ny - 1), np.clip(hi_y, 0, ny - 1)
    cells, owners = [], []
    for k in range(seg.shape[0]):
        ix = np.arange(lo_x[k], hi_x[k] + 1)
        iy = np.arange(lo_y[k], hi_y[k] + 1)
        c = (iy[:, None] * nx + ix[None, :]).ravel()
        if hi_x[k] > lo_x[k] and hi_y[k] > lo_y[k]:
            # A slanted segment: keep only the cells its padded line passes near.
            ccx = x0 + (c % nx + 0.5) * h
            ccy = y0 + (c // nx + 0.5) * h
            ex, ey = seg[k, 2] - seg[k, 0], seg[k, 3] - seg[k, 1]
            dist = np.abs((ccx - seg[k, 0]) * ey - (ccy - seg[k, 1]) * ex) / math.hypot(ex, ey)
            c = c[dist <= 0.5 * math.sqrt(2.0) * h + 2.0 * _PAD_M]
        cells.append(c)
        owners.append(np.full(c.size, k, dtype=np.int64))
    cell = np.concatenate(cells)
    owner = np.concatenate(owners)
    order = np.lexsort((owner, cell))
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    np.add.at(start, cell + 1, 1)
    items = owner[order].copy()
    cseg = np.column_stack(
        [seg[items, 0], seg[items, 1], seg[items, 2] - seg[items, 0], seg[items, 3] - seg[items, 1]]
    )
    ang = np.mod(np.arctan2(seg[:, 3] - seg[:, 1], seg[:, 2] - seg[:, 0]), np.pi)
    orient = np.unique(np.round(ang, 9))
    return SegmentGrid(seg, x0, y0, h, nx, ny, np.cumsum(start), items, cseg, orient)


#: Slack (rad) of the test that skips rays no wall direction can send back.
_ORIENT_TOL = 1e-6


def useful_rays(ray_angles: np.ndarray, window: float, grid: SegmentGrid) -> np.ndarray:
    """Which rays some wall could send back under eq. (3) (bool, shape of ``ray_angles``).

    A ray is accepted only by a wall whose normal lies within ``window`` =
    ``alpha / (2 lambda)`` of the ray, whatever the particle's position; a ray no wall
    direction of the plan can accept never contributes and need not be cast. Exact (with
    a slack of ``_ORIENT_TOL``); in a plan of axis-parallel walls it leaves about one ray in
    seven per sensor.
    """
    a = np.asarray(ray_angles, dtype=np.float64)
    if grid.orient.size == 0:
        return np.zeros(a.shape, dtype=bool)
    # acute angle between the ray and each wall's normal (wall direction + pi/2)
    diff = np.mod(a[..., None] - (grid.orient + 0.5 * np.pi), np.pi)
    acute = np.minimum(diff, np.pi - diff)
    return np.any(acute <= window + _ORIENT_TOL, axis=-1)


# ------------------------------------------------------------------------- traversal


@njit(cache=True, inline="always")
def _enter(ox, oy, dx, dy, tmax, x0, y0, h, nx, ny):  # pragma: no cover - compiled
    """Entry and exit parameters of the ray with the grid box (``t_in > t_out``: miss)."""
    t_in = 0.0
    t_out = tmax
    x1 = x0 + nx * h
    y1 = y0 + ny * h
    if dx != 0.0:
        a = (x0 - ox) / dx
        b = (x1 - ox) / dx
        if a > b:
            a, b = b, a
        t_in = max(t_in, a)
        t_out = min(t_out, b)
    elif ox < x0 or ox > x1:
        return 1.0, 0.0
    if dy != 0.0:
        a = (y0 - oy) / dy
        b = (y1 - oy) / dy
        if a > b:
            a, b = b, a
        t_in = max(t_in, a)
        t_out = min(t_out, b)
    elif oy < y0 or oy > y1:
        return 1.0, 0.0
    return t_in, t_out


@njit(cache=True)
def _cast_one(ox, oy, dx, dy, rmax, cseg, x0, y0, h, nx, ny, start, items):  # pragma: no cover
    """First hit ``(t, k, q)`` of one ray (``k = -1``: none; ``q`` the item), DDA."""
    best = np.inf
    best_k = -1
    best_q = -1
    inv_h = 1.0 / h
    fx = (ox - x0) * inv_h
    fy = (oy - y0) * inv_h
    if 0.0 <= fx < nx and 0.0 <= fy < ny:  # the usual case: the origin is in the grid
        ix = int(fx)
        iy = int(fy)
    else:
        t_in, t_out = _enter(ox, oy, dx, dy, rmax, x0, y0, h, nx, ny)
        if t_in > t_out:
            return best, best_k, best_q
        ix = min(max(int(math.floor((ox + t_in * dx - x0) * inv_h)), 0), nx - 1)
        iy = min(max(int(math.floor((oy + t_in * dy - y0) * inv_h)), 0), ny - 1)
    # Cell-boundary crossings only steer the traversal (segments are registered with a
    # pad), so reciprocals are fine here; hit distances use the exact division below.
    if dx > 0.0:
        sx = 1
        rx = 1.0 / dx
        tx = (x0 + (ix + 1) * h - ox) * rx
        ddx = h * rx
    elif dx < 0.0:
        sx = -1
        rx = 1.0 / dx
        tx = (x0 + ix * h - ox) * rx
        ddx = -h * rx
    else:
        sx = 0
        tx = np.inf
        ddx = np.inf
    if dy > 0.0:
        sy = 1
        ry = 1.0 / dy
        ty = (y0 + (iy + 1) * h - oy) * ry
        ddy = h * ry
    elif dy < 0.0:
        sy = -1
        ry = 1.0 / dy
        ty = (y0 + iy * h - oy) * ry
        ddy = -h * ry
    else:
        sy = 0
        ty = np.inf
        ddy = np.inf
    while True:
        c = iy * nx + ix
        for q in range(start[c], start[c + 1]):
            ex = cseg[q, 2]
            ey = cseg[q, 3]
            denom = dx * ey - dy * ex
            if denom == 0.0:
                continue
            wx = cseg[q, 0] - ox
            wy = cseg[q, 1] - oy
            t = (wx * ey - wy * ex) / denom
            if t < 0.0 or t > rmax or t > best:
                continue
            k = items[q]
            if t == best and k >= best_k:
                continue
            u = (wx * dy - wy * dx) / denom
            if u < 0.0 or u > 1.0:
                continue
            best = t
            best_k = k
            best_q = q
        t_exit = min(tx, ty)
        if best <= t_exit or t_exit > rmax:
            break
        if tx < ty:
            ix += sx
            tx += ddx
            if ix < 0 or ix >= nx:
                break
        else:
            iy += sy
            ty += ddy
            if iy < 0 or iy >= ny:
                break
    return best, best_k, best_q


@njit(cache=True)
def _cast_kernel(
    ox, oy, dx, dy, rmax, seg, cseg, x0, y0, h, nx, ny, start, items
):  # pragma: no cover - compiled
    n = ox.shape[0]
    dist = np.full(n, np.nan)
    hit = np.full(n, -1, dtype=np.int64)
    theta = np.full(n, np.nan)
    for i in range(n):
        t, k, _ = _cast_one(
            ox[i], oy[i], dx[i], dy[i], rmax[i], cseg, x0, y0, h, nx, ny, start, items
        )
        if k >= 0:
            ex = seg[k, 2] - seg[k, 0]
            ey = seg[k, 3] - seg[k, 1]
            dist[i] = t
            hit[i] = k
            theta[i] = np.arctan2(abs(dx[i] * ey - dy[i] * ex), abs(dx[i] * ex + dy[i] * ey))
    return dist, hit, theta


def cast_rays_grid(ox, oy, dx, dy, rmax, grid: SegmentGrid):
    """First hit of each ray ``o + t d``, ``0 <= t <= rmax`` (``d`` unit vectors).

    Inputs are float64 ``(n,)`` arrays. Returns ``(dist, hit, theta)`` as
    :func:`rangekit._raycast.cast` does: distance (NaN: no hit), segment index (-1) and
    incidence angle in ``[0, pi/2]`` (NaN).
    """
    f = np.ascontiguousarray
    return _cast_kernel(
        f(ox, np.float64), f(oy, np.float64), f(dx, np.float64), f(dy, np.float64),
        f(rmax, np.float64), grid.seg, grid.cseg, grid.x0, grid.y0, grid.cell_m, grid.nx,
        grid.ny, grid.start, grid.items,
    )  # fmt: skip


@njit(cache=True)
def _crosses_one(
    ax, ay, bx, by, seg, cseg, x0, y0, h, nx, ny, start, items
):  # pragma: no cover - compiled
    """Whether the closed move a -> b meets a segment (the tests of ``_raycast``)."""
    dx = bx - ax
    dy = by - ay
    dd = dx * dx + dy * dy
    if dd == 0.0:
        return False
    t_in, t_out = _enter(ax, ay, dx, dy, 1.0, x0, y0, h, nx, ny)
    if t_in > t_out:
        return False
    px = ax + t_in * dx
    py = ay + t_in * dy
    ix = min(max(int(math.floor((px - x0) / h)), 0), nx - 1)
    iy = min(max(int(math.floor((py - y0) / h)), 0), ny - 1)
    if dx > 0.0:
        sx, tx, ddx = 1, (x0 + (ix + 1) * h - ax) / dx, h / dx
    elif dx < 0.0:
        sx, tx, ddx = -1, (x0 + ix * h - ax) / dx, -h / dx
    else:
        sx, tx, ddx = 0, np.inf, np.inf
    if dy > 0.0:
        sy, ty, ddy = 1, (y0 + (iy + 1) * h - ay) / dy, h / dy
    elif dy < 0.0:
        sy, ty, ddy = -1, (y0 + iy * h - ay) / dy, -h / dy
    else:
        sy, ty, ddy = 0, np.inf, np.inf
    while True:
        c = iy * nx + ix
        for q in range(start[c], start[c + 1]):
            ex = cseg[q, 2]
            ey = cseg[q, 3]
            wx = cseg[q, 0] - ax
            wy = cseg[q, 1] - ay
            denom = dx * ey - dy * ex
            if denom != 0.0:
                t = (wx * ey - wy * ex) / denom
                u = (wx * dy - wy * dx) / denom
                if t >= 0.0 and t <= 1.0 and u >= 0.0 and u <= 1.0:
                    return True
            elif wx * dy - wy * dx == 0.0:
                k = items[q]
                s0 = (wx * dx + wy * dy) / dd
                s1 = ((seg[k, 2] - ax) * dx + (seg[k, 3] - ay) * dy) / dd
                if min(s0, s1) <= 1.0 and max(s0, s1) >= 0.0:
                    return True
        t_exit = min(tx, ty)
        if t_exit > 1.0:
            return False
        if tx < ty:
            ix += sx
            tx += ddx
            if ix < 0 or ix >= nx:
                return False
        else:
            iy += sy
            ty += ddy
            if iy < 0 or iy >= ny:
                return False


@njit(cache=True)
def _crosses_kernel(
    ax, ay, bx, by, seg, cseg, x0, y0, h, nx, ny, start, items
):  # pragma: no cover - compiled
    n = ax.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        out[i] = _crosses_one(
            ax[i], ay[i], bx[i], by[i], seg, cseg, x0, y0, h, nx, ny, start, items
        )
    return out


def crosses_grid(ax, ay, bx, by, grid: SegmentGrid) -> np.ndarray:
    """Whether each closed move ``a -> b`` meets a closed wall segment (bool ``(n,)``).

    Same rules as :func:`rangekit._raycast.crosses`: touching counts, a zero-length move
    never crosses.
    """
    f = np.ascontiguousarray
    return _crosses_kernel(
        f(ax, np.float64), f(ay, np.float64), f(bx, np.float64), f(by, np.float64),
        grid.seg, grid.cseg, grid.x0, grid.y0, grid.cell_m, grid.nx, grid.ny, grid.start,
        grid.items,
    )  # fmt: skip


# ------------------------------------------------------------------------- ray model


@njit(cache=True, inline="always")
def _accept(dx, dy, ex, ey, thr, cthr, sthr):  # pragma: no cover - compiled
    """Whether the incidence angle ``atan2(|d x e|, |d . e|)`` is ``>= thr`` (eq. (3)).

    Decided by ``|d x e| cos(thr) >= |d . e| sin(thr)`` and, within rounding of that
    boundary, by the arctangent itself (the reference's test).
    """
    c = abs(dx * ey - dy * ex)
    d = abs(dx * ex + dy * ey)
    f = c * cthr - d * sthr
    tol = 1e-9 * (c + d)
    if f > tol:
        return True
    if f < -tol:
        return False
    return np.arctan2(c, d) >= thr


@njit(cache=True, inline="always")
def _model_one(
    x,
    y,
    dxs,
    dys,
    order,
    use,
    rmax_ray,
    thr,
    cthr,
    sthr,
    min_range,
    cseg,
    x0,
    y0,
    h,
    nx,
    ny,
    start,
    items,
):  # pragma: no cover - compiled
    """Shortest accepted hit over the rays of one sensor at ``(x, y)`` (inf: none).

    Rays are cast in ``order`` (centre first); each looks no further than the best
    accepted hit so far, which cannot change the minimum.
    """
    best = np.inf
    for jj in range(order.shape[0]):
        j = order[jj]
        if not use[j]:
            continue
        lim = min(rmax_ray[j], best)
        t, k, q = _cast_one(x, y, dxs[j], dys[j], lim, cseg, x0, y0, h, nx, ny, start, items)
        if k < 0 or t < min_range or t >= best:
            continue
        if _accept(dxs[j], dys[j], cseg[q, 2], cseg[q, 3], thr, cthr, sthr):
            best = t
    return best


@njit(cache=True)
def _ray_model_shared(
    px,
    py,
    dxs,
    dys,
    order,
    cmask,
    rmax_ray,
    thr,
    cthr,
    sthr,
    min_range,
    cseg,
    x0,
    y0,
    h,
    nx,
    ny,
    start,
    items,
):  # pragma: no cover - compiled
    """All particles share the ray directions ``dxs, dys`` (n_sensors, lambda); a particle
    in cell ``c`` casts ray ``j`` of sensor ``s`` only if ``cmask[c, s, j]`` (row
    ``nx * ny``: particles outside the grid, all rays)."""
    n = px.shape[0]
    n_s = dxs.shape[0]
    out = np.full((n, n_s), np.inf)
    inv_h = 1.0 / h
    for i in range(n):
        fx = (px[i] - x0) * inv_h
        fy = (py[i] - y0) * inv_h
        c = nx * ny
        if 0.0 <= fx < nx and 0.0 <= fy < ny:
            c = int(fy) * nx + int(fx)
        for s in range(n_s):
            out[i, s] = _model_one(
                px[i], py[i], dxs[s], dys[s], order, cmask[c, s], rmax_ray, thr, cthr, sthr,
                min_range, cseg, x0, y0, h, nx, ny, start, items,
            )  # fmt: skip
    return out


@njit(cache=True)
def _cell_ray_mask(dxs, dys, rmax_ray, sin_w, seg, x0, y0, h, nx, ny):  # pragma: no cover
    """Per cell, which rays some wall could send back from a particle in that cell.

    Ray ``(s, j)`` can only be accepted (eq. (3)) by a wall within ``sin_w`` of
    perpendicular (``|d . e| <= sin_w |e|``) and at most ``rmax_ray[j]`` away; a cell whose
    centre is farther than ``rmax_ray[j]`` + half its diagonal from every such wall never
    needs the ray. Conservative (slack 1e-6), so the model's answer does not change.
    """
    n_s, lam = dxs.shape
    m = seg.shape[0]
    n_c = nx * ny
    mask = np.zeros((n_c + 1, n_s, lam), dtype=np.bool_)
    mask[n_c, :, :] = True
    half = 0.5 * math.sqrt(2.0) * h
    acc = np.empty(m, dtype=np.int64)
    for s in range(n_s):
        for j in range(lam):
            na = 0
            for k in range(m):
                ex = seg[k, 2] - seg[k, 0]
                ey = seg[k, 3] - seg[k, 1]
                if abs(dxs[s, j] * ex + dys[s, j] * ey) <= (sin_w + 1e-6) * math.hypot(ex, ey):
                    acc[na] = k
                    na += 1
            if na == 0:
                continue
            reach = rmax_ray[j] + half + 1e-6
            reach2 = reach * reach
            for c in range(n_c):
                cx = x0 + (c % nx + 0.5) * h
                cy = y0 + (c // nx + 0.5) * h
                for q in range(na):
                    k = acc[q]
                    ax = seg[k, 0]
                    ay = seg[k, 1]
                    ex = seg[k, 2] - ax
                    ey = seg[k, 3] - ay
                    u = ((cx - ax) * ex + (cy - ay) * ey) / (ex * ex + ey * ey)
                    u = min(max(u, 0.0), 1.0)
                    ddx = ax + u * ex - cx
                    ddy = ay + u * ey - cy
                    if ddx * ddx + ddy * ddy <= reach2:
                        mask[c, s, j] = True
                        break
    return mask


@njit(cache=True)
def _ray_model_each(
    px,
    py,
    heading,
    mounts,
    psi,
    order,
    rmax_ray,
    thr,
    cthr,
    sthr,
    min_range,
    cseg,
    x0,
    y0,
    h,
    nx,
    ny,
    start,
    items,
):  # pragma: no cover - compiled
    """Each particle has its own heading."""
    n = px.shape[0]
    n_s = mounts.shape[0]
    lam = psi.shape[0]
    out = np.full((n, n_s), np.inf)
    dxs = np.empty(lam)
    dys = np.empty(lam)
    use = np.ones(lam, dtype=np.bool_)
    for i in range(n):
        for s in range(n_s):
            for j in range(lam):
                a = heading[i] + mounts[s] + psi[j]
                dxs[j] = math.cos(a)
                dys[j] = math.sin(a)
            out[i, s] = _model_one(
                px[i], py[i], dxs, dys, order, use, rmax_ray, thr, cthr, sthr, min_range, cseg,
                x0, y0, h, nx, ny, start, items,
            )  # fmt: skip
    return out


def ray_model_grid(
    px, py, heading, mounts, psi, rmax_ray, thr, min_range, grid: SegmentGrid, *, skip_rays=True
):
    """Girard 2011 §3.2 ray-model distance for each particle and sensor (inf: none).

    Parameters
    ----------
    px, py : numpy.ndarray
        float64 ``(n,)`` particle positions, m.
    heading : float or numpy.ndarray
        Walking direction, rad: one for all particles (the fast path: the ray directions
        are computed once) or one per particle ``(n,)``.
    mounts : numpy.ndarray
        float64 ``(n_sensors,)`` sensor axes relative to the heading, rad.
    psi, rmax_ray : numpy.ndarray
        float64 ``(lambda,)`` off-axis angles of the rays and their maximum ranges.
    thr : float
        Smallest accepted incidence angle, ``pi/2 - alpha / (2 lambda)`` (eq. (3)).
    min_range : float
        Hits nearer than this are dropped (ring-down).
    skip_rays : bool
        With a shared heading, do not cast, from a grid cell, the rays that no wall
        within their range could send back under eq. (3) (a wall within
        ``alpha / (2 lambda)`` of perpendicular to the ray, ``_cell_ray_mask``); same
        result, fewer rays. Default True.

    Returns
    -------
    numpy.ndarray
        float64 ``(n, n_sensors)``: shortest accepted hit over the rays, ``inf`` if none;
        the numbers of :func:`rangekit.sensors.srf02.model_range` (``method="rays"``).
        Ray angles are ``(heading + mount) + psi``, as there.
    """
    f = np.ascontiguousarray
    px, py = f(px, np.float64), f(py, np.float64)
    mounts, psi = f(mounts, np.float64).reshape(-1), f(psi, np.float64).reshape(-1)
    rmax_ray = f(rmax_ray, np.float64).reshape(-1)
    order = np.argsort(np.abs(psi), kind="stable").astype(np.int64)
    thr = float(thr)
    args = (order, rmax_ray, thr, math.cos(thr), math.sin(thr), float(min_range), grid.cseg)
    geo = (grid.x0, grid.y0, grid.cell_m, grid.nx, grid.ny, grid.start, grid.items)
    if np.ndim(heading) == 0:
        ang = (float(heading) + mounts)[:, None] + psi[None, :]
        dxs, dys = f(np.cos(ang)), f(np.sin(ang))
        if skip_rays:
            cmask = _cell_ray_mask(
                dxs, dys, rmax_ray, math.cos(thr), grid.seg, grid.x0, grid.y0, grid.cell_m,
                grid.nx, grid.ny,
            )  # fmt: skip
        else:
            cmask = np.ones((grid.nx * grid.ny + 1, mounts.size, psi.size), dtype=np.bool_)
        return _ray_model_shared(px, py, dxs, dys, order, cmask, *args[1:], *geo)
    hd = f(heading, np.float64)
    return _ray_model_each(px, py, hd, mounts, psi, *args, *geo)


# ----------------------------------------------------------------------------- merge


@njit(cache=True)
def _merge_kernel(x, y, w, order, tau):  # pragma: no cover - compiled
    n = x.shape[0]
    size = 16
    while size < 4 * n:
        size *= 2
    mask = size - 1
    keys = np.empty(size, dtype=np.int64)
    used = np.zeros(size, dtype=np.bool_)
    head = np.full(size, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    owner = np.full(n, -1, dtype=np.int64)
    wout = np.zeros(n, dtype=np.float64)
    tau2 = tau * tau
    big = np.int64(1) << np.int64(31)
    for r in range(n):
        i = order[r]
        cx = np.int64(math.floor(x[i] / tau))
        cy = np.int64(math.floor(y[i] / tau))
        best_j = -1
        best_d = tau2
        for ddx in range(-1, 2):
            for ddy in range(-1, 2):
                key = (cx + ddx) * big + (cy + ddy)
                slot = (key * np.int64(0x9E3779B1)) & mask
                while used[slot] and keys[slot] != key:
                    slot = (slot + 1) & mask
                if not used[slot]:
                    continue
                j = head[slot]
                while j >= 0:
                    ex = x[j] - x[i]
                    ey = y[j] - y[i]
                    d2 = ex * ex + ey * ey
                    if d2 < best_d or (d2 == best_d and best_j >= 0 and j < best_j):
                        if d2 < tau2:
                            best_d = d2
                            best_j = j
                    j = nxt[j]
        if best_j >= 0:
            owner[i] = best_j
            wout[best_j] += w[i]
            continue
        owner[i] = i
        wout[i] = w[i]
        key = cx * big + cy
        slot = (key * np.int64(0x9E3779B1)) & mask
        while used[slot] and keys[slot] != key:
            slot = (slot + 1) & mask
        if not used[slot]:
            used[slot] = True
            keys[slot] = key
        nxt[i] = head[slot]
        head[slot] = i
    return owner, wout


def _merge_order(w: np.ndarray) -> np.ndarray:
    """Heaviest first; equal weights in index order."""
    return np.argsort(-w, kind="stable").astype(np.int64)


def merge_close(x, y, w, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge particles closer than ``tau`` (Girard et al. 2011 §3.2 step 5).

    Particles are visited heaviest first (ties in index order). A particle with a kept
    particle closer than ``tau`` (strictly) is removed and its weight added to the nearest
    such kept particle (ties: the lower index); otherwise it is kept.

    Returns
    -------
    keep : numpy.ndarray
        int64 indices of the kept particles, ascending.
    weight : numpy.ndarray
        float64 weights of the kept particles with the merged weights added.
    """
    f = np.ascontiguousarray
    x, y, w = f(x, np.float64), f(y, np.float64), f(w, np.float64)
    if x.size == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    owner, wout = _merge_kernel(x, y, w, _merge_order(w), float(tau))
    keep = np.flatnonzero(owner == np.arange(x.size))
    return keep, wout[keep]


def merge_close_reference(x, y, w, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """Plain-numpy O(n^2) version of :func:`merge_close` (its test oracle)."""
    x, y, w = (np.asarray(a, dtype=np.float64) for a in (x, y, w))
    kept: list[int] = []
    wsum: dict[int, float] = {}
    for i in _merge_order(w):
        if kept:
            ks = np.array(kept)
            d2 = (x[ks] - x[i]) ** 2 + (y[ks] - y[i]) ** 2
            near = d2 < tau * tau
            if np.any(near):
                cand = ks[near]
                dc = d2[near]
                j = int(cand[np.lexsort((cand, dc))[0]])
                wsum[j] += w[i]
                continue
        kept.append(int(i))
        wsum[int(i)] = float(w[i])
    keep = np.array(sorted(kept), dtype=np.int64)
    return keep, np.array([wsum[int(k)] for k in keep], dtype=np.float64)
