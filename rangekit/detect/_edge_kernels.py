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

#: Largest clock-rate mismatch between a beep's player and its recorder that
#: ``changepoint._combine`` (and :func:`_combine_py`) take for drift of the bursts, not
#: for inconsistency: 200 ppm.
MAX_DRIFT = 2e-4


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
    The windows are the innermost loop (one multiply-add over all windows per basis
    sample, which vectorises), not the samples of one window.
    """
    n_q, length = qt.shape
    n_out = max(seg.shape[0] - length + 1, 0)
    total = np.zeros(n_out)
    full = np.zeros(n_out)
    base = np.zeros(n_out)
    acc = np.empty(n_out)
    for ll in range(length):
        for i in range(n_out):
            v = seg[i + ll]
            total[i] += v * v
    for j in range(n_q):
        acc[:] = 0.0
        for ll in range(length):
            q = qt[j, ll]
            for i in range(n_out):
                acc[i] += seg[i + ll] * q
        if j < n_par:
            for i in range(n_out):
                full[i] += acc[i] * acc[i]
        else:
            for i in range(n_out):
                base[i] += acc[i] * acc[i]
    out = np.empty(n_out)
    for i in range(n_out):
        resid = max(total[i] - full[i], 1e-12 * total[i] + 1e-300) / (length - n_par)
        out[i] = max(full[i] - base[i], 0.0) / 2.0 / resid
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
    t00 = 0.0
    t10 = 0.0
    t11 = 0.0
    # the nuisance columns' products with the edge columns, in scalars (up to 4 columns;
    # each sum in sample order, as before)
    u00 = u01 = u10 = u11 = u20 = u21 = u30 = u31 = 0.0
    for ll in range(length):
        e = _env((n[ll] - tau) / fs, taper_s, burst_s)
        if e == 0.0:
            continue  # adds only zeros (before the onset)
        b0 = e * s[ll]
        b1 = e * c[ll]
        d = seg[ll]
        g0 += b0 * d
        g1 += b1 * d
        t00 += b0 * b0
        t10 += b1 * b0
        t11 += b1 * b1
        if pn > 0:
            u = nuis[ll, 0]
            u00 += u * b0
            u01 += u * b1
            u = nuis[ll, 1]
            u10 += u * b0
            u11 += u * b1
        if pn > 2:
            u = nuis[ll, 2]
            u20 += u * b0
            u21 += u * b1
            u = nuis[ll, 3]
            u30 += u * b0
            u31 += u * b1
    gram[0, 0] = t00
    gram[1, 0] = t10
    gram[1, 1] = t11
    if pn > 0:
        gram[2, 0] = u00
        gram[2, 1] = u01
        gram[3, 0] = u10
        gram[3, 1] = u11
    if pn > 2:
        gram[4, 0] = u20
        gram[4, 1] = u21
        gram[5, 0] = u30
        gram[5, 1] = u31
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


def _fit_summary(r, m: int, n_cols: int) -> tuple[float, float, float]:
    """``(tau, sigma, snr_db)`` of a :func:`_refine_py` result ``r`` over ``m`` samples with
    ``n_cols`` nuisance columns (as ``refine.fit_edge`` reports them)."""
    rss, tau, amp, perp2 = r[2], r[1], math.hypot(r[3], r[4]), r[5]
    noise_var = max(rss / max(m - n_cols - 1, 1), 1e-30)
    info = perp2 / noise_var
    sigma = 1.0 / math.sqrt(info) if info > 0 else math.inf
    return tau, sigma, 10.0 * math.log10(max(0.5 * amp * amp / noise_var, 1e-30))


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
    if n_h == 0:  # no conditioning: the raw samples as float64
        out = np.zeros(count, dtype=np.float64)
        for j in range(max(0, -start), min(count, n - start)):
            out[j] = x[start + j]
        return out
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


def _widen_py(f: np.ndarray, half: int, out: np.ndarray) -> None:
    """``changepoint._widen``: running maximum over ``+-half`` samples, zeros beyond the
    ends (``f >= 0``)."""
    n = f.shape[0]
    for i in range(n):
        m = 0.0
        for j in range(max(0, i - half), min(n, i + half + 1)):
            if f[j] > m:
                m = f[j]
        out[i] = m


def _first_edge_py(stat: np.ndarray, frac: float, floor: float, sep: int) -> int:
    """``changepoint._first_edge`` (the same comparisons)."""
    n = stat.shape[0]
    top = 0
    for i in range(1, n):
        if stat[i] > stat[top]:
            top = i
    thr = max(frac * stat[top], floor)
    for pk in range(1, n - 1):
        if pk > top - sep:
            break
        if stat[pk] >= stat[pk - 1] and stat[pk] > stat[pk + 1] and stat[pk] >= thr:
            return pk
    return top


def _median_py(v: np.ndarray, m: int) -> float:
    """``numpy.median`` of ``v[:m]`` (sorted copy; mean of the two middle ones)."""
    w = np.sort(v[:m])
    h = m // 2
    return w[h] if m % 2 else (w[h - 1] + w[h]) / 2.0


def _better_line(n, cost, mean, n_best, cost_best, mean_best) -> bool:
    """Whether a candidate drift line (``changepoint._combine``, :func:`_combine_py`)
    holding ``n`` bursts at ``cost`` (their summed squared residual over timing noise)
    with mean estimate ``mean`` beats the best so far: more bursts, else a lower cost (by
    more than 1e-9: rounding), else an earlier mean (a burst timed on a reflection is
    late). ``changepoint`` imports this function before it is compiled."""
    if n != n_best:
        return n > n_best
    if abs(cost - cost_best) > 1e-9:
        return cost < cost_best
    return mean < mean_best


def _drift_line_py(ks, est, w, members, m, lim):
    """``changepoint._drift_line`` of one set of bursts: ``(mean, slope, kbar)``."""
    sw = 0.0
    swk = 0.0
    swe = 0.0
    for i in range(m):
        if members[i]:
            sw += w[i]
            swk += w[i] * ks[i]
            swe += w[i] * est[i]
    if sw <= 0:
        return math.inf, 0.0, 0.0
    kbar = swk / sw
    mean = swe / sw
    sxx = 0.0
    sxy = 0.0
    for i in range(m):
        if members[i]:
            sxx += w[i] * (ks[i] - kbar) ** 2
            sxy += w[i] * (ks[i] - kbar) * (est[i] - mean)
    slope = sxy / sxx if sxx > 0 else 0.0
    return mean, min(max(slope, -lim), lim), kbar


def _drift_half_py(k: int, k_b: int, spacing: float) -> int:
    """Half-width, samples, within which burst ``k`` of ``k_b`` is sought about the
    beep's joint edge: 2 (rounding of the spacing, timing) or, where larger, the drift of
    :data:`MAX_DRIFT` from the beep's middle burst to burst k (``changepoint._fit_beep``;
    2 for the default beep: 200 ppm of 5000 samples is 1 a burst)."""
    return max(2, int(math.ceil(MAX_DRIFT * spacing * abs(k - 0.5 * (k_b - 1)))))


def _pair_of(c: int, m: int) -> tuple[int, int]:
    """The pair ``(i, j)``, ``i < j < m``, at index ``c`` of ``numpy.triu_indices(m, 1)``'s
    order."""
    i = 0
    while c >= m - 1 - i:
        c -= m - 1 - i
        i += 1
    return i, i + 1 + c


def _combine_py(
    on: np.ndarray,
    sg_raw: np.ndarray,
    snr: np.ndarray,
    fst: np.ndarray,
    have: np.ndarray,
    spacing: float,
    scale: float,
    min_bursts: int,
    model_sigma: float,
    res: np.ndarray,
    row: np.ndarray,
) -> bool:
    """``changepoint._combine`` of unclipped bursts: False when too few agree, else
    ``res = [onset, sigma, snr_db, confidence, n_ok, strength]`` and ``row`` the kept
    bursts' onsets (NaN for the others)."""
    k_b = on.shape[0]
    ks = np.empty(k_b, dtype=np.int64)
    m = 0
    for k in range(k_b):
        if have[k]:
            ks[m] = k
            m += 1
    if m < min_bursts:
        return False
    est = np.empty(m)
    sg = np.empty(m)
    base = np.empty(m)
    w_all = np.empty(m)
    for i in range(m):
        k = ks[i]
        est[i] = on[k] - k * spacing
        v = sg_raw[k]
        if math.isnan(v) or v > 1e6:
            v = 1e6
        sg[i] = min(max(v, 1e-3), 1e6)
        base[i] = 2.0 * scale + 4.0 * sg[i]
        w_all[i] = 1.0 / sg[i] ** 2
    lim = MAX_DRIFT * spacing
    # Candidate drift lines (changepoint._combine): through each pair of bursts (slope
    # held within MAX_DRIFT), then each burst alone (slope 0); the bursts near one give
    # its least-squares drift line, the bursts near that line are the candidate's; the
    # best by _better_line.
    ok = np.zeros(m, dtype=np.bool_)
    inl = np.zeros(m, dtype=np.bool_)
    top = -1
    best_cost = math.inf
    centre = math.inf
    n_pairs = m * (m - 1) // 2
    for c in range(n_pairs + m):
        if c < n_pairs:
            i, j = _pair_of(c, m)
            sl = min(max((est[j] - est[i]) / (ks[j] - ks[i]), -lim), lim)
            wp = w_all[i] + w_all[j]
            k_at = (w_all[i] * ks[i] + w_all[j] * ks[j]) / wp
            e_at = (w_all[i] * est[i] + w_all[j] * est[j]) / wp
        else:
            i = c - n_pairs
            sl, k_at, e_at = 0.0, float(ks[i]), est[i]
        for q in range(m):
            inl[q] = abs(est[q] - (e_at + sl * (ks[q] - k_at))) <= base[q]
        e_at, sl, k_at = _drift_line_py(ks, est, w_all, inl, m, lim)
        n_in = 0
        num = 0.0
        den = 0.0
        cost = 0.0
        for q in range(m):
            rq = est[q] - (e_at + sl * (ks[q] - k_at))
            inl[q] = abs(rq) <= base[q]
            if inl[q]:
                n_in += 1
                num += w_all[q] * est[q]
                den += w_all[q]
                cost += (rq / base[q]) ** 2
        mean = num / den if den > 0 else math.inf
        if c == 0 or _better_line(n_in, cost, mean, top, best_cost, centre):
            top = n_in
            best_cost = cost
            centre = mean
            for q in range(m):
                ok[q] = inl[q]
    n_ok = 0
    for i in range(m):
        if ok[i]:
            n_ok += 1
    if n_ok < min_bursts:
        return False
    sw = 0.0
    swe = 0.0
    for i in range(m):
        if ok[i]:
            wt = 1.0 / sg[i] ** 2
            sw += wt
            swe += wt * est[i]
    t0 = swe / sw
    s0 = 1.0 / math.sqrt(sw)
    if n_ok > 1:
        chi = 0.0
        for i in range(m):
            if ok[i]:
                chi += (1.0 / sg[i] ** 2) * (est[i] - t0) ** 2
        chi2 = chi / (n_ok - 1)
        s0 *= math.sqrt(max(1.0, chi2))
    s0 = math.hypot(s0, model_sigma * scale)
    snr_ok = np.empty(n_ok)
    strength = 0.0
    row[:] = np.nan
    c = 0
    for i in range(m):
        if ok[i]:
            k = ks[i]
            row[k] = on[k]
            snr_ok[c] = snr[k]
            strength += fst[k]
            c += 1
    res[0] = t0
    res[1] = s0
    res[2] = _median_py(snr_ok, n_ok)
    res[3] = n_ok / k_b
    res[4] = n_ok
    res[5] = strength
    return True


