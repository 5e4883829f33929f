"""Compiled inner step of the multipath transducer fit (:mod:`rangekit.detect.pathfit`).

One-way ranging fits every arrival's paths and transducers by Levenberg-Marquardt with
variable projection (Golub & Pereyra 1973; Kaufman 1975). Each evaluation of the model
is a few inverse FFTs of 1024 points and then a dozen small-array numpy calls (the
interleaved basis, its Gram matrix and inverse, the amplitudes, the residual, the
Jacobian's columns and Kaufman's projection), whose per-call overhead, not their
arithmetic, was most of a fit's time. :func:`_vp_py` does that part after the FFTs in one
compiled loop, and :func:`_lm_step_py` a Levenberg-Marquardt iteration's linear algebra:

* the basis ``B`` (columns: real and imaginary part of each path's waveform), the Gram
  matrix ``G = B^T B`` and its inverse (Cholesky), the amplitudes ``a = G^-1 B^T x``, the
  residual ``r = x - B a`` and its sum of squares;
* the model Jacobian: ``d/du_i`` from path ``i``'s derivative row only, ``d/dtheta_j``
  summed over the paths (``a_re Re + a_im Im`` of each row);
* Kaufman's projected Jacobian ``J - B G^-1 B^T J``;
* (:func:`_lm_step_py`) ``J^T J``, ``J^T r``, the Gauss-Newton gain ``g^T (J^T J)^-1 g``
  and the damped step ``(J^T J + lam diag(J^T J))^-1 g`` (Cholesky, the damping raised
  while singular), scaled so that no parameter moves more than its limit.

**A held fit in two calls.** Most arrivals are fitted with the transducers held at
their group's estimate (``fit_theta=False``): the spectrum ``s`` is then constant and
only the onsets move. :func:`_held_fit_py` runs that fit's whole Levenberg-Marquardt loop
(the rules of ``pathfit.fit_paths``), and :func:`_held_result_py` what
``pathfit._summarize`` makes of it (the ``theta`` columns at the fitted onsets, the
Gauss-Newton blocks, the first path, its Newton step, gain and variances). Neither calls
an FFT: a waveform at onset ``u = i + f`` (``i = round(u)``, ``|f| <= 1/2``) is the
circular shift by ``i`` of ``exp(-j wc f) sum_q (-j f)^q / q! D_q`` with ``D_q =
IFFT(s (w - wc)^q)`` tabulated once per held ``theta`` (the Taylor series of ``exp(-j (w
- wc) f)``; :func:`_shift_rows_py`; ``pathfit.SHIFT_TOL`` sets the terms: 13-14, the
rows equal to the inverse FFT's to 2e-14 of their peak, tested; the fits' results to
~1e-13, tested).

The numpy code of :func:`rangekit.detect.pathfit._evaluate_np` and
:func:`rangekit.detect.pathfit._lm_step_np` is the reference (used
for shorter recordings, and tested against this kernel in
``tests/detect/test_pathfit_kernels.py``); the two agree to rounding (sums in another
order, Cholesky against LU).

Import cost: numba is imported on first use only, and the fit uses the kernel only for
recordings of ``pathfit.KERNEL_MIN_SAMPLES`` or more (``pathfit.kernel_by_length`` on the
channel fits), so a short file pays neither the import nor the cache load, and the same
recording gives the same numbers whatever the process imported before.
"""

from __future__ import annotations

import functools
import math

import numpy as np

# The Cholesky factorisation and solve of the beep detector's kernels (compiled again in
# this module's namespace by :func:`_compiled`).
from rangekit.detect._edge_kernels import _chol_solve, _cholesky

__all__: list[str] = []


