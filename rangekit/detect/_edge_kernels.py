"""Compiled hot loops of the beep detector's edge fit (:mod:`rangekit.detect.refine`).

The edge fit times a few hundred bursts per minute of audio, each on a few hundred
samples; in numpy each step is a handful of small-array calls whose overhead (not their
arithmetic) dominates. The kernels here do the same arithmetic in one compiled loop per
step:

* :func:`_edge_stat_py` (stage 1): the edge's F statistic at every integer onset. On the
  integer grid the basis is the same for every window, so its orthonormal bases (full
  model and nuisance-only model, from one QR, cached per beep, rate and model by
  :func:`rangekit.detect.refine._integer_basis`) are computed once and each window is
  projected on them directly.
* :func:`_masked_stat_py` (stage 1, clipped stretches): per window the normal equations
  over the unmasked samples, solved by an explicit Cholesky factorisation.
* :func:`_refine_py` (stage 2): the residual at a continuous onset with the raised-cosine
  envelope evaluated inline and the 2x2 ... 6x6 normal equations solved by Cholesky, over
  the coarse and the fine grid, the parabola, and the Fisher information of the onset.

Each is the numpy code of :mod:`rangekit.detect.refine` (the reference, used for short
inputs and tested against these kernels, ``tests/detect/test_edge_kernels.py``) written as
loops; they agree to rounding (the order of the sums and LU against Cholesky differ).
:func:`_anchors_py` is :func:`rangekit.detect.changepoint._anchor` over all change points
at once (the same arithmetic in the same order, so the same numbers); :func:`_fir_py` is
:func:`rangekit.detect.condition.bandlimit` of the stretch one fit reads (to rounding).

Import cost: numba is imported on first use only. Like :func:`rangekit.detect._kernels
.band_energy`, the detector uses these kernels only for recordings of at least
:data:`NUMBA_MIN_SAMPLES` samples, where ``band_energy`` has imported numba already; a
short file (``rangekit range`` on one exchange) stays on the numpy path and pays neither
the numba import (~0.35 s) nor the cache loads.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from rangekit.detect._kernels import NUMBA_MIN_SAMPLES as _BAND_MIN

__all__: list[str] = []

#: Recordings with fewer samples than this use the numpy reference of the edge fit (the
#: same threshold as ``band_energy``: above it numba is imported anyway).
NUMBA_MIN_SAMPLES = _BAND_MIN


def _env(t: float, taper_s: float, burst_s: float) -> float:
    """:func:`rangekit.signals.beep.burst_envelope` at one time ``t`` (s)."""
    env = 1.0 if (t >= 0.0 and t <= burst_s) else 0.0
    if taper_s > 0.0:
        if t >= 0.0 and t < taper_s:
            env = 0.5 - 0.5 * math.cos(math.pi * t / taper_s)
        if t > burst_s - taper_s and t <= burst_s:
            env = 0.5 - 0.5 * math.cos(math.pi * (burst_s - t) / taper_s)
    return env


def _cholesky(g: np.ndarray, p: int, lo: np.ndarray) -> bool:
    """Lower Cholesky factor of ``g[:p, :p]`` into ``lo``; False if not positive definite."""
    for i in range(p):
        for j in range(i + 1):
            s = g[i, j]
            for k in range(j):
                s -= lo[i, k] * lo[j, k]
            if i == j:
                if not s > 0.0:
                    return False
                lo[i, i] = math.sqrt(s)
            else:
                lo[i, j] = s / lo[j, j]
    return True


def _chol_solve(lo: np.ndarray, p: int, rhs: np.ndarray, out: np.ndarray) -> None:
    """Solve ``L L^T out = rhs`` for the factor ``lo`` of :func:`_cholesky`."""
    for i in range(p):
        s = rhs[i]
        for k in range(i):
            s -= lo[i, k] * out[k]
        out[i] = s / lo[i, i]
    for i in range(p - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, p):
            s -= lo[k, i] * out[k]
        out[i] = s / lo[i, i]


def _edge_stat_py(seg: np.ndarray, qt: np.ndarray, n_base: int, n_par: int) -> np.ndarray:
    """Stage-1 F statistic per window (``refine.edge_statistic``, unmasked branch).

    ``seg`` holds ``n_out + L - 1`` samples; ``qt`` (p + n_base, L) stacks, one row per
    basis vector, the orthonormal bases of the full model (first ``p = n_par`` rows) and
    of the nuisance-only model (the last ``n_base`` rows, none without nuisance terms).
    """
    n_q, length = qt.shape
    n_out = seg.shape[0] - length + 1
    out = np.empty(max(n_out, 0), dtype=np.float64)
    for i in range(n_out):
        total = 0.0
        for ll in range(length):
            total += seg[i + ll] * seg[i + ll]
        full = 0.0
        base = 0.0
        for j in range(n_q):
            acc = 0.0
            for ll in range(length):
                acc += seg[i + ll] * qt[j, ll]
            if j < n_par:
                full += acc * acc
            else:
                base += acc * acc
        resid = max(total - full, 1e-12 * total + 1e-300) / (length - n_par)
        out[i] = max(full - base, 0.0) / 2.0 / resid
    return out


def _reg_solve(
    gram: np.ndarray, g: np.ndarray, p: int, lo: np.ndarray, coef: np.ndarray
) -> tuple[float, bool]:
    """Solve ``(G + r I) coef = g`` with ``refine``'s regularisation ``r = 1e-12 tr(G) / p +
    1e-300`` (``gram`` is changed in place); returns ``g^T coef`` (the explained energy)
    and False if the system is not positive definite."""
    tr = 0.0
    for a in range(p):
        tr += gram[a, a]
    reg = 1e-12 * tr / p + 1e-300
    for a in range(p):
        gram[a, a] += reg
    if not _cholesky(gram, p, lo):
        return 0.0, False
    _chol_solve(lo, p, g, coef)
    e = 0.0
    for a in range(p):
        e += g[a] * coef[a]
    return e, True


def _explained(
    gram: np.ndarray, g: np.ndarray, j0: int, p: int, lo: np.ndarray, tmp: np.ndarray
) -> tuple[float, bool]:
    """``g^T G^-1 g`` of the columns ``j0 ... p - 1`` (regularised as in ``refine``)."""
    m = p - j0
    sub = np.empty((m, m))
    rhs = np.empty(m)
    for a in range(m):
        rhs[a] = g[j0 + a]
        for b in range(m):
            sub[a, b] = gram[j0 + a, j0 + b]
    return _reg_solve(sub, rhs, m, lo, tmp)


def _masked_stat_py(seg: np.ndarray, keep: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, bool]:
    """Stage-1 F statistic with masked samples left out (``refine._masked_statistic``).

    ``keep`` is 1.0 for the samples used and 0.0 for the masked ones; ``cols`` (L, p) the
    integer-grid basis. Returns the statistic and False if a window's normal equations
    were not positive definite (the caller then uses the numpy reference).
    """
    length, p = cols.shape
    n_out = seg.shape[0] - length + 1
    out = np.empty(max(n_out, 0), dtype=np.float64)
    gram = np.zeros((p, p))
    g = np.zeros(p)
    lo = np.zeros((p, p))
    tmp = np.zeros(p)
    for i in range(n_out):
        gram[:, :] = 0.0
        g[:] = 0.0
        total = 0.0
        n_keep = 0.0
        for ll in range(length):
            wt = keep[i + ll]
            if wt == 0.0:
                continue
            d = seg[i + ll]
            total += d * d
            n_keep += wt
            for a in range(p):
                ba = cols[ll, a]
                g[a] += d * ba
                for b in range(a + 1):
                    gram[a, b] += ba * cols[ll, b]
        for a in range(p):
            for b in range(a):
                gram[b, a] = gram[a, b]
        full, ok = _explained(gram, g, 0, p, lo, tmp)
        if not ok:
            return out, False
        base = 0.0
        if p > 2:
            base, ok = _explained(gram, g, 2, p, lo, tmp)
            if not ok:
                return out, False
        dof = n_keep - p
        resid = max(total - full, 1e-12 * total + 1e-300) / max(dof, 1.0)
        f = max(full - base, 0.0) / 2.0 / resid
        out[i] = f if dof >= 8 else 0.0
    return out, True


def _linspace(start: float, stop: float, num: int, out: np.ndarray) -> None:
    """``numpy.linspace(start, stop, num)`` into ``out`` (numpy's arithmetic)."""
    div = num - 1
    delta = stop - start
    step = delta / div
    for i in range(num):
        if step == 0.0:
            out[i] = i / div * delta + start
        else:
            out[i] = i * step + start
    out[num - 1] = stop


def _fit_tau(
    tau: float,
    seg: np.ndarray,
    n: np.ndarray,
    nuis: np.ndarray,
    s: np.ndarray,
    c: np.ndarray,
    segsq: float,
    fs: float,
    taper_s: float,
    burst_s: float,
    nb: np.ndarray,
    ng: np.ndarray,
    gram: np.ndarray,
    g: np.ndarray,
    lo: np.ndarray,
    coef: np.ndarray,
) -> tuple[float, bool]:
    """Residual energy of the regularised least-squares fit at onset ``tau`` (``_fits``).

    ``nuis`` (L, p - 2) holds the nuisance columns (background tone, constant, slope),
    ``nb`` and ``ng`` their Gram block and their products with ``seg`` (independent of
    ``tau``); ``coef`` receives the amplitudes. False if the system is not positive
    definite.
    """
    length = seg.shape[0]
    pn = nuis.shape[1]
    p = 2 + pn
    gram[:, :] = 0.0
    g0 = 0.0
    g1 = 0.0
    for ll in range(length):
        e = _env((n[ll] - tau) / fs, taper_s, burst_s)
        b0 = e * s[ll]
        b1 = e * c[ll]
        d = seg[ll]
        g0 += b0 * d
        g1 += b1 * d
        gram[0, 0] += b0 * b0
        gram[1, 0] += b1 * b0
        gram[1, 1] += b1 * b1
        for a in range(pn):
            u = nuis[ll, a]
            gram[2 + a, 0] += u * b0
            gram[2 + a, 1] += u * b1
    g[0] = g0
    g[1] = g1
    for a in range(pn):
        g[2 + a] = ng[a]
        for b in range(a + 1):
            gram[2 + a, 2 + b] = nb[a, b]
    for a in range(p):
        for b in range(a):
            gram[b, a] = gram[a, b]
    e, ok = _reg_solve(gram, g, p, lo, coef)
    return segsq - e, ok


def _refine_py(
    seg: np.ndarray,
    n: np.ndarray,
    nuis: np.ndarray,
    s: np.ndarray,
    c: np.ndarray,
    segsq: float,
    a: float,
    h: float,
    n_coarse: int,
    n_fine: int,
    fs: float,
    taper_s: float,
    burst_s: float,
) -> np.ndarray:
    """Stage 2 of ``refine.refine_onset`` on the window ``seg`` at sample times ``n``.

    ``nuis`` (L, p - 2): nuisance columns; ``s``, ``c``: the carrier ``sin(w n)``,
    ``cos(w n)``; ``segsq``: ``seg @ seg``. Returns ``[ok, tau, rss, coef0, coef1,
    perp2]`` with ``perp2`` the squared norm of the onset derivative of the model
    orthogonal to the model's columns (the Fisher information times the noise variance);
    ``ok`` is 0 when a system was not positive definite (the caller then uses the numpy
    reference).
    """
    length = seg.shape[0]
    pn = nuis.shape[1]
    p = 2 + pn
    res = np.zeros(6)
    nb = np.zeros((pn, pn))
    ng = np.zeros(pn)
    for ll in range(length):
        for a2 in range(pn):
            u = nuis[ll, a2]
            ng[a2] += u * seg[ll]
            for b2 in range(a2 + 1):
                nb[a2, b2] += u * nuis[ll, b2]
    gram = np.zeros((p, p))
    g = np.zeros(p)
    lo = np.zeros((p, p))
    coef = np.zeros(p)
    args = (seg, n, nuis, s, c, segsq, fs, taper_s, burst_s, nb, ng, gram, g, lo, coef)

    # Coarse grid, fine grid between the coarse minimum's neighbours, parabola.
    grid = np.empty(n_coarse)
    _linspace(a - h, a + h, n_coarse, grid)
    best, j = math.inf, 0
    for i in range(n_coarse):
        r, ok = _fit_tau(grid[i], *args)
        if not ok:
            return res
        if r < best:
            best, j = r, i
    fine = np.empty(n_fine)
    _linspace(grid[max(j - 1, 0)], grid[min(j + 1, n_coarse - 1)], n_fine, fine)
    rf = np.empty(n_fine)
    best, m = math.inf, 0
    for i in range(n_fine):
        r, ok = _fit_tau(fine[i], *args)
        if not ok:
            return res
        rf[i] = r
        if r < best:
            best, m = r, i
    m = min(max(m, 1), n_fine - 2)
    y0, y1, y2 = rf[m - 1], rf[m], rf[m + 1]
    den = y0 - 2.0 * y1 + y2
    step = fine[1] - fine[0]
    vertex = min(max(0.5 * (y0 - y2) / den, -1.0), 1.0) if den > 0 else 0.0
    tau = fine[m] + vertex * step

    rss, ok = _fit_tau(tau, *args)
    if not ok:
        return res
    rss = max(rss, 0.0)
    c0, c1 = coef[0], coef[1]
    # Onset derivative of the model (central difference, as the reference) and its part
    # orthogonal to the model's columns at tau (unregularised normal equations).
    eps = 1e-3
    dm = np.empty(length)
    bt = np.empty((length, p))
    for ll in range(length):
        e = _env((n[ll] - tau) / fs, taper_s, burst_s)
        bt[ll, 0] = e * s[ll]
        bt[ll, 1] = e * c[ll]
        for a2 in range(pn):
            bt[ll, 2 + a2] = nuis[ll, a2]
        ep = _env((n[ll] - (tau + eps)) / fs, taper_s, burst_s)
        em = _env((n[ll] - (tau - eps)) / fs, taper_s, burst_s)
        dm[ll] = ((ep * s[ll] - em * s[ll]) * c0 + (ep * c[ll] - em * c[ll]) * c1) / (2 * eps)
    g0 = np.zeros((p, p))
    hv = np.zeros(p)
    for ll in range(length):
        for a2 in range(p):
            hv[a2] += bt[ll, a2] * dm[ll]
            for b2 in range(a2 + 1):
                g0[a2, b2] += bt[ll, a2] * bt[ll, b2]
    if not _cholesky(g0, p, lo):
        return res
    x = np.zeros(p)
    _chol_solve(lo, p, hv, x)
    perp2 = 0.0
    for ll in range(length):
        r = dm[ll]
        for a2 in range(p):
            r -= bt[ll, a2] * x[a2]
        perp2 += r * r
    res[0] = 1.0
    res[1] = tau
    res[2] = rss
    res[3] = c0
    res[4] = c1
    res[5] = perp2
    return res


def _anchors_py(
    cs_pts: np.ndarray,
    cs: np.ndarray,
    n_e: int,
    hop: int,
    w: int,
    n_plat: int,
    spacing: float,
    k_b: int,
    min_rise_db: float,
) -> np.ndarray:
    """``changepoint._anchor`` for every change-point sample in ``cs_pts``: (n, 2) int64
    rows of (beep start, rising burst places). Same arithmetic in the same order."""
    out = np.empty((cs_pts.shape[0], 2), dtype=np.int64)
    scores = np.zeros(k_b)
    rising = np.zeros(k_b, dtype=np.int64)
    for i in range(cs_pts.shape[0]):
        c = cs_pts[i]
        for j in range(k_b):
            tot = 0.0
            rising[j] = 0
            for k in range(k_b):
                f = int(np.rint((c + (k - j) * spacing) / hop))
                p0, p1 = f + w, f + w + n_plat
                q0, q1 = f - w - 8, f - w
                if q0 < 0 or p1 > n_e:
                    continue
                plat = (cs[p1] - cs[p0]) / (p1 - p0)
                pre = (cs[q1] - cs[q0]) / (q1 - q0)
                if plat > 0:
                    rise = min(30.0, max(0.0, 10.0 * math.log10(plat / max(pre, 1e-300))))
                    tot += rise
                    if rise >= min_rise_db:
                        rising[j] += 1
            scores[j] = tot
        top = scores.max() - 1e-9
        best_j = 0
        for j in range(k_b):
            if scores[j] >= top:
                best_j = j
                break
        out[i, 0] = int(np.rint(c - best_j * spacing))
        out[i, 1] = rising[best_j]
    return out


def _fir_py(x: np.ndarray, hr: np.ndarray, half: int, start: int, count: int) -> np.ndarray:
    """``condition.bandlimit`` of ``x`` at output samples ``start ... start + count - 1``.

    ``out[j] = sum_k h[k] x[start + j + half - k]`` (samples outside ``x`` are zero), with
    ``hr`` the taps reversed so that each output is one contiguous dot product.
    """
    n_h = hr.shape[0]
    n = x.shape[0]
    # The samples the outputs reach, zero outside x; then tap by tap over all outputs
    # (an axpy per tap, which vectorises).
    base = start + half - (n_h - 1)
    xp = np.zeros(count + n_h - 1, dtype=np.float64)
    for i in range(max(0, -base), min(xp.shape[0], n - base)):
        xp[i] = x[base + i]
    out = np.zeros(count, dtype=np.float64)
    for m in range(n_h):
        hm = hr[m]
        for j in range(count):
            out[j] += hm * xp[j + m]
    return out


_KERNELS = {
    "fir": _fir_py,
    "edge_stat": _edge_stat_py,
    "masked_stat": _masked_stat_py,
    "refine": _refine_py,
    "anchors": _anchors_py,
}
_HELPERS = (_env, _cholesky, _chol_solve, _reg_solve, _explained, _linspace, _fit_tau)


@functools.cache
def _compiled(name: str, cache: bool = True):
    """The numba-compiled kernel ``name`` (numba is imported on first use only).

    The helpers are compiled as numba functions in this module's namespace first, so the
    kernels call compiled code; exact IEEE arithmetic (no fastmath), like the reference.
    """
    import numba

    g = globals()
    if not isinstance(g["_env"], numba.core.registry.CPUDispatcher):
        for fn in _HELPERS:
            g[fn.__name__] = numba.njit(cache=True, nogil=True)(fn)
    # Stage 1's and the FIR's dot products may be reassociated (vectorised, like numpy's
    # own); the rest keeps IEEE order.
    fm = {"reassoc", "contract"} if name in ("edge_stat", "fir") else False
    return numba.njit(cache=cache, nogil=True, fastmath=fm)(_KERNELS[name])


def call(name: str, *args):
    """Run the compiled kernel ``name`` on ``args`` (contiguous float64 arrays, scalars)."""
    try:
        return _compiled(name)(*args)
    except ModuleNotFoundError:
        # numba's disk cache stores the defining module's name and re-imports it on load;
        # an entry written under another module name cannot be loaded: compile uncached.
        return _compiled(name, False)(*args)