def _onset_flags_py(
    e: np.ndarray,
    t0: float,
    hop: int,
    n_win: int,
    near: int,
    pre_run: int,
    rise: float,
    quiet: float,
    reverb_ratio: float,
    n_last: int,
    guard: float,
    rise_last: float,
    spacing: float,
    k_b: int,
) -> int:
    """``changepoint._before_onset_flags``: bit 0 ``ambiguous_first_path``, bit 1
    ``reverb_limited`` (the caller maps them to the flag bits)."""
    end = int(t0 - n_win) // hop
    lo_near = end - near
    lo_far = end - 2 * near
    if lo_far < 0 or end <= lo_near + pre_run:
        return 0
    # the frames just before each burst's onset over its level before, the smallest over
    # the bursts (changepoint._last_frames_ratio)
    ratio = np.full(n_last, np.inf)
    used = False
    for k in range(k_b):
        tk = t0 + k * spacing
        end_k = int(tk - n_win) // hop
        last = int(math.floor((tk - guard - n_win) / hop))
        if end_k - 2 * near < 0 or last - n_last + 1 < 0 or last >= e.shape[0]:
            continue
        s = 0.0
        for i in range(end_k - 2 * near, end_k - near):
            s += e[i]
        lvl = s / near
        if lvl > 0:
            used = True
            for j in range(n_last):
                ratio[j] = min(ratio[j], e[last - n_last + 1 + j] / lvl)
    top_last = -math.inf
    if used:
        for j in range(n_last):
            top_last = max(top_last, ratio[j])
    far = 0.0
    for i in range(lo_far, lo_near):
        far += e[i]
    far /= lo_near - lo_far
    top = -math.inf
    for i in range(lo_near, end - pre_run + 1):
        acc = 0.0
        for j in range(pre_run):
            acc += e[i + j] * (1.0 / pre_run)
        top = max(top, acc)
    out = 0
    if far > 0 and top > rise * far:
        out |= 1
    if top_last > rise_last:
        out |= 1
    if quiet > 0 and far > reverb_ratio * quiet:
        out |= 2
    return out