def _vp_py(rows: np.ndarray, x: np.ndarray, n: int):
    """Amplitudes, residual, Jacobian and projected Jacobian from the IFFT rows.

    ``rows`` is ``(nb, k, m)`` complex: row ``(0, i)`` path ``i``'s waveform, ``(1, i)``
    its onset derivative, ``(2 + j, i)`` its derivative by ``theta_j``; the first ``n``
    samples are used. Returns ``(ok, basis, gram_inv, a, r, cost, jac, jp)``; ``ok`` is
    False when the Gram matrix is not numerically positive definite (the caller then
    uses the numpy reference, which falls back to a pseudo-inverse).
    """
    nb, k = rows.shape[0], rows.shape[1]
    m2 = 2 * k
    p = k + nb - 2
    basis = np.empty((n, m2))
    for i in range(k):
        for t in range(n):
            z = rows[0, i, t]
            basis[t, 2 * i] = z.real
            basis[t, 2 * i + 1] = z.imag
    gram = np.zeros((m2, m2))
    bx = np.zeros(m2)
    for t in range(n):
        xt = x[t]
        for a_ in range(m2):
            ba = basis[t, a_]
            bx[a_] += ba * xt
            for b_ in range(a_ + 1):
                gram[a_, b_] += ba * basis[t, b_]
    # G^-1 column by column from its Cholesky factor (forward and back substitution).
    gi = np.empty((m2, m2))
    if not _inverse_spd(gram, m2, gi):
        e = np.empty((0, 0))
        return False, e, e, np.empty(0), np.empty(0), 0.0, e, e
    a = np.zeros(m2)
    for i in range(m2):
        s = 0.0
        for j in range(m2):
            s += gi[i, j] * bx[j]
        a[i] = s
    r = np.empty(n)
    cost = 0.0
    finite = True
    for t in range(n):
        s = x[t]
        for j in range(m2):
            s -= basis[t, j] * a[j]
        r[t] = s
        if not math.isfinite(s):
            finite = False
        cost += s * s
    if not finite:
        cost = math.inf
    jac = np.zeros((n, p))
    for i in range(k):
        ar, ai = a[2 * i], a[2 * i + 1]
        for t in range(n):
            z = rows[1, i, t]
            jac[t, i] = ar * z.real + ai * z.imag
            for j in range(nb - 2):
                z = rows[2 + j, i, t]
                jac[t, k + j] += ar * z.real + ai * z.imag
    # Kaufman: J - B (G^-1 (B^T J)).
    btj = np.zeros((m2, p))
    for t in range(n):
        for a_ in range(m2):
            ba = basis[t, a_]
            for j in range(p):
                btj[a_, j] += ba * jac[t, j]
    c_ = np.zeros((m2, p))
    for a_ in range(m2):
        for j in range(p):
            s = 0.0
            for b_ in range(m2):
                s += gi[a_, b_] * btj[b_, j]
            c_[a_, j] = s
    jp = np.empty((n, p))
    for t in range(n):
        for j in range(p):
            s = jac[t, j]
            for a_ in range(m2):
                s -= basis[t, a_] * c_[a_, j]
            jp[t, j] = s
    return True, basis, gi, a, r, cost, jac, jp


def _normal_py(jp: np.ndarray, r: np.ndarray, p: int):
    """``(J^T J, J^T r)`` of the first ``p`` columns of ``jp`` (the normal equations of a
    Gauss-Newton step), summed row by row."""
    jtj = np.zeros((p, p))
    g = np.zeros(p)
    for t in range(jp.shape[0]):
        rt = r[t]
        for i in range(p):
            ji = jp[t, i]
            g[i] += ji * rt
            for j in range(i + 1):
                jtj[i, j] += ji * jp[t, j]
    for i in range(p):
        for j in range(i):
            jtj[j, i] = jtj[i, j]
    return jtj, g


