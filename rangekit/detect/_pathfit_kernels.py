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
    lo = np.zeros((m2, m2))
    if not _cholesky(gram, m2, lo):
        e = np.empty((0, 0))
        return False, e, e, np.empty(0), np.empty(0), 0.0, e, e
    # G^-1 column by column from the factor (forward and back substitution).
    gi = np.empty((m2, m2))
    unit = np.zeros(m2)
    col = np.empty(m2)
    for c in range(m2):
        unit[c] = 1.0
        _chol_solve(lo, m2, unit, col)
        unit[c] = 0.0
        for i in range(m2):
            gi[i, c] = col[i]
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


def _lm_step_py(jp: np.ndarray, r: np.ndarray, p: int, lam: float, lim: np.ndarray):
    """One Levenberg-Marquardt proposal from the projected Jacobian's first ``p`` columns.

    Returns ``(gn, lam, step)``: ``gn = g^T (J^T J)^-1 g`` (the Gauss-Newton step's gain;
    nan where ``J^T J`` is singular), the damping the step was solved at (raised tenfold
    while ``J^T J + lam diag`` is singular; ``>= 1e8``: no step) and the step, scaled as a
    whole so that no parameter moves more than ``lim``.
    """
    n = jp.shape[0]
    jtj = np.zeros((p, p))
    g = np.zeros(p)
    for t in range(n):
        rt = r[t]
        for i in range(p):
            ji = jp[t, i]
            g[i] += ji * rt
            for j in range(i + 1):
                jtj[i, j] += ji * jp[t, j]
    for i in range(p):
        for j in range(i):
            jtj[j, i] = jtj[i, j]
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
        lam *= 10.0
    if lam < 1e8:
        scale = 1.0
        for i in range(p):
            v = lim[i] / max(abs(step[i]), 1e-300)
            if v < scale:
                scale = v
        for i in range(p):
            step[i] *= scale
    return gn, lam, step


_KERNELS = {"vp": _vp_py, "lm_step": _lm_step_py}


@functools.cache
def _compiled(name: str, cache: bool = True):
    """The numba-compiled kernel ``name`` (numba imported on first use only; the
    Cholesky helpers compiled first, in this module's namespace)."""
    import numba

    g = globals()
    for h in ("_cholesky", "_chol_solve"):
        if not isinstance(g[h], numba.core.registry.CPUDispatcher):
            g[h] = numba.njit(cache=cache, nogil=True)(g[h])
    return numba.njit(cache=cache, nogil=True)(_KERNELS[name])


def call(name: str, *args):
    """Run the compiled kernel ``name`` (contiguous float64 / complex128 arrays, scalars)."""
    try:
        return _compiled(name)(*args)
    except ModuleNotFoundError:
        # numba's disk cache stores the defining module's name and re-imports it on load;
        # an entry written under another module name cannot be loaded: compile uncached.
        return _compiled(name, False)(*args)