def _beeps_py(
    x: np.ndarray,
    hr: np.ndarray,
    half: int,
    anchors: np.ndarray,
    i_start: int,
    clip_idx: np.ndarray,
    mask: np.ndarray,
    qt: np.ndarray,
    n_base: int,
    n_par: int,
    qt_dc: np.ndarray,
    n_base_dc: int,
    cols_dc: np.ndarray,
    ipar: np.ndarray,
    fpar: np.ndarray,
    e: np.ndarray,
    found: np.ndarray,
    n_found: np.ndarray,
    out: np.ndarray,
    rows: np.ndarray,
    n_rows: np.ndarray,
) -> int:
    """``changepoint.detect_changepoint``'s loop over beep anchors: for each, the bursts'
    band-limited stretches (:func:`_fir_py`), edge statistics (:func:`_edge_stat_py`),
    the joint first edge, each burst's stage-2 fit (:func:`_refine_py`), the bursts
    combined (:func:`_combine_py`) and the flags from the band energy before the onset.

    ``ipar``: pre, post, u0, width, margin, k_b, sep, min_bursts, n_coarse, n_fine,
    background, hop, n_win, near, pre_run, lo_off, hi_off, n_last; ``fpar``:
    spacing, f_min, f_joint, h (stage 2's half range), fs, w, taper_s, burst_s, scale,
    model_sigma, quiet, rise, reverb_ratio, low_snr_db, scale_raw, f_raw_min, rise_last,
    guard. ``found`` (sorted, ``n_found[0]`` used) holds
    the onsets found so far; each row appends ``[onset, sigma, snr_db, confidence,
    n_ok, strength, flag bits]`` to ``out`` and the kept bursts' onsets to ``rows``.

    Stretches holding clipped samples (``clip_idx``, sorted; ``mask`` the recording's
    clip mask) are handled as ``changepoint._fit_beep`` does: the edge statistic also on
    the raw samples with the clipped ones left out and a constant and slope fitted
    (``qt_dc``, ``cols_dc``: that model's integer-grid bases), the onset refined on them.

    Returns the index of the first anchor not done: ``len(anchors)``, or an anchor the
    caller must do with the reference code (a system was not positive definite, or the
    joint edge lies at the search window's late end: the reference re-anchors on it).
    """
    pre, post, u0, width, margin, k_b, sep, min_bursts = (
        ipar[0],
        ipar[1],
        ipar[2],
        ipar[3],
        ipar[4],
        ipar[5],
        ipar[6],
        ipar[7],
    )
    n_coarse, n_fine, background, hop, n_win, near, pre_run = (
        ipar[8],
        ipar[9],
        ipar[10],
        ipar[11],
        ipar[12],
        ipar[13],
        ipar[14],
    )
    lo_off, hi_off = ipar[15], ipar[16]
    spacing, f_min, f_joint, h, fs, w = fpar[0], fpar[1], fpar[2], fpar[3], fpar[4], fpar[5]
    taper_s, burst_s, scale, model_sigma = fpar[6], fpar[7], fpar[8], fpar[9]
    quiet, rise, reverb_ratio, low_snr_db = fpar[10], fpar[11], fpar[12], fpar[13]
    scale_raw, f_raw_min, rise_last, guard = fpar[14], fpar[15], fpar[16], fpar[17]
    n_last = ipar[17]
    n_par_dc = cols_dc.shape[1]
    n_cols_dc = (4 if background else 2) + 2
    raw = np.zeros(width - 1 + 2 * margin)
    f_raw = np.zeros(width)
    clipped = np.zeros(k_b, dtype=np.bool_)
    n = x.shape[0]
    u1 = u0 + width - 1
    n_cols = 4 if background else 2
    seg_len = u1 - u0 + 2 * margin
    segs = np.zeros((k_b, seg_len))
    lens = np.zeros(k_b, dtype=np.int64)
    offs = np.zeros(k_b, dtype=np.int64)
    ps = np.zeros(k_b, dtype=np.int64)
    stats = np.zeros((k_b, width))
    widened = np.zeros((k_b, width))
    joint = np.zeros(width)
    on = np.zeros(k_b)
    sg = np.zeros(k_b)
    snr = np.zeros(k_b)
    fst = np.zeros(k_b)
    have = np.zeros(k_b, dtype=np.bool_)
    res = np.zeros(6)
    row = np.zeros(k_b)
    for i in range(i_start, anchors.shape[0]):
        a = anchors[i]
        nf = n_found[0]
        # an anchor whose search window holds a beep onset found already
        j_f = np.searchsorted(found[:nf], a + lo_off)
        if j_f < nf and found[j_f] <= a + hi_off:
            continue
        for k in range(k_b):
            p = int(np.rint(a + k * spacing))
            s0 = max(0, p + u0 - margin)
            s1 = min(n, p + u1 + margin)
            cnt = max(s1 - s0, 0)
            y = _fir_py(x, hr, half, s0, cnt)
            segs[k, :cnt] = y
            lens[k] = cnt
            offs[k] = s0
            ps[k] = p
            stats[k, :] = 0.0
            lo = max(p + u0 - s0, pre)
            hi = min(p + u1 - s0, cnt - post - 4)
            if hi >= lo:
                fk = _edge_stat_py(segs[k, lo - pre : hi + post], qt, n_base, n_par)
                j0 = lo + s0 - p - u0
                stats[k, j0 : j0 + fk.shape[0]] = fk
            if _any_in(clip_idx, s0, s1):
                # the raw samples, clipped ones left out, constant and slope fitted
                for ll in range(cnt):
                    raw[ll] = x[s0 + ll]
                f_raw[:] = 0.0
                if hi >= lo:
                    sub = raw[lo - pre : hi + post]
                    if _any_in(clip_idx, s0 + lo - pre, s0 + hi + post):
                        keep = np.empty(sub.shape[0])
                        for ll in range(sub.shape[0]):
                            keep[ll] = 0.0 if mask[s0 + lo - pre + ll] else 1.0
                        fk, ok = _masked_stat_py(sub, keep, cols_dc)
                        if not ok:
                            return i
                    else:
                        fk = _edge_stat_py(sub, qt_dc, n_base_dc, n_par_dc)
                    j0 = lo + s0 - p - u0
                    f_raw[j0 : j0 + fk.shape[0]] = fk
                if f_raw.max() >= f_raw_min:
                    for j in range(width):
                        stats[k, j] = scale_raw * f_raw[j]
            _widen_py(stats[k], _drift_half_py(k, k_b, spacing), widened[k])
            # No onset can gather min_bursts bursts reaching f_min any more: the anchor
            # gives no beep (the reference finds none either), skip its other bursts.
            top = 0
            for j in range(width):
                c = 0
                for k2 in range(k + 1):
                    if widened[k2, j] >= f_min:
                        c += 1
                top = max(top, c)
            if top + (k_b - 1 - k) < min_bursts:
                break
        if top + (k_b - 1 - k) < min_bursts:
            continue
        any_pos = False
        for j in range(width):
            v = widened[0, j]
            for k in range(1, k_b):
                v += widened[k, j]
            c = 0
            for k in range(k_b):
                if widened[k, j] >= f_min:
                    c += 1
            if v > 0:
                any_pos = True
            joint[j] = v if c >= min_bursts else 0.0
        if not any_pos:
            continue
        u = _first_edge_py(joint, 0.1, f_joint, sep)
        if joint[u] >= f_joint and u >= width - sep:
            return i  # an edge at the window's late end: the reference re-anchors on it
        if joint[u] < f_joint or not (sep <= u < width - sep):
            continue
        failed = False
        for k in range(k_b):
            have[k] = False
            clipped[k] = False
            hw = _drift_half_py(k, k_b, spacing)
            j0, j1 = max(0, u - hw), min(width, u + hw + 1)
            jb = j0
            for j in range(j0 + 1, j1):
                if stats[k, j] > stats[k, jb]:
                    jb = j
            if stats[k, jb] < f_min:
                continue
            a_k = ps[k] + u0 + jb
            if _any_in(clip_idx, a_k - 2 * pre, a_k + 2 * post):
                # refined on the raw samples, clipped ones left out (refine_onset, dc)
                clipped[k] = True
                r0 = max(0, a_k - 4 * pre - post)
                r1 = min(n, a_k + 4 * post + pre)
                a_r = a_k - r0
                i0 = max(0, int(math.floor(a_r - h)) - pre)
                i1 = min(r1 - r0, int(math.ceil(a_r + h)) + post)
                m = 0
                for t in range(i0, i1):
                    if not mask[r0 + t]:
                        m += 1
                if m >= 8 + 2 * n_cols_dc:
                    nn = np.empty(m)
                    sv = np.empty(m)
                    cv = np.empty(m)
                    sr = np.empty(m)
                    c = 0
                    segsq = 0.0
                    for t in range(i0, i1):
                        if not mask[r0 + t]:
                            nn[c] = float(t)
                            sr[c] = x[r0 + t]
                            segsq += sr[c] * sr[c]
                            c += 1
                    nuis = np.empty((m, n_cols_dc - 2))
                    span = max(nn[m - 1] - nn[0], 1.0)
                    for ll in range(m):
                        sv[ll] = math.sin(w * nn[ll])
                        cv[ll] = math.cos(w * nn[ll])
                        c = 0
                        if background:
                            nuis[ll, 0] = sv[ll]
                            nuis[ll, 1] = cv[ll]
                            c = 2
                        nuis[ll, c] = 1.0
                        nuis[ll, c + 1] = (nn[ll] - nn[0]) / span - 0.5
                    r = _refine_py(
                        sr,
                        nn,
                        nuis,
                        sv,
                        cv,
                        segsq,
                        float(a_r),
                        h,
                        n_coarse,
                        n_fine,
                        fs,
                        taper_s,
                        burst_s,
                    )
                    if r[0] != 1.0:
                        failed = True
                        break
                    tau, s_k, snr_k = _fit_summary(r, m, n_cols_dc)
                    on[k] = tau + r0
                    sg[k] = s_k
                    snr[k] = snr_k
                    fst[k] = stats[k, jb]
                    have[k] = True
                    continue
            a_loc = a_k - offs[k]
            seg = segs[k, : lens[k]]
            i0 = max(0, int(math.floor(a_loc - h)) - pre)
            i1 = min(lens[k], int(math.ceil(a_loc + h)) + post)
            m = i1 - i0
            nn = np.empty(m)
            sv = np.empty(m)
            cv = np.empty(m)
            nuis = np.empty((m, 2 if background else 0))
            segsq = 0.0
            for ll in range(m):
                t = float(i0 + ll)
                nn[ll] = t
                sv[ll] = math.sin(w * t)
                cv[ll] = math.cos(w * t)
                if background:
                    nuis[ll, 0] = sv[ll]
                    nuis[ll, 1] = cv[ll]
                segsq += seg[i0 + ll] * seg[i0 + ll]
            r = _refine_py(
                seg[i0:i1],
                nn,
                nuis,
                sv,
                cv,
                segsq,
                float(a_loc),
                h,
                n_coarse,
                n_fine,
                fs,
                taper_s,
                burst_s,
            )
            if r[0] != 1.0:
                failed = True
                break
            tau, s_k, snr_k = _fit_summary(r, m, n_cols)
            on[k] = tau + offs[k]
            sg[k] = s_k
            snr[k] = snr_k
            fst[k] = stats[k, jb]
            have[k] = True
        if failed:
            return i
        if not _combine_py(
            on, sg, snr, fst, have, spacing, scale, min_bursts, model_sigma, res, row
        ):
            continue
        t0 = res[0]
        fl = 0
        if res[4] < k_b:
            fl |= 4
        if res[2] < low_snr_db:
            fl |= 8
        for k in range(k_b):
            if clipped[k] and not math.isnan(row[k]):
                fl |= 16
        fl |= _onset_flags_py(
            e, t0, hop, n_win, near, pre_run, rise, quiet, reverb_ratio, n_last, guard,
            rise_last, spacing, k_b,
        )  # fmt: skip
        nr = n_rows[0]
        for c in range(6):
            out[nr, c] = res[c]
        out[nr, 6] = fl
        rows[nr, :] = row
        n_rows[0] = nr + 1
        j_f = np.searchsorted(found[:nf], t0)
        for c in range(nf, j_f, -1):
            found[c] = found[c - 1]
        found[j_f] = t0
        n_found[0] = nf + 1
    return anchors.shape[0]


