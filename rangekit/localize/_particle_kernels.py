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
  heading it answers from ray tables (:func:`build_ray_tables`, below) instead of casting;
* :func:`merge_close`: step 5 of Girard §3.2, merging particles closer than tau (greedy,
  heaviest first, over a dense grid of tau cells, or a hash of them for a sparse cloud);
  :func:`merge_close_reference` is its O(n^2) oracle.

Exactness: each ray/segment and move/segment pair is evaluated with the expressions of
:mod:`rangekit._raycast` in the same order, and ties between segments hit at the same
distance go to the lower segment index, as in the brute-force loop; segments are
registered in every cell their bounding box (padded by ``_PAD_M``) touches, and a ray
stops only once its best hit lies inside the cells already visited. So the grid answers
equal the brute-force answers bit for bit (tested). The one exception is degenerate: a ray
or move collinear with a wall to rounding (``d x e`` at rounding level) that starts on the
wall's line beyond its end; the brute force then divides rounding noise and may report a
"hit" on a wall it does not reach, which the grid never looks at (seen for about one move
in a thousand of those, never for the ray model's rays).

Traversal is Amanatides & Woo's 3-D-DDA in 2-D: from the ray's entry into the grid box,
step to the next cell boundary in x or y, whichever comes first.

Ray tables (one heading for all particles, the filters' case). A ray of the model only
counts if its first hit is a wall that eq. (3) accepts, and whether a wall is accepted
depends on the ray's and the wall's directions only. So for each grid cell holding
particles and each of the ``n_sensors x lambda`` ray directions, :func:`build_ray_tables`
lists the accepted walls ("answer walls") that a ray started anywhere in the cell can meet
within its range, and the other walls ("blockers") it can meet before the farthest
answer wall; each entry carries a lower bound of its hit distance from the cell and the
lists are sorted by it. A particle's ray then computes its nearest answer-wall hit ``ta``
(usually none: nothing else to do) and tests the blockers: the ray's reading is ``ta``
unless one of them is hit first. Hits use the expressions above and the same tie rule, so
the readings are the casting answers bit for bit (tested). The particles are sorted by
cell (counting sort) and a cell's particles are run through each of its entries together,
in branch-free loops the compiler vectorises (no fast-math: the same IEEE operations).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "RayTables",
    "SegmentGrid",
    "build_grid",
    "build_ray_tables",
    "cast_rays_grid",
    "crosses_grid",
    "merge_close",
    "merge_close_reference",
    "ray_model_grid",
    "sir_resample",
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


@njit(cache=True, inline="always")
def _crosses_cell(ax, ay, dx, dy, dd, c, seg, cseg, start, items):  # pragma: no cover
    """Whether the move ``a -> a + d`` meets a segment registered in cell ``c``."""
    for q in range(start[c], start[c + 1]):
        ex = cseg[q, 2]
        ey = cseg[q, 3]
        wx = cseg[q, 0] - ax
        wy = cseg[q, 1] - ay
        denom = dx * ey - dy * ex
        if denom != 0.0:
            t = (wx * ey - wy * ex) / denom
            if t >= 0.0 and t <= 1.0:
                u = (wx * dy - wy * dx) / denom
                if u >= 0.0 and u <= 1.0:
                    return True
        elif wx * dy - wy * dx == 0.0:
            k = items[q]
            s0 = (wx * dx + wy * dy) / dd
            s1 = ((seg[k, 2] - ax) * dx + (seg[k, 3] - ay) * dy) / dd
            if min(s0, s1) <= 1.0 and max(s0, s1) >= 0.0:
                return True
    return False


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
    if x0 <= ax <= x0 + nx * h and y0 <= ay <= y0 + ny * h:  # usual: a is in the grid box
        px = ax
        py = ay
    else:
        t_in, t_out = _enter(ax, ay, dx, dy, 1.0, x0, y0, h, nx, ny)
        if t_in > t_out:
            return False
        px = ax + t_in * dx
        py = ay + t_in * dy
    ix = min(max(int(math.floor((px - x0) / h)), 0), nx - 1)
    iy = min(max(int(math.floor((py - y0) / h)), 0), ny - 1)
    # Cell-boundary crossings only steer the traversal (segments are registered with a
    # pad), so reciprocals are fine here, as in _cast_one.
    if dx > 0.0:
        rx = 1.0 / dx
        sx, tx, ddx = 1, (x0 + (ix + 1) * h - ax) * rx, h * rx
    elif dx < 0.0:
        rx = 1.0 / dx
        sx, tx, ddx = -1, (x0 + ix * h - ax) * rx, -h * rx
    else:
        sx, tx, ddx = 0, np.inf, np.inf
    if dy > 0.0:
        ry = 1.0 / dy
        sy, ty, ddy = 1, (y0 + (iy + 1) * h - ay) * ry, h * ry
    elif dy < 0.0:
        ry = 1.0 / dy
        sy, ty, ddy = -1, (y0 + iy * h - ay) * ry, -h * ry
    else:
        sy, ty, ddy = 0, np.inf, np.inf
    while True:
        if _crosses_cell(ax, ay, dx, dy, dd, iy * nx + ix, seg, cseg, start, items):
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


@njit(cache=True, error_model="numpy")
def _crosses_kernel(
    ax, ay, bx, by, seg, cseg, x0, y0, h, nx, ny, start, items
):  # pragma: no cover - compiled
    """Moves within one grid cell (``a``'s cell holds ``b``, so the whole move) are
    sorted by cell and tested against the cell's segments together, in branch-free loops
    the compiler vectorises (the expressions and comparisons of :func:`_crosses_cell`);
    the others, and all of them when they are few for the grid, walk the grid
    (:func:`_crosses_one`)."""
    n = ax.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    if _SPARSE_PER_CELL * n < nx * ny:  # few moves on a large grid: walk each one
        for i in range(n):
            out[i] = _crosses_one(
                ax[i], ay[i], bx[i], by[i], seg, cseg, x0, y0, h, nx, ny, start, items
            )
        return out
    n_c = nx * ny
    cell = np.full(n, -1, dtype=np.int64)
    pos = np.zeros(n_c + 1, dtype=np.int64)
    x1 = x0 + nx * h
    y1 = y0 + ny * h
    for i in range(n):
        dx = bx[i] - ax[i]
        dy = by[i] - ay[i]
        if dx * dx + dy * dy == 0.0:
            continue  # a zero-length move never crosses
        if x0 <= ax[i] <= x1 and y0 <= ay[i] <= y1:
            ix = min(max(int(math.floor((ax[i] - x0) / h)), 0), nx - 1)
            iy = min(max(int(math.floor((ay[i] - y0) / h)), 0), ny - 1)
            fx = (bx[i] - x0) / h
            fy = (by[i] - y0) / h
            if ix <= fx <= ix + 1 and iy <= fy <= iy + 1:  # b in a's (closed) cell
                cell[i] = iy * nx + ix
                pos[cell[i] + 1] += 1
                continue
        out[i] = _crosses_one(
            ax[i], ay[i], bx[i], by[i], seg, cseg, x0, y0, h, nx, ny, start, items
        )
    m_max = 0
    for c in range(n_c):
        m_max = max(m_max, pos[c + 1])
        pos[c + 1] += pos[c]
    idx = np.empty(pos[n_c], dtype=np.int64)
    fill = pos[:-1].copy()
    for i in range(n):
        if cell[i] >= 0:
            idx[fill[cell[i]]] = i
            fill[cell[i]] += 1
    qx = np.empty(m_max)
    qy = np.empty(m_max)
    qdx = np.empty(m_max)
    qdy = np.empty(m_max)
    qdd = np.empty(m_max)
    res = np.empty(m_max, dtype=np.bool_)
    for c in range(n_c):
        m = pos[c + 1] - pos[c]
        if m == 0 or start[c] == start[c + 1]:
            continue
        for p in range(m):
            i = idx[pos[c] + p]
            qx[p] = ax[i]
            qy[p] = ay[i]
            qdx[p] = bx[i] - ax[i]
            qdy[p] = by[i] - ay[i]
            qdd[p] = qdx[p] * qdx[p] + qdy[p] * qdy[p]
            res[p] = False
        for q in range(start[c], start[c + 1]):
            ex = cseg[q, 2]
            ey = cseg[q, 3]
            sx = cseg[q, 0]
            sy = cseg[q, 1]
            k = items[q]
            tx = seg[k, 2]
            ty = seg[k, 3]
            for p in range(m):
                dx = qdx[p]
                dy = qdy[p]
                wx = sx - qx[p]
                wy = sy - qy[p]
                denom = dx * ey - dy * ex
                t = (wx * ey - wy * ex) / denom
                u = (wx * dy - wy * dx) / denom
                proper = (denom != 0.0) & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
                s0 = (wx * dx + wy * dy) / qdd[p]
                s1 = ((tx - qx[p]) * dx + (ty - qy[p]) * dy) / qdd[p]
                on_line = (denom == 0.0) & (wx * dy - wy * dx == 0.0)
                overlap = on_line & (min(s0, s1) <= 1.0) & (max(s0, s1) >= 0.0)
                res[p] = res[p] | proper | overlap
        for p in range(m):
            out[idx[pos[c] + p]] = res[p]
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
        lim = min(rmax_ray[j], best)
        t, k, q = _cast_one(x, y, dxs[j], dys[j], lim, cseg, x0, y0, h, nx, ny, start, items)
        if k < 0 or t < min_range or t >= best:
            continue
        if _accept(dxs[j], dys[j], cseg[q, 2], cseg[q, 3], thr, cthr, sthr):
            best = t
    return best


@njit(cache=True)
def _ray_model_cast(
    px,
    py,
    dxs,
    dys,
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
    """All particles share the ray directions ``dxs, dys`` (n_sensors, lambda); every ray
    is cast (the plain path: small clouds, and the reference of the tables)."""
    n = px.shape[0]
    n_s = dxs.shape[0]
    out = np.full((n, n_s), np.inf)
    for i in range(n):
        for s in range(n_s):
            out[i, s] = _model_one(
                px[i], py[i], dxs[s], dys[s], order, rmax_ray, thr, cthr, sthr,
                min_range, cseg, x0, y0, h, nx, ny, start, items,
            )  # fmt: skip
    return out


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
    for i in range(n):
        for s in range(n_s):
            for j in range(lam):
                a = heading[i] + mounts[s] + psi[j]
                dxs[j] = math.cos(a)
                dys[j] = math.sin(a)
            out[i, s] = _model_one(
                px[i], py[i], dxs, dys, order, rmax_ray, thr, cthr, sthr, min_range, cseg,
                x0, y0, h, nx, ny, start, items,
            )  # fmt: skip
    return out


# ------------------------------------------------------- ray tables (one shared heading)

#: Slack (m) of the lower bounds on hit distances kept in a ray table.
_LB_SLACK_M = 1e-6
#: Below this |sin| of the angle between a ray and a wall, a table entry's lower bound is
#: -inf: the rounding of a near-parallel intersection is not bounded by the slack.
_PARALLEL_SIN = 1e-9
#: The model uses ray tables when the particles average at least this many per occupied
#: grid cell (building one cell's tables costs about as much as casting the rays of two
#: particles), and there are at least ``_TABLE_MIN_PARTICLES``.
_TABLE_PER_CELL = 2.0
_TABLE_MIN_PARTICLES = 64
#: Kernels that sort points by grid cell (work proportional to the number of cells) are
#: skipped for fewer than one point per this many cells.
_SPARSE_PER_CELL = 16


class RayTables(NamedTuple):
    """Per occupied grid cell and ray, the walls that can answer the ray and those that can
    block it, for one heading shared by all particles (:func:`build_ray_tables`).

    Rays are numbered ``(s, jj)``: sensor ``s``, ``jj``-th ray in ``order`` (centre ray
    first). Key ``(slot[c] * n_sensors + s) * lambda + jj`` of cell ``c``;
    ``a_dat[a_start[key]:a_start[key + 1]]`` are the segments that the ray, started
    anywhere in the cell, can meet within its range and would accept under eq. (3) ("answer
    walls"), ``b_dat[...]`` the other segments it can meet before the farthest answer wall
    ("blockers"). Rows of ``a_dat``/``b_dat``: a lower bound of the hit distance from the
    cell, then ``x0, y0, ex, ey`` of the segment (the numbers of ``SegmentGrid.cseg``);
    sorted by the bound within a key. ``a_k``/``b_k``: segment indices.
    """

    cell: np.ndarray  # int64 (n,): each particle's cell, -1: outside the grid
    perm: np.ndarray  # int64 (n,): the particles ordered by cell
    slot: np.ndarray  # int64 (nx * ny,): index among the occupied cells, -1: not occupied
    dxs: np.ndarray  # float64 (n_sensors, lambda): ray directions, in ``order``
    dys: np.ndarray
    rmax: np.ndarray  # float64 (lambda,): ray ranges, in ``order``
    a_start: np.ndarray  # int64 (n_keys + 1,)
    a_dat: np.ndarray  # float64 (n_a, 5)
    a_k: np.ndarray  # int64 (n_a,)
    b_start: np.ndarray
    b_dat: np.ndarray
    b_k: np.ndarray


@njit(cache=True, inline="always")
def _sweep_meets_cell(ax, ay, bx, by, dx, dy, reach, half):  # pragma: no cover - compiled
    """Whether a ray ``o + t d``, ``0 <= t <= reach``, from a point ``o`` of the square of
    half side ``half`` centred on the origin, can meet segment ``a b`` (coordinates relative
    to the square's centre).

    Separating-axis test of the square against the parallelogram ``{p - t d}`` (``p`` on
    the segment) along the normals of ``d`` and of the segment (the caller has done the x
    and y axes by enumerating the cells of the bounding box).
    """
    r = half * (abs(dx) + abs(dy))
    pa = ay * dx - ax * dy
    pb = by * dx - bx * dy
    if min(pa, pb) > r or max(pa, pb) < -r:
        return False
    ex = bx - ax
    ey = by - ay
    r = half * (abs(ex) + abs(ey))
    pa = ay * ex - ax * ey
    de = dy * ex - dx * ey
    lo = pa - reach * max(de, 0.0)
    hi = pa - reach * min(de, 0.0)
    return lo <= r and hi >= -r


@njit(cache=True, inline="always")
def _push(keys, ks, vals, n, key, k, val):  # pragma: no cover - compiled
    """Append ``(key, k, val)`` to growable buffers holding ``n`` entries."""
    if n == keys.shape[0]:
        size = 2 * n + 256
        k2 = np.empty(size, np.int64)
        s2 = np.empty(size, np.int64)
        v2 = np.empty(size)
        k2[:n] = keys[:n]
        s2[:n] = ks[:n]
        v2[:n] = vals[:n]
        keys, ks, vals = k2, s2, v2
    keys[n] = key
    ks[n] = k
    vals[n] = val
    return keys, ks, vals


@njit(cache=True)
def _collect(
    seg,
    sbox,
    acc,
    answer,
    dx,
    dy,
    reach,
    kbase,
    stride,
    slot,
    box,
    obox,
    reach_key,
    x0,
    y0,
    h,
    nx,
    keys,
    ks,
    lbs,
    n,
):  # pragma: no cover - compiled
    """Enter each segment ``k`` with ``acc[k] == answer`` under every occupied cell from
    which a ray of direction ``d`` and length ``<= reach`` can meet it (key
    ``slot * stride + kbase``); ``box``: the cell-index range ``ix0, ix1, iy0, iy1`` of
    the occupied cells, ``obox`` its extent in m.

    ``answer``: raise ``reach_key[key]`` to an upper bound of the hit distance from the
    cell; otherwise (blockers) skip keys whose ``reach_key`` is below the lower bound.
    """
    half = 0.5 * h + _PAD_M
    # largest o . d over the padded square, relative to its centre
    o_ext = half * (abs(dx) + abs(dy))
    pad = 2.0 * _PAD_M
    for k in range(seg.shape[0]):
        if acc[k] != answer or not _may_reach(sbox, k, dx, dy, reach, obox):
            continue
        ax = seg[k, 0]
        ay = seg[k, 1]
        bx = seg[k, 2]
        by = seg[k, 3]
        ex = bx - ax
        ey = by - ay
        xlo = min(min(ax, bx), min(ax, bx) - reach * dx) - pad
        xhi = max(max(ax, bx), max(ax, bx) - reach * dx) + pad
        ylo = min(min(ay, by), min(ay, by) - reach * dy) - pad
        yhi = max(max(ay, by), max(ay, by) - reach * dy) + pad
        i0 = max(int(math.floor((xlo - x0) / h)), box[0])
        i1 = min(int(math.floor((xhi - x0) / h)), box[1])
        j0 = max(int(math.floor((ylo - y0) / h)), box[2])
        j1 = min(int(math.floor((yhi - y0) / h)), box[3])
        parallel = abs(dx * ey - dy * ex) <= _PARALLEL_SIN * math.hypot(ex, ey)
        for iy in range(j0, j1 + 1):
            for ix in range(i0, i1 + 1):
                sl = slot[iy * nx + ix]
                if sl < 0:
                    continue
                key = sl * stride + kbase
                cx = x0 + (ix + 0.5) * h
                cy = y0 + (iy + 0.5) * h
                pa = (ax - cx) * dx + (ay - cy) * dy
                pb = (bx - cx) * dx + (by - cy) * dy
                lb = -np.inf if parallel else min(pa, pb) - o_ext - _LB_SLACK_M
                if not answer and (reach_key[key] == -np.inf or lb > min(reach_key[key], reach)):
                    continue
                if not _sweep_meets_cell(ax - cx, ay - cy, bx - cx, by - cy, dx, dy, reach, half):
                    continue
                if answer:
                    reach_key[key] = max(reach_key[key], max(pa, pb) + o_ext + _LB_SLACK_M)
                keys, ks, lbs = _push(keys, ks, lbs, n, key, k, lb)
                n += 1
    return keys, ks, lbs, n


@njit(cache=True)
def _pack(keys, ks, lbs, n, n_keys, seg):  # pragma: no cover - compiled
    """CSR by key, entries sorted by their lower bound; rows ``lb, x0, y0, ex, ey``."""
    start = np.zeros(n_keys + 1, np.int64)
    for q in range(n):
        start[keys[q] + 1] += 1
    for key in range(n_keys):
        start[key + 1] += start[key]
    fill = start[:-1].copy()
    dat = np.empty((n, 5))
    kk = np.empty(n, np.int64)
    for q in range(n):
        p = fill[keys[q]]
        fill[keys[q]] += 1
        # insertion into the key's sorted run (runs are short)
        while p > start[keys[q]] and dat[p - 1, 0] > lbs[q]:
            dat[p] = dat[p - 1]
            kk[p] = kk[p - 1]
            p -= 1
        k = ks[q]
        dat[p, 0] = lbs[q]
        dat[p, 1] = seg[k, 0]
        dat[p, 2] = seg[k, 1]
        dat[p, 3] = seg[k, 2] - seg[k, 0]
        dat[p, 4] = seg[k, 3] - seg[k, 1]
        kk[p] = k
    return start, dat, kk


@njit(cache=True, inline="always")
def _may_reach(sbox, k, dx, dy, reach, obox):  # pragma: no cover - compiled
    """Whether the bounding box of segment ``k`` swept back by ``reach d`` meets ``obox``."""
    xlo = sbox[k, 0] - reach * max(dx, 0.0)
    xhi = sbox[k, 1] - reach * min(dx, 0.0)
    ylo = sbox[k, 2] - reach * max(dy, 0.0)
    yhi = sbox[k, 3] - reach * min(dy, 0.0)
    return xhi >= obox[0] and xlo <= obox[1] and yhi >= obox[2] and ylo <= obox[3]


@njit(cache=True)
def _ray_tables_kernel(
    dxs, dys, rmax, thr, cthr, sthr, seg, x0, y0, h, nx, ny, slot, n_occ
):  # pragma: no cover - compiled
    n_s, lam = dxs.shape
    m = seg.shape[0]
    n_keys = n_occ * n_s * lam
    stride = n_s * lam
    reach_key = np.full(n_keys, -np.inf)
    box = np.array([nx, -1, ny, -1])
    for c in range(nx * ny):
        if slot[c] >= 0:
            box[0] = min(box[0], c % nx)
            box[1] = max(box[1], c % nx)
            box[2] = min(box[2], c // nx)
            box[3] = max(box[3], c // nx)
    pad = 4.0 * _PAD_M
    obox = np.array(
        [x0 + box[0] * h - pad, x0 + (box[1] + 1) * h + pad,
         y0 + box[2] * h - pad, y0 + (box[3] + 1) * h + pad]
    )  # fmt: skip
    sbox = np.empty((m, 4))
    for k in range(m):
        sbox[k, 0] = min(seg[k, 0], seg[k, 2])
        sbox[k, 1] = max(seg[k, 0], seg[k, 2])
        sbox[k, 2] = min(seg[k, 1], seg[k, 3])
        sbox[k, 3] = max(seg[k, 1], seg[k, 3])
    acc = np.zeros((n_s, lam, m), dtype=np.bool_)
    for s in range(n_s):
        for jj in range(lam):
            for k in range(m):
                ex = seg[k, 2] - seg[k, 0]
                ey = seg[k, 3] - seg[k, 1]
                acc[s, jj, k] = _accept(dxs[s, jj], dys[s, jj], ex, ey, thr, cthr, sthr)
    keys = np.empty(1024, np.int64)
    ks = np.empty(1024, np.int64)
    lbs = np.empty(1024)
    n = 0  # answer walls, which also set reach_key
    for s in range(n_s):
        for jj in range(lam):
            if np.any(acc[s, jj]):
                keys, ks, lbs, n = _collect(
                    seg, sbox, acc[s, jj], True, dxs[s, jj], dys[s, jj], rmax[jj], s * lam + jj,
                    stride, slot, box, obox, reach_key, x0, y0, h, nx, keys, ks, lbs, n,
                )  # fmt: skip
    a_start, a_dat, a_k = _pack(keys, ks, lbs, n, n_keys, seg)
    n = 0  # blockers
    for s in range(n_s):
        for jj in range(lam):
            if np.any(acc[s, jj]):
                keys, ks, lbs, n = _collect(
                    seg, sbox, acc[s, jj], False, dxs[s, jj], dys[s, jj], rmax[jj], s * lam + jj,
                    stride, slot, box, obox, reach_key, x0, y0, h, nx, keys, ks, lbs, n,
                )  # fmt: skip
    b_start, b_dat, b_k = _pack(keys, ks, lbs, n, n_keys, seg)
    return a_start, a_dat, a_k, b_start, b_dat, b_k


@njit(cache=True)
def _cells_of(px, py, x0, y0, h, nx, ny):  # pragma: no cover - compiled
    """Cell of each point (-1: outside the grid), the slot of each occupied cell among the
    occupied ones (-1: empty), their number, and the points ordered by cell."""
    n = px.shape[0]
    n_c = nx * ny
    inv_h = 1.0 / h
    cell = np.empty(n, np.int64)
    pos = np.zeros(n_c + 2, np.int64)  # bucket c + 1: cell c, bucket 0: outside
    for i in range(n):
        fx = (px[i] - x0) * inv_h
        fy = (py[i] - y0) * inv_h
        c = -1
        if 0.0 <= fx < nx and 0.0 <= fy < ny:
            c = int(fy) * nx + int(fx)
        cell[i] = c
        pos[c + 2] += 1
    slot = np.full(n_c, -1, np.int64)
    n_occ = 0
    for c in range(n_c):
        if pos[c + 2] > 0:
            slot[c] = n_occ
            n_occ += 1
    for b in range(n_c + 1):
        pos[b + 1] += pos[b]
    perm = np.empty(n, np.int64)
    for i in range(n):
        b = cell[i] + 1
        perm[pos[b]] = i
        pos[b] += 1
    return cell, slot, n_occ, perm


def build_ray_tables(
    px, py, heading, mounts, psi, rmax_ray, thr, grid: SegmentGrid, *, cells=None
) -> RayTables:
    """Ray tables of the cells occupied by the particles, for one shared heading.

    Parameters are those of :func:`ray_model_grid` (``heading`` a float). A ray of
    direction ``d`` (``heading + mount + psi_j``) and range ``rmax_j`` started in cell
    ``c`` can only meet the segments whose parallelogram ``{p - t d: p on the segment,
    0 <= t <= rmax_j}`` meets the (padded) cell; among them, the answer walls are those
    eq. (3) accepts for ``d`` (the test of :func:`_accept`, which depends on the
    directions only), and a blocker matters only if it can be met before the farthest
    answer wall. Cost: one pass over the segments per ray direction, over the cells of
    each one's parallelogram. ``cells``: the particles' ``_cells_of`` if known.
    """
    f = np.ascontiguousarray
    px, py = f(px, np.float64), f(py, np.float64)
    mounts, psi = f(mounts, np.float64).reshape(-1), f(psi, np.float64).reshape(-1)
    rmax_ray = f(rmax_ray, np.float64).reshape(-1)
    order = np.argsort(np.abs(psi), kind="stable")
    ang = (float(heading) + mounts)[:, None] + psi[None, order]
    dxs, dys = f(np.cos(ang)), f(np.sin(ang))
    rmax = f(rmax_ray[order])
    if cells is None:
        cells = _cells_of(px, py, grid.x0, grid.y0, grid.cell_m, grid.nx, grid.ny)
    cell, slot, n_occ, perm = cells
    thr = float(thr)
    parts = _ray_tables_kernel(
        dxs, dys, rmax, thr, math.cos(thr), math.sin(thr), grid.seg, grid.x0, grid.y0,
        grid.cell_m, grid.nx, grid.ny, slot, n_occ,
    )  # fmt: skip
    return RayTables(cell, perm, slot, dxs, dys, rmax, *parts)


#: "No hit yet" for the segment index of a ray's nearest answer wall.
_NO_WALL = np.int64(1) << np.int64(62)


@njit(cache=True, error_model="numpy")
def _ray_model_tables(
    px, py, cell, perm, slot, dxs, dys, rmax, a_start, a_dat, a_k, b_start, b_dat, b_k, min_range
):  # pragma: no cover - compiled
    """The ray model from the tables (particles outside the grid: inf, see the caller).

    The particles of one cell are taken together: each table entry is tested against all
    of them in a branch-free loop that the compiler vectorises (the same expressions and
    comparisons as :func:`_cast_one`, so the same numbers). Per sensor and ray (centre
    first), each particle's nearest answer-wall hit ``(ta, a)`` within ``min(rmax, best)``
    (ties: lower index) is its reading unless a blocker is hit before it (or at ``ta``
    with a lower index); the reading replaces ``best`` if ``min_range <= ta < best``.
    Entries whose lower bound exceeds every particle's limit are skipped.
    """
    n = px.shape[0]
    n_s, lam = dxs.shape
    out = np.full((n, n_s), np.inf)
    m_max = 1
    r0 = 0
    while r0 < n:  # longest run of one cell in perm
        r1 = r0 + 1
        while r1 < n and cell[perm[r1]] == cell[perm[r0]]:
            r1 += 1
        m_max = max(m_max, r1 - r0)
        r0 = r1
    qx = np.empty(m_max)
    qy = np.empty(m_max)
    best = np.empty(m_max)
    ta = np.empty(m_max)
    aw = np.empty(m_max, dtype=np.int64)
    ok = np.empty(m_max, dtype=np.bool_)
    r0 = 0
    while r0 < n:
        c = cell[perm[r0]]
        r1 = r0 + 1
        while r1 < n and cell[perm[r1]] == c:
            r1 += 1
        m = r1 - r0
        if c < 0:
            r0 = r1
            continue
        for p in range(m):
            qx[p] = px[perm[r0 + p]]
            qy[p] = py[perm[r0 + p]]
        for s in range(n_s):
            best[:m] = np.inf
            kb = (slot[c] * n_s + s) * lam
            for jj in range(lam):
                key = kb + jj
                if a_start[key] == a_start[key + 1]:
                    continue
                dx = dxs[s, jj]
                dy = dys[s, jj]
                cut = -np.inf
                for p in range(m):
                    ta[p] = min(rmax[jj], best[p])
                    aw[p] = _NO_WALL
                    cut = max(cut, ta[p])
                for q in range(a_start[key], a_start[key + 1]):
                    if a_dat[q, 0] > cut:
                        break
                    ex = a_dat[q, 3]
                    ey = a_dat[q, 4]
                    denom = dx * ey - dy * ex
                    if denom == 0.0:
                        continue
                    sx = a_dat[q, 1]
                    sy = a_dat[q, 2]
                    k = a_k[q]
                    for p in range(m):
                        wx = sx - qx[p]
                        wy = sy - qy[p]
                        t = (wx * ey - wy * ex) / denom
                        u = (wx * dy - wy * dx) / denom
                        tp = ta[p]
                        hit = (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
                        take = hit & ((t < tp) | ((t == tp) & (k < aw[p])))
                        ta[p] = t if take else tp
                        aw[p] = k if take else aw[p]
                cut = -np.inf
                for p in range(m):
                    ok[p] = (aw[p] != _NO_WALL) & (ta[p] >= min_range) & (ta[p] < best[p])
                    cut = max(cut, ta[p] if ok[p] else -np.inf)
                for q in range(b_start[key], b_start[key + 1]):
                    if b_dat[q, 0] > cut:
                        break
                    ex = b_dat[q, 3]
                    ey = b_dat[q, 4]
                    denom = dx * ey - dy * ex
                    if denom == 0.0:
                        continue
                    sx = b_dat[q, 1]
                    sy = b_dat[q, 2]
                    k = b_k[q]
                    for p in range(m):
                        wx = sx - qx[p]
                        wy = sy - qy[p]
                        t = (wx * ey - wy * ex) / denom
                        u = (wx * dy - wy * dx) / denom
                        tp = ta[p]
                        hit = (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
                        ok[p] = ok[p] & ~(hit & ((t < tp) | ((t == tp) & (k < aw[p]))))
                for p in range(m):
                    best[p] = ta[p] if ok[p] else best[p]
            for p in range(m):
                out[perm[r0 + p], s] = best[p]
        r0 = r1
    return out


def ray_model_grid(
    px, py, heading, mounts, psi, rmax_ray, thr, min_range, grid: SegmentGrid, *, tables=None
):
    """Girard 2011 §3.2 ray-model distance for each particle and sensor (inf: none).

    Parameters
    ----------
    px, py : numpy.ndarray
        float64 ``(n,)`` particle positions, m.
    heading : float or numpy.ndarray
        Walking direction, rad: one for all particles (the fast path: ray tables) or one
        per particle ``(n,)`` (every ray cast).
    mounts : numpy.ndarray
        float64 ``(n_sensors,)`` sensor axes relative to the heading, rad.
    psi, rmax_ray : numpy.ndarray
        float64 ``(lambda,)`` off-axis angles of the rays and their maximum ranges.
    thr : float
        Smallest accepted incidence angle, ``pi/2 - alpha / (2 lambda)`` (eq. (3)).
    min_range : float
        Hits nearer than this are dropped (ring-down).
    tables : bool or None
        With a shared heading: answer from :func:`build_ray_tables` (True) or cast every
        ray through the grid (False); None (default): tables when the particles are
        dense enough (``_TABLE_PER_CELL`` per occupied cell, one per ``_SPARSE_PER_CELL``
        grid cells). Same numbers either way.

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
    min_range = float(min_range)
    args = (order, rmax_ray, thr, math.cos(thr), math.sin(thr), min_range, grid.cseg)
    geo = (grid.x0, grid.y0, grid.cell_m, grid.nx, grid.ny, grid.start, grid.items)
    if np.ndim(heading) != 0:
        return _ray_model_each(px, py, f(heading, np.float64), mounts, psi, *args, *geo)
    ang = (float(heading) + mounts)[:, None] + psi[None, :]
    dxs, dys = f(np.cos(ang)), f(np.sin(ang))
    cells = None
    if tables is None:
        n_cells = grid.nx * grid.ny
        tables = px.size >= _TABLE_MIN_PARTICLES and _SPARSE_PER_CELL * px.size >= n_cells
        if tables:
            cells = _cells_of(px, py, grid.x0, grid.y0, grid.cell_m, grid.nx, grid.ny)
            tables = px.size >= _TABLE_PER_CELL * cells[2]
    if not tables:
        return _ray_model_cast(px, py, dxs, dys, *args, *geo)
    tb = build_ray_tables(px, py, heading, mounts, psi, rmax_ray, thr, grid, cells=cells)
    out = _ray_model_tables(px, py, *tb, min_range)
    outside = np.flatnonzero(tb.cell < 0)
    if outside.size:  # particles outside the grid cast every ray
        out[outside] = _ray_model_cast(px[outside], py[outside], dxs, dys, *args, *geo)
    return out


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


#: The merge uses a dense grid of tau cells (not a hash) up to this many cells per particle.
_MERGE_DENSE_PER_POINT = 4


@njit(cache=True)
def _merge_dense(x, y, w, order, tau, max_cells):  # pragma: no cover - compiled
    """:func:`_merge_kernel` on a dense grid of tau cells over the points' extent (the
    same cells, ``floor(x / tau)``, so the same answer); ``ok`` False, and nothing done,
    when that grid would exceed ``max_cells``."""
    n = x.shape[0]
    cxs = np.empty(n, dtype=np.int64)
    cys = np.empty(n, dtype=np.int64)
    lo_x = hi_x = np.int64(math.floor(x[0] / tau))
    lo_y = hi_y = np.int64(math.floor(y[0] / tau))
    for i in range(n):
        cx = np.int64(math.floor(x[i] / tau))
        cy = np.int64(math.floor(y[i] / tau))
        cxs[i] = cx
        cys[i] = cy
        lo_x = min(lo_x, cx)
        hi_x = max(hi_x, cx)
        lo_y = min(lo_y, cy)
        hi_y = max(hi_y, cy)
    nbx = hi_x - lo_x + 1
    nby = hi_y - lo_y + 1
    owner = np.full(n, -1, dtype=np.int64)
    wout = np.zeros(n, dtype=np.float64)
    if nbx > max_cells or nby > max_cells or nbx * nby > max_cells:
        return owner, wout, False
    head = np.full(nbx * nby, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    tau2 = tau * tau
    for r in range(n):
        i = order[r]
        cx = cxs[i] - lo_x
        cy = cys[i] - lo_y
        best_j = -1
        best_d = tau2
        for yy in range(max(cy - 1, 0), min(cy + 2, nby)):
            for xx in range(max(cx - 1, 0), min(cx + 2, nbx)):
                j = head[yy * nbx + xx]
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
        c = cy * nbx + cx
        nxt[i] = head[c]
        head[c] = i
    return owner, wout, True


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
    if not tau > 0.0:  # nothing is closer than 0
        return np.arange(x.size, dtype=np.int64), w.copy()
    order = _merge_order(w)
    max_cells = _MERGE_DENSE_PER_POINT * x.size + 4096
    owner, wout, ok = _merge_dense(x, y, w, order, float(tau), max_cells)
    if not ok:  # a sparse cloud: hash the occupied cells
        owner, wout = _merge_kernel(x, y, w, order, float(tau))
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


# ------------------------------------------------------------------ SIR resampling


@njit(cache=True)
def _blocked(
    ax, ay, bx, by, use_plan, bx0, by0, bx1, by1, seg, cseg, x0, y0, h, nx, ny, start, items
):  # pragma: no cover - compiled
    """Moves ``a -> b`` that end outside the box ``[bx0, bx1] x [by0, by1]`` or cross a
    wall (none without a plan)."""
    n = ax.shape[0]
    if not use_plan:
        return np.zeros(n, dtype=np.bool_)
    out = _crosses_kernel(ax, ay, bx, by, seg, cseg, x0, y0, h, nx, ny, start, items)
    for i in range(n):
        out[i] = out[i] or not (bx0 <= bx[i] <= bx1 and by0 <= by[i] <= by1)
    return out


def _plan_args(bounds: tuple[float, float, float, float] | None, grid: SegmentGrid) -> tuple:
    """The trailing arguments of :func:`_blocked` (``bounds`` None: no plan)."""
    b = (0.0, 0.0, 0.0, 0.0) if bounds is None else tuple(float(v) for v in bounds)
    return (bounds is not None, *b, grid.seg, grid.cseg, grid.x0, grid.y0, grid.cell_m,
            grid.nx, grid.ny, grid.start, grid.items)  # fmt: skip


@njit(cache=True)
def _sir_resample_kernel(x, y, w, u0, n_out, z, rough, nscale, *plan):  # pragma: no cover
    """Systematic resampling of ``n_out`` from ``(x, y, w)`` with offset ``u0``, then
    roughening by ``rough * extent * nscale * z`` with moves that leave the box or cross
    a wall undone (``z`` empty: no roughening); ``plan``: see :func:`_plan_args`."""
    n_w = w.shape[0]
    c = np.empty(n_w)
    acc = 0.0
    for i in range(n_w):
        acc += w[i]
        c[i] = acc
    ox = np.empty(n_out)
    oy = np.empty(n_out)
    j = 0
    for i in range(n_out):
        u = (u0 + i) / n_out
        while j < n_w and c[j] <= u:  # searchsorted(c, u, side="right")
            j += 1
        k = min(j, n_w - 1)
        ox[i] = x[k]
        oy[i] = y[k]
    if z.shape[0] == 0:
        return ox, oy
    lo_x, hi_x, lo_y, hi_y = ox[0], ox[0], oy[0], oy[0]
    for i in range(n_out):
        lo_x = min(lo_x, ox[i])
        hi_x = max(hi_x, ox[i])
        lo_y = min(lo_y, oy[i])
        hi_y = max(hi_y, oy[i])
    sx = rough * (hi_x - lo_x) * nscale  # the reference's operation order
    sy = rough * (hi_y - lo_y) * nscale
    mx = np.empty(n_out)
    my = np.empty(n_out)
    for i in range(n_out):
        mx[i] = ox[i] + sx * z[i, 0]
        my[i] = oy[i] + sy * z[i, 1]
    bad = _blocked(ox, oy, mx, my, *plan)
    for i in range(n_out):
        if bad[i]:
            mx[i] = ox[i]
            my[i] = oy[i]
    return mx, my


def sir_resample(
    xy: np.ndarray,
    w: np.ndarray,
    n_out: int,
    rng: np.random.Generator,
    *,
    roughening: float,
    bounds: tuple[float, float, float, float] | None,
    grid: SegmentGrid,
) -> np.ndarray:
    """Systematic resampling and roughening of a weighted cloud, compiled (SIR).

    Draws from ``rng`` exactly what the numpy reference
    (``rangekit.localize.particle._sir_resample_reference``) draws, in the same order (one
    uniform offset, then ``(n_out, 2)`` standard normals when roughening), and computes
    the same IEEE operations, so the result is the same array bit for bit.

    Parameters
    ----------
    xy : numpy.ndarray
        float64 ``(n, 2)`` positions.
    w : numpy.ndarray
        float64 ``(n,)`` weights summing to 1.
    n_out : int
        Particles drawn.
    rng : numpy.random.Generator
    roughening : float
        K of the jitter ``K E n_out^(-1/2) N(0, 1)`` per axis, E the resampled cloud's
        extent along the axis; 0: none.
    bounds : (x0, y0, x1, y1) or None
        With a floor plan: a jitter that ends outside this box or crosses a wall of
        ``grid`` is undone. None: no plan.
    grid : SegmentGrid

    Returns
    -------
    numpy.ndarray
        float64 ``(n_out, 2)``.

    Notes
    -----
    Systematic resampling (Kitagawa 1996): particle ``k`` is drawn for each
    ``u_i = (u0 + i) / n_out`` with ``C_(k-1) <= u_i < C_k``, ``C`` the cumulative
    weights, in one merge pass (``u`` is sorted) instead of a binary search per draw.
    """
    u0 = float(rng.random())
    rough = roughening > 0.0 and n_out > 1
    z = rng.standard_normal((n_out, 2)) if rough else np.zeros((0, 2))
    f = np.ascontiguousarray
    mx, my = _sir_resample_kernel(
        f(xy[:, 0]), f(xy[:, 1]), f(w, np.float64), u0, int(n_out), z, float(roughening),
        n_out ** (-0.5), *_plan_args(bounds, grid),
    )  # fmt: skip
    return np.column_stack([mx, my])


# --------------------------------------------------------------------- SIR step


@njit(cache=True)
def _sir_move_kernel(x, y, w, length, cos_h, sin_h, *plan):  # pragma: no cover - compiled
    """Each particle moved by its own step; the weight of a move that leaves the box or
    crosses a wall set to 0; whether any move ended inside the box (``plan``: see
    :func:`_plan_args`)."""
    n = x.shape[0]
    mx = np.empty(n)
    my = np.empty(n)
    wo = w.copy()
    for i in range(n):
        mx[i] = x[i] + length[i] * cos_h[i]
        my[i] = y[i] + length[i] * sin_h[i]
    if plan[0]:
        bx0, by0, bx1, by1 = plan[1], plan[2], plan[3], plan[4]
        any_inside = False
        for i in range(n):
            if bx0 <= mx[i] <= bx1 and by0 <= my[i] <= by1:
                any_inside = True
                break
        if not any_inside:  # the reference stops here too
            return mx, my, wo, False
    bad = _blocked(x, y, mx, my, *plan)
    for i in range(n):
        if bad[i]:
            wo[i] = 0.0
    return mx, my, wo, True


def sir_move(xy, w, length, heading, *, bounds, grid: SegmentGrid):
    """SIR propagation: ``xy + length (cos heading, sin heading)`` per particle, weights of
    moves that leave ``bounds`` or cross a wall of ``grid`` set to 0 (``bounds`` None: no
    plan). Returns ``(new_xy, w, any_inside)``, bit for bit the numpy reference's
    (``rangekit.localize.particle._sir_step_reference``; cos and sin are numpy's)."""
    f = np.ascontiguousarray
    mx, my, wo, any_inside = _sir_move_kernel(
        f(xy[:, 0]), f(xy[:, 1]), f(w, np.float64), f(length, np.float64), np.cos(heading),
        np.sin(heading), *_plan_args(bounds, grid),
    )  # fmt: skip
    return np.column_stack([mx, my]), wo, bool(any_inside)


@njit(cache=True)
def _mixture_exponents(delta, meas, bias, sig):  # pragma: no cover - compiled
    """``-0.5 r^2`` with ``r = (z - d - bias) / sig`` where the model sees a wall, else 0."""
    n, m = delta.shape
    out = np.zeros((n, m))
    for j in range(m):
        z = meas[j]
        if math.isnan(z):
            continue
        for i in range(n):
            d = delta[i, j]
            if math.isfinite(d):
                r = (z - d - bias) / sig
                out[i, j] = -0.5 * r * r
    return out


@njit(cache=True)
def _mixture_product(delta, meas, g, sig, p_outlier, p_miss, dmax):  # pragma: no cover
    """Product over readings of the SRF02 mixture likelihood, ``g = exp(exponents)``."""
    n, m = delta.shape
    like = np.ones(n)
    norm = sig * math.sqrt(2.0 * math.pi)
    floor = p_outlier / dmax
    for j in range(m):
        z = meas[j]
        for i in range(n):
            seen = math.isfinite(delta[i, j])
            if math.isnan(z):
                lj = p_miss if seen else 1.0 - p_miss
            else:
                lj = ((1.0 - p_outlier) * (g[i, j] / norm) if seen else 0.0) + floor
            like[i] *= lj
    return like


def sir_likelihood(delta, meas, *, bias, sig, p_outlier, p_miss, dmax) -> np.ndarray:
    """The SIR likelihood of ``rangekit.localize.particle`` over model distances
    ``delta`` (n, m; inf: no wall) and readings ``meas`` (m,; NaN: no echo), bit for bit
    the numpy reference (the exponential is numpy's)."""
    f = np.ascontiguousarray
    delta, meas = f(delta, np.float64), f(meas, np.float64)
    g = np.exp(_mixture_exponents(delta, meas, float(bias), float(sig)))
    return _mixture_product(delta, meas, g, float(sig), float(p_outlier), float(p_miss),
                            float(dmax))  # fmt: skip