def _lm_step_py(jp: np.ndarray, r: np.ndarray, p: int, lam: float, lim: np.ndarray):
    """One Levenberg-Marquardt proposal from the projected Jacobian's first ``p`` columns.

    Returns ``(gn, lam, step)``: ``gn = g^T (J^T J)^-1 g`` (the Gauss-Newton step's gain;
    nan where ``J^T J`` is singular), the damping the step was solved at (raised tenfold
    while ``J^T J + lam diag`` is singular, from 1e-9 where ``lam`` is 0; ``>= 1e8``: no
    step) and the step, scaled as a whole so that no parameter moves more than ``lim``.
    """
    jtj, g = _normal_py(jp, r, p)
    d = np.empty(p)
    for i in range(p):
        d[i] = jtj[i, i] if jtj[i, i] > 0.0 else 1.0
    sol = np.empty(p)
    lo = np.zeros((p, p))
    gn = math.nan
    if _cholesky(jtj, p, lo):
        _chol_solve(lo, p, g, sol)
        gn = 0.0
        for i in range(p):
            gn += g[i] * sol[i]
    step = np.zeros(p)
    a = jtj.copy()
    while lam < 1e8:
        for i in range(p):
            a[i, i] = jtj[i, i] + lam * d[i]
        if _cholesky(a, p, lo):
            _chol_solve(lo, p, g, step)
            break
        # raised tenfold; from zero (an undamped request) to the fit's smallest damping
        lam = lam * 10.0 if lam > 0.0 else 1e-9
    if lam < 1e8:
        scale = 1.0
        for i in range(p):
            v = lim[i] / max(abs(step[i]), 1e-300)
            if v < scale:
                scale = v
        for i in range(p):
            step[i] *= scale
    return gn, lam, step


def _shift_rows_py(
    tab: np.ndarray, nt: int, wc: float, m: int, u: np.ndarray, n: int, rows: np.ndarray
):  # fmt: skip
    """Rows ``IFFT(s exp(-j w u_i))[:n]`` and ``IFFT(s (-j w) exp(-j w u_i))[:n]`` from
    the shift tables of one held spectrum ``s`` (no FFT).

    ``tab[q]`` is ``D_q = IFFT(s (w - wc)^q)`` on the ``m``-point grid followed by its
    first ``n`` or more samples again (a circular shift is a slice). With ``u = i + f``,
    ``i = round(u)``:
    ``exp(-j w u) = exp(-j w i) exp(-j wc f) sum_q (-j f (w - wc))^q / q!``; the factor
    ``exp(-j w i)`` is the circular shift by ``i``, so row ``0`` is
    ``exp(-j wc f) sum_q c_q D_q[t - i]`` with ``c_q = (-j f)^q / q!``, ``q < nt``, and
    row ``1`` (``-j w = -j wc - j (w - wc)``) is ``-j wc`` row 0 ``- j exp(-j wc f) sum_q
    c_q D_{q+1}[t - i]``. ``tab`` holds ``nt + 1`` tables.
    """
    # Row 1's series is row 0's on the tables from D_1 on (tab[1:]): the one-row series
    # twice, the second into rows[1], then row 1 = -j wc row 0 - j (that series).
    _shift_row_py(tab[1:], nt, wc, m, u, n, rows[1])
    _shift_row_py(tab, nt, wc, m, u, n, rows[0])
    mjwc = -1j * wc
    for i in range(u.shape[0]):
        for t in range(n):
            rows[1, i, t] = mjwc * rows[0, i, t] - 1j * rows[1, i, t]


def _held_fit_py(
    x: np.ndarray, tab: np.ndarray, nt: int, wc: float, m: int, u0: np.ndarray, u_lo: float,
    u_hi: float, tol: float, max_iter: int,
):  # fmt: skip
    """The whole Levenberg-Marquardt fit of the path onsets with the transducer held.

    The loop of :func:`rangekit.detect.pathfit.fit_paths` (``fit_theta=False``: steps of
    at most 4 samples, damping ``1e-3`` raised tenfold on a rejected step and lowered
    threefold on an accepted one, the same stopping rules), each evaluation the rows of
    :func:`_shift_rows_py` and the step after them of :func:`_vp_py`. Returns ``(ok, u,
    cost, a, r, basis, gram_inv, jac, jp, rows)`` (``rows``: the final state's two rows,
    which :func:`_held_summary_py` reuses); ``ok`` False if a Gram matrix was not
    positive definite (the caller then runs the reference, whose pseudo-inverse copes).
    """
    n = x.shape[0]
    k = u0.shape[0]
    lim = np.full(k, 4.0)
    rows = np.empty((2, k, n), dtype=np.complex128)
    cand = np.empty((2, k, n), dtype=np.complex128)
    u = u0.copy()
    _shift_rows_py(tab, nt, wc, m, u, n, rows)
    ok, basis, gi, a, r, cost, jac, jp = _vp_py(rows, x, n)
    if not ok:
        return False, u, cost, a, r, basis, gi, jac, jp, rows
    lam = 1e-3
    nu = np.empty(k)
    for _ in range(max_iter):
        gn, lam, step = _lm_step_py(jp, r, k, lam, lim)
        if gn < tol:
            break  # the Gauss-Newton step would gain less than tol: converged
        accepted = False
        while lam < 1e8:
            for i in range(k):
                nu[i] = min(max(u[i] + step[i], u_lo), u_hi)
            _shift_rows_py(tab, nt, wc, m, nu, n, cand)
            c_ok, c_basis, c_gi, c_a, c_r, c_cost, c_jac, c_jp = _vp_py(cand, x, n)
            if not c_ok:
                return False, u, cost, a, r, basis, gi, jac, jp, rows
            if c_cost <= cost:
                accepted = True
                lam = max(lam / 3.0, 1e-9)
                break
            lam *= 10.0
            if lam < 1e8:
                _, lam, step = _lm_step_py(jp, r, k, lam, lim)
        if not accepted:
            break
        small = True
        for i in range(k):
            if not abs(nu[i] - u[i]) < 1e-4:
                small = False
        gain = cost - c_cost
        u = nu.copy()
        basis, gi, a, r, cost, jac, jp = c_basis, c_gi, c_a, c_r, c_cost, c_jac, c_jp
        rows, cand = cand, rows
        if gain < tol or (small and (lam < 1.0 or gain <= 1e-12 * cost)):
            break
    return True, u, cost, a, r, basis, gi, jac, jp, rows