def _any_in(idx: np.ndarray, a: int, b: int) -> bool:
    """Whether the sorted ``idx`` holds a value in ``[max(a, 0), b)``."""
    if idx.shape[0] == 0:
        return False
    j = np.searchsorted(idx, max(a, 0))
    return j < idx.shape[0] and idx[j] < b


def _all_finite_py(x: np.ndarray) -> bool:
    """Whether every sample of ``x`` is finite (one pass, no temporary array)."""
    acc = 0.0
    for i in range(x.shape[0]):
        acc += x[i] * 0.0  # NaN for a NaN or an infinity, else 0
    return acc == 0.0


def _change_points_py(
    e: np.ndarray, floor: np.ndarray, gap: int, nb: int, thr_f: float, thr_r: float, w: int
) -> np.ndarray:
    """``changepoint._change_points`` (the same arithmetic per frame): frames where ``e``
    first exceeds both ``thr_f`` times the floor and ``thr_r`` times the mean of the
    ``nb`` frames ending ``gap`` frames earlier, and inside each such run the frames ``w``
    or more into it (or into the step before) exceeding ``thr_r`` times the largest of
    its first ``w`` frames."""
    n = e.shape[0]
    cs = np.empty(n + 1)
    cs[0] = 0.0
    acc = 0.0
    for i in range(n):
        acc += e[i]
        cs[i + 1] = acc
    out = np.empty(n, dtype=np.int64)
    m = 0
    prev = False
    start = 0
    level = 0.0
    for i in range(n):
        fl = max(floor[i], 1e-30)
        hi = max(i - gap, 0)
        lo = max(i - gap - nb, 0)
        cnt = hi - lo
        pre = (cs[hi] - cs[lo]) / max(cnt, 1) if cnt > 0 else fl
        thr = max(fl * thr_f, pre * thr_r)
        above = e[i] > thr
        if above and not prev:
            out[m] = i
            m += 1
            start = i
            level = e[i]
        elif above:
            if i < start + w:
                level = max(level, e[i])
            elif e[i] > thr_r * level:
                # a second step: a new run start, its level from its own first w frames
                out[m] = i
                m += 1
                start = i
                level = e[i]
        prev = above
    return out[:m]


