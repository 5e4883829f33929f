"""Compiled core of the UHL pose solver (Kim & Kim 2013 §II-B), shared by
:func:`rangekit.localize.uhl.solve_pose` and the DUHL filter loop.

Every function is a numba ``njit`` kernel working on float64 arrays; the equations and
the choices where the paper is silent are documented in :func:`~rangekit.localize.uhl.
solve_pose`. Inputs are not validated here (the callers do it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Txs count as collinear when the smaller principal spread of their x-y positions is at
#: most this fraction of the larger one.
COLLINEAR_RTOL = 1e-6
#: Grid of angles on which the zeros of eq (7) are bracketed.
_NGRID = 72
#: ``method`` codes of :func:`uhl_core`.
HYBRID, DIRECT, INDIRECT = 0, 1, 2


@njit(cache=True)
def wrap_angle(a: float) -> float:
    """``a`` wrapped to ``(-pi, pi]``."""
    a = a - 2.0 * math.pi * math.floor(a / (2.0 * math.pi) + 0.5)
    if a <= -math.pi:
        a += 2.0 * math.pi
    elif a > math.pi:
        a -= 2.0 * math.pi
    return a


@njit(cache=True)
def _cost(a: np.ndarray, b: np.ndarray, phi: float) -> float:
    c, s = math.cos(phi), math.sin(phi)
    j = 0.0
    for k in range(a.shape[0]):
        r = a[k, 0] * c + a[k, 1] * s - b[k]
        j += r * r
    return j


@njit(cache=True)
def _f7cs(a1: float, a2: float, a3: float, b1: float, b2: float, c: float, s: float) -> float:
    """Eq (7) from ``c = cos(phi)``, ``s = sin(phi)``."""
    return a3 * (c * c - s * s) + (a2 - a1) * s * c + b2 * c - b1 * s


@njit(cache=True)
def _zero_in(
    a1: float, a2: float, a3: float, b1: float, b2: float, lo: float, hi: float, flo: float
) -> float:
    """The zero of eq (7) in the bracket ``[lo, hi]`` (``f(lo) = flo``, sign change):
    Newton steps, bisection whenever a step leaves the bracket."""
    x = 0.5 * (lo + hi)
    for _ in range(100):
        c, s = math.cos(x), math.sin(x)
        f = _f7cs(a1, a2, a3, b1, b2, c, s)
        if f == 0.0:
            return x
        if (f < 0.0) == (flo < 0.0):
            lo, flo = x, f
        else:
            hi = x
        fp = -2.0 * a3 * 2.0 * s * c + (a2 - a1) * (c * c - s * s) - b2 * s - b1 * c
        nx = x - f / fp if fp != 0.0 else 0.5 * (lo + hi)
        if not lo < nx < hi:
            nx = 0.5 * (lo + hi)
        if abs(nx - x) < 1e-15 or hi - lo < 1e-15:
            return nx
        x = nx
    return x


@njit(cache=True)
def heading(txy: np.ndarray, d2: np.ndarray, r_R: float) -> float:
    """Heading by Kim & Kim 2013 eqs (4)-(9), polished by Newton steps on eq (7)."""
    n = txy.shape[0]
    npair = n * (n - 1) // 2
    s3 = math.sqrt(3.0)
    a = np.empty((2 * npair, 2))
    b = np.empty(2 * npair)
    scale = 1.0 / (2.0 * s3 * r_R)
    k = 0
    for i in range(n):
        ui = 2.0 * d2[i, 0] - d2[i, 1] - d2[i, 2]
        vi = -d2[i, 1] + d2[i, 2]
        for j in range(i + 1, n):
            dx = txy[j, 0] - txy[i, 0]
            dy = txy[j, 1] - txy[i, 1]
            uj = 2.0 * d2[j, 0] - d2[j, 1] - d2[j, 2]
            vj = -d2[j, 1] + d2[j, 2]
            a[2 * k, 0] = s3 * dx
            a[2 * k, 1] = s3 * dy
            a[2 * k + 1, 0] = -dy
            a[2 * k + 1, 1] = dx
            b[2 * k] = (ui - uj) * scale
            b[2 * k + 1] = (vi - vj) * scale
            k += 1
    a1 = 0.0
    a2 = 0.0
    a3 = 0.0
    c0 = 0.0
    c1 = 0.0
    for r in range(2 * npair):
        a1 += a[r, 0] * a[r, 0]
        a2 += a[r, 1] * a[r, 1]
        a3 += a[r, 0] * a[r, 1]
        c0 += a[r, 0] * b[r]
        c1 += a[r, 1] * b[r]
    b1, b2 = -c0, -c1
    # pseudoinverse solution of eq (4): the 2x2 normal equations, lstsq if singular
    det = a1 * a2 - a3 * a3
    if det > 1e-12 * (a1 + a2) ** 2:
        pinv0 = (a2 * c0 - a3 * c1) / det
        pinv1 = (a1 * c1 - a3 * c0) / det
    else:
        pv = np.linalg.lstsq(a, b)[0]
        pinv0, pinv1 = pv[0], pv[1]

    # Candidates: the stationary points of J on the circle, i.e. the zeros of eq (7),
    # f(phi) = a3 cos 2phi + (a2 - a1)/2 sin 2phi + b2 cos phi - b1 sin phi, bracketed
    # on a grid of _NGRID angles and refined by bisection. They are the roots of the
    # quartic eq (8) in sin(phi) with the sign of cos(phi) of eq (9) that satisfies (7).
    cands = np.empty(_NGRID)
    nc = 0
    step = 2.0 * math.pi / _NGRID
    phi0 = -math.pi + 0.3 * step  # off the grid of "round" angles such as 0 and pi
    cd, sd = math.cos(step), math.sin(step)
    cg, sg = math.cos(phi0), math.sin(phi0)
    f_first = _f7cs(a1, a2, a3, b1, b2, cg, sg)
    f_prev = f_first
    for g in range(1, _NGRID + 1):
        cg, sg = cg * cd - sg * sd, sg * cd + cg * sd  # rotate by one grid step
        # the last point is the first one again: the same value closes the circle
        f_g = f_first if g == _NGRID else _f7cs(a1, a2, a3, b1, b2, cg, sg)
        lo = phi0 + (g - 1) * step
        if f_prev == 0.0:
            cands[nc] = lo
            nc += 1
        elif f_prev * f_g < 0.0:
            cands[nc] = _zero_in(a1, a2, a3, b1, b2, lo, lo + step, f_prev)
            nc += 1
        f_prev = f_g

    if nc > 0:
        best = 0
        best_gap = np.inf
        best_cost = np.inf
        for q in range(nc):
            gap = math.hypot(math.cos(cands[q]) - pinv0, math.sin(cands[q]) - pinv1)
            gap = round(gap, 12)
            cst = _cost(a, b, cands[q])
            # closest to the pseudoinverse solution; ties broken by the eq (5) cost
            if gap < best_gap or (gap == best_gap and cst < best_cost):
                best, best_gap, best_cost = q, gap, cst
        phi = cands[best]
    elif pinv0 != 0.0 or pinv1 != 0.0:
        phi = math.atan2(pinv1, pinv0)
    else:
        phi = 0.0

    # Newton on eq (7), f(phi) = dJ/dphi / 2, accepted only while the cost J decreases.
    j0 = _cost(a, b, phi)
    for _ in range(30):
        f = a3 * math.cos(2 * phi) + 0.5 * (a2 - a1) * math.sin(2 * phi)
        f += b2 * math.cos(phi) - b1 * math.sin(phi)
        fp = -2 * a3 * math.sin(2 * phi) + (a2 - a1) * math.cos(2 * phi)
        fp += -b2 * math.sin(phi) - b1 * math.cos(phi)
        if not fp > 0.0:
            break
        step = max(-0.1, min(0.1, -f / fp))
        accepted = False
        j1 = j0
        for _ in range(20):
            j1 = _cost(a, b, phi + step)
            if j1 <= j0:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            break
        phi, j0 = phi + step, j1
        if abs(step) < 1e-15:
            break
    return phi


@njit(cache=True)
def sphere_ls(centres: np.ndarray, rhs_r2: np.ndarray) -> tuple[float, float]:
    """Least-squares ``(x, y)`` from ``|c_k - p|^2 = r2_k`` linearised in
    ``(x, y, x^2 + y^2)``: the spherical interpolation of Kim & Kim 2013 eq (10)."""
    m = centres.shape[0]
    # normal equations of rows [c_x, c_y, -0.5] . [x, y, w] = (|c|^2 - r2) / 2, summed
    # directly (the frame is centred on the Txs, so they are well conditioned)
    gtg = np.zeros((3, 3))
    gth = np.zeros(3)
    for k in range(m):
        r0, r1, r2 = centres[k, 0], centres[k, 1], -0.5
        h = 0.5 * (centres[k, 0] ** 2 + centres[k, 1] ** 2 - rhs_r2[k])
        gtg[0, 0] += r0 * r0
        gtg[0, 1] += r0 * r1
        gtg[0, 2] += r0 * r2
        gtg[1, 1] += r1 * r1
        gtg[1, 2] += r1 * r2
        gtg[2, 2] += r2 * r2
        gth[0] += r0 * h
        gth[1] += r1 * h
        gth[2] += r2 * h
    gtg[1, 0], gtg[2, 0], gtg[2, 1] = gtg[0, 1], gtg[0, 2], gtg[1, 2]
    det = (
        gtg[0, 0] * (gtg[1, 1] * gtg[2, 2] - gtg[1, 2] * gtg[2, 1])
        - gtg[0, 1] * (gtg[1, 0] * gtg[2, 2] - gtg[1, 2] * gtg[2, 0])
        + gtg[0, 2] * (gtg[1, 0] * gtg[2, 1] - gtg[1, 1] * gtg[2, 0])
    )
    tr = gtg[0, 0] + gtg[1, 1] + gtg[2, 2]
    if abs(det) > 1e-12 * tr**3:
        sol = np.linalg.solve(gtg, gth)
    else:  # rank deficient: minimum-norm least squares
        g = np.empty((m, 3))
        hh = np.empty(m)
        for k in range(m):
            g[k, 0], g[k, 1], g[k, 2] = centres[k, 0], centres[k, 1], -0.5
            hh[k] = 0.5 * (centres[k, 0] ** 2 + centres[k, 1] ** 2 - rhs_r2[k])
        sol = np.linalg.lstsq(g, hh)[0]
    return sol[0], sol[1]


@njit(cache=True)
def position_dm(
    txy: np.ndarray, z2: np.ndarray, d2: np.ndarray, phi: float, r_R: float
) -> tuple[float, float]:
    """Position by the direct method, Kim & Kim 2013 eq (10)."""
    n = txy.shape[0]
    c, s = math.cos(phi), math.sin(phi)
    centres = np.empty((3 * n, 2))
    r2 = np.empty(3 * n)
    for ell in range(3):
        ga = 2.0 * math.pi * ell / 3.0
        lx, ly = r_R * math.cos(ga), r_R * math.sin(ga)
        gx, gy = lx * c - ly * s, lx * s + ly * c
        for i in range(n):
            centres[3 * i + ell, 0] = txy[i, 0] - gx
            centres[3 * i + ell, 1] = txy[i, 1] - gy
            r2[3 * i + ell] = d2[i, ell] - z2[i]
    return sphere_ls(centres, r2)


@njit(cache=True)
def ranges_horizontal2(d2: np.ndarray, z2: np.ndarray, r_R: float) -> np.ndarray:
    """Squared horizontal range to the array centre, eq (11): ``rho^2 - z^2``, clipped."""
    n = d2.shape[0]
    out = np.empty(n)
    for i in range(n):
        rho2 = (d2[i, 0] + d2[i, 1] + d2[i, 2]) / 3.0 - r_R * r_R
        out[i] = max(rho2 - z2[i], 0.0)
    return out


@njit(cache=True)
def position_imr_collinear(
    txy: np.ndarray, r2: np.ndarray, u: np.ndarray, nrm: np.ndarray, px: float, py: float
) -> tuple[float, float]:
    """Collinear-Tx IMR: circle intersections, eqs (12)-(13), side chosen by the DM."""
    n = txy.shape[0]
    t = txy @ u
    off = 0.0
    tmax = 0.0
    for i in range(n):
        off += txy[i, 0] * nrm[0] + txy[i, 1] * nrm[1]
        tmax = max(tmax, abs(t[i]))
    off /= n
    sx = np.zeros(2)
    sy = np.zeros(2)
    count = 0
    for i in range(n):
        for j in range(i + 1, n):
            dist = t[j] - t[i]
            if abs(dist) <= 1e-12 * (1.0 + tmax):
                continue  # coincident Txs: no intersection information
            aa = (r2[i] - r2[j] + dist * dist) / (2.0 * dist)
            hh = math.sqrt(max(0.0, r2[i] - aa * aa))  # no intersection: tangent point
            fx = (t[i] + aa) * u[0] + off * nrm[0]
            fy = (t[i] + aa) * u[1] + off * nrm[1]
            sx[0] += fx + hh * nrm[0]  # Delta >= 0 (set I_1)
            sy[0] += fy + hh * nrm[1]
            sx[1] += fx - hh * nrm[0]  # Delta <= 0 (set I_2)
            sy[1] += fy - hh * nrm[1]
            count += 1
    if count == 0:
        return px, py
    x0, y0 = sx[0] / count, sy[0] / count
    x1, y1 = sx[1] / count, sy[1] / count
    if math.hypot(x1 - px, y1 - py) < math.hypot(x0 - px, y0 - py):
        return x1, y1
    return x0, y0


@njit(cache=True)
def uhl_core(
    tx_xyz: np.ndarray, d: np.ndarray, r_R: float, method: int, d_th: float
) -> tuple[float, float, float, bool, float, bool]:
    """One UHL solve: ``(x, y, phi, used_direct, residual_m, ok)``.

    ``ok`` is False (and the pose NaN) when all Txs are at the same x-y point, where the
    heading is unobservable. ``phi`` is wrapped to ``(-pi, pi]``.
    """
    n = tx_xyz.shape[0]
    ox = 0.0
    oy = 0.0
    for i in range(n):
        ox += tx_xyz[i, 0]
        oy += tx_xyz[i, 1]
    ox /= n
    oy /= n
    txy = np.empty((n, 2))
    z2 = np.empty(n)
    d2 = np.empty((n, 3))
    amax = 0.0
    for i in range(n):
        txy[i, 0] = tx_xyz[i, 0] - ox  # frame centred on the Txs (conditioning)
        txy[i, 1] = tx_xyz[i, 1] - oy
        amax = max(amax, abs(tx_xyz[i, 0]), abs(tx_xyz[i, 1]))
        z2[i] = tx_xyz[i, 2] ** 2
        for ell in range(3):
            d2[i, ell] = d[i, ell] * d[i, ell]
    # principal axes of the x-y positions: eigen of the 2x2 scatter matrix
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for i in range(n):
        sxx += txy[i, 0] * txy[i, 0]
        syy += txy[i, 1] * txy[i, 1]
        sxy += txy[i, 0] * txy[i, 1]
    mean_ev = 0.5 * (sxx + syy)
    rad = math.hypot(0.5 * (sxx - syy), sxy)
    sv0 = math.sqrt(max(mean_ev + rad, 0.0))
    sv1 = math.sqrt(max(mean_ev - rad, 0.0))
    if not sv0 > 1e-12 * (1.0 + amax):
        return np.nan, np.nan, np.nan, False, np.nan, False
    collinear = sv1 <= COLLINEAR_RTOL * sv0
    ang = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # direction of the larger spread
    u = np.array([math.cos(ang), math.sin(ang)])
    nrm = np.array([-u[1], u[0]])

    phi = heading(txy, d2, r_R)
    px, py = position_dm(txy, z2, d2, phi, r_R)
    if method == DIRECT:
        use_dm = True
    elif method == INDIRECT:
        use_dm = False
    else:
        mean_n = 0.0
        for i in range(n):
            mean_n += txy[i, 0] * nrm[0] + txy[i, 1] * nrm[1]
        mean_n /= n
        use_dm = collinear and abs(nrm[0] * px + nrm[1] * py - mean_n) < d_th
    if not use_dm:
        r2 = ranges_horizontal2(d2, z2, r_R)
        if collinear:
            px, py = position_imr_collinear(txy, r2, u, nrm, px, py)
        else:
            px, py = sphere_ls(txy, r2)

    phi = wrap_angle(phi)
    c, s = math.cos(phi), math.sin(phi)
    ss = 0.0
    for ell in range(3):
        ga = 2.0 * math.pi * ell / 3.0
        lx, ly = r_R * math.cos(ga), r_R * math.sin(ga)
        rx, ry = px + lx * c - ly * s, py + lx * s + ly * c
        for i in range(n):
            pred = math.sqrt((txy[i, 0] - rx) ** 2 + (txy[i, 1] - ry) ** 2 + z2[i])
            ss += (pred - d[i, ell]) ** 2
    residual = math.sqrt(ss / (3 * n))
    return px + ox, py + oy, phi, use_dm, residual, True