def _shift_row_py(
    tab: np.ndarray, nt: int, wc: float, m: int, u: np.ndarray, n: int, out: np.ndarray
):  # fmt: skip
    """Row 0 of :func:`_shift_rows_py` alone (``out[i] = IFFT(spec exp(-j w u_i))[:n]``
    for the tables ``tab`` of any one-sided spectrum ``spec``, ``nt`` of them read)."""
    acc = np.empty(n, dtype=np.complex128)
    for i in range(u.shape[0]):
        sh = int(math.floor(u[i] + 0.5))
        f = u[i] - sh
        start = (-sh) % m
        for t in range(n):
            acc[t] = tab[0, start + t]
        c = 1.0 + 0.0j
        mjf = -1j * f
        for q in range(1, nt):
            c = c * mjf / q
            for t in range(n):
                acc[t] += c * tab[q, start + t]
        e = complex(math.cos(wc * f), -math.sin(wc * f))
        for t in range(n):
            out[i, t] = e * acc[t]


def _inverse_spd(g: np.ndarray, p: int, out: np.ndarray) -> bool:
    """``out = g^-1`` of a symmetric positive definite ``g`` (Cholesky); False if not."""
    lo = np.zeros((p, p))
    if not _cholesky(g, p, lo):
        return False
    unit = np.zeros(p)
    col = np.empty(p)
    for c in range(p):
        unit[c] = 1.0
        _chol_solve(lo, p, unit, col)
        unit[c] = 0.0
        for i in range(p):
            out[i, c] = col[i]
    return True