def _dedupe_py(starts: np.ndarray, rising: np.ndarray, min_rise: int, hop: int) -> np.ndarray:
    """``detect_changepoint``'s anchors: starts with ``min_rise`` rising places, each more
    than ``hop`` from the last 8 kept ones."""
    out = np.empty(starts.shape[0], dtype=np.int64)
    m = 0
    for i in range(starts.shape[0]):
        if rising[i] < min_rise:
            continue
        a = starts[i]
        ok = True
        for j in range(max(0, m - 8), m):
            if abs(a - out[j]) <= hop:
                ok = False
                break
        if ok:
            out[m] = a
            m += 1
    return out[:m]


_KERNELS = {
    "fir": _fir_py,
    "edge_stat": _edge_stat_py,
    "masked_stat": _masked_stat_py,
    "refine": _refine_py,
    "anchors": _anchors_py,
    "beeps": _beeps_py,
    "dedupe": _dedupe_py,
    "all_finite": _all_finite_py,
    "change_points": _change_points_py,
}
_HELPERS = (
    _env,
    _cholesky,
    _chol_solve,
    _reg_solve,
    _explained,
    _linspace,
    _fit_tau,
    _fir_py,
    _edge_stat_py,
    _refine_py,
    _fit_summary,
    _widen_py,
    _first_edge_py,
    _median_py,
    _pair_of,
    _drift_half_py,
    _drift_line_py,
    _better_line,
    _combine_py,
    _onset_flags_py,
    _any_in,
    _masked_stat_py,
)
#: Functions whose dot products may be reassociated and fused (vectorised, like numpy's
#: own); the rest keeps IEEE order.
_FASTMATH = {
    "_edge_stat_py": {"reassoc", "contract"},
    "_fir_py": {"reassoc", "contract"},
    "_all_finite_py": {"reassoc"},
}


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
            fm = _FASTMATH.get(fn.__name__, False)
            g[fn.__name__] = numba.njit(cache=True, nogil=True, fastmath=fm)(fn)
    fn = _KERNELS[name]
    if cache and isinstance(g.get(fn.__name__), numba.core.registry.CPUDispatcher):
        return g[fn.__name__]  # a helper too: one compiled version
    fm = _FASTMATH.get(fn.__name__, False)
    return numba.njit(cache=cache, nogil=True, fastmath=fm)(fn)


def call(name: str, *args):
    """Run the compiled kernel ``name`` on ``args`` (contiguous float64 arrays, scalars)."""
    try:
        return _compiled(name)(*args)
    except ModuleNotFoundError:
        # numba's disk cache stores the defining module's name and re-imports it on load;
        # an entry written under another module name cannot be loaded: compile uncached.
        return _compiled(name, False)(*args)