def _held_summary_py(
    x: np.ndarray, rows01: np.ndarray, tabd: np.ndarray, nt: int, wc: float, m: int,
    u: np.ndarray,
):  # fmt: skip
    """What :func:`rangekit.detect.pathfit._summarize` computes of a held fit's paths
    ``u``: the evaluation with the ``theta`` columns (``rows01`` the paths' waveform and
    onset-derivative rows at ``u``, those of :func:`_held_fit_py`; the rows of
    ``ds / dtheta_j`` from its shift tables ``tabd[j]``) and the Gauss-Newton
    blocks of the projected Jacobian, onsets (``A``), ``theta`` (``C``), cross (``B``).

    Returns ``(ok, a, cost, sig_energy, A^-1, A^-1 B, A^-1 g_u, S, S^-1 (g_t - B^T A^-1
    g_u), S^-1)`` with ``S = C - B^T A^-1 B``; ``ok`` False if the Gram matrix, ``A`` or
    ``S`` is not numerically positive definite (the caller then runs the reference,
    which raises or falls back as its ``np.linalg`` calls do).
    """
    n = x.shape[0]
    k = u.shape[0]
    p = tabd.shape[0]
    rows = np.empty((2 + p, k, n), dtype=np.complex128)
    rows[:2] = rows01
    for j in range(p):
        _shift_row_py(tabd[j], nt, wc, m, u, n, rows[2 + j])
    ok, basis, _, a, r, cost, _, jp = _vp_py(rows, x, n)
    e2 = np.empty((0, 0))
    e1 = np.empty(0)
    if not ok:
        return False, a, cost, 0.0, e2, e2, e1, e2, e1, e2
    q = k + p
    jtj, g = _normal_py(jp, r, q)
    sig_energy = 0.0
    m2 = basis.shape[1]
    for t in range(n):
        v = 0.0
        for c in range(m2):
            v += basis[t, c] * a[c]
        sig_energy += v * v
    amat = jtj[:k, :k].copy()
    ai = np.empty((k, k))
    if not _inverse_spd(amat, k, ai):
        return False, a, cost, 0.0, e2, e2, e1, e2, e1, e2
    aib = np.zeros((k, p))
    aig = np.zeros(k)
    for i in range(k):
        for j in range(k):
            aig[i] += ai[i, j] * g[j]
            for c in range(p):
                aib[i, c] += ai[i, j] * jtj[j, k + c]
    smat = np.empty((p, p))
    rhs = np.empty(p)
    for i in range(p):
        s_ = g[k + i]
        for j in range(k):
            s_ -= jtj[j, k + i] * aig[j]
        rhs[i] = s_
        for c in range(p):
            s_ = jtj[k + i, k + c]
            for j in range(k):
                s_ -= jtj[j, k + i] * aib[j, c]
            smat[i, c] = s_
    for i in range(p):  # symmetric to rounding: make it exactly so for the factor
        for c in range(i):
            v = 0.5 * (smat[i, c] + smat[c, i])
            smat[i, c] = v
            smat[c, i] = v
    si = np.empty((p, p))
    if not _inverse_spd(smat, p, si):
        return False, a, cost, 0.0, e2, e2, e1, e2, e1, e2
    d = np.zeros(p)
    for i in range(p):
        for j in range(p):
            d[i] += si[i, j] * rhs[j]
    return True, a, cost, sig_energy, ai, aib, aig, smat, d, si


def _stable_order(v: np.ndarray) -> np.ndarray:
    """``np.argsort(v, kind="stable")`` of a short vector (insertion sort)."""
    k = v.shape[0]
    order = np.arange(k)
    for i in range(1, k):
        j = i
        while j > 0 and v[order[j - 1]] > v[order[j]]:
            order[j - 1], order[j] = order[j], order[j - 1]
            j -= 1
    return order


def _held_result_py(
    x: np.ndarray, rows01: np.ndarray, tabd: np.ndarray, nt: int, wc: float, m: int,
    u: np.ndarray, theta: np.ndarray, n0: float, lo: float, hi: float, sigma: float,
    energy: float, k_noise: float, rel_threshold: float, tstep: np.ndarray,
):  # fmt: skip
    """The whole of :func:`rangekit.detect.pathfit._summarize` of a held fit but its
    ``PathFit``: :func:`_held_summary_py`'s blocks, then the first path (the earliest
    path inside ``[lo - 1, hi)`` that clears ``k_noise`` and ``rel_threshold`` of the
    strongest inside, else the strongest), its Newton step, gain and variances, and the
    values at the arrival's own ``theta_hat`` (``PathFit.at``).

    Returns ``(status, first_s, onsets, amplitudes, onset, sigma_onset, snr, misfit,
    misfit_z, chi2, theta_hat, info, gain, var_given)``; ``status`` 0: not positive
    definite (the caller runs the reference), 1: done, 2: no path inside (None).
    """
    n = x.shape[0]
    k = u.shape[0]
    p = tabd.shape[0]
    ok, a, cost, sig_energy, ai, aib, aig, smat, d, si = _held_summary_py(
        x, rows01, tabd, nt, wc, m, u
    )
    e1 = np.empty(0)
    e2 = np.empty((0, 0))
    if not ok:
        return 0, 0, e1, e1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, e1, e2, e1, 0.0
    amp = np.empty(k)
    u_abs = np.empty(k)
    inside = np.zeros(k, dtype=np.bool_)
    se = math.sqrt(energy)
    any_in = False
    for i in range(k):
        amp[i] = np.hypot(a[2 * i], a[2 * i + 1])
        u_abs[i] = n0 + u[i]
        inside[i] = (u_abs[i] >= lo - 1.0) and (u_abs[i] < hi)
        any_in = any_in or inside[i]
    if not any_in:
        return 2, 0, e1, e1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, e1, e2, e1, 0.0
    top = -1.0
    strongest = 0
    for i in range(k):
        v = amp[i] if inside[i] else -1.0
        if v > top:
            top, strongest = v, i
    first = strongest
    for i in _stable_order(u):
        if inside[i] and u_abs[i] < u_abs[strongest] and amp[i] * se / sigma >= k_noise:
            if amp[i] >= rel_threshold * top:
                first = i
                break
    newton = aig[first]
    onset_lin = u_abs[first] + (newton if abs(newton) < 1.0 else 0.0)
    gain = np.empty(p)
    theta_hat = np.empty(p)
    info = np.empty((p, p))
    good = True
    s2 = sigma**2
    for j in range(p):
        gain[j] = -aib[first, j]
        theta_hat[j] = theta[j] + d[j]
        if not (math.isfinite(theta_hat[j]) and abs(theta_hat[j] - theta[j]) <= 3.0 * tstep[j]):
            good = False
        for c in range(p):
            info[j, c] = smat[j, c] / s2
    if not good:
        theta_hat[:] = theta  # a Newton step beyond the fit's reach: keep the fit's value
    var_given = s2 * ai[first, first]
    dof = max(1, n - 2 * k - k - 2)
    misfit = (cost - dof * s2) / sig_energy if sig_energy > 0 else 0.0
    order = _stable_order(u_abs)
    onsets = np.empty(k)
    amps = np.empty(k)
    first_s = 0
    for i in range(k):
        onsets[i] = u_abs[order[i]]
        amps[i] = amp[order[i]]
        if order[i] == first:
            first_s = i
    onsets[first_s] = onset_lin
    onset = onsets[first_s]
    var = var_given
    for j in range(p):
        onset += gain[j] * (theta_hat[j] - theta[j])
        for c in range(p):
            var += gain[j] * (si[j, c] * s2) * gain[c]
    return (
        1, first_s, onsets, amps, onset, math.sqrt(max(var, 0.0)), amp[first] * se / sigma,
        misfit, (cost / s2 - dof) / math.sqrt(2.0 * dof), cost / s2, theta_hat, info, gain,
        var_given,
    )  # fmt: skip


_KERNELS = {"vp": _vp_py, "lm_step": _lm_step_py, "held_fit": _held_fit_py,
            "shift_rows": _shift_rows_py, "held_result": _held_result_py}  # fmt: skip
#: Helpers the kernels call, compiled into this module's namespace first.
_HELPERS = ("_cholesky", "_chol_solve", "_normal_py", "_inverse_spd", "_vp_py", "_lm_step_py",
            "_shift_row_py", "_shift_rows_py", "_held_summary_py", "_stable_order")  # fmt: skip


@functools.cache
def _compiled(name: str, cache: bool = True):
    """The numba-compiled kernel ``name`` (numba imported on first use only; the
    helpers it calls compiled first, in this module's namespace)."""
    import numba

    g = globals()
    for h in _HELPERS:
        if not isinstance(g[h], numba.core.registry.CPUDispatcher):
            g[h] = numba.njit(cache=cache, nogil=True)(g[h])
    fn = _KERNELS[name]
    for h in _HELPERS:
        if getattr(g[h], "py_func", None) is fn:
            return g[h]
    return numba.njit(cache=cache, nogil=True)(fn)


def call(name: str, *args):
    """Run the compiled kernel ``name`` (contiguous float64 / complex128 arrays, scalars)."""
    try:
        return _compiled(name)(*args)
    except ModuleNotFoundError:
        # numba's disk cache stores the defining module's name and re-imports it on load;
        # an entry written under another module name cannot be loaded: compile uncached.
        return _compiled(name, False)(*args)
